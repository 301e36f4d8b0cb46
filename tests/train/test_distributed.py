"""Data-parallel training (train/loop/distributed.py): a 2-process gloo training step against one
process, and ``torchrun -m train`` end to end."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp
import torch.nn.functional as F

import train.loop.epoch as te
import train.run as tt
from core.dataset import Dataset
from tests.train.conftest import TINY_OVERRIDES
from train.config import AugmentConfig, ModelConfig, OptimConfig
from train.data import SplitData, augment_batch, batches, downsample_split, load_split
from train.loop.distributed import SINGLE, DistWorld, check_batch_size
from train.loop.optim import make_optimizer
from train.losses import IGNORE, median_frequency_weights, pixel_loss_weights, segmentation_loss
from train.net.segnet import build_segnet
from train.run_identity import train_settings

REPO = Path(__file__).resolve().parents[2]
MODEL = ModelConfig(width=0.125, stages=3, convs_per_stage=[1, 1, 1])
NUM_CLASSES = 8
BATCH = 4  # one global batch: 2 images per rank
#: No augmentation: identical images stay identical (the "same pixels" case).
NO_AUGMENT = AugmentConfig(scale=(1.0, 1.0), hflip=0.0, brightness=0.0, contrast=0.0,
                           saturation=0.0, hue=0.0, blur_prob=0.0, noise_std=0.0)
#: Gradients of the 2-process step against one process: relative to the largest gradient
#: component. The two differ only by float32 rounding: half-batch sums added by gloo instead
#: of one sum over the batch (1.1e-6 measured); a missing average (factor 2) or
#: BatchNorm statistics of another batch (percent) lie far above.
GRAD_TOLERANCE = 1e-4


def step_data(dataset: Path, same_pixels: bool) -> SplitData:
    """The training split at the network's resolution, ``BATCH`` images: the first ones, or
    (``same_pixels``) the first image's pixels under the first ``BATCH`` images' labels."""
    data = load_split(Dataset(dataset), "train", NUM_CLASSES, limit=BATCH)
    if same_pixels:
        data = SplitData(data.images[:1].expand_as(data.images).clone(), data.labels, data.paths)
    return downsample_split(data, 4)


def one_step(dataset: Path, same_pixels: bool, world: DistWorld = SINGLE,
             ddp: bool = False) -> tuple[torch.nn.Module, SplitData, torch.Tensor, dict]:
    """``train_one_epoch`` over one global batch of ``BATCH`` images (seed 0), as ``python -m
    train`` runs it; returns the network (its gradients of the step in ``.grad``), the data,
    the class weights and the step's settings."""
    data = step_data(dataset, same_pixels)
    weights = median_frequency_weights(data.labels, NUM_CLASSES, 10.0, 0.5)
    model = build_segnet(MODEL, NUM_CLASSES, torch.Generator().manual_seed(0))
    model = model.to(memory_format=torch.channels_last)
    optimizer, scheduler = make_optimizer(model, OptimConfig(), 1)
    settings = {"augment": NO_AUGMENT if same_pixels else AugmentConfig().at_resolution(4),
                "boundary_weight": 1.0 if same_pixels else 2.0}
    res = te.train_one_epoch(
        model, data, weights, optimizer, scheduler, settings["augment"],
        torch.Generator().manual_seed(7), BATCH, world=world,
        boundary_weight=settings["boundary_weight"],
        ddp=te.data_parallel(model, False, False, world) if ddp else None)
    assert res.steps == 1
    settings["loss"] = res.loss
    return model, data, weights, settings


def grads(model: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: p.grad.detach().clone() for k, p in model.named_parameters()}


def _worker(rank: int, store: str, dataset: str, out: str) -> None:
    """One of 2 gloo processes (torch.multiprocessing.spawn): both cases' step, gradients
    saved to ``out/rank<r>.pt``."""
    torch.set_num_threads(1)
    dist.init_process_group("gloo", init_method=f"file://{store}", rank=rank, world_size=2)
    try:
        world, result = DistWorld(rank, 2), {}
        for same in (True, False):
            model, _, _, settings = one_step(Path(dataset), same, world, ddp=True)
            result[same] = {"grads": grads(model), "loss": settings["loss"]}
        torch.save(result, Path(out) / f"rank{rank}.pt")
    finally:
        dist.destroy_process_group()


@pytest.fixture(scope="module")
def two_process_step(synthetic_dataset: Path, tmp_path_factory) -> list[dict]:
    """Both ranks' results of the 2-process step (``_worker``)."""
    out = tmp_path_factory.mktemp("ddp_step")
    mp.spawn(_worker, args=(str(out / "store"), str(synthetic_dataset), str(out)), nprocs=2,
             join=True)
    return [torch.load(out / f"rank{r}.pt", weights_only=False) for r in range(2)]


def assert_grads_close(got: dict, want: dict) -> None:
    scale = max(float(g.abs().max()) for g in want.values())
    for k in want:
        torch.testing.assert_close(got[k], want[k], rtol=0.0, atol=GRAD_TOLERANCE * scale,
                                   msg=lambda m, k=k: f"{k}: {m}")


def relative_difference(got: dict, want: dict) -> float:
    scale = max(float(g.abs().max()) for g in want.values())
    return max(float((got[k] - want[k]).abs().max()) for k in want) / scale


def test_ranks_hold_the_same_gradients(two_process_step: list[dict]) -> None:
    for same in (True, False):
        for k, g in two_process_step[0][same]["grads"].items():
            assert torch.equal(g, two_process_step[1][same]["grads"][k]), k
        assert two_process_step[0][same]["loss"] == two_process_step[1][same]["loss"]


