"""The training run behind ``python -m train``: train, validate, test, export, report.

Output folder ``<out_root>/<name>/``:

- ``config.json``: the training config and its hash (config + dataset.json digest);
- ``checkpoint_last.pt``: everything needed to resume (weights, optimizer, schedule, history);
- ``checkpoint_best.pt``: weights of the epoch with the best validation score;
- ``train_log.csv``: one row per epoch;
- ``metrics.json``, ``confusion.png``: test-split scores of the best checkpoint;
- ``segnet.onnx``: the best checkpoint exported and checked with onnxruntime.

Re-running with the same config resumes from ``checkpoint_last.pt``; a folder made with
another config is refused unless ``overwrite=true`` (core.outputs; docs/outputs.md).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn.functional as F
from omegaconf import DictConfig, OmegaConf
from torch.optim.swa_utils import AveragedModel
from tqdm import tqdm

from core.atomic import atomic_write, atomic_write_json, atomic_write_text
from core.dataset import Dataset
from core.outputs import Claim, FolderPolicy, claim_output, releases_claims, without
from train.data import (
    AugmentConfig,
    SplitData,
    augment_batch,
    batches,
    block_majority,
    check_classes,
    downsample_split,
    load_split,
    num_batches,
    to_float,
)
from train.export import ParityError, export_checked, onnx_metadata
from train.losses import image_edge_mask, median_frequency_weights, segmentation_loss
from train.metrics import confusion_matrix, metrics_json, plot_confusion, scores
from train.quantize import CALIBRATION, INT8_NAME, int8_summary, quantize_model_dir
from train.quantize import REPORT_NAME as QUANTIZE_REPORT
from train.refine import GuidedRefine, refine_logits
from train.segnet import (
    STEM_CONV_KEY,
    SegNet,
    build_segnet,
    count_parameters,
    finer_unshuffle_stem,
    model_kwargs,
)

log = logging.getLogger(__name__)

#: Training time granted when ``finish_by`` has already passed (s): enough for a model.
MIN_FINISH_BY_SECONDS = 120

#: Config keys that do not change what is trained (left out of the config hash).
HASH_EXCLUDE = (
    "name",
    "out_root",
    "threads",
    "max_minutes",
    "finish_by",
    "fit_budget",
    "overwrite",
    "progress",
    "eval.batch_size",
    "eval.flip_average",
    "eval.refine",
    "export",
)
#: A model folder belongs to its training config and dataset.json (core.outputs): config.json
#: holds them; one run at a time.
MODEL_POLICY = FolderPolicy(record="config.json", keys=("config", "dataset_digest"),
                            results=("checkpoint_*.pt", "segnet.onnx", "metrics.json"))


# ----------------------------------------------------------------------------- config, resume


def training_config(cfg: DictConfig) -> dict:
    """The part of the config that determines the trained weights (resolved, plain dict)."""
    d = OmegaConf.to_container(cfg, resolve=True)
    d.pop("hydra", None)
    return without(d, HASH_EXCLUDE)


def _loss_resolution(cfg: DictConfig) -> str:
    """``loss.resolution``: network (block-majority labels at the logits' resolution) or
    input (the logits upsampled to the full-resolution labels)."""
    res = str(cfg.loss.get("resolution", "network"))
    if res not in ("network", "input"):
        raise ValueError(f"loss.resolution={res!r}: use network or input")
    return res


def config_hash(train_cfg: dict, dataset_json: bytes) -> str:
    """16 hex digits of sha256 over the training config and the dataset's dataset.json."""
    h = hashlib.sha256(json.dumps(train_cfg, sort_keys=True).encode())
    h.update(hashlib.sha256(dataset_json).digest())
    return h.hexdigest()[:16]


def resolve_precision(precision: str) -> bool:
    """Whether to train in bfloat16 autocast for ``precision`` (the ``precision`` key).

    "bf16" uses bfloat16 convolutions (oneDNN; about 1.5-2.5x faster where the CPU has
    AVX512-BF16 or AMX, emulated and slow elsewhere), "fp32" never does, "auto" does where the
    CPU supports bfloat16 natively. Weights, optimizer state, validation, the test metrics and
    the ONNX export stay float32.
    """
    if precision not in ("auto", "bf16", "fp32"):
        raise ValueError(f"precision={precision!r}: use auto, bf16 or fp32")
    if precision == "auto":
        return bool(torch.cpu._is_avx512_bf16_supported() or torch.cpu._is_amx_tile_supported())
    return precision == "bf16"


def prepare_output(out_dir: Path, info: dict, overwrite: bool) -> Claim:
    """Claim ``out_dir`` for this config (``MODEL_POLICY``) and write its config.json.

    Args:
        out_dir: the model folder.
        info: {"config_hash", "config", "dataset_digest"} of this run.
        overwrite: empty a folder made with another config instead of failing.

    Returns:
        The claim: the folder stays locked until ``run`` returns.

    Raises:
        core.outputs.OutputFolderError: the folder holds another config's model (naming the
            differing keys) and not ``overwrite``.
        core.outputs.FolderBusy: another run writes the folder.
    """
    return claim_output(out_dir, info, MODEL_POLICY, overwrite=overwrite)


def save_torch(path: Path, obj: dict) -> None:
    """torch.save through a temporary file (atomic)."""
    atomic_write(path, lambda p: torch.save(obj, p))


def load_init_weights(model: SegNet, source: str | Path, mcfg: dict, num_classes: int) -> Path:
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


# ----------------------------------------------------------------------------- loops


@dataclass
class EpochResult:
    loss: float
    steps: int
    stopped: bool


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
    edge_weight: float = 1.0,
    edge_threshold: float = 0.03,
) -> EpochResult:
    """One pass over the training split with augmentation, at the network's resolution (the
    loss at the input's with ``full_labels``).

    Args:
        model: network in train mode after the call.
        data: the training split in memory, already at the network's resolution
            (``downsample_split``).
        class_weights: (C,) cross-entropy weights or None.
        optimizer, scheduler: stepped every batch.
        augment: augmentation parameters.
        generator: shuffling and augmentation randomness.
        batch_size: images per step.
        deadline: ``time.monotonic()`` value after which the epoch stops early.
        progress: show a progress bar.
        desc: progress bar label.
        bf16: run the forward pass in bfloat16 autocast (the loss is taken in float32).
        ema: moving average of the weights, updated after every step (``make_ema``), or None.
        boundary_weight: loss factor on pixels next to a class change (``segmentation_loss``).
        full_labels: ``data`` holds the input-resolution labels; the loss is taken on the
            logits upsampled to them as at inference (``loss.resolution: input``) instead of
            on block-majority labels at the network's resolution.
        edge_weight, edge_threshold: loss factor on image edges inside one class, and what
            counts as an image edge (``segmentation_loss``, ``image_edge_mask``).

    Returns:
        Mean loss, number of steps done, and whether the deadline stopped the epoch.
    """
    model.train()
    total, steps, stopped = 0.0, 0, False
    n_steps = num_batches(len(data), batch_size, drop_last=True)
    bar = tqdm(
        batches(len(data), batch_size, generator, drop_last=True),
        total=n_steps,
        desc=desc,
        disable=not progress,
        leave=False,
    )
    for idx in bar:
        if time.monotonic() > deadline:
            stopped = True
            break
        x, y = augment_batch(data.images[idx], data.labels[idx], augment, generator)
        if not full_labels and model.training_factor != model.downsample:
            y = block_majority(y, model.downsample).long()  # full-res input, low-res logits
        x = x.contiguous(memory_format=torch.channels_last)
        head = full_labels and model.refine_head is not None  # full-resolution x (unshuffle stem)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            logits = model.forward_network_resolution(x)
            if head:  # as at inference: bilinear, then the learned head (1.5x a step's time)
                logits = model.to_input_resolution(logits, x)
        logits = logits.float()
        if full_labels and not head:  # as at inference: bilinear to the input's resolution
            logits = F.interpolate(logits, size=y.shape[-2:], mode="bilinear",
                                   align_corners=False)
        edges = (image_edge_mask(x, edge_threshold, tuple(y.shape[-2:]))
                 if edge_weight != 1.0 else None)
        loss = segmentation_loss(logits, y, class_weights, boundary_weight, edge_weight, edges)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        scheduler.step()
        if ema is not None:
            ema.update_parameters(model)
        total += float(loss.detach())
        steps += 1
        bar.set_postfix(loss=f"{total / steps:.3f}")
    bar.close()
    return EpochResult(total / max(steps, 1), steps, stopped)


