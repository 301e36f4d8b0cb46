"""Run the filter over every flight x edge mode x init x seed, resumably, and write the report.

Layout of ``outputs/reports/<name>/``::

    report.md, metrics.json, plots/*.png
    trajectories/<flight>/<mode>_seed<k>.txt          tracking init (TUM, world_from_body)
    trajectories/<flight>/<mode>_global_seed<k>.txt   global init
    runs/<flight>/<mode>_<init>_seed<k>.json          per-frame errors, timings, diagnostics,
                                                      status and pose hypotheses
    cache/visibility_<hash>.npz                       occlusion grid of the world
    viz/<flight>_<mode>.rrd                           with viz=rerun: the pass for the viewer

One pass per (flight, mode) reads each frame once, makes its edges once (``FrontEnd.frame``)
and steps every (init, seed) ``Localizer`` that is not finished yet with that frame
(``run_pass``: the one loop, over any ``core.frames.FrameSource``; a recording's run,
``localize.offline.recorded``, goes through it and through ``prepare`` too). A run is
finished when its trajectory and run file exist, so a stopped job resumes where it was
(``overwrite=true`` re-runs everything).
"""

from __future__ import annotations

import json
import logging
import time
import zlib
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from core.atomic import atomic_write_json, disk_full_guard, file_sha256
from core.dataset import FLIGHT_SETS, Camera, Dataset
from core.frames import Frame, FrameSource, frame_count
from core.occupancy import OccupancyMap
from core.outputs import Claim, FolderPolicy, claim_output, releases_claims
from core.poses import pose_from_xyzyaw, write_tum, xyzyaw_from_pose
from localize.config import MODES
from localize.context import Context, SourceWrappers, open_map, report_folder, settings_of
from localize.edge_model import EdgeModel
from localize.filter.start_hint import start_of_settings
from localize.frontend.segmenter import load_segmenter, runtime_model
from localize.localizer import Estimate, LikelihoodOverride, Localizer
from localize.offline.metrics import position_errors, yaw_errors_deg
from localize.viewers.viz import open_viewer

log = logging.getLogger(__name__)

INITS = ("tracking", "global")
STAGES = ("acquisition", "segmentation", "preprocessing", "filter", "total")
DIAGNOSTICS = ("ess", "best_score", "num_particles", "injected", "position_std", "confidence",
               "quality")

@dataclass(frozen=True)
class RunSpec:
    """One filter run: a flight, an edge mode, an init and a seed."""

    flight: str
    mode: str
    init: str
    seed: int
    likelihood: str = "vectorized"  # or paper_faithful
    recording: bool = False  # a recording's run: one per mode, its files named by the mode

    @property
    def stem(self) -> str:
        """File stem of the trajectory (the issue's ``<mode>_seed<k>`` for tracking; the mode
        alone for a recording's run)."""
        if self.recording:
            return self.mode
        tag = "" if self.init == "tracking" else f"_{self.init}"
        lik = "" if self.likelihood == "vectorized" else f"_{self.likelihood}"
        return f"{self.mode}{lik}{tag}_seed{self.seed}"

    def paths(self, out_dir: Path) -> tuple[Path, Path]:
        """(trajectory .txt, run record .json): ``trajectories/<flight>/<stem>.txt`` and
        ``runs/<flight>/<stem>.json``; a recording's: ``trajectories/<mode>.txt`` and
        ``runs/<mode>.json``."""
        sub = Path() if self.recording else Path(self.flight)
        return (out_dir / "trajectories" / sub / f"{self.stem}.txt",
                out_dir / "runs" / sub / f"{self.stem}.json")

    def done(self, out_dir: Path) -> bool:
        return all(p.is_file() for p in self.paths(out_dir))

    def rng(self) -> np.random.Generator:
        """The run's generator, seeded from (seed, mode, init, likelihood): not from the flight's
        or recording's name, so a result never depends on a folder's name."""
        key = [zlib.crc32(s.encode()) for s in (self.mode, self.init, self.likelihood)]
        return np.random.default_rng([int(self.seed), *key])


