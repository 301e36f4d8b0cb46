"""Shared fixtures: a really rendered mini dataset; torch's global generator seeded per test."""

from __future__ import annotations

from pathlib import Path

import pytest

import datagen  # noqa: F401  (each stage's package registers its config schema)
import localize  # noqa: F401
import train  # noqa: F401
from core.config import TINY_DATAGEN, compose_config


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> Path:
    """A mini dataset rendered by the real datagen (128x96; 12/4/4 images; two 30-frame
    flights at 10 fps). Read-only: copy it before changing anything."""
    from datagen.generate import run

    out = tmp_path_factory.mktemp("datasets") / "tiny"
    cfg = compose_config("datagen", [*TINY_DATAGEN, "name=tiny", f"out_dir={out}"])
    return run(cfg, progress=False)


@pytest.fixture(autouse=True)
def _seed_torch():
    """Every test starts from the same torch global generator state, so a test that draws from
    it (``torch.rand`` without a generator) gives the same numbers whatever ran before it."""
    import torch

    torch.manual_seed(0)
