"""The keep rule of a fine-tune (train/keep.py): the fine-tuned network ships only where the
validation images show a boundary-F gain beyond their noise; otherwise the folder's segnet.onnx
is the starting network's. Real tiny trainings: a harmful fine-tune keeps its start, one that
learns keeps itself."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import train.run as tt
from core import classes as C
from core.atomic import read_png
from core.dataset import Dataset
from core.segmenter import OnnxSegmenter, read_metadata
from train.config import KeepConfig
from train.keep import SCORES, decide, mean_iou_of, paired_bootstrap
from train.loop.evaluate import ImageScores
from train.metrics import boundary_counts, confusion_matrix, scores

# ------------------------------------------------------------------------ the rule on its own


def image_scores(rng: np.random.Generator, n: int, hit: float, size: int = 40) -> ImageScores:
    """Scores of n images of a two-class (left / right) scene, each predicted with its
    boundary moved by a random shift, right within 2 px with probability ``hit``.

    Args:
        rng: draws the shifts.
        n: images.
        hit: chance that an image's predicted boundary lies within 2 px of the true one.
        size: the images' side (px).
    """
    truth = np.zeros((size, size), np.int64)
    truth[:, size // 2:] = 1
    cms, counts = [], []
    for _ in range(n):
        shift = int(rng.integers(0, 3)) if rng.random() < hit else int(rng.integers(4, 9))
        pred = np.zeros_like(truth)
        pred[:, size // 2 + shift:] = 1
        cms.append(confusion_matrix(_t(pred), _t(truth), 2).numpy())
        counts.append(boundary_counts(pred, truth))
    return ImageScores(np.stack(cms), np.stack(counts))


def _t(a: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(a.astype(np.int64))


def test_the_same_network_keeps_the_start() -> None:
    """No training (the scores equal): no gain, the starting network ships."""
    s = image_scores(np.random.default_rng(0), 30, 0.7)
    d = decide(s, s, KeepConfig(init_unless_gain=True), "models/generalist",
               np.random.default_rng(0))
    assert d.kept == "init" and d.gain == {"boundary_f": 0.0, "mean_iou": 0.0}
    assert d.message().startswith("kept generalist (init_from=models/generalist): val "
                                  "boundary F")
    assert d.message().endswith("30 images: no gain beyond the margin")


def test_a_clear_gain_ships_the_fine_tune() -> None:
    rng = np.random.default_rng(1)
    before, after = image_scores(rng, 30, 0.3), image_scores(rng, 30, 0.95)
    d = decide(before, after, KeepConfig(init_unless_gain=True), "a/checkpoint_best.pt",
               np.random.default_rng(0))
    assert d.kept == "finetuned" and d.gain["boundary_f"] > d.margin["boundary_f"] > 0
    assert d.finetuned["boundary_f"] == pytest.approx(after.summary()["boundary_f"])
    assert "fine-tuned network over a:" in d.message()
    assert json.loads(json.dumps(d.as_dict()))["kept"] == "finetuned"


def test_a_boundary_gain_with_wrong_regions_keeps_the_start() -> None:
    """Boundary F up, but mean IoU down beyond its margin (a class swapped): no."""
    rng = np.random.default_rng(2)
    before, after = image_scores(rng, 30, 0.3), image_scores(rng, 30, 0.95)
    swapped = after.confusion[:, :, ::-1].copy()  # every pixel labelled the other class
    d = decide(before, ImageScores(swapped, after.boundary), KeepConfig(init_unless_gain=True),
               "g", np.random.default_rng(0))
    assert d.gain["boundary_f"] > d.margin["boundary_f"]
    assert d.gain["mean_iou"] < -d.margin["mean_iou"] and d.kept == "init"
    assert d.reason() == "the fine-tune loses mIoU beyond the margin"


def test_regions_decide_where_boundaries_tie() -> None:
    """Boundary F the same, mean IoU clearly up (the corridor's own SegNet against the
    generalist): the fine-tune ships."""
    before = image_scores(np.random.default_rng(6), 30, 0.7)
    better = before.confusion.copy()
    fixed = better[:, 1, 0] // 2  # half the right side's pixels labelled left, put right
    better[:, 1, 1] += fixed
    better[:, 1, 0] -= fixed
    d = decide(before, ImageScores(better, before.boundary), KeepConfig(init_unless_gain=True),
               "g", np.random.default_rng(0))
    assert d.gain["boundary_f"] == 0.0 and d.gain["mean_iou"] > d.margin["mean_iou"]
    assert d.kept == "finetuned"


def test_the_margin_follows_the_validation_noise() -> None:
    """The same modest gain counts on 300 images and not on 6: the bootstrap's standard
    error of the paired difference shrinks as 1 / sqrt(n)."""
    cfg = KeepConfig(init_unless_gain=True, min_gain=0.0)
    kept, se = {}, {}
    for n in (6, 300):
        rng = np.random.default_rng(3)
        before, after = image_scores(rng, n, 0.6), image_scores(rng, n, 0.8)
        d = decide(before, after, cfg, "g", np.random.default_rng(0))
        kept[n], se[n] = d.kept, d.std_error["boundary_f"]
    assert kept == {6: "init", 300: "finetuned"}
    assert se[6] / se[300] == pytest.approx(np.sqrt(300 / 6), rel=0.5)


def test_bootstrap_is_seeded_and_paired() -> None:
    rng = np.random.default_rng(4)
    a, b = image_scores(rng, 20, 0.5), image_scores(rng, 20, 0.7)
    one = paired_bootstrap(a, b, np.random.default_rng(7), 200)
    assert one == paired_bootstrap(a, b, np.random.default_rng(7), 200)
    assert set(one) == set(SCORES) and all(v > 0 for v in one.values())
    # a network against itself: every resample differs by exactly 0
    assert paired_bootstrap(a, a, np.random.default_rng(7), 200) == dict.fromkeys(SCORES, 0.0)


def test_mean_iou_of_matches_the_metrics() -> None:
    cms = np.random.default_rng(5).integers(0, 50, size=(4, 3, 3))
    cms[1, 2, :] = 0  # a class absent from the truth
    assert mean_iou_of(cms) == pytest.approx([scores(c)["mean_iou"] for c in cms])


def test_an_empty_validation_split_is_named() -> None:
    empty = ImageScores(np.zeros((0, 2, 2), np.int64), np.zeros((0, 4), np.int64))
    with pytest.raises(ValueError, match=r"val split is empty.*keep.init_unless_gain=false"):
        decide(empty, empty, KeepConfig(), "g", np.random.default_rng(0))


def test_the_rule_needs_init_from(synthetic_dataset, compose_train, tmp_path) -> None:
    with pytest.raises(ValueError, match=r"keep.init_unless_gain=true .* init_from="):
        tt.run(compose_train(synthetic_dataset, tmp_path, "keep.init_unless_gain=true"))
    assert not (tmp_path / "demo").exists()


# ------------------------------------------------------------------- real tiny fine-tunes


@pytest.fixture(scope="module")
def building(make_dataset, tmp_path_factory) -> Path:
    """A dataset at 128 x 96, large enough for class boundaries 2 px apart to mean something
    (at 64 x 48 nearly every pixel lies within 2 px of one)."""
    root = tmp_path_factory.mktemp("keep") / "building"
    return make_dataset(root, {"train": 32, "val": 12, "test": 4}, seed=3, height=96,
                        width=128)


@pytest.fixture(scope="module")
def start(building, compose_train, tmp_path_factory) -> Path:
    """The network fine-tunes start from: one epoch, far from done."""
    out_root = tmp_path_factory.mktemp("start")
    tt.run(compose_train(building, out_root, "name=start", "epochs=1", "export.int8=false"))
    return out_root / "start"


def val_split(dataset: Path) -> tuple[np.ndarray, np.ndarray]:
    """(N, H, W, 3) RGB images and (N, H, W) labels of the validation split."""
    rgb, label = Dataset(dataset).split("val")
    return (np.stack([read_png(p) for p in rgb]),
            np.stack([read_png(p, rgb=False) for p in label]))


def val_labels(onnx_path: Path, dataset: Path) -> np.ndarray:
    """(N, H, W) labels of a graph on the validation images."""
    return OnnxSegmenter(onnx_path, threads=2).labels(val_split(dataset)[0])


def finetune(building: Path, start: Path, out_root: Path, compose_train, *overrides: str
             ) -> tuple[dict, Path]:
    metrics = tt.run(compose_train(building, out_root, "name=ft", f"init_from={start}",
                                   "keep.init_unless_gain=true", "export.int8=false",
                                   *overrides))
    return metrics, out_root / "ft"


@pytest.mark.slow
def test_a_harmful_fine_tune_keeps_the_start(building, start, compose_train, tmp_path,
                                             capsys) -> None:
    """A learning rate of 1 wrecks the network: the folder ships the start's network, with the
    decision and both scores in metrics.json and the graph's metadata."""
    metrics, out = finetune(building, start, tmp_path, compose_train, "optim.lr=1.0")
    keep = metrics["keep"]
    assert keep["kept"] == "init" and keep["init_from"] == str(start)
    assert keep["finetuned"]["boundary_f"] < keep["init"]["boundary_f"]
    assert keep["images"] == 12 and keep["message"].startswith("kept start (init_from=")
    assert json.loads((out / "metrics.json").read_text())["keep"] == keep
    assert read_metadata(out / "segnet.onnx")["keep"] == {"kept": "init",
                                                          "init_from": str(start)}
    assert "(init_from's network" in capsys.readouterr().out
    # the start's own graph and the folder's label the images alike
    same = val_labels(out / "segnet.onnx", building) == val_labels(start / "segnet.onnx",
                                                                    building)
    assert same.mean() > 0.999
    # the test scores are the shipped graph's
    assert metrics["test"]["mean_iou"] < 1.0
    again = tt.run(compose_train(building, tmp_path, "name=ft", f"init_from={start}",
                                 "keep.init_unless_gain=true", "export.int8=false",
                                 "optim.lr=1.0"))
    assert again["keep"] == keep  # a re-run decides alike (the baseline kept in the state)


@pytest.mark.slow
def test_a_fine_tune_that_learns_keeps_itself(building, start, compose_train, tmp_path
                                              ) -> None:
    metrics, out = finetune(building, start, tmp_path, compose_train, "epochs=3")
    keep = metrics["keep"]
    assert keep["kept"] == "finetuned"
    assert keep["gain"]["boundary_f"] > keep["margin"]["boundary_f"] >= 0.01
    assert keep["finetuned"]["boundary_f"] == pytest.approx(
        metrics["val_best"]["val_boundary_f"], abs=1e-4)
    truth = val_split(building)[1]
    miou = {name: scores(confusion_matrix(_t(val_labels(f / "segnet.onnx", building)),
                                          _t(truth), C.NUM_CLASSES))["mean_iou"]
            for name, f in (("ft", out), ("start", start))}
    # the folder's graph is the fine-tune's: its labels score as the rule's figures say
    assert miou["ft"] == pytest.approx(keep["finetuned"]["mean_iou"], abs=0.01)
    assert miou["start"] == pytest.approx(keep["init"]["mean_iou"], abs=0.01)
