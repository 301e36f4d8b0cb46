"""The datagen job: render the training splits and the evaluation flights of one world
(``run``): ``datagen.job`` prepares it, ``datagen.rendering.split`` and
``datagen.rendering.flight`` render it, ``datagen.dataset_writer`` writes it."""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from pathlib import Path

from core.dataset import SPLITS
from datagen.config import DatagenConfig
from datagen.dataset_writer import claim_dataset, write_stats
from datagen.job import prepare
from datagen.rendering.flight import render_flight
from datagen.rendering.split import render_split

log = logging.getLogger(__name__)


def run(cfg: DatagenConfig | Mapping, progress: bool | None = None) -> Path:
    """Render (this shard of) a dataset; returns the dataset directory.

    Args:
        cfg: the settings (``prepare``).
        progress: tqdm progress bars; None: the config's ``progress``.
    """
    from core.imaging.variant import choose_variant

    job = prepare(cfg)
    progress = job.cfg.progress if progress is None else progress
    variant = choose_variant(job.cfg.render.variant)
    with claim_dataset(job, variant):
        t0 = time.perf_counter()
        counts = {s: render_split(job, s, progress) for s in SPLITS if len(job.split_poses[s])}
        counts.update({f"flight:{n}": render_flight(job, n, progress) for n in job.flights})
        seconds = time.perf_counter() - t0
        write_stats(job, variant, counts, seconds)
    return job.out
