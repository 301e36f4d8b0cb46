"""``train_log.csv``, a model folder's record of its epochs: one row per epoch (loss, learning
rate, validation scores, seconds), also kept in the checkpoint's history."""

from __future__ import annotations

import csv
import io
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
        "seconds": round(seconds, 1),
    }


def write_train_log(path: Path, history: list[dict]) -> None:
    """Write ``train_log.csv`` (atomic): one row per epoch (``epoch_row``)."""
    if not history:
        return
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(history[0]))
    writer.writeheader()
    writer.writerows(history)
    with disk_space_guard(path.parent, path.name):
        atomic_write_text(path, buf.getvalue())
