"""``python -m localize recording=PATH dataset=DATASET``: localize a recording (a folder or a
ROS bag, ``localize.recording``) against DATASET's world, with the camera the recording brings.

Output folder ``<out_root>/<name>/recordings/<recording name>/``::

    trajectory.txt              the first mode's estimates (cnn when it runs), TUM, world_from_body
    trajectory.json             its companion: per frame the timestamp, the filter's status
                                (tracking, coasting, lost, global), confidence (0-1) and
                                particle spread (m)
    trajectories/<mode>.txt     each mode's estimates (TUM), and <mode>.json their companions
    report.md, metrics.json     per mode: errors against groundtruth (when the recording has it),
                                frame timings, the settings used
    overlay.png                 model edges at the estimates (green) and the truth (magenta) on
                                eight frames of the first mode

A recording has no true labels, so mode ``oracle`` is skipped. The start: ``start=[x, y, z,
yaw_deg]`` tracks from that world pose; else the first ground-truth pose when the recording
has one; else a global (uniform) start. Each mode is one run of ``seeds[0]``; the whole run is
made again on every call (a single pass, nothing to resume).
"""

from __future__ import annotations

import logging
from itertools import islice
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from core.atomic import atomic_write_json, atomic_write_text
from core.dataset import Dataset
from core.poses import pose_from_xyzyaw, write_tum, xyzyaw_from_pose
from localize.frontend.segmenter import load_segmenter, model_path
from localize.localizer import EdgeModel, Localizer
from localize.metrics import (
    error_stats,
    health_stats,
    position_errors,
    timing_stats,
    yaw_errors_deg,
)
from localize.overlay import camera_poses, overlay_strip
from localize.recording import Recording, read_recording
from localize.runner import Context, RunSpec, check_run_lists, settings_of

log = logging.getLogger(__name__)

OVERLAY_FRAMES = 8


def start_state(cfg: DictConfig, rec: Recording) -> np.ndarray | None:
    """(4,) x, y, z (m), yaw (rad) to track from, or None for a global start."""
    if cfg.start is not None:
        start = np.asarray(OmegaConf.to_container(cfg.start), dtype=np.float64)
        if start.shape != (4,):
            raise ValueError(f"start={list(start)}: give [x, y, z, yaw_deg] in the world frame")
        return np.array([*start[:3], np.radians(start[3])])
    if rec.groundtruth is not None:
        return xyzyaw_from_pose(rec.groundtruth[0])[0]
    return None


def track(ctx: Context, rec: Recording, mode: str, start: np.ndarray | None, seed: int,
          max_frames: int | None, progress: bool
          ) -> tuple[np.ndarray, dict[str, list], dict[str, list]]:
    """Step one Localizer through the recording.

    Returns:
        (T, 4) estimated states, per-stage frame times (ms), and the per-frame companion
        (``timestamp``, ``status``, ``confidence``, ``position_std_m``).
    """
    init = "global" if start is None else "tracking"
    rng = RunSpec(rec.name, mode, init, seed).rng()  # a flight's run of the same name and seed
    loc = Localizer(ctx.world, rec.camera, ctx.front_end(mode), ctx.settings, rng,
                    model=ctx.model_for(mode))
    loc.reset(start)
    T = len(rec) if max_frames is None else min(int(max_frames), len(rec))
    states, timing = np.zeros((T, 4)), {"segmentation": [], "preprocessing": [], "filter": []}
    health: dict[str, list] = {"timestamp": [], "status": [], "confidence": [],
                               "position_std_m": []}
    for f in tqdm(islice(rec.steps(), T), total=T, desc=f"{rec.name}/{mode}",
                  disable=not progress, leave=False, mininterval=2.0):
        est = loc.step(f.image, f.odometry_increment, f.attitude, f.timestamp)
        states[f.index] = est.state
        for k in timing:
            timing[k].append(est.timing_ms[k])
        for k, v in (("timestamp", est.timestamp), ("status", est.status),
                     ("confidence", est.confidence), ("position_std_m", est.position_std)):
            health[k].append(v)
    return states, timing, health


def summary(states: np.ndarray, timing: dict, rec: Recording, health: dict) -> dict:
    """Errors (with ground truth), frame times and the filter's own health of one mode's run:
    the share of coasting frames, the losses it declared, its mean confidence."""
    out = {"num_frames": len(states),
           "timing_ms": {k: timing_stats(v) for k, v in timing.items()},
           **health_stats(health["status"], health["confidence"])}
    total = np.sum([timing[k] for k in timing], axis=0)
    out["timing_ms"]["total"] = timing_stats(total)
    if rec.groundtruth is not None:
        truth = xyzyaw_from_pose(rec.groundtruth[:len(states)])
        out["errors"] = error_stats(position_errors(states, truth),
                                    yaw_errors_deg(states, truth))
    return out


