"""Checkpoints of a model folder: save, resume, start from another model (``init_from``), load.

``checkpoint_last.pt`` holds everything a resume needs (weights, optimizer, schedule, weight
average, the run's state: epochs done, best score, history, time trained);
``checkpoint_best.pt`` the weights of the epoch with the best validation score, with their
``model_kwargs`` and classes. Writes go through a temporary file (atomic); a full disk raises
``DiskFullError`` naming the folder and its free space.
"""

from __future__ import annotations

import io
import logging
import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import torch
from torch.optim.swa_utils import AveragedModel

from core.atomic import atomic_write_bytes, disk_full_guard
from train.config import ModelConfig
from train.net.build import from_kwargs, model_kwargs
from train.net.segnet import STEM_CONV_KEY, SegNet, finer_unshuffle_stem

log = logging.getLogger(__name__)


#: The checkpoint a re-run resumes from (``save_last``), in the model folder.
LAST_CHECKPOINT = "checkpoint_last.pt"


@contextmanager
def disk_space_guard(folder: str | Path, what: str) -> Iterator[None]:
    """``core.atomic.disk_full_guard`` for a model folder: a full disk raises ``DiskFullError``
    naming the folder, its free space and what a re-run does (resume from ``LAST_CHECKPOINT``
    where there is one, else start again).

    Args:
        folder: the model folder written to.
        what: the files being written (for the message), e.g. "checkpoint_last.pt".
    """
    folder = Path(folder)
    rerun = ("training resumes from the last checkpoint" if (folder / LAST_CHECKPOINT).is_file()
             else "no checkpoint was written yet, so training starts again from its first epoch")
    with disk_full_guard(folder, what, fix="Free space (old outputs/models/* folders, "
                         "outputs/hydra/) or pass out_root= on a disk with room, then run the "
                         f"same command again: {rerun}"):
        yield


def save_torch(path: Path, obj: dict) -> None:
    """``torch.save`` through a temporary file (atomic).

    The object is serialized in memory first, so a full disk surfaces as an OSError of the
    file write (raised as ``DiskFullError``), not as an internal error of PyTorch's writer.
    """
    buf = io.BytesIO()
    torch.save(obj, buf)
    with disk_space_guard(Path(path).parent, Path(path).name):
        atomic_write_bytes(path, buf.getvalue())


def new_state(epochs: int) -> dict:
    """The run's state before its first epoch (saved in ``checkpoint_last.pt``).

    Args:
        epochs: the schedule's span (``train.run.refit_schedule`` may change it later).
    """
    return {
        "epoch": 0,
        "best_score": -math.inf,
        "best_epoch": -1,
        "history": [],
        "train_seconds": 0.0,
        "stopped_by_budget": False,
        "epochs": epochs,
        # init_from's network on the validation split, image by image (train.run.init_scores):
        # the keep rule's baseline; None without the rule or before it is scored
        "init_val": None,
    }


def read_last(path: Path) -> dict | None:
    """The contents of ``checkpoint_last.pt`` (``save_last``), or None when there is none."""
    if not path.is_file():
        return None
    return torch.load(path, map_location="cpu", weights_only=False)


def resume(
    path: Path,
    model: SegNet,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LRScheduler,
    ema: AveragedModel | None,
    state: dict,
    ckpt: dict | None = None,
) -> bool:
    """Load ``checkpoint_last.pt`` into the run's objects, if there is one.

    Args:
        path: the folder's ``checkpoint_last.pt``.
        model, optimizer, scheduler, ema: restored in place.
        state: ``new_state``'s dict, updated in place with the saved values.
        ckpt: the file's contents already read (``read_last``; under torchrun rank 0 reads it
            and sends it to the others), or None to read ``path``.

    Returns:
        Whether a checkpoint was found and loaded.
    """
    if ckpt is None:
        ckpt = read_last(path)
    if ckpt is None:
        return False
    model.load_state_dict(ckpt["model"])
    optimizer.load_state_dict(ckpt["optimizer"])
    scheduler.load_state_dict(ckpt["scheduler"])
    if ema is not None:
        if "ema" not in ckpt:
            raise RuntimeError(f"{path} has no weight average; pass overwrite=true")
        ema.load_state_dict(ckpt["ema"])
    state.update({k: ckpt.get(k, state[k]) for k in state})
    log.info("resuming %s after epoch %d (%.0f s trained)", path, state["epoch"],
             state["train_seconds"])
    return True