def select_flights(dataset: Dataset, wanted, flight_set: str = "test") -> list[str]:
    """Flight names of ``flight_set`` (test | val) to run; errors name the key, the dataset
    and what exists."""
    if flight_set not in FLIGHT_SETS:
        raise ValueError(f"flight_set={flight_set!r}: use one of {FLIGHT_SETS} (test: the "
                         "flights figures are reported on; val: those settings are tuned on)")
    every = dataset.flight_names()
    if not every:
        raise ValueError(f"dataset {dataset.root} has no flights (no {dataset.root / 'flights'}/"
                         "<name>/); render some with `python -m datagen` (render_flights)")
    names = dataset.flight_names(flight_set)
    if not names:
        key = "render_flights" if flight_set == "test" else "val_flights"
        raise ValueError(f"dataset {dataset.root} has no {flight_set} flights (flight_set="
                         f"{flight_set}; flights there: {every}); render some with `python -m "
                         f"datagen` ({key})")
    if wanted is None:
        return names
    wanted = [str(w) for w in wanted]
    other = [w for w in wanted if w in every and w not in names]
    if other:
        raise ValueError(f"flight_names: {other} are not {flight_set} flights (flight_set="
                         f"{flight_set}); pick the set they belong to or flights of "
                         f"{names}")
    missing = [w for w in wanted if w not in names]
    if missing:
        raise ValueError(f"flights {missing} not in {dataset.root / 'flights'}; available: "
                         f"{names}")
    return wanted


def check_run_lists(cfg: DictConfig) -> None:
    """Raise ValueError naming the key when ``modes``, ``inits`` or ``seeds`` is empty, repeats
    an entry or holds one that is not a known mode, a known init or a non-negative integer."""
    for key, example in (("modes", "[none,cnn,oracle]"), ("inits", "[tracking]"),
                         ("seeds", "[0,1,2]")):
        values = list(cfg[key] or [])
        if not values:
            raise ValueError(f"{key} is empty: nothing to run; give at least one, e.g. "
                             f"{key}={example}")
        if len(set(map(str, values))) < len(values):
            raise ValueError(f"{key}={values} repeats an entry; give each once")
    for mode in cfg.modes:
        if mode not in MODES:
            raise ValueError(f"modes: unknown edge mode {mode!r}; use {', '.join(MODES)}")
    for init in cfg.inits:
        if init not in INITS:
            raise ValueError(f"inits: unknown init {init!r}; use {INITS}")
    for seed in cfg.seeds:
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seeds: {seed!r} is not a non-negative integer")


def check_max_frames(cfg: DictConfig) -> None:
    """Raise ValueError naming ``max_frames`` when it is set and below 1 (null: every frame)."""
    n = cfg.max_frames
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise ValueError(f"max_frames={n!r}: a run needs at least one frame; give a positive "
                         "count, or max_frames=null for every frame")