def write_overlay(path: Path, rec: Recording, ctx: Context, states: np.ndarray) -> None:
    """``overlay.png``: eight frames spread over the run, model edges at estimate and truth."""
    picks = np.unique(np.linspace(0, len(states) - 1, OVERLAY_FRAMES).round().astype(int))
    images = [rec.image(int(i)) for i in picks]
    est = camera_poses(states[picks], rec.odometry[picks], rec.camera)
    truth = None
    if rec.groundtruth is not None:
        gt = rec.groundtruth[picks]
        truth = camera_poses(xyzyaw_from_pose(gt), gt, rec.camera)
    overlay_strip(path, images, rec.camera, ctx.world.segments, est, truth,
                  [f"frame {i}" for i in picks])


def markdown(rec: Recording, results: dict[str, dict], start: str) -> str:
    """report.md of a recording's run."""
    lines = [f"# {rec.name}: localized against the model", "",
             f"Recording `{rec.source}`, {len(rec)} frames, camera {rec.camera.width}x"
             f"{rec.camera.height}; start: {start}.", "",
             "| mode | frames | mean error (m) | p95 (m) | max (m) | mean yaw error (deg) | "
             "frame ms (mean) |", "|---|---|---|---|---|---|---|"]
    for mode, r in results.items():
        e = r.get("errors", {})
        cells = [e.get(k) for k in ("mean_position_error_m", "p95_m", "max_m",
                                    "mean_yaw_error_deg")]
        text = ["-" if v is None else f"{v:.3f}" for v in cells]
        lines.append(f"| {mode} | {r['num_frames']} | {' | '.join(text)} | "
                     f"{r['timing_ms']['total']['avg']:.1f} |")
    if rec.groundtruth is None:
        lines += ["", "No ground truth in the recording: errors are not measured."]
    lines += ["", "![model edges at the estimate (green) and the truth (magenta)](overlay.png)", ""]
    return "\n".join(lines)


def run_recording(cfg: DictConfig) -> Path:
    """Localize ``cfg.recording`` in each mode of ``cfg.modes`` but oracle; write the outputs.

    Returns:
        Path of report.md.
    """
    check_run_lists(cfg)
    modes = [m for m in cfg.modes if m != "oracle"]
    if not modes:
        raise ValueError("modes: a recording has no true labels, so oracle cannot run; use "
                         "modes=[cnn] or modes=[none,cnn]")
    settings = settings_of(cfg)
    dataset = Dataset(cfg.dataset)
    world = dataset.world()
    mount = settings.recording_body_from_cam
    rec = read_recording(cfg.recording, dataset.camera, topics=settings.recording_topics,
                         body_from_cam=None if mount is None else np.asarray(mount,
                                                                             dtype=np.float64))
    out = Path(cfg.out_root) / str(cfg.name) / "recordings" / rec.name
    segmenter = (load_segmenter(model_path(cfg.onnx_model, cfg.dataset), dataset.classes,
                                int(cfg.threads))
                 if "cnn" in modes else None)
    ctx = Context(cfg, dataset, rec.camera, world, settings,
                  EdgeModel.build(world, settings, out / "cache"), out, segmenter)
    start = start_state(cfg, rec)
    how = ("global (uniform)" if start is None else
           f"tracking from x {start[0]:.2f}, y {start[1]:.2f}, z {start[2]:.2f} m, "
           f"yaw {np.degrees(start[3]):.1f} deg")
    results, first = {}, None
    for mode in sorted(modes, key=lambda m: m != "cnn"):  # cnn first: it gives trajectory.txt
        states, timing, health = track(ctx, rec, mode, start, int(cfg.seeds[0]),
                                       cfg.max_frames, bool(cfg.progress))
        ts = rec.timestamps[:len(states)]
        write_tum(out / "trajectories" / f"{mode}.txt", ts, pose_from_xyzyaw(states))
        atomic_write_json(out / "trajectories" / f"{mode}.json", health)
        if first is None:
            first = states
            write_tum(out / "trajectory.txt", ts, pose_from_xyzyaw(states))
            atomic_write_json(out / "trajectory.json", health)
        results[mode] = summary(states, timing, rec, health)
    write_overlay(out / "overlay.png", rec, ctx, first)
    atomic_write_json(out / "metrics.json", {"recording": str(rec.source), "start": how,
                                             "modes": results})
    atomic_write_text(out / "report.md", markdown(rec, results, how))
    log.info("trajectory: %s", out / "trajectory.txt")
    return out / "report.md"
