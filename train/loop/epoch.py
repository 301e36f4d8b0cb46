"""One epoch of training: the forward pass a step's loss is taken on, the loss (summed over
the torchrun processes), the optimizer and weight-average steps, over one pass of the training
split."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch.optim.swa_utils import AveragedModel
from tqdm import tqdm

from train.config import AugmentConfig
from train.data import SplitData, augment_batch, batches, block_majority, num_batches
from train.loop.distributed import SINGLE, DistWorld
from train.losses import IGNORE, pixel_loss_weights, segmentation_loss
from train.net.segnet import SegNet


@dataclass
class EpochResult:
    loss: float
    steps: int
    stopped: bool


def network_logits(model: SegNet, x: torch.Tensor, head: bool, bf16: bool) -> torch.Tensor:
    """The part of a training step's forward pass that holds the weights.

    Args:
        model: the network (train mode).
        x: (B, 3, h, w) float32 augmented images at the training resolution.
        head: also run ``model.to_input_resolution`` (the sharpen head).
        bf16: in bfloat16 autocast.

    Returns:
        (B, C, h', w') logits, bfloat16 or float32.
    """
    with torch.autocast(x.device.type, dtype=torch.bfloat16, enabled=bf16):
        logits = model.forward_network_resolution(x)
        if head:
            logits = model.to_input_resolution(logits, x)
    return logits


class TrainingForward(torch.nn.Module):
    """``network_logits`` as a module's ``forward``: what DistributedDataParallel wraps (it
    syncs the gradients of the parameters used by its module's forward)."""

    def __init__(self, model: SegNet, head: bool, bf16: bool) -> None:
        super().__init__()
        self.model, self.head, self.bf16 = model, head, bf16

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return network_logits(self.model, x, self.head, self.bf16)


def uses_head(model: SegNet, full_labels: bool) -> bool:
    """Whether training runs the sharpen head (full-resolution x, unshuffle stem)."""
    return full_labels and model.sharpen_head is not None


def data_parallel(model: SegNet, full_labels: bool, bf16: bool, world: DistWorld
                  ) -> torch.nn.parallel.DistributedDataParallel | None:
    """The training forward pass (``TrainingForward``) in DistributedDataParallel, which
    averages the gradients over the ranks (rank 0's weights and buffers copied to all at
    construction), on the model's device; None for one process."""
    if not world.active:
        return None
    device = next(model.parameters()).device
    return torch.nn.parallel.DistributedDataParallel(
        TrainingForward(model, uses_head(model, full_labels), bf16),
        device_ids=[device] if device.type == "cuda" else None)


def training_logits(model: SegNet, x: torch.Tensor, label_size: tuple[int, int],
                    full_labels: bool, bf16: bool,
                    ddp: torch.nn.parallel.DistributedDataParallel | None = None
                    ) -> torch.Tensor:
    """The logits a training step's loss is taken on, float32.

    Args:
        model: the network (train mode).
        x: (B, 3, h, w) float32 augmented images at the training resolution.
        label_size: (H, W) of the step's labels.
        full_labels: ``loss.resolution: input``: the logits brought to the labels' (input)
            resolution as at inference (bilinear, then the sharpen head where there is one;
            the head costs 1.5x a step's time); else at the network's resolution.
        bf16: the forward pass in bfloat16 autocast.
        ddp: ``data_parallel(model, ...)`` under torchrun (it runs the forward pass), or None.

    Returns:
        (B, C, H, W) logits at the labels' resolution.
    """
    head = uses_head(model, full_labels)
    logits = network_logits(model, x, head, bf16) if ddp is None else ddp(x)
    logits = logits.float()
    if full_labels and not head:  # as at inference: bilinear to the input's resolution
        logits = F.interpolate(logits, size=label_size, mode="bilinear", align_corners=False)
    return logits


