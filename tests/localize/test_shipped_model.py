"""models/generalist/: the SegNet that ships with the code, for buildings it never saw. It is
small enough to keep in the repository, carries its classes and test scores, segments a
freshly rendered corridor it was never trained in, and fine-tuning can start from it."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from core import classes as C
from core.atomic import read_png
from core.config import TINY_DATAGEN, compose_config
from core.dataset import Dataset
from localize.frontend.segmenter import SHIPPED_MODEL, load_segmenter
from train.metrics import confusion_matrix, scores

FOLDER = SHIPPED_MODEL.parent


def test_small_and_complete():
    assert SHIPPED_MODEL.stat().st_size <= 10 * 2**20
    for name in ("checkpoint_best.pt", "metrics.json", "README.md"):
        assert (FOLDER / name).is_file(), name
    seg = load_segmenter(SHIPPED_MODEL, C.as_json())  # raises on another class list
    assert seg.metadata["test_metrics"]["mean_iou"] > 0.5
    metrics = json.loads((FOLDER / "metrics.json").read_text())
    meta = seg.metadata["test_metrics"]
    assert {k: metrics["test"][k] for k in meta} == meta


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    """Four test images of the corridor at the shipped model's 320 x 240, no flights."""
    from datagen.generate import run

    out = tmp_path_factory.mktemp("datasets") / "corridor"
    cfg = compose_config("datagen", [
        *TINY_DATAGEN, "name=corridor", f"out_dir={out}", "camera.width=320",
        "camera.height=240", "splits.train=0", "splits.val=0", "splits.test=4",
        "render_flights=[]", "val_flights=[]"])
    return Dataset(run(cfg, progress=False))


def test_segments_a_building_it_never_saw(corridor):
    """On the corridor (no image of which it was trained on) most pixels get their class."""
    seg = load_segmenter(SHIPPED_MODEL, corridor.classes)
    rgb_paths, label_paths = corridor.split("test")
    pred = seg.labels(np.stack([read_png(p) for p in rgb_paths]))
    truth = np.stack([read_png(p, rgb=False) for p in label_paths])
    s = scores(confusion_matrix(torch.from_numpy(pred.astype(np.int64)),
                                torch.from_numpy(truth.astype(np.int64)), len(C.as_json())))
    assert s["pixel_accuracy"] > 0.75
