"""The optimizer, its one-cycle learning-rate schedule and the moving average of the weights."""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch.optim.swa_utils import AveragedModel

from core.config import as_config
from train.config import OptimConfig
from train.net.segnet import SegNet


def make_ema(model: SegNet, decay: float) -> AveragedModel | None:
    """Exponential moving average of the weights and BatchNorm statistics (None if decay is 0).

    ``decay`` per step (warmed up as ``min(decay, (1 + n) / (10 + n))`` after n updates, so
    short runs average their recent steps too): the average spans ~``1 / (1 - decay)`` steps.
    """
    if not decay:
        return None
    if not 0.0 < decay < 1.0:
        raise ValueError(f"ema_decay={decay}: use 0 (off) or a value in (0, 1), e.g. 0.999")

    @torch.no_grad()
    def update(averages: list, currents: list, num_averaged: torch.Tensor) -> None:
        # warm-up: early on the average must not hold on to the random initial weights
        n = float(num_averaged)
        d = min(decay, (1.0 + n) / (10.0 + n))
        if averages[0].is_floating_point():
            torch._foreach_lerp_(averages, currents, 1.0 - d)
        else:  # integer buffers (BatchNorm's batch counter): the current value
            torch._foreach_copy_(averages, currents)

    return AveragedModel(model, multi_avg_fn=update, use_buffers=True)


def _optim(cfg: OptimConfig | Mapping) -> OptimConfig:
    return as_config(OptimConfig, cfg, "optim")


def make_optimizer(
    model: torch.nn.Module, optim_cfg: OptimConfig | Mapping, total_steps: int
) -> tuple[torch.optim.Optimizer, torch.optim.lr_scheduler.LRScheduler]:
    """AdamW or SGD (the ``optim`` config, conf/optim/; a mapping is read as a partial
    ``OptimConfig``) with a one-cycle schedule over ``total_steps`` batches."""
    cfg = _optim(optim_cfg)
    if cfg.name == "adamw":
        opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    elif cfg.name == "sgd":
        opt = torch.optim.SGD(model.parameters(), lr=cfg.lr, momentum=cfg.momentum,
                              weight_decay=cfg.weight_decay, nesterov=True)
    else:
        raise ValueError(f"optim.name={cfg.name!r} is not known; use adamw or sgd (conf/optim/)")
    return opt, make_scheduler(opt, cfg, total_steps)


def make_scheduler(
    optimizer: torch.optim.Optimizer, optim_cfg: OptimConfig | Mapping, total_steps: int,
    done_steps: int = 0,
) -> torch.optim.lr_scheduler.OneCycleLR:
    """The one-cycle schedule over ``total_steps`` batches, positioned after ``done_steps``.

    With ``done_steps > 0`` it replaces a running schedule by one of another length (the
    optimizer must have been given a schedule before: it holds ``initial_lr``); the learning
    rate is set at once to the new schedule's value at that step.
    """
    cfg = _optim(optim_cfg)
    return torch.optim.lr_scheduler.OneCycleLR(
        optimizer,
        max_lr=cfg.lr,
        total_steps=max(total_steps, 1),
        pct_start=cfg.warmup,
        cycle_momentum=cfg.name == "sgd",
        div_factor=25.0,
        final_div_factor=1e3,
        last_epoch=done_steps - 1,
    )