def save_last(
    path: Path,
    model: SegNet,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LRScheduler,
    ema: AveragedModel | None,
    state: dict,
    config_hash: str,
) -> None:
    """Write ``checkpoint_last.pt``: what ``resume`` reads back."""
    save_torch(path, {
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict(),
        "scheduler": scheduler.state_dict(),
        **({} if ema is None else {"ema": ema.state_dict()}),
        "config_hash": config_hash,
        **state,
    })


def save_best(path: Path, net: SegNet, mcfg: ModelConfig | Mapping, classes: list[dict],
              num_classes: int, epoch: int, val: dict, config_hash: str) -> None:
    """Write ``checkpoint_best.pt``: the weights ``load_checkpoint`` and ``init_from`` read.

    Args:
        path: the folder's ``checkpoint_best.pt``.
        net: the network validated (the weight average where there is one).
        mcfg: the ``model`` config (its ``model_kwargs`` rebuild the network).
        classes: the dataset's class list; num_classes: its length.
        epoch: the epoch (1-based) the weights are from.
        val: its validation scores.
        config_hash: the run's config hash.
    """
    save_torch(path, {
        "model": net.state_dict(),
        "model_kwargs": model_kwargs(mcfg),
        "num_classes": num_classes,
        "classes": classes,
        "epoch": epoch,
        "val": val,
        "config_hash": config_hash,
    })


def load_checkpoint(path: str | Path) -> SegNet:
    """The network (SegNet or LR-ASPP) with the weights of checkpoint_best.pt (eval mode)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint not found: {path}; train with `python -m train`")
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    model = from_kwargs(ckpt["num_classes"], ckpt["model_kwargs"])
    model.load_state_dict(ckpt["model"])
    return model.eval()


def load_init_weights(model: SegNet, source: str | Path, mcfg: ModelConfig | Mapping,
                      num_classes: int) -> Path:
    """Start ``model`` from a trained model's best weights (the ``init_from`` key: fine-tuning).

    Args:
        model: the freshly built network (same ``model.*`` settings as the source, but for
            a finer ``downsample`` with the ``unshuffle`` stem: the source's stem convolution
            is carried over by ``segnet.finer_unshuffle_stem``; and for ``context_layers``
            on a source without them: the new branch keeps its zero start).
        source: a model folder made by ``python -m train`` or its ``checkpoint_best.pt``.
        mcfg: this run's ``model`` config; num_classes: this dataset's class count.

    Returns:
        The checkpoint file read.
    """
    path = Path(source)
    if path.is_dir():
        path = path / "checkpoint_best.pt"
    if not path.is_file():
        raise FileNotFoundError(
            f"init_from={source}: no {path.name} there; give a model folder made by "
            "`python -m train` (or its checkpoint_best.pt), or init_from=null")
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    if "model" not in ckpt or "model_kwargs" not in ckpt:
        raise ValueError(f"init_from={source}: {path} is not a checkpoint_best.pt of "
                         "`python -m train`")
    theirs, ours = ckpt["model_kwargs"], model_kwargs(mcfg)
    state = ckpt["model"]
    d_from, d_to = int(theirs.get("downsample", 1)), int(ours.get("downsample", 1))
    if (theirs.get("stem") == ours.get("stem") == "unshuffle" and 1 < d_to < d_from
            and d_from % d_to == 0):  # the same network at a finer resolution
        state = {**state, STEM_CONV_KEY: finer_unshuffle_stem(state[STEM_CONV_KEY], d_from, d_to)}
        log.info("init_from: the unshuffle stem carried from downsample %d to %d", d_from, d_to)
    if int(theirs.get("context_layers", 0)) == 0 and model.context is not None:
        # a context branch added to a trained network: it starts at zero (SegNet docstring)
        state = {**state, **{f"context.{k}": v for k, v in model.context.state_dict().items()}}
        log.info("init_from: a %d-layer context branch added at the bottleneck",
                 model.context_layers)
    try:
        model.load_state_dict(state)  # refuses other layer shapes or class counts
    except RuntimeError as err:
        diff = [f"{k}={theirs.get(k)!r} there, {ours.get(k)!r} here"
                for k in sorted(set(theirs) | set(ours)) if theirs.get(k) != ours.get(k)]
        if ckpt.get("num_classes") != num_classes:
            diff.append(f"{ckpt.get('num_classes')} classes there, {num_classes} here")
        raise ValueError(
            f"init_from={source}: {path} holds another network ({'; '.join(diff) or err}); "
            "train with the model.* settings and classes it was trained with") from err
    return path
