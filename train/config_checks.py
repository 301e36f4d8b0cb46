"""The checks of a training config that need no data, each error naming its key."""

from __future__ import annotations

import torch

from train.budget import budget_clock
from train.config import KeepConfig, LossConfig, TrainConfig

#: The validation scores ``eval.select`` can pick the kept checkpoint by
#: (``train.loop.evaluate.ImageScores.summary``).
SELECT_SCORES = ("mean_iou", "pixel_accuracy", "class_accuracy", "boundary_f")


def resolve_precision(precision: str, device: str = "cpu") -> bool:
    """Whether to train in bfloat16 autocast for ``precision`` (the ``precision`` key) on
    ``device`` (``cpu`` or ``cuda``).

    "bf16" uses bfloat16 convolutions (oneDNN on the CPU), "fp32" never does, "auto" does where
    the CPU has AMX tiles (on a GPU: never, its float32 is fast enough). AVX512-BF16 alone is
    not enough: on such a 2-core CPU a demo training step takes 1.3-1.4x longer in bfloat16
    than in float32 (docs/train.md). Weights, optimizer state, validation, the test metrics and
    the ONNX export stay float32.
    """
    if precision not in ("auto", "bf16", "fp32"):
        raise ValueError(f"precision={precision!r}: use auto, bf16 or fp32")
    if precision == "auto":
        if device == "cuda":
            return False
        return bool(torch.cpu._is_amx_tile_supported())
    return precision == "bf16"



def check_counts(cfg: TrainConfig) -> None:
    """Raise ValueError naming the key when a count or the time budget is out of range (before
    any loading: ``batch_size=0`` would otherwise end in a division by zero mid-run)."""
    counts = {"epochs": cfg.epochs, "batch_size": cfg.batch_size,
              "eval.batch_size": cfg.eval.batch_size, "threads": cfg.threads}
    for key, value in counts.items():
        if value < 1:
            raise ValueError(f"{key}={value!r} must be an integer >= 1")
    if cfg.max_minutes is not None and not cfg.max_minutes >= 0:
        raise ValueError(f"max_minutes={cfg.max_minutes:g} must be >= 0 (null: no time budget)")
    budget_clock(cfg.budget_clock)
    if cfg.budget_clock == "cpu" and cfg.finish_by is not None:
        raise ValueError("finish_by is a wall-clock time and budget_clock=cpu counts CPU time: "
                         "drop finish_by, or use budget_clock=wall")
    if cfg.eval.select not in SELECT_SCORES:
        raise ValueError(f"eval.select={cfg.eval.select!r}: use one of {', '.join(SELECT_SCORES)}")


def check_loss(loss: LossConfig) -> None:
    """Raise ValueError naming the ``loss.*`` key out of range."""
    if loss.resolution not in ("network", "input"):
        raise ValueError(f"loss.resolution={loss.resolution!r}: use network or input")
    if not loss.boundary_weight > 0:
        raise ValueError(f"loss.boundary_weight={loss.boundary_weight:g} must be positive "
                         "(1 = off)")


def check_keep(keep: KeepConfig, init_from: str | None) -> None:
    """Raise ValueError naming the ``keep.*`` key out of range, or the rule without a network
    to keep (``init_from``)."""
    if keep.init_unless_gain and init_from is None:
        raise ValueError("keep.init_unless_gain=true chooses between the fine-tune and the "
                         "network it starts from: give init_from=<model folder>, or "
                         "keep.init_unless_gain=false")
    for key in ("min_gain", "sigmas"):
        if not getattr(keep, key) >= 0:
            raise ValueError(f"keep.{key}={getattr(keep, key):g} must be >= 0")
    if keep.resamples < 0:
        raise ValueError(f"keep.resamples={keep.resamples} must be >= 0 (0: no bootstrap, "
                         "the margin is keep.min_gain)")


def check_config(cfg: TrainConfig, device: str = "cpu") -> bool:
    """Every setting ``run`` can check before loading anything, each error naming its key.

    Args:
        cfg: the settings.
        device: the device type training runs on (``cpu``, ``cuda``).

    Returns:
        Whether to train in bfloat16 autocast (``precision``).
    """
    check_counts(cfg)
    bf16 = resolve_precision(cfg.precision, device)
    check_loss(cfg.loss)
    check_keep(cfg.keep, cfg.init_from)
    if cfg.model.head == "sharpen" and cfg.loss.resolution != "input":
        raise ValueError(
            "model.head=sharpen learns at the input's resolution: add loss.resolution=input"
        )
    return bf16
