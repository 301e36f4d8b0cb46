"""The training run behind ``python -m train``: train, validate, export, test, report.

Output folder ``<out_root>/<name>/``:

- ``config.json``: the training config and its hash (config + dataset.json digest);
- ``localize.yaml``: the localize settings the model is tuned for (the ``localize`` key;
  ``python -m localize`` applies them under its command line);
- ``checkpoint_last.pt``: everything needed to resume (weights, optimizer, schedule, history);
- ``checkpoint_best.pt``: weights of the epoch with the best validation score;
- ``train_log.csv``: one row per epoch;
- ``segnet.onnx``: the best checkpoint exported and checked with onnxruntime; with
  ``keep.init_unless_gain`` (a fine-tune) the starting network (``init_from``) instead where
  the validation images show the fine-tune no gain (train/keep.py);
- ``metrics.json``, ``confusion.png``: test-split scores of ``segnet.onnx``'s labels, the
  labels the localizer reads.

Re-running with the same config resumes from ``checkpoint_last.pt`` (written after every
epoch: a run killed mid-epoch trains that epoch again, from the same batches); a folder made with
another config is refused unless ``overwrite=true`` (core.outputs; docs/outputs.md). The run
reads its settings as a ``train.config.TrainConfig`` and is ``prepare`` (config checks, data,
network, optimizer), ``fit`` (the epochs, each ``train_one_epoch`` then validation and
checkpoints) and ``finish`` (export, test, metrics). Under ``torchrun`` several processes
train together (train/loop/distributed.py) and rank 0 alone writes the folder.
"""

from __future__ import annotations

import hashlib
import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf
from torch.optim.swa_utils import AveragedModel

from core.atomic import atomic_write_json, atomic_write_text, remove_temp_files
from core.dataset import Dataset, open_datasets
from core.imaging import camera_effects
from core.imaging.realism import load_realism
from core.model_folder import LOCALIZE_METADATA_KEY, LOCALIZE_SETTINGS_NAME
from core.outputs import releases_claims
from train.budget import budget_clock, fit_epochs, training_budget
from train.config import AugmentConfig, LossConfig, TrainConfig
from train.config_checks import check_config
from train.data import (
    SplitData,
    check_classes,
    check_same_kind,
    downsample_split,
    load_splits,
    num_batches,
    through_camera,
    to_float,
)
from train.deploy.export import ParityError, export_checked, onnx_metadata, update_metadata
from train.deploy.quantize import INT8_NAME, int8_summary, quantize_model_dir
from train.deploy.quantize import REPORT_NAME as QUANTIZE_REPORT
from train.keep import KeepDecision, decide
from train.loop.checkpoint import (
    LAST_CHECKPOINT,
    disk_space_guard,
    load_init_weights,
    new_state,
    read_last,
    resume,
    save_best,
    save_last,
)
from train.loop.distributed import (
    CPU,
    SINGLE,
    DistWorld,
    check_batch_size,
    process_group,
    training_device,
)
from train.loop.epoch import data_parallel, train_one_epoch
from train.loop.evaluate import ImageScores, score_images, score_onnx
from train.loop.optim import make_ema, make_optimizer, make_scheduler
from train.loop.train_log import TRAIN_LOG, epoch_row, time_left, write_train_log
from train.losses import median_frequency_weights
from train.metrics import metrics_json, plot_confusion
from train.net.build import build_model
from train.net.segnet import SegNet, count_parameters
from train.run_identity import config_hash, prepare_output, train_settings, training_config

log = logging.getLogger(__name__)