@torch.inference_mode()
def evaluate(
    model: SegNet,
    data: SplitData,
    num_classes: int,
    batch_size: int = 8,
    progress: bool = False,
    desc: str = "eval",
    refine: GuidedRefine | None = None,
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Confusion matrices of the model on a split (full images, no augmentation).

    Args:
        refine: when set, the same logits are also guided-filtered with the image
            (train.refine) and scored.

    Returns:
        (C, C) int64 of the network, rows = truth; the same after the refinement, or None.
    """
    model.eval()
    cm = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    cm_refined = None if refine is None else torch.zeros_like(cm)
    bar = tqdm(
        batches(len(data), batch_size),
        total=num_batches(len(data), batch_size),
        desc=desc,
        disable=not progress,
        leave=False,
    )
    for idx in bar:
        x = to_float(data.images[idx])
        logits = model(x)
        cm += confusion_matrix(logits.argmax(1), data.labels[idx], num_classes)
        if cm_refined is not None:
            pred = refine_logits(x, logits, refine).argmax(1)
            cm_refined += confusion_matrix(pred, data.labels[idx], num_classes)
    return cm, cm_refined


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


def make_optimizer(
    model: SegNet, optim_cfg: dict, total_steps: int
) -> tuple[torch.optim.Optimizer, torch.optim.lr_scheduler.LRScheduler]:
    """AdamW or SGD with a one-cycle schedule over ``total_steps`` batches."""
    name = optim_cfg["name"]
    if name == "adamw":
        opt = torch.optim.AdamW(
            model.parameters(), lr=optim_cfg["lr"], weight_decay=optim_cfg["weight_decay"]
        )
    elif name == "sgd":
        opt = torch.optim.SGD(
            model.parameters(),
            lr=optim_cfg["lr"],
            momentum=optim_cfg["momentum"],
            weight_decay=optim_cfg["weight_decay"],
            nesterov=True,
        )
    else:
        raise ValueError(f"optim.name={name!r} is not known; use adamw or sgd (conf/optim/)")
    return opt, make_scheduler(opt, optim_cfg, total_steps)


def make_scheduler(
    optimizer: torch.optim.Optimizer, optim_cfg: dict, total_steps: int, done_steps: int = 0
) -> torch.optim.lr_scheduler.OneCycleLR:
    """The one-cycle schedule over ``total_steps`` batches, positioned after ``done_steps``.

    With ``done_steps > 0`` it replaces a running schedule by one of another length (the
    optimizer must have been given a schedule before: it holds ``initial_lr``); the learning
    rate is set at once to the new schedule's value at that step.
    """
    return torch.optim.lr_scheduler.OneCycleLR(
        optimizer,
        max_lr=optim_cfg["lr"],
        total_steps=max(total_steps, 1),
        pct_start=optim_cfg.get("warmup", 0.1),
        cycle_momentum=optim_cfg["name"] == "sgd",
        div_factor=25.0,
        final_div_factor=1e3,
        last_epoch=done_steps - 1,
    )


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


def training_budget(cfg: DictConfig, trained_seconds: float) -> float:
    """Seconds of training allowed in all (over resumes): ``max_minutes``, and no later than
    the Unix time ``finish_by`` (at least ``MIN_FINISH_BY_SECONDS`` from now). inf: none."""
    budget = float(cfg.max_minutes) * 60.0 if cfg.max_minutes is not None else math.inf
    finish_by = cfg.get("finish_by")
    if finish_by is not None:
        left = float(finish_by) - time.time()
        if left < MIN_FINISH_BY_SECONDS:
            log.warning("finish_by leaves %.0f s: training %d s anyway", left,
                        MIN_FINISH_BY_SECONDS)
        budget = min(budget, trained_seconds + max(left, MIN_FINISH_BY_SECONDS))
    return budget


def _write_log(path: Path, history: list[dict]) -> None:
    if not history:
        return
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(history[0]))
    writer.writeheader()
    writer.writerows(history)
    atomic_write_text(path, buf.getvalue())


# ----------------------------------------------------------------------------- the run


def check_counts(cfg: DictConfig) -> None:
    """Raise ValueError naming the key when a count or the time budget is out of range (before
    any loading: ``batch_size=0`` would otherwise end in a division by zero mid-run)."""
    for key in ("epochs", "batch_size", "eval.batch_size", "threads"):
        value = OmegaConf.select(cfg, key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{key}={value!r} must be an integer >= 1")
    minutes = cfg.get("max_minutes")
    if minutes is not None and not float(minutes) >= 0:
        raise ValueError(f"max_minutes={minutes!r} must be >= 0 (null: no time budget)")


@releases_claims
def run(cfg: DictConfig) -> dict:
    """Train (or resume), evaluate the best checkpoint on the test split, export ONNX.

    Args:
        cfg: the composed ``conf/train.yaml``.

    Returns:
        The metrics.json contents.
    """
    t_start = time.monotonic()
    check_counts(cfg)
    torch.set_num_threads(int(cfg.threads))
    bf16 = resolve_precision(str(cfg.precision))  # a bad value fails before any loading
    full_labels = _loss_resolution(cfg) == "input"
    if cfg.model.get("head") == "refine" and not full_labels:
        raise ValueError(
            "model.head=refine learns at the input's resolution: add loss.resolution=input"
        )
    pixel_weights = {k: float(cfg.loss[k])  # the loss's pixel weights
                     for k in ("boundary_weight", "edge_weight", "edge_threshold")}
    for key, value in pixel_weights.items():
        if not value > 0:
            raise ValueError(f"loss.{key}={cfg.loss.get(key)} must be positive (1 = off for the "
                             "weights)")
    progress = bool(cfg.progress)
    dataset = Dataset(cfg.dataset)
    ds_json = (dataset.root / "dataset.json").read_bytes()
    classes = dataset.classes
    names = [c["name"] for c in classes]
    num_classes = check_classes(
        classes, cfg.model.get("num_classes"), str(dataset.root / "dataset.json")
    )
    train_cfg = training_config(cfg)
    info = {
        "config_hash": config_hash(train_cfg, ds_json),
        "dataset_digest": hashlib.sha256(ds_json).hexdigest()[:16],
        "dataset": str(dataset.root),
        "config": train_cfg,
    }
    mcfg = OmegaConf.to_container(cfg.model, resolve=True)
    model = build_segnet(mcfg, num_classes, torch.Generator().manual_seed(int(cfg.seed)))
    if cfg.get("init_from") is not None:  # fine-tuning (a resume replaces these weights)
        log.info("weights from %s", load_init_weights(model, cfg.init_from, mcfg, num_classes))
    out_dir = Path(cfg.out_root) / cfg.name
    prepare_output(out_dir, info, bool(cfg.overwrite))
    last_path, best_path = out_dir / "checkpoint_last.pt", out_dir / "checkpoint_best.pt"

    limit = cfg.data.get("limit")
    train_data = load_split(dataset, "train", num_classes, limit, progress)
    val_data = load_split(dataset, "val", num_classes, limit, progress)
    augment = AugmentConfig.from_dict(OmegaConf.to_container(cfg.data.augment, resolve=True))

    weights = None
    if cfg.loss.class_weighting == "median_frequency":
        weights = median_frequency_weights(
            train_data.labels, num_classes, cfg.loss.max_weight, cfg.loss.get("power", 1.0)
        )
    elif cfg.loss.class_weighting != "none":
        raise ValueError(
            f"loss.class_weighting={cfg.loss.class_weighting!r}: use median_frequency or none"
        )
    # by class name: logged, and recorded in metrics.json and the ONNX metadata at the end
    class_weights = None if weights is None else {
        n: round(float(w), 6) for n, w in zip(names, weights, strict=True)}
    if class_weights is not None:
        log.info("class weights: %s", class_weights)

    # Training runs at the network's resolution (augmentation and loss 1/d^2 as costly) and
    # channels-last (oneDNN's faster layout for these convolutions on CPU).
    model = model.to(memory_format=torch.channels_last)
    train_data = downsample_split(train_data, model.training_factor, keep_labels=full_labels)
    augment = augment.at_resolution(model.training_factor)
    batch_size = min(int(cfg.batch_size), len(train_data))
    steps_per_epoch = num_batches(len(train_data), batch_size, drop_last=True)
    optim_cfg = OmegaConf.to_container(cfg.optim, resolve=True)
    requested = int(cfg.epochs)  # the longest schedule; fit_budget may span fewer
    optimizer, scheduler = make_optimizer(model, optim_cfg, requested * steps_per_epoch)
    ema = make_ema(model, float(cfg.get("ema_decay") or 0.0))
    net = model if ema is None else ema.module  # what is validated, kept and exported
    log.info(
        "model %s: %d parameters, channels %s; %d train / %d val images, %d steps/epoch, %s",
        mcfg.get("name", "segnet"),
        count_parameters(model),
        model.channels,
        len(train_data),
        len(val_data),
        steps_per_epoch,
        "bfloat16 autocast" if bf16 else "float32",
    )

    state = {
        "epoch": 0,
        "best_score": -math.inf,
        "best_epoch": -1,
        "history": [],
        "train_seconds": 0.0,
        "stopped_by_budget": False,
        "epochs": requested,  # the schedule's span: fewer when the budget cannot hold it
    }
    if last_path.is_file():
        ckpt = torch.load(last_path, map_location="cpu", weights_only=False)
        model.load_state_dict(ckpt["model"])
        optimizer.load_state_dict(ckpt["optimizer"])
        scheduler.load_state_dict(ckpt["scheduler"])
        if ema is not None:
            if "ema" not in ckpt:
                raise RuntimeError(f"{last_path} has no weight average; pass overwrite=true")
            ema.load_state_dict(ckpt["ema"])
        state.update({k: ckpt.get(k, state[k]) for k in state})
        log.info(
            "resuming %s after epoch %d (%.0f s trained)",
            last_path,
            state["epoch"],
            state["train_seconds"],
        )

    budget = training_budget(cfg, state["train_seconds"])
    fit = bool(cfg.get("fit_budget", True))
    while state["epoch"] < state["epochs"] and not state["stopped_by_budget"]:
        epoch = state["epoch"]
        t0 = time.monotonic()
        deadline = t0 + budget - state["train_seconds"]
        if deadline <= t0:
            state["stopped_by_budget"] = True
            break
        gen = torch.Generator().manual_seed(int(cfg.seed) * 100_003 + epoch)
        res = train_one_epoch(
            model,
            train_data,
            weights,
            optimizer,
            scheduler,
            augment,
            gen,
            batch_size,
            deadline,
            progress,
            desc=f"epoch {epoch + 1}/{state['epochs']}",
            bf16=bf16,
            ema=ema,
            **pixel_weights,
            full_labels=full_labels,
        )
        cm, _ = evaluate(net, val_data, num_classes, int(cfg.eval.batch_size), progress, "val")
        val = scores(cm)
        dt = time.monotonic() - t0
        state["train_seconds"] += dt
        state["epoch"] = epoch + 1
        state["stopped_by_budget"] = res.stopped
        score = val[cfg.eval.select]
        row = {
            "epoch": epoch + 1,
            "steps": res.steps,
            "train_loss": round(res.loss, 5),
            "lr": scheduler.get_last_lr()[0],
            "val_pixel_accuracy": round(val["pixel_accuracy"], 5),
            "val_class_accuracy": round(val["class_accuracy"], 5),
            "val_mean_iou": round(val["mean_iou"], 5),
            "seconds": round(dt, 1),
        }
        state["history"].append(row)
        improved = score > state["best_score"]
        if improved:
            state["best_score"], state["best_epoch"] = score, epoch + 1
            save_torch(
                best_path,
                {
                    "model": net.state_dict(),
                    "model_kwargs": model_kwargs(mcfg),
                    "num_classes": num_classes,
                    "classes": classes,
                    "epoch": epoch + 1,
                    "val": {k: row[k] for k in row if k.startswith("val_")},
                    "config_hash": info["config_hash"],
                },
            )
        if fit and state["epoch"] < state["epochs"] and not res.stopped:
            span = fit_epochs(requested, state["epoch"], state["train_seconds"], budget, dt,
                              state["epochs"])
            if span != state["epochs"]:
                log.warning(
                    "at %.0f s per epoch, %d of the %d epochs fit the time budget (%.1f min): "
                    "the one-cycle schedule now ends after epoch %d (fit_budget=false keeps "
                    "it)", dt, span, requested, budget / 60, span)
                state["epochs"] = span
                scheduler = make_scheduler(optimizer, optim_cfg, span * steps_per_epoch,
                                           scheduler.last_epoch)
        save_torch(
            last_path,
            {
                "model": model.state_dict(),
                "optimizer": optimizer.state_dict(),
                "scheduler": scheduler.state_dict(),
                **({} if ema is None else {"ema": ema.state_dict()}),
                "config_hash": info["config_hash"],
                **state,
            },
        )
        _write_log(out_dir / "train_log.csv", state["history"])
        log.info(
            "epoch %d/%d: loss %.4f, val pixel acc %.4f, mIoU %.4f%s (%.0f s)%s",
            epoch + 1,
            state["epochs"],
            res.loss,
            val["pixel_accuracy"],
            val["mean_iou"],
            " *" if improved else "",
            dt,
            "; time budget used up, stopping" if res.stopped else "",
        )

    if not best_path.is_file():
        raise RuntimeError(
            f"no checkpoint in {out_dir}: the time budget max_minutes="
            f"{cfg.max_minutes} ended before the first epoch; raise it"
        )
    best = torch.load(best_path, map_location="cpu", weights_only=False)
    model = model.to(memory_format=torch.contiguous_format)
    model.load_state_dict(best["model"])
    model.eval()
    flip = bool(cfg.eval.get("flip_average", False))
    model.set_flip_average(flip)  # the test metrics describe the exported graph
    n_train = len(train_data)
    del train_data
    test_data = load_split(dataset, "test", num_classes, limit, progress)
    refine = GuidedRefine.from_cfg(cfg.eval.get("refine"))
    refine_settings = None if refine is None else refine.as_dict()
    cm_net, cm_refined = evaluate(model, test_data, num_classes, int(cfg.eval.batch_size),
                                  progress, "test", refine)
    cm = cm_net if cm_refined is None else cm_refined
    test = metrics_json(cm, names)
    plot_confusion(
        cm,
        names,
        out_dir / "confusion.png",
        title=f"{cfg.name}: test, pixel acc {test['pixel_accuracy']:.3f}, "
        f"mIoU {test['mean_iou']:.3f}",
    )

    metrics = {
        "test": test,  # the segmenter as shipped: network, then the guided refinement if on
        "test_network": metrics_json(cm_net, names),  # the network alone (segnet.onnx logits)
        "refine": refine_settings,
        # The loss's class weights: localize takes this prior out of its structural decisions
        # (localize.edges.structural_prior_labels); null without class weighting.
        "class_weights": class_weights,
        "onnx_max_abs_diff": None,
        "train_seconds": round(state["train_seconds"], 1),
        "epochs_done": state["epoch"],
        "epochs": state["epochs"],
        "epochs_requested": requested,
        "stopped_by_budget": state["stopped_by_budget"],
        "best_epoch": state["best_epoch"],
        "val_best": best.get("val"),
        "model": {
            "name": mcfg.get("name"),
            "parameters": count_parameters(model),
            "channels": model.channels,
            "convs_per_stage": model.convs_per_stage,
        },
        "images": {"train": n_train, "val": len(val_data), "test": len(test_data)},
        "config_hash": info["config_hash"],
        "threads": int(cfg.threads),
        "flip_average": flip,
    }
    onnx_path = out_dir / "segnet.onnx"
    n_par = min(int(cfg.export.parity_images), len(test_data))
    parity_images = to_float(test_data.images[:n_par])
    pooling = str(cfg.export.pooling)
    meta = onnx_metadata(
        model,
        classes,
        parity_images.shape[2],
        parity_images.shape[3],
        info["config_hash"],
        pooling=pooling,
        extra={
            "test_metrics": {k: test[k] for k in ("pixel_accuracy", "class_accuracy", "mean_iou")},
            "flip_average": flip,
            "refine": refine_settings,
            "class_weights": class_weights,
        },
    )
    try:
        report = export_checked(
            model,
            onnx_path,
            parity_images,
            meta,
            tolerance=float(cfg.export.tolerance),
            threads=int(cfg.threads),
            batch_size=int(cfg.export.batch_size),
            opset=int(cfg.export.opset),
            pooling=pooling,
        )
    except ParityError as err:
        metrics["onnx_max_abs_diff"] = err.report.max_abs_diff
        metrics["onnx_parity"] = err.report.as_dict()
        metrics["run_seconds"] = round(time.monotonic() - t_start, 1)
        atomic_write_json(out_dir / "metrics.json", metrics)
        raise
    metrics["onnx_max_abs_diff"] = report.max_abs_diff
    metrics["onnx_parity"] = report.as_dict()
    metrics["run_seconds"] = round(time.monotonic() - t_start, 1)
    atomic_write_json(out_dir / "metrics.json", metrics)
    alone = metrics["test_network"]
    log.info(
        "test: pixel acc %.4f, class acc %.4f, mIoU %.4f (network alone: %.4f / %.4f / %.4f); "
        "onnx max |diff| %.2e",
        test["pixel_accuracy"],
        test["class_accuracy"],
        test["mean_iou"],
        alone["pixel_accuracy"],
        alone["class_accuracy"],
        alone["mean_iou"],
        report.max_abs_diff,
    )
    if bool(cfg.export.get("int8", False)):
        calibration = int(cfg.export.get("int8_calibration", CALIBRATION))
        q = quantize_model_dir(out_dir, dataset.root, calibration, limit, int(cfg.threads),
                               progress)
        metrics["int8"] = int8_summary(q)
        atomic_write_json(out_dir / "metrics.json", metrics)
        log.info("int8: test pixel acc %.4f, mIoU %.4f; labels equal to the float graph's on "
                 "%.2f %% of pixels", q["int8"]["pixel_accuracy"], q["int8"]["mean_iou"],
                 100 * q["label_agreement"])
    else:  # an int8 copy of an earlier export would not match this segnet.onnx
        for name in (INT8_NAME, QUANTIZE_REPORT):
            (out_dir / name).unlink(missing_ok=True)
    print(f"metrics: {out_dir / 'metrics.json'}")
    print(f"onnx:    {onnx_path}")
    if "int8" in metrics:
        print(f"int8:    {out_dir / INT8_NAME}")
    return metrics


def load_checkpoint(path: str | Path) -> SegNet:
    """A SegNet with the weights of checkpoint_best.pt (eval mode)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint not found: {path}; train with `python -m train`")
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    model = SegNet(num_classes=ckpt["num_classes"], **ckpt["model_kwargs"])
    model.load_state_dict(ckpt["model"])
    return model.eval()