def test_two_processes_match_one(two_process_step: list[dict], synthetic_dataset: Path
                                 ) -> None:
    """Where BatchNorm's per-rank statistics equal the whole batch's (every image the same
    pixels, each its own labels and so its own loss), the averaged gradients of 2 gloo
    processes are the single process's gradients of the same global batch."""
    model, _, _, settings = one_step(synthetic_dataset, same_pixels=True)
    want = grads(model)
    got = two_process_step[0][True]
    assert_grads_close(got["grads"], want)
    assert got["loss"] == pytest.approx(settings["loss"], rel=1e-5)
    print(f"2 processes vs 1: max |grad diff| = {relative_difference(got['grads'], want):.3g} "
          "of the largest gradient")


def test_two_processes_are_one_with_per_rank_batchnorm(two_process_step: list[dict],
                                                       synthetic_dataset: Path) -> None:
    """Distinct augmented images: the 2-process gradients are those of one process whose
    BatchNorm normalizes each half batch on its own (train/loop/distributed.py), and differ from
    the whole-batch statistics' gradients by far more than the tolerance."""
    model, data, weights, settings = one_step(synthetic_dataset, same_pixels=False)
    whole = grads(model)
    model = build_segnet(MODEL, NUM_CLASSES, torch.Generator().manual_seed(0))
    model = model.to(memory_format=torch.channels_last).train()
    gen = torch.Generator().manual_seed(7)
    idx = next(iter(batches(len(data), BATCH, gen, drop_last=True)))
    x, y = augment_batch(data.images[idx], data.labels[idx], settings["augment"], gen)
    w = pixel_loss_weights(y, weights, settings["boundary_weight"])
    numerator = sum(
        (F.cross_entropy(te.training_logits(model, x[h].contiguous(
            memory_format=torch.channels_last), tuple(y.shape[-2:]), False, False), y[h],
            ignore_index=IGNORE, reduction="none") * w[h]).sum()
        for h in (slice(0, BATCH // 2), slice(BATCH // 2, BATCH)))
    (numerator / w.sum()).backward()
    got = two_process_step[0][False]["grads"]
    assert_grads_close(got, grads(model))
    assert relative_difference(got, whole) > 10 * GRAD_TOLERANCE
    print(f"per-rank BatchNorm vs whole batch: max |grad diff| = "
          f"{relative_difference(got, whole):.3g} of the largest gradient")


@pytest.mark.parametrize("boundary_weight", [1.0, 2.0])
def test_split_loss_adds_up(boundary_weight: float) -> None:
    """Half batches' weighted cross-entropy sums over the summed pixel weights give the whole
    batch's ``segmentation_loss``."""
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(4, NUM_CLASSES, 6, 8, generator=g)
    target = torch.randint(0, NUM_CLASSES, (4, 6, 8), generator=g)
    target[0, 0, :3] = IGNORE
    weights = torch.rand(NUM_CLASSES, generator=g) + 0.5
    w = pixel_loss_weights(target, weights, boundary_weight)
    halves = sum((F.cross_entropy(logits[h], target[h], ignore_index=IGNORE, reduction="none")
                  * w[h]).sum() for h in (slice(0, 2), slice(2, 4)))
    whole = segmentation_loss(logits, target, weights, boundary_weight)
    torch.testing.assert_close(halves / w.sum(), whole)


def test_batch_size_must_split(synthetic_dataset: Path, compose_train, tmp_path: Path) -> None:
    check_batch_size(4, DistWorld(1, 2))
    with pytest.raises(ValueError, match=r"batch_size=4 .* multiple of 3"):
        check_batch_size(4, DistWorld(0, 3))
    cfg = train_settings(compose_train(synthetic_dataset, tmp_path))  # batch_size=4
    with pytest.raises(ValueError, match="batch_size=4"):
        tt.prepare(cfg, DistWorld(0, 3))
    assert not (tmp_path / "demo").exists()  # refused before anything is written


def torchrun_train(dataset: Path, out_root: Path, cwd: Path) -> subprocess.CompletedProcess:
    """``torchrun --standalone --nproc_per_node=2 -m train`` on the tiny dataset."""
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
           "-m", "train", f"dataset={dataset}", f"out_root={out_root}", *TINY_OVERRIDES,
           "threads=1", "export.int8=false"]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_torchrun_trains_and_rank0_writes(synthetic_dataset: Path, tmp_path: Path) -> None:
    t0 = time.monotonic()
    run = torchrun_train(synthetic_dataset, tmp_path / "models", tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    out = tmp_path / "models" / "demo"
    for name in ("segnet.onnx", "metrics.json", "checkpoint_best.pt", "checkpoint_last.pt",
                 "config.json", "localize.yaml"):
        assert (out / name).is_file(), name
    with open(out / "train_log.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["steps"]) for r in rows] == [24 // 4, 24 // 4]  # global batches of 4
    assert run.stdout.count("metrics:") == 1  # rank 0 alone finishes
    # one Hydra run folder with its record and log: rank 0's
    records = list((tmp_path / "outputs" / "hydra").rglob(".hydra"))
    assert len(records) == 1, records
    assert not list(tmp_path.glob("*.log"))
    print(f"torchrun, 2 processes: {time.monotonic() - t0:.1f} s")
    # the same command again: every rank resumes from rank 0's checkpoint, nothing to train
    best = (out / "checkpoint_best.pt").read_bytes()
    again = torchrun_train(synthetic_dataset, tmp_path / "models", tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "resuming" in again.stdout + again.stderr
    assert (out / "checkpoint_best.pt").read_bytes() == best
    with open(out / "train_log.csv") as f:
        assert len(list(csv.DictReader(f))) == 2