def train_one_epoch(
    model: SegNet,
    data: SplitData,
    class_weights: torch.Tensor | None,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LRScheduler,
    augment: AugmentConfig,
    generator: torch.Generator,
    batch_size: int,
    deadline: float = math.inf,
    progress: bool = False,
    desc: str = "train",
    bf16: bool = False,
    ema: AveragedModel | None = None,
    boundary_weight: float = 1.0,
    full_labels: bool = False,
    world: DistWorld = SINGLE,
    ddp: torch.nn.parallel.DistributedDataParallel | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> EpochResult:
    """One pass over the training split with augmentation, at the network's resolution (the
    loss at the input's with ``full_labels``).

    Args:
        model: network in train mode after the call, on the device it trains on (the
            batches go there).
        data: the training split in memory (CPU), already at the network's resolution
            (``downsample_split``).
        class_weights: (C,) cross-entropy weights or None.
        optimizer, scheduler: stepped every batch.
        augment: augmentation parameters.
        generator: shuffling and augmentation randomness.
        batch_size: images per step.
        deadline: ``clock()`` value after which the epoch stops early.
        progress: show a progress bar.
        desc: progress bar label.
        bf16: run the forward pass in bfloat16 autocast (the loss is taken in float32).
        ema: moving average of the weights, updated after every step (``make_ema``), or None.
        boundary_weight: loss factor on pixels next to a class change (``segmentation_loss``).
        full_labels: ``data`` holds the input-resolution labels; the loss is taken on the
            logits upsampled to them as at inference (``loss.resolution: input``) instead of
            on block-majority labels at the network's resolution.
        world: the torchrun processes: every rank draws the same global batch of
            ``batch_size`` images and trains on its ``world.shard``, the loss scaled so that
            DDP's gradient average is the whole batch's gradient; the deadline is checked
            by all together.
        ddp: ``data_parallel(model, ...)`` when ``world.active``.
        clock: the budget's clock (``train.budget.budget_clock``): wall or process CPU time.

    Returns:
        Mean loss (of the global batches), number of steps done, and whether the deadline
        stopped the epoch.
    """
    if world.active and ddp is None:
        raise ValueError("train_one_epoch: world.active needs ddp=data_parallel(model, ...)")
    model.train()
    device = next(model.parameters()).device
    total, steps, stopped = 0.0, 0, False
    n_steps = num_batches(len(data), batch_size, drop_last=True)
    bar = tqdm(
        batches(len(data), batch_size, generator, drop_last=True),
        total=n_steps,
        desc=desc,
        disable=not (progress and world.is_main),
        leave=False,
    )
    for idx in bar:
        if world.any(clock() > deadline):  # every rank stops at the same step
            stopped = True
            break
        x, y = augment_batch(data.images[idx], data.labels[idx], augment, generator)
        x, y = world.shard(x), world.shard(y)
        reduce = model.output_stride // model.training_factor  # labels per logit
        if not full_labels and reduce > 1:
            y = block_majority(y, reduce).long()  # the labels at the logits' resolution
        x = x.to(device).contiguous(memory_format=torch.channels_last)
        y = y.to(device)
        logits = training_logits(model, x, tuple(y.shape[-2:]), full_labels, bf16, ddp)
        loss, value = batch_loss(logits, y, class_weights, boundary_weight, world)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        scheduler.step()
        if ema is not None:
            ema.update_parameters(model)
        total += value
        steps += 1
        bar.set_postfix(loss=f"{total / steps:.3f}")
    bar.close()
    if world.active:  # the global batches' loss: the ranks' shares summed
        total = float(world.sum(torch.tensor([total], dtype=torch.float64)))
    return EpochResult(total / max(steps, 1), steps, stopped)


def batch_loss(logits: torch.Tensor, y: torch.Tensor, class_weights: torch.Tensor | None,
               boundary_weight: float, world: DistWorld) -> tuple[torch.Tensor, float]:
    """The loss this rank backpropagates, and its share of the global batch's loss value.

    One process: ``segmentation_loss`` and its value. Under torchrun the loss of a global
    batch is sum(numerators) / sum(denominators) over its pixels (``pixel_loss_weights``);
    rank r backpropagates N * numerator_r / denominator (the denominator summed over the
    ranks), so DDP's average of the N gradients is the gradient of the global batch's loss, as
    one process computes it (up to float rounding and BatchNorm's per-rank statistics;
    train/loop/distributed.py); its share of the value is numerator_r / denominator.

    Args:
        logits: (B, C, H, W) float32 at the labels' resolution (this rank's images).
        y: (B, H, W) int64 labels, 255 ignored.
        class_weights, boundary_weight: as for ``segmentation_loss``.
        world: the training processes.
    """
    if not world.active:
        loss = segmentation_loss(logits, y, class_weights, boundary_weight)
        return loss, float(loss.detach())
    pixel_weights = pixel_loss_weights(y, class_weights, boundary_weight)
    denominator = float(world.sum(pixel_weights.sum(dtype=torch.float64)).clamp(min=1e-12))
    numerator = (F.cross_entropy(logits, y, ignore_index=IGNORE, reduction="none")
                 * pixel_weights).sum()
    return numerator * (world.size / denominator), float(numerator.detach()) / denominator

