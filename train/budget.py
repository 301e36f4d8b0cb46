"""The training time budget: how long a run may train, and how many epochs fit in it."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

from train.config import TrainConfig

log = logging.getLogger(__name__)

#: The clocks ``budget_clock`` can name: elapsed time, or the process's CPU time (all threads).
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.monotonic, "cpu": time.process_time}


def budget_clock(name: str) -> Callable[[], float]:
    """The clock (seconds) the training budget counts (the ``budget_clock`` key)."""
    if name not in CLOCKS:
        raise ValueError(f"budget_clock={name!r}: use {' or '.join(CLOCKS)}")
    return CLOCKS[name]


#: Training time granted when ``finish_by`` has already passed (s): enough for a model.
MIN_FINISH_BY_SECONDS = 120


def training_budget(cfg: TrainConfig, trained_seconds: float) -> float:
    """Seconds of training allowed in all (over resumes): ``max_minutes``, and no later than
    the Unix time ``finish_by`` (at least ``MIN_FINISH_BY_SECONDS`` from now). inf: none.

    Args:
        cfg: the train config (``max_minutes``, ``finish_by``).
        trained_seconds: training time the run has already spent (s, over resumes).
    """
    budget = float(cfg.max_minutes) * 60.0 if cfg.max_minutes is not None else math.inf
    if cfg.finish_by is not None:
        left = float(cfg.finish_by) - time.time()
        if left < MIN_FINISH_BY_SECONDS:
            log.warning("finish_by leaves %.0f s: training %d s anyway", left,
                        MIN_FINISH_BY_SECONDS)
        budget = min(budget, trained_seconds + max(left, MIN_FINISH_BY_SECONDS))
    return budget


def fit_epochs(requested: int, epochs_done: int, seconds: float, budget: float,
               last_epoch_seconds: float, current: int | None = None) -> int:
    """How many epochs the schedule should span so that training ends within its time budget.

    The epochs left are timed at the latest epoch's time, not the mean so far: the first epoch
    carries the warm-up (and any load the machine had then), and a schedule cut on its time
    alone would stay too short. Re-fitted after every epoch, the span can shrink or grow again.
    With the ``current`` span given, it shrinks as soon as that no longer fits, but grows only
    when the extra epoch fits with half an epoch to spare: where the budget ends near an epoch
    boundary, epoch times that wobble by a few per cent would otherwise flip the span (and
    re-span the learning-rate schedule) back and forth every epoch.

    Args:
        requested: the configured epochs (the longest schedule).
        epochs_done: epochs finished so far (>= 1).
        seconds: wall time they took, validation included (s).
        budget: the whole training budget (s).
        last_epoch_seconds: wall time of the latest epoch (s).
        current: the span the schedule has now, or None (no hysteresis).

    Returns:
        The epochs done plus the whole epochs that fit in the budget left, at most
        ``requested`` and at least ``epochs_done`` (the schedule cannot end in the past).
    """
    if last_epoch_seconds <= 0 or not math.isfinite(budget):
        return requested
    fit = epochs_done + max(budget - seconds, 0.0) / last_epoch_seconds  # fractional epochs
    span = int(fit)
    if current is not None and span > current >= epochs_done:
        span = max(current, int(fit - 0.5))  # grow only with half an epoch to spare
    return max(epochs_done, min(requested, span))
