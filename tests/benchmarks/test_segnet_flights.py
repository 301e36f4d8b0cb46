"""benchmarks/segnet_flights.py: a SegNet's accuracy on flight frames, as localize reads them."""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import numpy as np

from benchmarks.segnet_flights import confusion, flight_frames
from core import classes as C
from core.atomic import read_png, write_png
from core.dataset import Dataset
from localize.frontend.segmenter import load_segmenter
from tests.localize.conftest import palette_segnet
from train.metrics import scores


def test_flight_frames_leave_out_dropouts():
    flight = SimpleNamespace(rgb=[None] * 6, frames=np.array([0, 1, 2, 4, 5, 7]),
                             info={"dropout": [{"frames": [1, 3]}, {"frames": [7, 8]}]})
    np.testing.assert_array_equal(flight_frames(flight),
                                  [True, False, False, True, True, False])
    flight = SimpleNamespace(rgb=[None] * 3, frames=None, info={})
    assert flight_frames(flight).all()


def test_exact_segmenter_scores_one_and_a_wrong_one_less(tiny_dataset, tmp_path):
    root = tmp_path / "flat"
    shutil.copytree(tiny_dataset, root)
    for label in sorted(root.glob("flights/*/label/*.png")):
        write_png(label.parent.parent / "rgb" / label.name,
                  C.colorize(read_png(label, rgb=False)))
    cam = json.loads((root / "dataset.json").read_text())["camera"]
    onnx = palette_segnet(tmp_path / "segnet.onnx", int(cam["height"]), int(cam["width"]))
    ds = Dataset(root)
    seg = load_segmenter(onnx, ds.classes)
    cm = confusion(seg, ds, "test", seg.num_classes, progress=False)
    frames = sum(len(ds.flight(n).rgb) for n in ds.flight_names("test"))
    assert int(cm.sum()) == frames * int(cam["height"]) * int(cam["width"])
    assert scores(cm)["pixel_accuracy"] == 1.0

    class Wall:  # every pixel wall
        num_classes = seg.num_classes

        def labels(self, rgb):
            return np.full(rgb.shape[:3], C.WALL, dtype=np.uint8)

    wrong = scores(confusion(Wall(), ds, "test", seg.num_classes, progress=False))
    assert 0.0 < wrong["pixel_accuracy"] < 0.9