def prepare(cfg: DictConfig, source_wrappers: SourceWrappers | None = None,
            recording: FrameSource | None = None, camera: Camera | None = None) -> Context:
    """Open the map (the dataset's, or ``world.path``'s with a recording:
    ``context.open_map``), sample the model edges, load or build the visibility grid, load the
    segmenter (cnn mode).

    Args:
        cfg: the composed localize config.
        source_wrappers: per edge mode, the edge source to use instead (``SourceWrappers``).
        recording: a recording to run instead of the dataset's flights: the output folder is
            ``<out_root>/<name>/recordings/<recording name>``.
        camera: the camera of the frames (a recording's); None: the dataset's.
    """
    check_run_lists(cfg)
    check_max_frames(cfg)
    if cfg.world.path and (recording is None or camera is None):
        raise ValueError(f"world={cfg.world.path}: a building file has no flights or camera; "
                         "localize a recording in it (recording=PATH)")
    dataset, world, classes, digest = open_map(cfg)
    if recording is None:
        select_flights(dataset, cfg.flight_names, cfg.flight_set)
    out_dir = report_folder(cfg)
    if recording is not None:
        out_dir = out_dir / "recordings" / recording.name
    settings = settings_of(cfg)
    # fail before any run on a hint off the map
    start_of_settings(settings.hint, world.info, world.free, settings.filter.init_std)
    model = EdgeModel.build(world, settings, out_dir / "cache")
    segmenter = None
    if "cnn" in cfg.modes:
        segmenter = load_segmenter(runtime_model(cfg.onnx_model, cfg.dataset,
                                                 cfg.segnet_int8), classes,
                                   int(cfg.threads))
    return Context(cfg, dataset, dataset.camera if camera is None else camera, world, settings,
                   model, out_dir, segmenter, dict(source_wrappers or {}), digest)


class PassRecord:
    """Per delivered frame: the estimates, diagnostics and timings of the runs of one pass,
    the frame's index, timestamp and true state (when the source has ground truth)."""

    def __init__(self, n_runs: int, T: int):
        self.estimate = np.zeros((n_runs, T, 4))
        self.diag = {k: np.zeros((n_runs, T)) for k in DIAGNOSTICS}
        self.timing = {k: np.zeros((n_runs, T)) for k in STAGES}
        self.status = [[""] * T for _ in range(n_runs)]
        self.hypotheses = [[[] for _ in range(T)] for _ in range(n_runs)]
        self.quality_inputs = [[[] for _ in range(T)] for _ in range(n_runs)]
        self.index: list[int] = []
        self.timestamps: list[float] = []
        self.truth: list[np.ndarray] | None = []
        self.num_frames = T  # frames of the source the pass covered, delivered or dropped

    def add_frame(self, frame: Frame) -> int:
        """Register a delivered frame; returns its row."""
        self.index.append(frame.index)
        self.timestamps.append(frame.timestamp)
        if frame.truth is None:
            self.truth = None
        elif self.truth is not None:
            self.truth.append(frame.truth)
        return len(self.index) - 1

    def add(self, i: int, t: int, est: Estimate, acquisition_ms: float) -> None:
        """Run i's estimate of row t (``acquisition_ms``: reading the frame)."""
        self.estimate[i, t] = est.state
        for k in DIAGNOSTICS:
            self.diag[k][i, t] = getattr(est, k)
        self.status[i][t] = est.status
        self.hypotheses[i][t] = [h.as_list() for h in est.hypotheses]
        self.quality_inputs[i][t] = [round(v, 5) for v in est.quality_inputs]
        stages = {"acquisition": acquisition_ms, **est.timing_ms}
        for k, v in stages.items():
            self.timing[k][i, t] = v
        self.timing["total"][i, t] = sum(stages.values())

    def write(self, i: int, run: RunSpec, out_dir: Path, num_particles: int,
              free: OccupancyMap) -> None:
        """Run i's trajectory (TUM, world_from_body) and run record (JSON: per delivered frame
        the estimate, the timings, the diagnostics, the status, the pose hypotheses
        ``[x, y, z, yaw, mass]``, heaviest first, and the quality's inputs
        (``quality.INPUTS``); where there is truth, the errors and how many
        true poses lie outside the free space ``free``, and how far at most)."""
        traj, rec = run.paths(out_dir)
        n = len(self.index)
        estimate = self.estimate[i, :n]
        ts = np.asarray(self.timestamps, dtype=np.float64)
        write_tum(traj, ts, pose_from_xyzyaw(estimate))
        record = {
            "flight": run.flight, "mode": run.mode, "init": run.init, "seed": run.seed,
            "likelihood": run.likelihood, "num_frames": n,
            "dropped_frames": self.num_frames - n,
            "filter_particles": int(num_particles),
            "timestamps": ts.tolist(),
            "estimate": estimate.tolist(),
        }
        if self.truth is not None:
            truth = xyzyaw_from_pose(np.stack(self.truth))
            record.update({"truth": truth.tolist(),
                           "position_error_m": position_errors(estimate, truth).tolist(),
                           "yaw_error_deg": yaw_errors_deg(estimate, truth).tolist()})
            outside = free.outside_distance_xyz(truth[:, :3])
            record["truth_outside_free"] = {"frames": int(np.count_nonzero(outside > 0)),
                                            "max_m": round(float(outside.max()), 3)}
        if n < self.num_frames:
            record["frame_index"] = list(self.index)
        record.update({"timing_ms": {k: v[i, :n].tolist() for k, v in self.timing.items()},
                       **{k: v[i, :n].tolist() for k, v in self.diag.items()},
                       "status": self.status[i][:n],
                       "hypotheses": self.hypotheses[i][:n],
                       "quality_inputs": self.quality_inputs[i][:n]})
        atomic_write_json(rec, record)