@dataclass
class TrainJob:
    """What ``prepare`` sets up for ``fit`` and ``finish``: the config, the folder, the data
    (at the network's resolution), the network, its weight average and its optimizer."""

    cfg: TrainConfig
    out_dir: Path
    datasets: list[Dataset]  # what ``dataset`` names (a folder or a glob pattern)
    num_classes: int
    info: dict  # config_hash, dataset_digest, dataset, config (config.json)
    model: SegNet
    ema: AveragedModel | None
    optimizer: torch.optim.Optimizer
    scheduler: torch.optim.lr_scheduler.LRScheduler
    train_data: SplitData | None
    val_data: SplitData | None  # rank 0's only under torchrun
    augment: AugmentConfig
    weights: torch.Tensor | None  # (C,) cross-entropy class weights
    batch_size: int
    steps_per_epoch: int
    requested: int  # the configured epochs (the longest schedule)
    bf16: bool
    world: DistWorld = SINGLE  # the torchrun processes (train/loop/distributed.py)
    ddp: torch.nn.parallel.DistributedDataParallel | None = None  # under torchrun
    device: torch.device = CPU  # where the network trains (``device``)

    @property
    def full_labels(self) -> bool:
        """The loss at the input's resolution (``loss.resolution: input``)."""
        return self.cfg.loss.resolution == "input"

    @property
    def net(self) -> SegNet:
        """What is validated, kept and exported: the weight average, else the network."""
        return self.model if self.ema is None else self.ema.module

    @property
    def classes(self) -> list[dict]:
        return self.datasets[0].classes

    @property
    def names(self) -> list[str]:
        return [c["name"] for c in self.classes]

    @property
    def class_weights(self) -> dict[str, float] | None:
        """The loss's class weights by class name (metrics.json and the ONNX metadata:
        localize takes this prior out of its structural decisions); None without them."""
        if self.weights is None:
            return None
        return {n: round(float(w), 6) for n, w in zip(self.names, self.weights, strict=True)}


def write_localize_settings(out_dir: Path, settings: dict) -> Path:
    """Write the model folder's ``localize.yaml`` (``python -m localize`` reads it)."""
    path = out_dir / LOCALIZE_SETTINGS_NAME
    text = ("# The localize settings this model is tuned for (python -m train's `localize` key).\n"
            "# python -m localize onnx_model=<this folder>/segnet.onnx applies them, under the\n"
            "# keys its command line gives.\n" + OmegaConf.to_yaml(OmegaConf.create(settings)))
    with disk_space_guard(out_dir, LOCALIZE_SETTINGS_NAME):
        atomic_write_text(path, text)
    return path


def class_weight_tensor(loss: LossConfig, data: SplitData, num_classes: int
                        ) -> torch.Tensor | None:
    """(C,) cross-entropy class weights of ``loss.class_weighting`` on the training labels."""
    if loss.class_weighting == "median_frequency":
        return median_frequency_weights(data.labels, num_classes, loss.max_weight, loss.power)
    if loss.class_weighting != "none":
        raise ValueError(
            f"loss.class_weighting={loss.class_weighting!r}: use median_frequency or none"
        )
    return None


def build_network(cfg: TrainConfig, num_classes: int) -> SegNet:
    """The network of ``model`` (a SegNet or LR-ASPP, train/net/build.py): seeded random
    weights, or ``init_from``'s."""
    model = build_model(cfg.model, num_classes, torch.Generator().manual_seed(cfg.seed))
    if cfg.init_from is not None:  # fine-tuning (a resume replaces these weights)
        log.info("weights from %s", load_init_weights(model, cfg.init_from, cfg.model,
                                                      num_classes))
    return model


