"""``python -m localize recording=PATH dataset=DATASET``: localize a recording (a folder or a
ROS bag, ``localize.recordings.recording``) against DATASET's world, with the camera the recording
brings.

A recording is a frame source (``core.frames.FrameSource``) as a rendered flight is: it goes
through the runner's context (``runner.prepare``), output policy (``runner.check_resume``:
claimed, resumed, refused when its result settings differ) and loop (``runner.run_pass``).

Output folder ``<out_root>/<name>/recordings/<recording name>/``::

    config.json                 the settings its results depend on (core.outputs)
    trajectory.txt              the first mode's estimates (cnn when it ran), TUM, world_from_body
    trajectory.json             its companion: per frame the timestamp, the filter's status
                                (tracking, ambiguous, coasting, lost), confidence (0-1),
                                particle spread (m) and pose hypotheses [x, y, z, yaw, mass]
    trajectories/<mode>.txt     each mode's estimates (TUM), and <mode>.json their companions
    runs/<mode>.json            each mode's run record (as a flight's, ``runner.PassRecord``)
    report.md, metrics.json     per mode: errors against groundtruth (when the recording has it),
                                frame timings, dropped frames; the recording, dataset and model
    overlay.png                 model edges at the estimates (green) and the truth (magenta) on
                                eight frames of the first mode

A recording has no true labels, so mode ``oracle`` is skipped. The start: what ``hint``
gives (``hint.pose=[x, y, z, yaw_deg]`` tracks from that world pose; with ``hint.pose_std``,
``hint.region`` or ``hint.space`` a search there); else the first ground-truth pose when the
recording has one; else a global start over the free space. Each mode is one run of
``seeds[0]``; a mode whose trajectory and run record exist is not run again
(``overwrite=true`` re-runs it), and the report covers every mode run in the folder. A frame
that cannot be read is dropped (counted in ``dropped_frames``), the odometry increment then spans
from the last frame read.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from core.atomic import atomic_write_json, atomic_write_text, disk_full_guard
from core.dataset import Camera, Dataset
from core.outputs import FolderPolicy, releases_claims
from core.poses import xyzyaw_from_pose
from localize.context import Context, report_folder
from localize.filter.start_hint import StartHint, start_of_settings
from localize.frontend.segmenter import model_path
from localize.offline.report import model_of, results_sections, summarize
from localize.offline.runner import (
    REPORT_DISK_FULL_FIX,
    RESULT_KEYS,
    SPEED_ONLY,
    RunSpec,
    check_resume,
    check_run_lists,
    prepare,
    run_pass,
    settings_of,
)
from localize.recordings.read import read_recording
from localize.recordings.recording import Recording
from localize.viewers.overlay import camera_poses, overlay_strip
from localize.world_file import frames_target, segnet_size

log = logging.getLogger(__name__)

OVERLAY_FRAMES = 8
#: A recording's folder belongs to its result settings: a flight's, the recording, how it is
#: read and where the runs start (``seeds``: its first is the one run).
RECORDING_POLICY = FolderPolicy(
    record="config.json",
    keys=(*RESULT_KEYS, "recording", "recording_topics", "recording_body_from_cam", "seeds"),
    grow=("onnx_sha256",), speed_only=SPEED_ONLY, results=("runs",))


def start_state(ctx: Context, rec: Recording) -> np.ndarray | StartHint | None:
    """Where a recording's run starts: what ``hint`` starts (``start_hint.start_of_settings``:
    (4,) x, y, z (m), yaw (rad) to track from, or a ``StartHint`` to search inside), else the
    first true pose; None for a global start over the free space."""
    s = ctx.settings
    start = start_of_settings(s.hint, ctx.world.info, ctx.world.free, s.filter.init_std)
    if start is not None:
        return start
    if rec.groundtruth is not None:
        return xyzyaw_from_pose(rec.groundtruth[0])[0]
    return None


def companion(record: dict) -> dict[str, list]:
    """A trajectory's companion of a run record: per frame the timestamp, the filter's status,
    confidence (0-1), particle spread (m) and pose hypotheses ([x, y, z, yaw, mass], m and rad,
    heaviest first)."""
    return {"timestamp": record["timestamps"], "status": record["status"],
            "confidence": record["confidence"], "position_std_m": record["position_std"],
            "hypotheses": record.get("hypotheses", [[] for _ in record["timestamps"]])}


def write_overlay(path: Path, rec: Recording, ctx: Context, record: dict) -> None:
    """``overlay.png``: eight frames spread over the run, model edges at estimate and truth."""
    states = np.asarray(record["estimate"])
    index = np.asarray(record.get("frame_index", range(len(states))), dtype=int)
    rows = np.unique(np.linspace(0, len(states) - 1, OVERLAY_FRAMES).round().astype(int))
    picks = index[rows]
    images = [rec.image(int(i)) for i in picks]
    est = camera_poses(states[rows], rec.odometry[picks], rec.camera)
    truth = None
    if rec.groundtruth is not None:
        gt = rec.groundtruth[picks]
        truth = camera_poses(xyzyaw_from_pose(gt), gt, rec.camera)
    overlay_strip(path, images, rec.camera, ctx.world.segments, est, truth,
                  [f"frame {i}" for i in picks])


def frames_run(metrics: dict, name: str) -> tuple[int, int]:
    """The frames the runs of recording ``name`` covered (delivered or dropped; ``max_frames``
    limits them) and the frames dropped, the most of any mode (metrics.json entries)."""
    entries = [e if "num_frames" in e else e.get("global", {})
               for e in metrics["flights"][name].values()]
    covered = max((e.get("num_frames", 0) + e.get("dropped_frames", 0) for e in entries),
                  default=0)
    return covered, max((e.get("dropped_frames", 0) for e in entries), default=0)


def model_line(metrics: dict) -> str:
    """The map (the dataset's, or a building file's) and the SegNet (the cnn mode's) a
    recording's report was made with."""
    model = metrics.get("model") or {}
    if model.get("onnx_model"):
        digest = model.get("onnx_sha256")
        segnet = f"SegNet `{model['onnx_model']}`" + (f" (sha256 {digest[:12]})" if digest
                                                       else "")
    else:
        segnet = "no SegNet (no cnn mode run)"
    if metrics.get("world"):
        w = metrics["world"]
        return (f"Building `{w['path']}` (imported, content {w['sha256']}; the camera from the "
                f"recording); {segnet}.")
    return f"Dataset `{metrics['dataset']}` (the building model and the camera); {segnet}."


def markdown(rec: Recording, metrics: dict, cfg: DictConfig, start: str) -> str:
    """report.md of a recording: its header (the recording, the frames run, the dataset and
    the SegNet), then the sections of a flight's report (``report.results_sections``: accuracy
    and convergence where there is ground truth, time per frame) and the overlay."""
    covered, dropped = frames_run(metrics, rec.name)
    frames = (f"{covered} frames" if covered == len(rec) else
              f"its first {covered} of {len(rec)} frames (max_frames={cfg.max_frames})")
    lines = [f"# {rec.name}: localized against the model", "",
             f"Recording `{rec.source}`: {frames}, camera {rec.camera.width}x"
             f"{rec.camera.height}; start: {start}."
             + (f" {dropped} frames could not be read and were dropped." if dropped else ""),
             model_line(metrics), "", *results_sections(metrics, cfg)]
    if rec.groundtruth is None:
        lines += ["No ground truth in the recording: errors are not measured.", ""]
    lines += ["![model edges at the estimate (green) and the truth (magenta)](overlay.png)", ""]
    return "\n".join(lines)


def write_recording_report(ctx: Context, rec: Recording, start: str) -> Path:
    """trajectory.txt/.json (the first mode's: cnn when it ran), each mode's companion,
    overlay.png, metrics.json and report.md, from every run record under ``runs/`` (runs of
    other modes made earlier in the folder, of the same result settings, are reported too).

    Returns:
        Path of report.md.
    """
    out = ctx.out_dir
    paths = sorted((out / "runs").glob("*.json"), key=lambda p: (p.stem != "cnn", p.stem))
    records = {p.stem: json.loads(p.read_text()) for p in paths}
    modes = list(records)
    for mode, record in records.items():
        atomic_write_json(out / "trajectories" / f"{mode}.json", companion(record))
    first = modes[0]
    atomic_write_text(out / "trajectory.txt",
                      (out / "trajectories" / f"{first}.txt").read_text())
    atomic_write_json(out / "trajectory.json", companion(records[first]))
    metrics = {"recording": str(rec.source), **summarize(list(records.values()), ctx.cfg),
               "model": model_of(out, ctx.cfg, modes), "start": start}
    if ctx.cfg.world.path:
        del metrics["dataset"]  # not read: the map is the building file's
        metrics["world"] = {"path": str(ctx.cfg.world.path), "sha256": ctx.world_digest}
    del metrics["paper"], metrics["targets"]  # the paper's corridor and the flights
    write_overlay(out / "overlay.png", rec, ctx, records[first])
    atomic_write_json(out / "metrics.json", metrics)
    atomic_write_text(out / "report.md", markdown(rec, metrics, ctx.cfg, start))
    log.info("trajectory: %s", out / "trajectory.txt")
    return out / "report.md"


def frames_target_of(cfg: DictConfig) -> Camera:
    """The camera a recording's frames are delivered as: the dataset's; with ``world.path``,
    the SegNet's input size and no mount of its own (``world_file.frames_target``: the
    recording's mount, else the forward camera, with a warning)."""
    if not cfg.world.path:
        return Dataset(cfg.dataset).camera
    return frames_target(segnet_size(model_path(str(cfg.onnx_model), str(cfg.dataset))))


@releases_claims
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
    modes.sort(key=lambda m: m != "cnn")  # cnn first: it gives trajectory.txt
    settings = settings_of(cfg)
    mount = settings.recording_body_from_cam
    rec = read_recording(cfg.recording, frames_target_of(cfg), topics=settings.recording_topics,
                         body_from_cam=None if mount is None else np.asarray(mount,
                                                                             dtype=np.float64))
    with disk_full_guard(report_folder(cfg), "the report", REPORT_DISK_FULL_FIX):
        # one pass a mode, from the first seed: the folder records that seed alone, so a
        # longer seed list (a flight's runs) resumes it
        ctx = prepare(OmegaConf.merge(cfg, {"modes": modes, "seeds": [int(cfg.seeds[0])]}),
                      recording=rec, camera=rec.camera)
        check_resume(ctx.out_dir, ctx.cfg, RECORDING_POLICY, ctx.world_digest)
        start = start_state(ctx, rec)
        init = "tracking" if isinstance(start, np.ndarray) else "global"
        how = ("global (the whole free space)" if start is None else
               "a search inside the hint" if init == "global" else
               f"tracking from x {start[0]:.2f}, y {start[1]:.2f}, z {start[2]:.2f} m, "
               f"yaw {np.degrees(start[3]):.1f} deg")
        for mode in modes:
            # a flight's run of the same mode, init and seed draws the same numbers
            run = RunSpec(rec.name, mode, init, int(cfg.seeds[0]), recording=True)
            if cfg.overwrite or not run.done(ctx.out_dir):
                run_pass(ctx, rec, mode, [run], start=start if init == "tracking" else None)
        return write_recording_report(ctx, rec, how)