def run_pass(ctx: Context, source: FrameSource, mode: str, runs: list[RunSpec],
             likelihood_override: LikelihoodOverride | None = None,
             num_particles: int | None = None, start: np.ndarray | None = None) -> None:
    """Step every run of one (frame source, mode) through the source, frame by frame, and
    write each run's trajectory and run record (``PassRecord.write``).

    Args:
        ctx: the shared context.
        source: the frames (a flight, a recording: ``core.frames.FrameSource``).
        mode: edge mode.
        runs: the runs to do (all share the source and mode).
        likelihood_override: replaces the edge likelihood (the paper-faithful comparison).
        num_particles: override of the filter's particle count (both inits).
        start: (4,) x, y, z (m), yaw (rad) the tracking runs start from; None: the source's
            first true pose. The global runs start inside the config's ``hint``
            (``start_hint.start_of_settings``; none set: the whole free space).

    With ``viz=rerun`` the pass's first run (its frames, labels, estimate, particles) is
    logged to ``<out_dir>/viz/<source>_<mode>.rrd`` (``localize.viewers.viz``).
    """
    if not runs:
        return
    cfg = ctx.cfg
    check_max_frames(cfg)
    T = frame_count(source, cfg.max_frames)
    if T < 1:
        raise ValueError(f"{source.name} has no frames")
    settings = ctx.settings if num_particles is None else ctx.settings.with_particles(
        num_particles)
    front = ctx.front_end(mode)
    if start is None and any(r.init == "tracking" for r in runs):
        if source.groundtruth is None:
            raise ValueError(f"{source.name}: a tracking run needs a start pose and the source "
                             "has no ground truth; give hint.pose=[x, y, z, yaw_deg]")
        start = xyzyaw_from_pose(source.groundtruth[0])[0]
    warn_outside_free_space(source, ctx.world.free, T, start, settings.filter.free_space_slack)
    hint = start_of_settings(ctx.settings.hint, ctx.world.info, ctx.world.free,
                             settings.filter.init_std)
    localizers = []
    for r in runs:
        loc = Localizer(ctx.world, ctx.camera, front, settings, r.rng(),
                        model=ctx.model_for(mode), likelihood_override=likelihood_override)
        loc.reset(start if r.init == "tracking" else hint)
        localizers.append(loc)
    record = PassRecord(len(runs), T)
    desc = f"{source.name}/{mode}" + (f"/{runs[0].likelihood}"
                                      if runs[0].likelihood != "vectorized" else "")
    frames = source.steps(T, images=front.source.needs_image, labels=front.source.needs_truth)
    viewer = open_viewer(ctx.settings.viz, ctx.world,
                         ctx.out_dir / "viz" / f"{source.name}_{mode}.rrd", camera=ctx.camera,
                         connect=ctx.settings.viz_connect)
    with (viewer or nullcontext()), tqdm(total=T, desc=desc, disable=not cfg.progress,
                                         leave=False, mininterval=2.0) as bar:
        while True:
            t0 = time.perf_counter()
            f = next(frames, None)
            acquisition_ms = (time.perf_counter() - t0) * 1e3
            if f is None:
                break
            row = record.add_frame(f)
            frame = front.frame(f.image, f.labels)
            for i, loc in enumerate(localizers):
                est = loc.step(frame, f.odometry_increment, f.attitude, f.timestamp)
                record.add(i, row, est, acquisition_ms)
                if viewer is not None and i == 0:
                    viewer.log_step(f.timestamp, f.image, frame.labels, est,
                                    loc.filter.particles, attitude=f.attitude, truth=f.truth)
            bar.update(f.index + 1 - bar.n)
    if not record.index:
        raise ValueError(f"{source.name}: none of its {T} frames could be read")
    if len(record.index) < T:
        log.warning("%s/%s: %d of %d frames could not be read and were dropped", source.name,
                    mode, T - len(record.index), T)
    for i, r in enumerate(runs):
        record.write(i, r, ctx.out_dir, localizers[i].filter_params.num_particles,
                     ctx.world.free)


