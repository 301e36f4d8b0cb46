"""``train_log.csv``, a model folder's record of its epochs: one row per epoch (loss, learning
rate, validation scores, seconds), also kept in the checkpoint's history; and the time left."""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

from core.atomic import atomic_write_text
from train.loop.checkpoint import disk_space_guard
from train.loop.epoch import EpochResult

#: The model folder's log of its epochs.
TRAIN_LOG = "train_log.csv"


def epoch_row(epoch: int, res: EpochResult, lr: float, val: dict, seconds: float) -> dict:
    """One row of ``train_log.csv`` (and of the checkpoint's history)."""
    return {
        "epoch": epoch,
        "steps": res.steps,
        "train_loss": round(res.loss, 5),
        "lr": lr,
        "val_pixel_accuracy": round(val["pixel_accuracy"], 5),
        "val_class_accuracy": round(val["class_accuracy"], 5),
        "val_mean_iou": round(val["mean_iou"], 5),
        "val_boundary_f": round(val["boundary_f"], 5),
        "seconds": round(seconds, 1),
    }


def write_train_log(path: Path, history: list[dict]) -> None:
    """Write ``train_log.csv`` (atomic): one row per epoch (``epoch_row``)."""
    if not history:
        return
    buf = io.StringIO()
    fields = list(dict.fromkeys(k for row in history for k in row))  # rows of older runs: fewer
    writer = csv.DictWriter(buf, fieldnames=fields, restval="")
    writer.writeheader()
    writer.writerows(history)
    with disk_space_guard(path.parent, path.name):
        atomic_write_text(path, buf.getvalue())


def time_left(epochs_left: int, epoch_seconds: float, now: float | None = None) -> str:
    """The epoch log's estimate of the training time left, e.g. "7 epochs left, ~12 min,
    until ~14:32" (the epochs left at the latest epoch's time, as ``train.budget.fit_epochs``
    times them); "" when none is left.

    Args:
        epochs_left: epochs of the schedule still to train.
        epoch_seconds: the latest epoch's wall time (s), validation included.
        now: Unix time the estimate starts from (default: the clock).
    """
    if epochs_left <= 0:
        return ""
    seconds = epochs_left * epoch_seconds
    end = time.strftime("%H:%M", time.localtime((time.time() if now is None else now) + seconds))
    span = f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.1f} h"
    return f"{epochs_left} epoch{'s' if epochs_left > 1 else ''} left, ~{span}, until ~{end}"
