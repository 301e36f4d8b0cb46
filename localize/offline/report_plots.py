"""The report's plots: trajectories, top-down view, errors over time, one frame's edges,
the confidence calibration.

Each takes the run records (``runs/<flight>/*.json``) of one flight, or its metrics, and
writes one PNG.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from core.atomic import atomic_write  # noqa: E402
from core.classes import colorize  # noqa: E402

MODE_COLORS = {"none": "tab:red", "cnn": "tab:blue", "oracle": "tab:green"}
MODE_LABELS = {"none": "none (Canny + Hough)", "cnn": "cnn (segnet.onnx)",
               "oracle": "oracle (true labels)"}


def main_records(records: list[dict]) -> list[dict]:
    """The records of the filter's own likelihood (not a comparison's)."""
    return [r for r in records if r["likelihood"] == "vectorized"]


def tracking_seed0(records: list[dict], flight: str) -> dict[str, dict]:
    out = {}
    for r in main_records(records):
        if r["flight"] == flight and r["init"] == "tracking":
            if r["mode"] not in out or r["seed"] < out[r["mode"]]["seed"]:
                out[r["mode"]] = r
    return dict(sorted(out.items(), key=lambda kv: list(MODE_COLORS).index(kv[0])
                       if kv[0] in MODE_COLORS else 9))


def _save(fig, path: Path) -> None:
    atomic_write(path, lambda p: fig.savefig(p, dpi=110, bbox_inches="tight"))
    plt.close(fig)


def plot_xy(records: list[dict], flight: str, path: Path) -> None:
    """X and Y over time, estimate vs ground truth per mode (the paper's Fig. 3 and 4)."""
    runs = tracking_seed0(records, flight)
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for ax, k, name in zip(axes, (0, 1), ("X", "Y"), strict=True):
        any_run = next(iter(runs.values()))
        t = np.array(any_run["timestamps"])
        ax.plot(t, np.array(any_run["truth"])[:, k], "k-", lw=2, label="ground truth")
        for mode, r in runs.items():
            ax.plot(np.array(r["timestamps"]), np.array(r["estimate"])[:, k], "--",
                    color=MODE_COLORS.get(mode), label=MODE_LABELS.get(mode, mode))
        ax.set_ylabel(f"{name} (m)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[1].set_xlabel("time (s)")
    axes[0].set_title(f"{flight}: position over time (tracking init, seed 0)")
    _save(fig, path)


def corridor_outline(world) -> np.ndarray:
    """Floor edges of the model (K, 2, 2) in XY: the building's plan."""
    seg = np.asarray(world.segments)
    floor_z = float(world.info.get("floor_z", 0.0))
    floor = (np.abs(seg[:, :, 2] - floor_z).max(axis=1) < 1e-3) & (
        np.asarray(world.segment_classes).min(axis=1) <= 1)
    return seg[floor][:, :, :2]


def plot_topdown(records: list[dict], flight: str, world, path: Path) -> None:
    """Top-down trajectories over the corridor plan."""
    runs = tracking_seed0(records, flight)
    fig, ax = plt.subplots(figsize=(5, 9))
    for s in corridor_outline(world):
        ax.plot(s[:, 0], s[:, 1], color="0.4", lw=1)
    free = world.free
    ext = free.extent
    ax.contour(free.free.astype(float), levels=[0.5], colors="0.7", linestyles=":",
               extent=(ext[0], ext[2], ext[1], ext[3]), origin="lower")
    any_run = next(iter(runs.values()))
    gt = np.array(any_run["truth"])
    ax.plot(gt[:, 0], gt[:, 1], "k-", lw=2, label="ground truth")
    for mode, r in runs.items():
        e = np.array(r["estimate"])
        ax.plot(e[:, 0], e[:, 1], "--", color=MODE_COLORS.get(mode),
                label=MODE_LABELS.get(mode, mode))
    ax.set_aspect("equal")
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(f"{flight}: top view")
    _save(fig, path)


def plot_errors(records: list[dict], flight: str, path: Path, threshold: float) -> None:
    """Position error over time per mode: tracking (mean and range over seeds) and global."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for ax, init in zip(axes, ("tracking", "global"), strict=True):
        by_mode = defaultdict(list)
        for r in main_records(records):
            if r["flight"] == flight and r["init"] == init:
                by_mode[r["mode"]].append(r)
        for mode, runs in sorted(by_mode.items()):
            E = np.array([r["position_error_m"] for r in runs])
            t = np.array(runs[0]["timestamps"])
            c = MODE_COLORS.get(mode)
            if init == "tracking":
                ax.plot(t, E.mean(axis=0), color=c, label=MODE_LABELS.get(mode, mode))
                ax.fill_between(t, E.min(axis=0), E.max(axis=0), color=c, alpha=0.2)
            else:
                for i, e in enumerate(E):
                    ax.plot(np.arange(len(e)), e, color=c, alpha=0.6, lw=1,
                            label=MODE_LABELS.get(mode, mode) if i == 0 else None)
        if init == "global":
            ax.axhline(threshold, color="k", ls=":", lw=1)
            ax.set_xlabel("frame")
            ax.set_yscale("log")
            ax.set_title("global init: error per seed")
        else:
            ax.set_xlabel("time (s)")
            ax.set_title("tracking init: mean over seeds (band: min-max)")
        ax.set_ylabel("position error (m)")
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(flight)
    _save(fig, path)


def plot_calibration(by_init: dict[str, dict[str, dict]], flight: str, path: Path) -> None:
    """Reliability plot: per confidence bin, the share of frames within the error bound, one
    line per mode, one panel per init (``by_init``: init -> mode -> its
    ``metrics.calibration``); a marker's area is the bin's share of the frames, a bin without
    frames is left out."""
    fig, axes = plt.subplots(1, len(by_init), figsize=(6 * len(by_init), 4), squeeze=False)
    for ax, (init, by_mode) in zip(axes[0], sorted(by_init.items(), reverse=True),
                                   strict=True):
        for mode, cal in sorted(by_mode.items()):
            centre = np.array([b["confidence"] for b in cal["bins"]]).mean(axis=1)
            share = np.array([np.nan if b["within_share"] is None else b["within_share"]
                              for b in cal["bins"]])
            frames = np.array([b["frame_share"] for b in cal["bins"]])
            c = MODE_COLORS.get(mode)
            ax.plot(centre, share, "-", color=c, alpha=0.8, label=MODE_LABELS.get(mode, mode))
            ax.scatter(centre, share, s=20 + 300 * frames, color=c, alpha=0.6)
        cal = next(iter(by_mode.values()))
        ax.axvline(cal["high_confidence"]["min_confidence"], color="k", ls=":", lw=1)
        ax.plot([0, 1], [0, 1], color="0.6", ls="--", lw=1, label="share = confidence")
        ax.set_xticks(sorted({e for b in cal["bins"] for e in b["confidence"]}))
        ax.set_xlim(0, 1)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("filter confidence (bin centre)")
        ax.set_ylabel(f"share of the bin's frames within {cal['within_m']:g} m")
        ax.grid(alpha=0.3)
        ax.set_title(f"{init} init")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8,
               bbox_to_anchor=(0.5, -0.06))
    fig.suptitle(f"{flight}: confidence calibration")
    _save(fig, path)


def plot_frame(ctx, records: list[dict], flight_name: str, path: Path) -> None:
    """One frame: model edges at the estimate over the image, segmentation, edge map (Fig. 2)."""
    from localize.filter.projection import (
        cam_from_world,
        camera_centres,
        pixel_index,
        projection_matrices,
        tilt_from_pose,
    )
    from localize.frontend.front_end import FrontEnd
    from localize.frontend.sources import LabelFunction

    runs = tracking_seed0(records, flight_name)
    mode = "cnn" if "cnn" in runs else next(iter(runs))
    r = runs[mode]
    flight = ctx.dataset.flight(flight_name)
    t = int(round(float(ctx.cfg.report.figure_frame) * (r["num_frames"] - 1)))
    rgb = flight.image(t)
    truth = flight.labels(t)
    segnet = mode == "cnn" and ctx.segmenter is not None
    if mode == "cnn" and not segnet:  # no SegNet loaded: the cnn edges of the true labels
        front = FrontEnd(LabelFunction(lambda rgb, labels: labels, needs_truth=True),
                         ctx.settings.edges)
    else:
        front = ctx.front_end(mode)
    frame = front.frame(rgb, truth)
    labels = truth if frame.labels is None else frame.labels
    seg_title = "SegNet segmentation" if segnet else "true labels"
    edge = frame.edge
    model = ctx.model_for(mode)
    state = np.array(r["estimate"][t])[None]
    tilt = tilt_from_pose(flight.odometry[t])
    cam = ctx.camera
    P = projection_matrices(cam_from_world(state, cam.body_from_cam, tilt), cam.K)
    idx, valid, _ = pixel_index(P, model.samples.points_h, cam.width, cam.height)
    valid &= model.visibility.mask(camera_centres(state, cam.body_from_cam, tilt))
    v, u = np.divmod(idx[0][valid[0]], cam.width)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    axes[0].imshow(rgb)
    axes[0].scatter(u, v, s=2, c="lime")
    axes[0].set_title(f"model edges at the {mode} estimate (frame {t})")
    axes[1].imshow(colorize(labels))
    axes[1].scatter(u, v, s=1, c="white")
    axes[1].set_title(seg_title)
    shown = np.zeros(edge.edges.shape + (3,), dtype=np.uint8)
    shown[~edge.known] = (90, 0, 0)
    shown[edge.edges] = 255
    axes[2].imshow(shown)
    axes[2].set_title(f"{mode} edges (dark red: unknown)")
    for ax in axes:
        ax.axis("off")
    _save(fig, path)


# --- report ----------------------------------------------------------------------------------
