"""Run the filter over every flight x edge mode x init x seed, resumably, and write the report.

Layout of ``outputs/reports/<name>/``::

    report.md, metrics.json, plots/*.png
    trajectories/<flight>/<mode>_seed<k>.txt          tracking init (TUM, world_from_body)
    trajectories/<flight>/<mode>_global_seed<k>.txt   global init
    runs/<flight>/<mode>_<init>_seed<k>.json          per-frame errors, timings, diagnostics
    cache/visibility_<hash>.npz                       occlusion grid of the world

One pass per (flight, mode) reads each frame and computes its edges once, then steps every
(init, seed) filter that is not finished yet. A run is finished when its trajectory and run
file exist, so a stopped job resumes where it was (``overwrite=true`` re-runs everything).
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf
from threadpoolctl import ThreadpoolController
from tqdm import tqdm

from core.atomic import atomic_write_json, read_png
from core.dataset import Camera, Dataset, Flight, World
from core.outputs import Claim, FolderPolicy, claim_output, releases_claims
from core.poses import pose_from_xyzyaw, write_tum, xyzyaw_from_pose
from localize.edges import (
    MODES,
    CnnSettings,
    EdgeExtractor,
    class_boundaries_only,
    load_segmenter,
    pair_code,
)
from localize.likelihood import EdgeLikelihood, LikelihoodParams
from localize.metrics import position_errors, yaw_errors_deg
from localize.particle_filter import FilterParams, ParticleFilter, odometry_increment
from localize.projection import ModelSamples, sample_segments, tilt_from_pose
from localize.visibility import VisibilityGrid, load_or_build

log = logging.getLogger(__name__)

INITS = ("tracking", "global")
STAGES = ("acquisition", "segmentation", "preprocessing", "filter", "total")
_BLAS = ThreadpoolController()


@dataclass(frozen=True)
class RunSpec:
    """One filter run: a flight, an edge mode, an init and a seed."""

    flight: str
    mode: str
    init: str
    seed: int
    likelihood: str = "vectorized"  # or paper_faithful

    @property
    def stem(self) -> str:
        """File stem of the trajectory (the issue's ``<mode>_seed<k>`` for tracking)."""
        tag = "" if self.init == "tracking" else f"_{self.init}"
        lik = "" if self.likelihood == "vectorized" else f"_{self.likelihood}"
        return f"{self.mode}{lik}{tag}_seed{self.seed}"

    def paths(self, out_dir: Path) -> tuple[Path, Path]:
        """(trajectory .txt, run record .json)."""
        return (out_dir / "trajectories" / self.flight / f"{self.stem}.txt",
                out_dir / "runs" / self.flight / f"{self.stem}.json")

    def done(self, out_dir: Path) -> bool:
        return all(p.is_file() for p in self.paths(out_dir))

    def rng(self) -> np.random.Generator:
        """The run's generator, seeded from (seed, flight, mode, init, likelihood)."""
        key = [zlib.crc32(s.encode()) for s in (self.flight, self.mode, self.init,
                                                 self.likelihood)]
        return np.random.default_rng([int(self.seed), *key])


@dataclass
class Context:
    """What every pass shares: the dataset, the model samples and the settings."""

    cfg: DictConfig
    dataset: Dataset
    camera: Camera
    world: World
    samples: dict[str, tuple[ModelSamples, VisibilityGrid]]
    filter_params: FilterParams
    likelihood_params: LikelihoodParams
    out_dir: Path
    segmenter: object | None = None

    def sample_pairs(self, samples: ModelSamples) -> np.ndarray:
        """(P,) uint8 ``pair_code`` of the two classes each sample's world segment separates."""
        sc = np.asarray(self.world.segment_classes)[samples.segment]
        return pair_code(sc[:, 0], sc[:, 1])

    def model_for(self, mode: str) -> tuple[ModelSamples, VisibilityGrid]:
        """Edge samples (and their visibility) a mode scores against."""
        edges_cfg = OmegaConf.to_container(self.cfg.edges, resolve=True)
        key = "class_change" if class_boundaries_only(mode, edges_cfg) else "all"
        return self.samples[key if key in self.samples else "all"]


def filter_settings(cfg: DictConfig) -> tuple[FilterParams, LikelihoodParams]:
    """Split ``cfg.filter`` into the filter and likelihood settings."""
    f = OmegaConf.to_container(cfg.filter, resolve=True)
    lik = f.pop("likelihood", {})
    return FilterParams.from_cfg(f), LikelihoodParams.from_cfg(lik)


def mode_likelihood_params(lp: LikelihoodParams, fparams: FilterParams,
                           mode: str) -> LikelihoodParams:
    """The likelihood settings of one edge mode: ``lp`` updated by
    ``filter.mode_likelihood[mode]`` (unknown keys raise)."""
    over = fparams.mode_likelihood.get(mode)
    if not over:
        return lp
    try:
        return LikelihoodParams.from_cfg({**asdict(lp), **dict(over)})
    except (TypeError, ValueError) as err:
        raise ValueError(f"filter.mode_likelihood.{mode}: {err}") from err


def select_flights(dataset: Dataset, wanted) -> list[str]:
    """Flight names to run; errors name the dataset and what exists."""
    names = dataset.flight_names()
    if not names:
        raise ValueError(f"dataset {dataset.root} has no flights (no {dataset.root / 'flights'}/"
                         "<name>/); render some with `python -m datagen` (render_flights)")
    if wanted is None:
        return names
    wanted = [str(w) for w in wanted]
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


def prepare(cfg: DictConfig) -> Context:
    """Open the dataset, sample the model edges, load or build the visibility grid."""
    check_run_lists(cfg)
    dataset = Dataset(cfg.dataset)
    select_flights(dataset, cfg.flight_names)
    world = dataset.world()
    camera = dataset.camera
    out_dir = Path(cfg.out_root) / str(cfg.name)
    fparams, lparams = filter_settings(cfg)
    for mode in cfg.modes:  # fail before any run on a bad per-mode setting
        mode_likelihood_params(lparams, fparams, mode)
    CnnSettings.from_cfg(OmegaConf.to_container(cfg.edges, resolve=True).get("cnn"))  # checked
    samples = sample_segments(world.segments, float(cfg.model_edges.spacing))
    v = cfg.visibility
    vis = load_or_build(world, samples.points, out_dir / "cache", float(v.cell_xy),
                        float(v.cell_z), float(v.pad), float(v.eps), str(v.variant))
    models = {"all": (samples, vis)}
    if cfg.model_edges.label_modes_class_change_only:
        sc = np.asarray(world.segment_classes)
        keep = (sc[:, 0] != sc[:, 1]) & (sc.min(axis=1) > 0)
        if keep.any():
            sub, cols = samples.select(keep)
            models["class_change"] = (sub, vis.select(cols))
    segmenter = None
    if "cnn" in cfg.modes:
        segmenter = load_segmenter(cfg.onnx_model, dataset.classes, int(cfg.threads))
    return Context(cfg, dataset, camera, world, models, fparams, lparams, out_dir, segmenter)


def _truth_states(flight: Flight, n: int) -> np.ndarray:
    return xyzyaw_from_pose(flight.groundtruth[:n])


def run_pass(ctx: Context, flight: Flight, mode: str, runs: list[RunSpec],
             make_loglik: Callable | None = None, num_particles: int | None = None) -> None:
    """Step every run of one (flight, mode) through the flight, frame by frame.

    Args:
        ctx: the shared context.
        flight: the flight.
        mode: edge mode.
        runs: the runs to do (all share the flight and mode).
        make_loglik: ``(obs, tilt) -> (states -> (log_w, score))`` to replace the vectorized
            likelihood (the paper-faithful comparison); None uses ``EdgeLikelihood``.
        num_particles: override of the filter's particle count (both inits).
    """
    if not runs:
        return
    cfg = ctx.cfg
    T = len(flight.timestamps) if cfg.max_frames is None else min(int(cfg.max_frames),
                                                                  len(flight.timestamps))
    if T < 1:
        raise ValueError(f"flight {flight.name} has no frames")
    fparams = ctx.filter_params.for_mode(mode)
    if num_particles is not None:
        fparams = replace(fparams, num_particles=int(num_particles),
                          global_particles=max(int(num_particles), fparams.global_particles))
    samples, vis = ctx.model_for(mode)
    lp = mode_likelihood_params(ctx.likelihood_params, fparams, mode)
    pairs = ctx.sample_pairs(samples)
    lik = EdgeLikelihood(samples, ctx.camera, lp, vis, pairs)
    wide = None  # the global phase's likelihood: thinned samples, its own settings
    if any(r.init == "global" for r in runs) and (fparams.global_likelihood
                                                   or fparams.global_thin > 1):
        coarse, cols = samples.thin(fparams.global_thin)
        gp = LikelihoodParams.from_cfg({**asdict(lp), **dict(fparams.global_likelihood)})
        gp = replace(gp, evidence_norm=gp.evidence_norm / max(fparams.global_thin, 1))
        wide = EdgeLikelihood(coarse, ctx.camera, gp, vis.select(cols), pairs[cols])
    extractor = EdgeExtractor(mode, OmegaConf.to_container(cfg.edges, resolve=True),
                              ctx.segmenter)
    truth = _truth_states(flight, T)
    world = ctx.world
    filters = []
    for r in runs:
        pf = ParticleFilter(fparams, world.free_boxes, world.z_range, r.rng())
        if r.init == "tracking":
            pf.init_tracking(truth[0])
        else:
            pf.init_global()
        filters.append(pf)
    n_runs = len(runs)
    est = np.zeros((n_runs, T, 4))
    diag = {k: np.zeros((n_runs, T)) for k in ("ess", "best_score", "num_particles", "injected")}
    t_filter = np.zeros((n_runs, T))
    t_stage = {k: np.zeros(T) for k in ("acquisition", "segmentation", "preprocessing")}
    desc = f"{flight.name}/{mode}" + (f"/{runs[0].likelihood}"
                                      if runs[0].likelihood != "vectorized" else "")
    for t in tqdm(range(T), desc=desc, disable=not cfg.progress, leave=False, mininterval=2.0):
        t0 = time.perf_counter()
        rgb = labels = conf = None
        if mode in ("none", "cnn"):
            rgb = read_png(flight.rgb[t])
        if mode == "oracle":
            labels = read_png(flight.label[t], rgb=False)
        t1 = time.perf_counter()
        if mode == "cnn":
            labels, conf = extractor.segment(rgb)
        t2 = time.perf_counter()
        edge = extractor.edges(rgb, labels, conf)
        obs = lik.observe(edge)
        t3 = time.perf_counter()
        t_stage["acquisition"][t] = (t1 - t0) * 1e3
        t_stage["segmentation"][t] = (t2 - t1) * 1e3
        t_stage["preprocessing"][t] = (t3 - t2) * 1e3
        tilt = tilt_from_pose(flight.odometry[t])  # roll and pitch from the IMU
        delta = odometry_increment(flight.odometry[t - 1], flight.odometry[t]) if t else None
        if make_loglik is None:
            def loglik(states, obs=obs, tilt=tilt):
                return lik.log_likelihood(states, obs, tilt)
        else:
            loglik = make_loglik(edge, tilt)
        obs_wide = None
        for i, pf in enumerate(filters):
            s0 = time.perf_counter()
            fn = loglik
            if wide is not None and pf.in_global_phase and make_loglik is None:
                if obs_wide is None:
                    obs_wide = wide.observe(edge)

                def fn(states, obs=obs_wide, tilt=tilt):
                    return wide.log_likelihood(states, obs, tilt)
            with _BLAS.limit(limits=1, user_api="blas"):  # tiny GEMMs: threads only hurt
                if delta is not None:
                    pf.predict(delta)
                info = pf.update(fn)
            t_filter[i, t] = (time.perf_counter() - s0) * 1e3
            est[i, t] = info.estimate
            diag["ess"][i, t] = info.ess
            diag["best_score"][i, t] = info.best_score
            diag["num_particles"][i, t] = info.num_particles
            diag["injected"][i, t] = info.injected
    for i, r in enumerate(runs):
        traj, rec = r.paths(ctx.out_dir)
        ts = flight.timestamps[:T]
        write_tum(traj, ts, pose_from_xyzyaw(est[i]))
        timing = {k: v.tolist() for k, v in t_stage.items()}
        timing["filter"] = t_filter[i].tolist()
        timing["total"] = (sum(t_stage.values()) + t_filter[i]).tolist()
        atomic_write_json(rec, {
            "flight": r.flight, "mode": r.mode, "init": r.init, "seed": r.seed,
            "likelihood": r.likelihood, "num_frames": T,
            "filter_particles": int(fparams.num_particles),
            "timestamps": ts.tolist(),
            "estimate": est[i].tolist(), "truth": truth.tolist(),
            "position_error_m": position_errors(est[i], truth).tolist(),
            "yaw_error_deg": yaw_errors_deg(est[i], truth).tolist(),
            "timing_ms": timing,
            **{k: v[i].tolist() for k, v in diag.items()},
        })


def paper_faithful_runs(ctx: Context) -> None:
    """The comparison: paper-faithful vs vectorized likelihood, same particles and frames."""
    pcfg = ctx.cfg.paper_faithful
    if not pcfg.enabled:
        return
    names = ctx.dataset.flight_names()
    if pcfg.flight not in names:
        log.warning("paper_faithful: flight %r not in the dataset; skipped", pcfg.flight)
        return
    mode = str(pcfg.mode)
    if mode == "cnn" and ctx.segmenter is None:
        log.warning("paper_faithful: mode cnn needs the model; skipped")
        return
    from localize.paper_faithful import PaperFaithfulLikelihood

    flight = ctx.dataset.flight(pcfg.flight)
    sub = OmegaConf.merge(ctx.cfg, {"max_frames": int(pcfg.frames)})
    sub_ctx = Context(**{**ctx.__dict__, "cfg": sub})
    n = int(pcfg.num_particles)
    vec = [RunSpec(flight.name, mode, "tracking", int(s), f"vectorized_n{n}")
           for s in pcfg.seeds]
    todo = [r for r in vec if ctx.cfg.overwrite or not r.done(ctx.out_dir)]
    run_pass(sub_ctx, flight, mode, todo, num_particles=n)
    pf_runs = [RunSpec(flight.name, mode, "tracking", int(s), f"paper_faithful_n{n}")
               for s in pcfg.seeds]
    todo = [r for r in pf_runs if ctx.cfg.overwrite or not r.done(ctx.out_dir)]
    if todo:
        pfl = PaperFaithfulLikelihood(ctx.world, ctx.camera, ctx.likelihood_params,
                                      hough=dict(pcfg.hough),
                                      samples_per_line=int(pcfg.samples_per_line),
                                      search_px=float(pcfg.search_px),
                                      variant=str(pcfg.render_variant))

        def make(edge, tilt):
            return lambda states: pfl.log_likelihood(states, edge, tilt)

        run_pass(sub_ctx, flight, mode, todo, make_loglik=make, num_particles=n)


@releases_claims
def run(cfg: DictConfig) -> Path:
    """Run every flight x mode x init x seed (skipping finished runs) and write the report.

    Returns:
        Path of report.md.
    """
    from localize.report import write_report

    ctx = prepare(cfg)
    out = ctx.out_dir
    check_resume(out, cfg)
    for name in select_flights(ctx.dataset, cfg.flight_names):
        flight = ctx.dataset.flight(name)
        for mode in cfg.modes:
            runs = [RunSpec(name, mode, init, int(seed)) for init in cfg.inits
                    for seed in cfg.seeds]
            todo = [r for r in runs if cfg.overwrite or not r.done(out)]
            if len(todo) < len(runs):
                log.info("%s/%s: %d of %d runs already done", name, mode,
                         len(runs) - len(todo), len(runs))
            run_pass(ctx, flight, mode, todo)
    paper_faithful_runs(ctx)
    return write_report(ctx)


# Settings a finished run's trajectory depends on; the others (modes, seeds, inits, flights)
# only choose which runs exist, so they may change between resumes. The segnet.onnx digest
# may be set where no cnn run had one.
RESULT_KEYS = ("dataset", "onnx_model", "max_frames", "filter", "edges", "model_edges",
               "visibility", "onnx_sha256")
# settings under RESULT_KEYS that change only how fast the results come, not the results
SPEED_ONLY = ("filter.likelihood.workers", "filter.likelihood.chunk")
#: A report folder belongs to its result settings (core.outputs); one run at a time.
REPORT_POLICY = FolderPolicy(record="config.json", keys=RESULT_KEYS, grow=("onnx_sha256",),
                             speed_only=SPEED_ONLY, results=("runs",))


def result_settings(conf: dict) -> dict:
    """The settings of ``conf`` (a config.json) its runs' results depend on (dotted keys)."""
    return REPORT_POLICY.settings(conf)


def check_resume(out: Path, cfg: DictConfig) -> Claim:
    """Claim ``out`` for this config and write ``out/config.json`` (the whole config and the
    segnet.onnx digest): the runs already in ``out`` must come from the same result settings
    and segnet.onnx bytes (``REPORT_POLICY``).

    With ``overwrite=true`` a folder of other settings is emptied (every run is re-done);
    otherwise it raises naming the differing keys.
    """
    conf = OmegaConf.to_container(cfg, resolve=True)
    onnx_path = Path(str(cfg.onnx_model))
    conf["onnx_sha256"] = (hashlib.sha256(onnx_path.read_bytes()).hexdigest()[:16]
                           if "cnn" in cfg.modes and onnx_path.is_file() else None)
    path = out / "config.json"
    if not conf["onnx_sha256"] and path.is_file():  # no cnn run now: keep the runs' digest
        try:
            conf["onnx_sha256"] = json.loads(path.read_text()).get("onnx_sha256")
        except json.JSONDecodeError:
            pass  # claim_output names the broken file
    return claim_output(out, conf, REPORT_POLICY, overwrite=bool(cfg.overwrite))


def load_runs(out_dir: Path) -> list[dict]:
    """Every run record under ``out_dir/runs``."""
    return [json.loads(p.read_text()) for p in sorted((out_dir / "runs").glob("*/*.json"))]
