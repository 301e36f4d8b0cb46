"""A training killed at any point and started again with the same command ends where an
uninterrupted one does: the same epochs, the same learning-rate schedule, the same weights, the
time of the epochs trained before the kill counted."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

import train.run as tt
from core.atomic import is_temp
from tests.train.conftest import TINY_OVERRIDES
from train.loop.checkpoint import LAST_CHECKPOINT

ROOT = Path(__file__).resolve().parents[2]
#: epochs of the runs below: enough that a kill after the first lands before the last
EPOCHS = 3


def rows(folder: Path) -> list[dict]:
    return list(csv.DictReader((folder / "train_log.csv").open()))


def checkpoint_epoch(folder: Path) -> int:
    path = folder / LAST_CHECKPOINT
    return torch.load(path, weights_only=False)["epoch"] if path.is_file() else 0


def assert_same_training(resumed: Path, reference: Path) -> None:
    """Same epochs, same learning rate at each (the schedule), weights within the rounding of
    oneDNN's multithreaded reductions."""
    a, b = rows(resumed), rows(reference)
    assert [r["epoch"] for r in a] == [r["epoch"] for r in b] == [str(e) for e in
                                                                  range(1, EPOCHS + 1)]
    assert [float(r["lr"]) for r in a] == pytest.approx([float(r["lr"]) for r in b], rel=1e-9)
    got = torch.load(resumed / LAST_CHECKPOINT, weights_only=False)
    ref = torch.load(reference / LAST_CHECKPOINT, weights_only=False)
    assert got["epochs"] == ref["epochs"] == EPOCHS
    for k, v in ref["model"].items():
        torch.testing.assert_close(got["model"][k], v, rtol=1e-4, atol=1e-5)


@pytest.mark.slow
def test_killed_and_started_again(synthetic_dataset: Path, compose_train, tmp_path: Path
                                  ) -> None:
    """`python -m train` killed with SIGKILL mid-run, then the same command again."""
    overrides = [f"dataset={synthetic_dataset}", f"out_root={tmp_path / 'models'}",
                 *TINY_OVERRIDES, f"epochs={EPOCHS}", "export.int8=false"]
    cmd = [sys.executable, "-m", "train", *overrides, f"hydra.run.dir={tmp_path / 'hydra'}"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONUNBUFFERED": "1"}
    out = tmp_path / "models" / "demo"
    console = tmp_path / "first.log"
    with console.open("w") as sink:  # killed once epoch 1 is logged (its checkpoint is written)
        first = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=sink, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 300
        while (f"epoch 1/{EPOCHS}: loss" not in console.read_text() and first.poll() is None
               and time.monotonic() < deadline):
            time.sleep(0.02)
        first.send_signal(signal.SIGKILL)
        first.wait()
    log = console.read_text()
    killed_at = checkpoint_epoch(out)
    assert first.returncode == -signal.SIGKILL, log
    assert 1 <= killed_at < EPOCHS, "the kill came too late to interrupt the training"
    assert not (out / "segnet.onnx").exists()
    assert f"epoch 1/{EPOCHS}: loss" in log and "epochs left, ~" in log  # the time left

    again = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stdout + again.stderr
    log = again.stdout + again.stderr
    assert f"training epochs {killed_at + 1}-{EPOCHS} of {EPOCHS} (resumed:" in log

    reference = tmp_path / "reference"  # uninterrupted, in this process (no export)
    tt.fit(tt.prepare(tt.train_settings(compose_train(synthetic_dataset, reference,
                                                      f"epochs={EPOCHS}"))))
    assert_same_training(out, reference / "demo")
    metrics = json.loads((out / "metrics.json").read_text())
    assert (metrics["epochs_done"], metrics["epochs"]) == (EPOCHS, EPOCHS)
    # the time budget counts every epoch kept, the ones trained before the kill too
    assert metrics["train_seconds"] == pytest.approx(
        sum(float(r["seconds"]) for r in rows(out)), abs=0.1 * EPOCHS)
    assert json.loads((out / "config.json").read_text())["config_hash"] == metrics["config_hash"]
    assert not [p for p in out.rglob(".*") if is_temp(p)]


@pytest.mark.slow
def test_killed_between_checkpoint_and_log(synthetic_dataset: Path, compose_train,
                                           tmp_path: Path, monkeypatch) -> None:
    """A kill after the last epoch's checkpoint but before its train_log.csv row: the re-run
    trains nothing and writes the whole log."""
    real = tt.write_train_log

    def killed_at_the_last(path: Path, history: list[dict]) -> None:
        if len(history) == 2:
            raise KeyboardInterrupt
        real(path, history)

    cfg = compose_train(synthetic_dataset, tmp_path, "epochs=2", "export.int8=false")
    monkeypatch.setattr(tt, "write_train_log", killed_at_the_last)
    with pytest.raises(KeyboardInterrupt):
        tt.run(cfg)
    assert checkpoint_epoch(tmp_path / "demo") == 2 and len(rows(tmp_path / "demo")) == 1
    monkeypatch.setattr(tt, "write_train_log", real)
    metrics = tt.run(cfg)
    assert metrics["epochs_done"] == 2 and [r["epoch"] for r in rows(tmp_path / "demo")] == [
        "1", "2"]
