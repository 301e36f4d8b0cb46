"""LR-ASPP (model=lraspp): builds, trains, exports with parity, runs end to end; the CPU-time
budget (budget_clock=cpu) and the checkpoint pick by boundary F (eval.select=boundary_f)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import train.run as tt
from core.classes import as_json
from core.dataset import Dataset
from core.segmenter import OnnxSegmenter, read_metadata
from train.budget import budget_clock
from train.data import AugmentConfig, load_split, to_float
from train.deploy.export import ParityError, export_checked, onnx_metadata
from train.loop.checkpoint import load_checkpoint, save_best
from train.loop.epoch import train_one_epoch
from train.losses import segmentation_loss
from train.net.build import build_model, model_kwargs
from train.net.lraspp import LRASPPNet
from train.net.segnet import SegNet
from train.run_identity import training_config

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"


def lraspp_model_cfg(*overrides: str) -> dict:
    """conf/train.yaml's ``model`` with ``model=lraspp``, as ``python -m train`` composes it."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("train", overrides=["model=lraspp", *overrides])
    return OmegaConf.to_container(cfg.model)


@pytest.fixture(scope="module")
def model() -> LRASPPNet:
    return build_model(lraspp_model_cfg(), 8, torch.Generator().manual_seed(0)).eval()


def test_builds_from_the_preset(model: LRASPPNet) -> None:
    """model=lraspp builds LR-ASPP: logits at the input's size (padded inside), the head's at
    1/8; the same seed draws the same weights, another seed others."""
    assert isinstance(model, LRASPPNet) and model.channels == [24, 576, 128]
    assert 0.9e6 < sum(p.numel() for p in model.parameters()) < 1.3e6
    x = torch.rand(2, 3, 48, 72, generator=torch.Generator().manual_seed(1))  # 72: padded
    with torch.inference_mode():
        assert model(x).shape == (2, 8, 48, 72)
        assert model.forward_network_resolution(x).shape == (2, 8, 6, 9)
    again = build_model(lraspp_model_cfg(), 8, torch.Generator().manual_seed(0))
    other = build_model(lraspp_model_cfg(), 8, torch.Generator().manual_seed(1))
    w = [m.state_dict()["head.low_classifier.weight"] for m in (model, again, other)]
    assert torch.equal(w[0], w[1]) and not torch.equal(w[0], w[2])
    assert isinstance(build_model({}, 8), SegNet)  # no arch: the SegNet


def test_segnet_options_refused() -> None:
    with pytest.raises(ValueError, match="model.head='sharpen' is a SegNet option"):
        model_kwargs(lraspp_model_cfg("model.head=sharpen"))
    with pytest.raises(ValueError, match="model.arch='unet': use segnet or lraspp"):
        build_model({"arch": "unet"}, 8)


def test_trains(synthetic_dataset: Path) -> None:
    """Steps on the synthetic corridor lower the loss, at the head's resolution (labels reduced
    8x) and at the input's."""
    data = load_split(Dataset(synthetic_dataset), "train", 8, limit=8)
    for full_labels in (False, True):
        net = build_model(lraspp_model_cfg(), 8, torch.Generator().manual_seed(0))
        opt = torch.optim.AdamW(net.parameters(), lr=1e-2)
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda _: 1.0)
        gen = torch.Generator().manual_seed(0)
        losses = [train_one_epoch(net, data, None, opt, sched, AugmentConfig(), gen, 4,
                                  full_labels=full_labels).loss for _ in range(8)]
        assert all(math.isfinite(v) for v in losses) and losses[-1] < 0.8 * losses[0], losses
    x, y = to_float(data.images), data.labels.long()
    net.eval()
    with torch.inference_mode():  # and the trained network beats chance on what it saw
        assert (net(x).argmax(1) == y).float().mean() > 0.4
        assert segmentation_loss(net(x), y) < losses[0]


def test_exports_with_parity(model: LRASPPNet, tmp_path: Path) -> None:
    """The ONNX graph matches torch within the export's tolerance, gives labels at the input's
    resolution as the localizer reads them, and describes LR-ASPP in its metadata."""
    g = torch.Generator().manual_seed(2)
    with torch.no_grad():  # logits of a trained network's size, not a fresh one's
        model.head.low_classifier.weight.normal_(0.0, 2.0, generator=g)
    images = torch.rand(3, 3, 48, 64, generator=g)
    meta = onnx_metadata(model, as_json(), 48, 64, "test")
    report = export_checked(model, tmp_path / "segnet.onnx", images, meta, batch_size=2)
    assert report.max_abs_diff <= 1e-4 and report.labels_output_mismatch == 0
    seg = OnnxSegmenter(tmp_path / "segnet.onnx")
    rgb = (images.permute(0, 2, 3, 1).numpy() * 255).round().astype(np.uint8)
    with torch.inference_mode():
        ref = model(torch.from_numpy(rgb).permute(0, 3, 1, 2).float() / 255).numpy()
    logits, labels = seg.logits_and_labels(rgb)
    assert labels.shape == (3, 48, 64)
    np.testing.assert_allclose(logits, ref, atol=1e-4)
    assert (labels == ref.argmax(1)).mean() > 0.999
    read = read_metadata(tmp_path / "segnet.onnx")
    assert read["model"]["architecture"].startswith("LR-ASPP")
    assert read["padding"]["multiple"] == 16
    with pytest.raises(ParityError):  # a tolerance it cannot meet: the check is real
        export_checked(model, tmp_path / "tight.onnx", images, meta, tolerance=0.0)


