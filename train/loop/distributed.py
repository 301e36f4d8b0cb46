"""Data-parallel training under ``torchrun``: the process group, its rank, and the collectives
``train.run`` needs (torch.distributed; docs/train.md, "Several processes: torchrun").

``torchrun`` starts N copies of ``python -m train`` and gives each the environment variables
``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``MASTER_ADDR``, ``MASTER_PORT``; with ``WORLD_SIZE``
> 1 ``process_group`` joins them (``init_method="env://"``), backend gloo on CPU and nccl on
CUDA, each process on the GPU of its ``LOCAL_RANK`` (``training_device``). Every rank draws the
same global batch (same indices and augmentation from the same seeded generator) and trains on
its slice of ``batch_size / N`` images (``DistWorld.shard``);
``torch.nn.parallel.DistributedDataParallel`` averages the gradients, and the loss is scaled so
that the average is the gradient of the whole batch's loss (``train.loop.epoch.train_one_epoch``).
Rank 0 alone validates and writes the model folder.

BatchNorm normalizes with each rank's own statistics (its ``batch_size / N`` images), on a GPU
as on the CPU: ``torch.nn.SyncBatchNorm`` refuses CPU tensors in this torch ("SyncBatchNorm
expected input tensor to be on GPU"), and one recipe gives one result. Between steps DDP copies
rank 0's BatchNorm running statistics to the other ranks (``broadcast_buffers``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import timedelta
from typing import Any, TypeVar

import torch
import torch.distributed as dist

T = TypeVar("T")

#: The CPU, the default device.
CPU = torch.device("cpu")


@dataclass(frozen=True)
class DistWorld:
    """This process's place among the training processes.

    Attributes:
        rank: 0 .. size - 1; rank 0 validates and writes.
        size: the number of processes (1: a plain ``python -m train``, no process group).
        device: where the collectives' tensors go (nccl reduces CUDA tensors only).
    """

    rank: int = 0
    size: int = 1
    device: torch.device = CPU

    @property
    def active(self) -> bool:
        """Several processes train together (a process group is up)."""
        return self.size > 1

    @property
    def is_main(self) -> bool:
        """This process validates, logs and writes the model folder."""
        return self.rank == 0

    def shard(self, batch: torch.Tensor) -> torch.Tensor:
        """This rank's slice of a global batch: (B, ...) -> (B / size, ...), rank r taking
        images r B / size .. (r + 1) B / size - 1."""
        if not self.active:
            return batch
        n = batch.shape[0] // self.size
        return batch[self.rank * n : (self.rank + 1) * n]

    def sum(self, values: torch.Tensor) -> torch.Tensor:
        """``values`` summed over the ranks (a float64 or float32 tensor of any shape, on any
        device; the sum on the same device); the tensor itself when alone."""
        if not self.active:
            return values
        on = values.to(self.device)
        dist.all_reduce(on, op=dist.ReduceOp.SUM)
        return on.to(values.device)

    def any(self, flag: bool) -> bool:
        """Whether ``flag`` is true on any rank (``flag`` itself when alone)."""
        if not self.active:
            return bool(flag)
        return bool(self.sum(torch.tensor([float(flag)], dtype=torch.float64)) > 0)

    def from_main(self, make: Callable[[], T]) -> T:
        """``make()`` as rank 0 computes it, on every rank (pickled through the process group;
        the other ranks do not call ``make``)."""
        if not self.active:
            return make()
        box: list[Any] = [make() if self.is_main else None]
        dist.broadcast_object_list(box, src=0)
        return box[0]

    def barrier(self) -> None:
        """Wait until every rank is here."""
        if self.active:
            dist.barrier()


SINGLE = DistWorld()


def training_device(device: str) -> torch.device:
    """The device of the ``device`` key: ``cpu``; ``cuda`` (the GPU of this process's
    ``LOCAL_RANK`` under torchrun, else GPU 0); ``auto``: ``cuda`` where torch sees a GPU, else
    ``cpu``.

    Raises:
        ValueError: another value, or ``cuda`` without a GPU (naming the key and the fix).
    """
    if device not in ("auto", "cpu", "cuda"):
        raise ValueError(f"device={device!r}: use auto, cpu or cuda")
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cpu":
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise ValueError("device=cuda, but torch sees no GPU (torch.cuda.is_available() is "
                         "false): use device=auto or device=cpu, or install a CUDA build of "
                         "torch")
    return torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))


def world_from_env(device: torch.device = CPU) -> DistWorld:
    """The ``DistWorld`` that ``torchrun`` describes in ``RANK`` and ``WORLD_SIZE`` (one process
    when they are not set), its collectives on ``device``."""
    size = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    if size < 1 or not 0 <= rank < size:
        raise ValueError(f"RANK={rank} and WORLD_SIZE={size} from the environment do not fit "
                         "together; start several processes with torchrun")
    return DistWorld(rank, size, device)


def backend_for(device: torch.device) -> str:
    """The process group backend for tensors on ``device``: nccl for CUDA, gloo on CPU."""
    return "nccl" if device.type == "cuda" else "gloo"


def check_batch_size(batch_size: int, world: DistWorld) -> None:
    """Raise ValueError naming ``batch_size`` when it does not split evenly between the ranks."""
    if batch_size % world.size:
        raise ValueError(
            f"batch_size={batch_size} does not split between the {world.size} torchrun "
            f"processes: use a multiple of {world.size} (each process trains on batch_size / "
            f"{world.size} images of every global batch)")


@contextmanager
def process_group(device: torch.device = CPU, timeout_minutes: float = 30.0) -> Iterator[DistWorld]:
    """Join ``torchrun``'s processes for the block (nothing to join for one process).

    Args:
        device: where the training tensors live (``training_device``; ``backend_for``).
        timeout_minutes: how long a collective waits for the slowest rank (the other ranks
            wait while rank 0 validates and saves after each epoch).

    Yields:
        This process's ``DistWorld``. On a normal exit every rank meets at a barrier before the
        group is destroyed; after an error the group is destroyed at once (torchrun then
        stops the other processes).
    """
    world = world_from_env(device)
    if not world.active:
        yield world
        return
    if device.type == "cuda":  # nccl's object collectives use the current GPU
        torch.cuda.set_device(device)
    dist.init_process_group(backend_for(device), init_method="env://",
                            rank=world.rank, world_size=world.size,
                            timeout=timedelta(minutes=timeout_minutes))
    try:
        yield world
        dist.barrier()
    finally:
        dist.destroy_process_group()
