"""Confusion matrix and SegNet-paper scores against hand-computed values."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from core import classes as C
from train.metrics import (
    IGNORE,
    boundary_counts,
    boundary_f,
    class_boundaries,
    confusion_matrix,
    metrics_json,
    pair_boundary_counts,
    pair_boundary_json,
    plot_confusion,
    scores,
)


class TestConfusionMatrix:
    def test_hand_made(self) -> None:
        target = torch.tensor([[0, 0, 1, 1], [2, 2, 255, 1]])
        pred = torch.tensor([[0, 1, 1, 1], [2, 0, 2, 0]])
        cm = confusion_matrix(pred, target, 3)
        expected = [
            [1, 1, 0],  # true 0: one right, one as 1
            [1, 2, 0],  # true 1: two right, one as 0 (the 255 pixel is skipped)
            [1, 0, 1],
        ]  # true 2: one right, one as 0
        assert cm.tolist() == expected

    def test_shape_mismatch(self) -> None:
        with pytest.raises(ValueError, match="differ"):
            confusion_matrix(torch.zeros(2, 2), torch.zeros(2, 3), 3)

    def test_out_of_range(self) -> None:
        with pytest.raises(ValueError, match="outside"):
            confusion_matrix(torch.tensor([3]), torch.tensor([0]), 3)


class TestScores:
    def test_hand_computed(self) -> None:
        cm = np.array([[1, 1, 0], [1, 2, 0], [1, 0, 1]])
        s = scores(cm)
        assert s["pixel_accuracy"] == pytest.approx(4 / 7)
        # recalls 1/2, 2/3, 1/2
        assert s["class_accuracy"] == pytest.approx((1 / 2 + 2 / 3 + 1 / 2) / 3)
        # IoU = tp / (gt + pred - tp): 1/(2+3-1), 2/(3+3-2), 1/(2+1-1)
        np.testing.assert_allclose(s["iou"], [1 / 4, 2 / 4, 1 / 2])
        assert s["mean_iou"] == pytest.approx((1 / 4 + 1 / 2 + 1 / 2) / 3)

    def test_absent_class_excluded(self) -> None:
        # class 2 never in the truth, predicted once (a false positive for class 0's pixel)
        cm = np.array([[3, 0, 1], [0, 4, 0], [0, 0, 0]])
        s = scores(cm)
        assert math.isnan(s["iou"][2]) and not s["present"][2]
        assert s["mean_iou"] == pytest.approx((3 / 4 + 1.0) / 2)
        assert s["class_accuracy"] == pytest.approx((3 / 4 + 1.0) / 2)
        assert s["pixel_accuracy"] == pytest.approx(7 / 8)

    def test_perfect(self) -> None:
        s = scores(np.diag([5, 0, 2]))
        assert s["pixel_accuracy"] == s["class_accuracy"] == s["mean_iou"] == 1.0

    def test_metrics_json_and_plot(self, tmp_path) -> None:
        cm = np.array([[3, 0, 1], [0, 4, 0], [0, 0, 0]])
        d = metrics_json(cm, ["a", "b", "c"])
        json.dumps(d)  # serializable
        assert d["per_class_iou"] == {"a": 0.75, "b": 1.0, "c": None}
        for k in ("pixel_accuracy", "class_accuracy", "mean_iou"):
            assert 0.0 <= d[k] <= 1.0
        plot_confusion(cm, ["a", "b", "c"], tmp_path / "cm.png", title="t")
        assert (tmp_path / "cm.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


class TestBoundaryF:
    @staticmethod
    def halves(col: int, shape=(20, 30)) -> np.ndarray:
        """Class 1 left of column ``col``, class 2 from it on."""
        lab = np.full(shape, 2, np.uint8)
        lab[:, :col] = 1
        return lab

    def test_boundaries_where_the_class_changes(self):
        b = class_boundaries(self.halves(10))
        assert b[:, 9].all() and b.sum() == 20
        ignored = self.halves(10)
        ignored[:, 10] = IGNORE
        assert not class_boundaries(ignored).any()

    def test_perfect_shifted_and_missing(self):
        truth = self.halves(10)
        assert boundary_f(boundary_counts(truth, truth))["boundary_f"] == 1.0
        near = boundary_f(boundary_counts(self.halves(12), truth, tolerance_px=2))
        far = boundary_f(boundary_counts(self.halves(14), truth, tolerance_px=2))
        assert near["boundary_f"] == 1.0 and far["boundary_f"] == 0.0
        none = boundary_f(boundary_counts(np.full_like(truth, 1), truth))
        assert math.isnan(none["boundary_precision"]) and none["boundary_recall"] == 0.0

    def test_spurious_edges_lower_precision_only(self):
        truth = self.halves(10)
        pred = truth.copy()
        pred[5:8, 20:25] = 3  # a blob where the truth is plain
        f = boundary_f(boundary_counts(pred, truth))
        assert f["boundary_recall"] == 1.0 and 0.3 < f["boundary_precision"] < 1.0

    def test_per_pair_tells_which_boundary_is_wrong(self):
        """A door predicted as wall: the floor | wall boundary stays right, the wall | door one
        is missed entirely, though the overall boundary F is still high."""
        truth = np.full((20, 30), C.WALL, np.uint8)
        truth[12:] = C.FLOOR
        truth[2:12, 10:16] = C.DOOR
        pred = truth.copy()
        pred[2:12, 10:16] = C.WALL
        pairs = pair_boundary_counts(pred, truth)
        names = [c["name"] for c in C.as_json()]
        out = pair_boundary_json(pairs, names)
        assert set(out) == {"wall | door", "floor | wall", "floor | door"}
        assert out["wall | door"]["boundary_f"] == 0.0
        assert out["wall | door"]["predicted_px"] == 0 and out["wall | door"]["true_px"] > 10
        assert out["floor | wall"]["boundary_f"] > 0.85
        assert boundary_f(boundary_counts(pred, truth))["boundary_f"] > 0.6
        # a right prediction scores every pair 1; an ignored truth pixel counts for neither
        truth[5, :] = IGNORE
        perfect = pair_boundary_json(pair_boundary_counts(truth, truth), names)
        assert all(p["boundary_f"] == 1.0 for p in perfect.values())
        test = metrics_json(confusion_matrix(torch.from_numpy(pred), torch.from_numpy(truth),
                                             8).numpy(), names, boundary_counts(pred, truth),
                            pair_boundary_counts(pred, truth))
        assert test["per_pair_boundary"]["wall | door"]["boundary_f"] == 0.0
        assert 0.6 < test["boundary_f"] < 1.0