#: the keys a warning about a pose outside the free space points at.
FREE_SPACE_KEYS = ("the dataset's free space (world/free.npz) comes from datagen's "
                   "world.z_range, world.camera_margin, world.free_close, "
                   "world.free_max_hole and world.obstacle_span; the filter's prior "
                   "penalises beyond filter.free_space_slack")


def warn_outside_free_space(source: FrameSource, free: OccupancyMap, T: int,
                            start: np.ndarray | None, slack: float) -> None:
    """Log a warning when the start pose or any of the first ``T`` true poses of ``source``
    lies outside the free space ``free``, with the distance (m) and the keys of the map.

    Args:
        source: the frames (its ``groundtruth``, if any, is checked).
        free: the world's free space.
        T: frames the pass covers.
        start: (4,) x, y, z (m), yaw (rad) of the tracking runs, or None.
        slack: m beyond the free space the filter does not penalise.
    """
    if start is not None:
        d = float(free.outside_distance_xyz(np.asarray(start)[None, :3])[0])
        if d > 0:
            log.warning("%s: the start pose %s lies %.2f m outside the free space (%s "
                        "%.2f m)", source.name, np.round(start[:3], 2).tolist(), d,
                        FREE_SPACE_KEYS, slack)
    if source.groundtruth is None:
        return
    truth = xyzyaw_from_pose(np.asarray(source.groundtruth[:T]))[:, :3]
    d = free.outside_distance_xyz(truth)
    if (d > 0).any():
        worst = int(np.argmax(d))
        log.warning("%s: %d of %d true poses lie outside the free space, up to %.2f m (frame "
                    "%d at %s); %s %.2f m", source.name, int(np.count_nonzero(d > 0)), len(d),
                    d[worst], worst, np.round(truth[worst], 2).tolist(), FREE_SPACE_KEYS,
                    slack)


@releases_claims
def run(cfg: DictConfig, source_wrappers: SourceWrappers | None = None) -> Path:
    """Run every flight x mode x init x seed (skipping finished runs) and write the report.

    Args:
        cfg: the composed localize config.
        source_wrappers: per edge mode, a function of the mode's own edge source giving the
            source to use instead (``SourceWrappers``); None: every mode's own.

    Returns:
        Path of report.md.
    """
    from localize.offline.report import write_report

    with disk_full_guard(report_folder(cfg), "the report", REPORT_DISK_FULL_FIX):
        ctx = prepare(cfg, source_wrappers)
        out = ctx.out_dir
        check_resume(out, cfg)
        for name in select_flights(ctx.dataset, cfg.flight_names, cfg.flight_set):
            flight = ctx.dataset.flight(name)
            for mode in cfg.modes:
                runs = [RunSpec(name, mode, init, int(seed)) for init in cfg.inits
                        for seed in cfg.seeds]
                todo = [r for r in runs if cfg.overwrite or not r.done(out)]
                if len(todo) < len(runs):
                    log.info("%s/%s: %d of %d runs already done", name, mode,
                             len(runs) - len(todo), len(runs))
                run_pass(ctx, flight, mode, todo)
        return write_report(ctx)