def prepare(cfg: TrainConfig, world: DistWorld = SINGLE,
            device: torch.device = CPU) -> TrainJob:
    """Check the config, claim the output folder, load the data, build network and optimizer
    (the network, its weight average and the class weights on ``device``; the data on the
    CPU).

    Nothing is written before every check that needs no data has passed. Under torchrun
    (``world.active``) rank 0 alone claims and writes the folder and loads the validation
    split; every rank loads the training split and wraps the network in DDP (``job.ddp``).
    """
    bf16 = check_config(cfg, device.type)
    check_batch_size(cfg.batch_size, world)
    camera = load_realism(cfg.data.realism, "data.realism")
    torch.set_num_threads(cfg.threads)
    datasets = open_datasets(cfg.dataset)
    check_same_kind(datasets)
    ds_json = b"".join((d.root / "dataset.json").read_bytes() for d in datasets)
    num_classes = check_classes(
        datasets[0].classes, cfg.model.num_classes, str(datasets[0].root / "dataset.json")
    )
    train_cfg = training_config(cfg)
    info = {
        "config_hash": config_hash(train_cfg, ds_json),
        "dataset_digest": hashlib.sha256(ds_json).hexdigest()[:16],
        "dataset": str(datasets[0].root) if len(datasets) == 1 else cfg.dataset,
        "config": train_cfg,
    }
    model = build_network(cfg, num_classes)
    out_dir = Path(cfg.out_root) / cfg.name
    if world.is_main:
        prepare_output(out_dir, info, cfg.overwrite)
        stale = remove_temp_files(out_dir)  # the folder is this run's alone
        if stale:
            log.info("%s: removed %d temporary files of killed writes", out_dir, len(stale))
        write_localize_settings(out_dir, cfg.localize)

    full_labels = cfg.loss.resolution == "input"
    progress = cfg.progress and world.is_main
    train_data = load_splits(datasets, "train", num_classes, cfg.data.limit, progress)
    val_data = (load_splits(datasets, "val", num_classes, cfg.data.limit, progress)
                if world.is_main else None)
    if camera_effects.is_active(camera):
        train_data = through_camera(train_data, camera, cfg.seed, stream=0)
        if val_data is not None:
            val_data = through_camera(val_data, camera, cfg.seed, stream=1)
    weights = class_weight_tensor(cfg.loss, train_data, num_classes)
    if weights is not None:
        weights = weights.to(device)
    # Training runs at the network's resolution (augmentation and loss 1/d^2 as costly) and
    # channels-last (oneDNN's faster layout for these convolutions on CPU).
    model = model.to(device, memory_format=torch.channels_last)
    train_data = downsample_split(train_data, model.training_factor, keep_labels=full_labels)
    batch_size = min(cfg.batch_size, len(train_data))
    check_batch_size(batch_size, world)  # fewer training images than batch_size
    steps_per_epoch = num_batches(len(train_data), batch_size, drop_last=True)
    # the longest schedule: refit_schedule may span fewer epochs
    optimizer, scheduler = make_optimizer(model, cfg.optim, cfg.epochs * steps_per_epoch)
    job = TrainJob(cfg, out_dir, datasets, num_classes, info, model, make_ema(model, cfg.ema_decay),
              optimizer, scheduler, train_data, val_data,
              cfg.data.augment.at_resolution(model.training_factor), weights, batch_size,
              steps_per_epoch, cfg.epochs, bf16, world,
              data_parallel(model, full_labels, bf16, world), device)
    if not world.is_main:
        return job
    if job.class_weights is not None:
        log.info("class weights: %s", job.class_weights)
    log.info(
        "model %s: %d parameters, channels %s; %d train / %d val images, %d steps/epoch, %s "
        "on %s", cfg.model.name, count_parameters(model), model.channels, len(train_data),
        len(val_data), steps_per_epoch, "bfloat16 autocast" if bf16 else "float32", device,
    )
    if world.active:
        log.info("data-parallel: %d processes (torch.distributed %s), %d images each per step",
                 world.size, torch.distributed.get_backend(), batch_size // world.size)
    return job


def refit_schedule(job: TrainJob, state: dict, budget: float, epoch_seconds: float) -> None:
    """Re-span the one-cycle schedule over the epochs that fit the budget left
    (``fit_epochs``), in place (``job.scheduler``, ``state["epochs"]``): a run the budget cuts
    off still anneals."""
    span = fit_epochs(job.requested, state["epoch"], state["train_seconds"], budget,
                      epoch_seconds, state["epochs"])
    if span == state["epochs"]:
        return
    if job.world.is_main:
        log.warning(
            "at %.0f s per epoch, %d of the %d epochs fit the time budget (%.1f min): the "
            "one-cycle schedule now ends after epoch %d", epoch_seconds, span, job.requested,
            budget / 60, span)
    state["epochs"] = span
    job.scheduler = make_scheduler(job.optimizer, job.cfg.optim, span * job.steps_per_epoch,
                                   job.scheduler.last_epoch)


def run_epoch(job: TrainJob, state: dict, budget: float) -> bool:
    """Train one epoch, validate, keep the best weights, save the checkpoint and the log.

    Under torchrun rank 0 alone validates and writes; the others take its epoch time.

    Args:
        job: the prepared run.
        state: the run's state (``checkpoint.new_state``), updated in place.
        budget: the whole training budget (s).

    Returns:
        False when the budget was used up before the epoch began (nothing done).
    """
    cfg, epoch = job.cfg, state["epoch"]
    clock = budget_clock(cfg.budget_clock)
    t0 = clock()
    deadline = t0 + budget - state["train_seconds"]
    if deadline <= t0:
        return False
    res = train_one_epoch(
        job.model, job.train_data, job.weights, job.optimizer, job.scheduler, job.augment,
        torch.Generator().manual_seed(cfg.seed * 100_003 + epoch), job.batch_size,
        deadline, cfg.progress, desc=f"epoch {epoch + 1}/{state['epochs']}",
        bf16=job.bf16, ema=job.ema, boundary_weight=cfg.loss.boundary_weight,
        full_labels=job.full_labels, world=job.world, ddp=job.ddp, clock=clock,
    )
    main = job.world.is_main
    val = (score_images(job.net, job.val_data, job.num_classes, cfg.eval.batch_size,
                        cfg.progress, "val").summary() if main else None)
    # rank 0's epoch time on every rank, so that all re-span the schedule alike
    dt = job.world.from_main(lambda: clock() - t0)
    state.update(train_seconds=state["train_seconds"] + dt, epoch=epoch + 1,
                 stopped_by_budget=res.stopped)
    if main:
        row = epoch_row(epoch + 1, res, job.scheduler.get_last_lr()[0], val, dt)
        state["history"].append(row)
        improved = val[cfg.eval.select] > state["best_score"]
        if improved:
            state["best_score"], state["best_epoch"] = val[cfg.eval.select], epoch + 1
            save_best(job.out_dir / "checkpoint_best.pt", job.net, job.cfg.model, job.classes,
                      job.num_classes, epoch + 1,
                      {k: row[k] for k in row if k.startswith("val_")}, job.info["config_hash"])
    if state["epoch"] < state["epochs"] and not res.stopped:
        refit_schedule(job, state, budget, dt)
    if not main:
        return True
    save_last(job.out_dir / LAST_CHECKPOINT, job.model, job.optimizer, job.scheduler,
              job.ema, state, job.info["config_hash"])
    write_train_log(job.out_dir / TRAIN_LOG, state["history"])
    left = "" if res.stopped else time_left(state["epochs"] - state["epoch"], dt)
    log.info("epoch %d/%d: loss %.4f, val pixel acc %.4f, mIoU %.4f, boundary F %.4f%s "
             "(%.0f s)%s", epoch + 1, state["epochs"], res.loss, val["pixel_accuracy"],
             val["mean_iou"], val["boundary_f"], " *" if improved else "", dt,
             "; time budget used up, stopping" if res.stopped else f"; {left}" if left else "")
    return True


def keeps_init(cfg: TrainConfig) -> bool:
    """Whether the keep rule (train/keep.py) chooses between the fine-tune and ``init_from``."""
    return cfg.keep.init_unless_gain and cfg.init_from is not None


def init_scores(job: TrainJob) -> dict:
    """``init_from``'s network scored on the validation split, image by image (the keep
    rule's baseline, kept in the run's state): {"confusion": (N, C, C), "boundary": (N, 4)}."""
    net = build_network(job.cfg, job.num_classes).to(job.device)
    s = score_images(net, job.val_data, job.num_classes, job.cfg.eval.batch_size,
                     job.cfg.progress, "val of init_from")
    return {"confusion": s.confusion, "boundary": s.boundary}


def keep_decision(job: TrainJob, state: dict, model: SegNet) -> KeepDecision:
    """The keep rule on ``init_from``'s network (the state's ``init_val``, else scored now)
    and the fine-tuned ``model``, both on the validation split."""
    init = state.get("init_val") or init_scores(job)
    tuned = score_images(model, job.val_data, job.num_classes, job.cfg.eval.batch_size,
                         job.cfg.progress, "val of the fine-tune")
    return decide(ImageScores(np.asarray(init["confusion"]), np.asarray(init["boundary"])),
                  tuned, job.cfg.keep, str(job.cfg.init_from),
                  np.random.default_rng(job.cfg.seed))


def fit(job: TrainJob) -> dict:
    """Train (resuming from ``checkpoint_last.pt`` if there is one) until the schedule ends or
    the time budget is used up.

    Under torchrun every rank resumes from rank 0's checkpoint.

    Returns:
        The run's state (``checkpoint.new_state``'s keys).
    """
    state = new_state(job.requested)
    last = job.out_dir / LAST_CHECKPOINT
    # under torchrun rank 0 reads the checkpoint and the clock, and sends both to the others
    resume(last, job.model, job.optimizer, job.scheduler, job.ema, state,
           job.world.from_main(lambda: read_last(last)))
    budget = job.world.from_main(lambda: training_budget(job.cfg, state["train_seconds"]))
    if job.world.is_main:
        write_train_log(job.out_dir / TRAIN_LOG, state["history"])  # a kill before it was
        if keeps_init(job.cfg) and state["init_val"] is None:
            state["init_val"] = init_scores(job)
            base = ImageScores(state["init_val"]["confusion"],
                               state["init_val"]["boundary"]).summary()
            log.info("init_from %s on the %d validation images: boundary F %.4f, mIoU %.4f; "
                     "the fine-tune ships only with a gain (keep.init_unless_gain)",
                     job.cfg.init_from, len(job.val_data), base["boundary_f"], base["mean_iou"])
        if state["epoch"] < state["epochs"]:
            log.info("training epochs %d-%d of %d%s", state["epoch"] + 1, state["epochs"],
                     state["epochs"], f" (resumed: {state['train_seconds'] / 60:.1f} min "
                     "trained before)" if state["epoch"] else "")
    while state["epoch"] < state["epochs"] and not state["stopped_by_budget"]:
        if not run_epoch(job, state, budget):
            state["stopped_by_budget"] = True
    return state


def load_best(job: TrainJob) -> tuple[SegNet, dict]:
    """The network with the best checkpoint's weights, on the CPU in eval mode (what is
    exported), and the checkpoint."""
    path = job.out_dir / "checkpoint_best.pt"
    if not path.is_file():
        raise RuntimeError(
            f"no checkpoint in {job.out_dir}: the time budget max_minutes="
            f"{job.cfg.max_minutes} ended before the first epoch; raise it"
        )
    best = torch.load(path, map_location="cpu", weights_only=False)
    model = job.model.to("cpu", memory_format=torch.contiguous_format)
    model.load_state_dict(best["model"])
    model.eval()
    return model, best


def export_onnx(job: TrainJob, model: SegNet, test_data: SplitData, metrics: dict) -> Path:
    """Export ``segnet.onnx`` checked against torch on the first test images; its parity
    figures go into ``metrics``. A failed check writes metrics.json, then raises ParityError."""
    cfg, out_dir = job.cfg, job.out_dir
    onnx_path = out_dir / "segnet.onnx"
    parity_images = to_float(test_data.images[: min(cfg.export.parity_images, len(test_data))])
    meta = onnx_metadata(
        model, job.classes, parity_images.shape[2], parity_images.shape[3],
        job.info["config_hash"],
        extra={"class_weights": job.class_weights, LOCALIZE_METADATA_KEY: job.cfg.localize,
               **({} if metrics.get("keep") is None else
                  {"keep": {k: metrics["keep"][k] for k in ("kept", "init_from")}})},
    )
    try:
        with disk_space_guard(out_dir, onnx_path.name):
            report = export_checked(
                model, onnx_path, parity_images, meta, tolerance=cfg.export.tolerance,
                threads=cfg.threads, batch_size=cfg.export.batch_size, opset=cfg.export.opset,
            )
    except ParityError as err:
        metrics.update(onnx_max_abs_diff=err.report.max_abs_diff,
                       onnx_parity=err.report.as_dict())
        with disk_space_guard(out_dir, "metrics.json"):
            atomic_write_json(out_dir / "metrics.json", metrics)
        raise
    metrics.update(onnx_max_abs_diff=report.max_abs_diff, onnx_parity=report.as_dict())
    return onnx_path


def run_metrics(job: TrainJob, state: dict, model: SegNet, best: dict, images: dict) -> dict:
    """metrics.json without the test scores and the export's figures (``finish`` adds them)."""
    return {
        "test": None,  # segnet.onnx's labels output on the test split (``finish``)
        "test_source": "segnet.onnx labels output (onnxruntime), as localize reads them",
        # The loss's class weights: localize takes this prior out of its structural decisions
        # (localize.frontend.segmenter.structural_prior_labels); null without class weighting.
        "class_weights": job.class_weights,
        "onnx_max_abs_diff": None,
        "train_seconds": round(state["train_seconds"], 1),
        "budget_clock": job.cfg.budget_clock,  # what train_seconds counts (wall or cpu)
        "epochs_done": state["epoch"],
        "epochs": state["epochs"],
        "epochs_requested": job.requested,
        "stopped_by_budget": state["stopped_by_budget"],
        "best_epoch": state["best_epoch"],
        "val_best": best.get("val"),
        "keep": None,  # the keep rule's decision (``finish``; train/keep.py), or null
        "model": {
            "name": job.cfg.model.name,
            "arch": job.cfg.model.arch,
            "parameters": count_parameters(model),
            "channels": model.channels,
            "convs_per_stage": model.convs_per_stage,
        },
        "images": images,
        "config_hash": job.info["config_hash"],
        "threads": job.cfg.threads,
        "localize": job.cfg.localize,
        "run_seconds": None,  # the whole run's wall time (``finish``)
    }


def score_graph(job: TrainJob, onnx_path: Path, test_data: SplitData) -> dict:
    """Score ``segnet.onnx``'s labels on the test split (the labels localize reads), draw
    ``confusion.png`` and record the scores in the graph's metadata (``test_metrics``)."""
    cfg = job.cfg
    graph = score_onnx(onnx_path, test_data, job.num_classes, cfg.eval.batch_size,
                       cfg.threads, cfg.progress, "test")
    cm = graph.confusion
    test = metrics_json(cm, job.names, graph.boundary, graph.pairs)
    with disk_space_guard(job.out_dir, f"{onnx_path.name}'s metadata and confusion.png"):
        update_metadata(onnx_path, {"test_metrics": {
            k: test[k] for k in ("pixel_accuracy", "class_accuracy", "mean_iou", "boundary_f")}})
        plot_confusion(cm, job.names, job.out_dir / "confusion.png",
                       title=f"{cfg.name}: test, pixel acc {test['pixel_accuracy']:.3f}, "
                       f"mIoU {test['mean_iou']:.3f}")
    return test


def quantize(job: TrainJob, metrics: dict) -> None:
    """``export.int8``: write segnet_int8.onnx scored against the float graph (metrics'
    ``int8``); otherwise remove an int8 copy of an earlier export."""
    cfg, out_dir = job.cfg, job.out_dir
    if not cfg.export.int8:
        for name in (INT8_NAME, QUANTIZE_REPORT):  # it would not match this segnet.onnx
            (out_dir / name).unlink(missing_ok=True)
        return
    with disk_space_guard(out_dir, INT8_NAME):
        q = quantize_model_dir(out_dir, job.info["dataset"], cfg.export.int8_calibration,
                               cfg.data.limit, cfg.threads, cfg.progress)
        metrics["int8"] = int8_summary(q)
        atomic_write_json(out_dir / "metrics.json", metrics)
    log.info("int8: test pixel acc %.4f, mIoU %.4f; labels equal to the float graph's on "
             "%.2f %% of pixels", q["int8"]["pixel_accuracy"], q["int8"]["mean_iou"],
             100 * q["label_agreement"])


def finish(job: TrainJob, state: dict, t_start: float) -> dict:
    """Export the best checkpoint, score the exported graph on the test split, write
    metrics.json (and the int8 copy).

    Args:
        job: the prepared run, trained.
        state: ``fit``'s state.
        t_start: ``time.monotonic()`` at the start of the run.

    Returns:
        The metrics.json contents.
    """
    model, best = load_best(job)
    decision = keep_decision(job, state, model) if keeps_init(job.cfg) else None
    if decision is not None and decision.kept_init:
        model = build_network(job.cfg, job.num_classes).eval()  # on the CPU, as exported
    n_train = len(job.train_data)
    job.train_data = None  # its memory, before the test split is loaded
    test_data = load_splits(job.datasets, "test", job.num_classes, job.cfg.data.limit,
                            job.cfg.progress)
    images = {"train": n_train, "val": len(job.val_data), "test": len(test_data)}
    metrics = run_metrics(job, state, model, best, images)
    if decision is not None:
        metrics["keep"] = decision.as_dict()
        log.info("%s", decision.message())
    onnx_path = export_onnx(job, model, test_data, metrics)
    metrics["test"] = test = score_graph(job, onnx_path, test_data)
    metrics["run_seconds"] = round(time.monotonic() - t_start, 1)
    with disk_space_guard(job.out_dir, "metrics.json"):
        atomic_write_json(job.out_dir / "metrics.json", metrics)
    log.info("test (segnet.onnx's labels): pixel acc %.4f, class acc %.4f, mIoU %.4f, boundary "
             "F %.4f; onnx max |diff| %.2e", test["pixel_accuracy"], test["class_accuracy"],
             test["mean_iou"], test["boundary_f"] or float("nan"), metrics["onnx_max_abs_diff"])
    quantize(job, metrics)
    print(f"metrics: {job.out_dir / 'metrics.json'}")
    print(f"onnx:    {onnx_path}" + ("" if decision is None else
                                          f" ({decision.kept_what()})"))
    if "int8" in metrics:
        print(f"int8:    {job.out_dir / INT8_NAME}")
    return metrics


@releases_claims
def run(cfg: DictConfig | Mapping | TrainConfig) -> dict:
    """Train (or resume), export the best checkpoint to ONNX, score it on the test split.

    Under ``torchrun`` (``WORLD_SIZE`` > 1 in the environment) the processes train together
    (train/loop/distributed.py); rank 0 alone writes the model folder, exports and tests, the
    others return an empty dict once training is done.

    Args:
        cfg: the composed ``conf/train.yaml`` (``train_settings``).

    Returns:
        The metrics.json contents.
    """
    t_start = time.monotonic()
    settings = train_settings(cfg)
    device = training_device(settings.device)
    with process_group(device) as world:
        job = prepare(settings, world, device)
        state = fit(job)
        job.ddp = None
    if not world.is_main:
        return {}
    return finish(job, state, t_start)