def test_checkpoint_rebuilds_lraspp(model: LRASPPNet, tmp_path: Path) -> None:
    save_best(tmp_path / "checkpoint_best.pt", model, lraspp_model_cfg(), as_json(), 8, 1, {},
              "h")
    back = load_checkpoint(tmp_path / "checkpoint_best.pt")
    assert isinstance(back, LRASPPNet)
    x = torch.rand(1, 3, 48, 64)
    with torch.inference_mode():
        torch.testing.assert_close(back(x), model(x))


def test_config_hash_keeps_segnet_identity() -> None:
    """The LR-ASPP-only keys stay out of a SegNet's hashed config (folders trained before
    them keep their identity) and are in an LR-ASPP's."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        seg = training_config(compose("train"))
        lr = training_config(compose("train", overrides=["model=lraspp", "budget_clock=cpu"]))
    assert "arch" not in seg["model"] and "inter_channels" not in seg["model"]
    assert lr["model"]["arch"] == "lraspp" and lr["model"]["inter_channels"] == 128
    assert "budget_clock" not in lr  # times the run, as max_minutes does


def test_cpu_clock_counts_cpu_not_wall(synthetic_dataset: Path) -> None:
    """budget_clock=cpu: a deadline in CPU seconds ignores time spent waiting (here asleep),
    which the wall clock counts, and stops the epoch once the CPU time is spent."""
    data = load_split(Dataset(synthetic_dataset), "train", 8, limit=16)
    net = SegNet(8, width=0.125, stages=2, convs_per_stage=[1, 1],
                 generator=torch.Generator().manual_seed(0))
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda _: 1.0)

    def epoch(clock, deadline):
        return train_one_epoch(net, data, None, opt, sched, AugmentConfig(),
                               torch.Generator().manual_seed(0), 2, deadline=deadline,
                               clock=clock)

    assert budget_clock("cpu") is time.process_time and budget_clock("wall") is time.monotonic
    with pytest.raises(ValueError, match="budget_clock='gpu': use wall or cpu"):
        budget_clock("gpu")
    wall, cpu = budget_clock("wall"), budget_clock("cpu")
    w0, c0 = wall(), cpu()
    time.sleep(0.6)  # 0.6 s of wall time, next to no CPU time
    stopped_wall = epoch(wall, w0 + 0.5)
    assert stopped_wall.stopped and stopped_wall.steps == 0
    c1 = cpu()
    done = epoch(cpu, c0 + 60.0)
    assert not done.stopped and done.steps == 8
    # a CPU deadline of about three steps' CPU time: stopped part way
    short = epoch(cpu, cpu() + 3 * (cpu() - c1) / 8)
    assert short.stopped and 1 <= short.steps < 8, short


@pytest.mark.slow
def test_run_end_to_end(synthetic_dataset: Path, compose_train, tmp_path: Path) -> None:
    """python -m train model=lraspp budget_clock=cpu eval.select=boundary_f: the folder holds an
    LR-ASPP graph, its test scores with boundary F per class pair; the kept epoch is the one
    of best validation boundary F; the CPU seconds are what the run spent."""
    c0 = time.process_time()
    metrics = tt.run(compose_train(synthetic_dataset, tmp_path, "model=lraspp",
                                   "loss.resolution=input", "budget_clock=cpu",
                                   "eval.select=boundary_f", "epochs=3", "export.int8=false"))
    spent = time.process_time() - c0
    out = tmp_path / "demo"
    on_disk = json.loads((out / "metrics.json").read_text())
    assert on_disk["model"]["arch"] == "lraspp" and on_disk["budget_clock"] == "cpu"
    assert 0 < on_disk["train_seconds"] < spent
    test = on_disk["test"]
    assert 0.0 <= test["boundary_f"] <= 1.0
    pairs = test["per_pair_boundary"]
    assert "floor | wall" in pairs and "wall | door" in pairs
    assert sum(p["true_px"] for p in pairs.values()) > 0
    for p in pairs.values():
        assert p["boundary_f"] is None or 0.0 <= p["boundary_f"] <= 1.0
    val_f = [row["val_boundary_f"] for row in metrics_history(out)]
    assert metrics["best_epoch"] == 1 + int(np.nanargmax(val_f))
    assert read_metadata(out / "segnet.onnx")["model"]["architecture"].startswith("LR-ASPP")
    assert OnnxSegmenter(out / "segnet.onnx").labels(np.zeros((48, 64, 3), np.uint8)).shape \
        == (48, 64)


def metrics_history(out: Path) -> list[dict]:
    return torch.load(out / "checkpoint_last.pt", map_location="cpu",
                      weights_only=False)["history"]


@pytest.mark.parametrize("override,match", [
    ("eval.select=loss", "eval.select='loss': use one of mean_iou"),
    ("finish_by=1", "finish_by is a wall-clock time and budget_clock=cpu"),
])
def test_bad_settings(synthetic_dataset, compose_train, tmp_path, override, match) -> None:
    with pytest.raises(ValueError, match=match):
        tt.run(compose_train(synthetic_dataset, tmp_path, "budget_clock=cpu", override))
    assert not any(tmp_path.iterdir())  # nothing written