# Settings a finished run's trajectory depends on; the others (modes, seeds, inits, flights)
# only choose which runs exist, so they may change between resumes. The segnet.onnx digest
# may be set where no cnn run had one.
RESULT_KEYS = ("dataset", "onnx_model", "max_frames", "filter", "edges", "model_edges",
               "visibility", "hint", "onnx_sha256", "world", "world_sha256", "edges_sha256")
# settings under RESULT_KEYS that change only how fast the results come, not the results (the
# map cache's folder: its maps are found by content)
SPEED_ONLY = ("filter.likelihood.workers", "filter.likelihood.chunk", "world.cache")
#: What to do when the disk fills during a run (``core.atomic.DiskFullError``'s advice).
REPORT_DISK_FULL_FIX = ("Free space (old outputs/reports/* folders, outputs/hydra/) or pass "
                        "out_root= on a disk with room, then run the same command again: the "
                        "finished runs are kept and the others resume")
#: A report folder belongs to its result settings (core.outputs); one run at a time.
REPORT_POLICY = FolderPolicy(record="config.json", keys=RESULT_KEYS, grow=("onnx_sha256",),
                             speed_only=SPEED_ONLY, results=("runs",))


def result_settings(conf: dict) -> dict:
    """The settings of ``conf`` (a config.json) its runs' results depend on (dotted keys)."""
    return REPORT_POLICY.settings(conf)


def check_resume(out: Path, cfg: DictConfig, policy: FolderPolicy = REPORT_POLICY,
                 world_digest: str | None = None) -> Claim:
    """Claim ``out`` for this config and write ``out/config.json`` (the whole config and the
    segnet.onnx digest): the runs already in ``out`` must come from the same result settings
    and segnet.onnx bytes (``policy``: ``REPORT_POLICY``, a recording's
    ``recorded.RECORDING_POLICY``).

    With ``overwrite=true`` a folder of other settings is emptied (every run is re-done);
    otherwise it raises naming the differing keys. A run in a building file (``world.path``)
    also records its content (``world_digest``, ``Context.world_digest``) as ``world_sha256``;
    a run in a dataset records no ``world`` but the digest of its model edges
    (``world/edges.npz``, ``edges_sha256``), so edges rebuilt since
    (``datagen.mesh.rebuild_edges``) are never resumed into runs made with the old ones.
    """
    conf = OmegaConf.to_container(cfg, resolve=True)
    if cfg.world.path:
        conf["world_sha256"] = world_digest
    else:
        conf.pop("world", None)
        edges = Path(str(cfg.dataset)) / "world" / "edges.npz"
        if edges.is_file():
            conf["edges_sha256"] = file_sha256(edges)[:16]
    onnx_path = runtime_model(str(cfg.onnx_model), str(cfg.dataset), cfg.segnet_int8)
    conf["onnx_sha256"] = (file_sha256(onnx_path)[:16]
                           if "cnn" in cfg.modes and onnx_path.is_file() else None)
    path = out / "config.json"
    if not conf["onnx_sha256"] and path.is_file():  # no cnn run now: keep the runs' digest
        try:
            conf["onnx_sha256"] = json.loads(path.read_text()).get("onnx_sha256")
        except json.JSONDecodeError:
            pass  # claim_output names the broken file
    return claim_output(out, conf, policy, overwrite=bool(cfg.overwrite))


def load_runs(out_dir: Path) -> list[dict]:
    """Every run record under ``out_dir/runs``."""
    return [json.loads(p.read_text()) for p in sorted((out_dir / "runs").glob("*/*.json"))]
