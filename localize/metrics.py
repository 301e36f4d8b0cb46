"""Trajectory errors, convergence and timing statistics."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from core.poses import wrap_angle


def position_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Euclidean position error per frame.

    Args:
        estimate, truth: (T, 4) x, y, z, yaw or (T, 3) positions, metres.

    Returns:
        (T,) metres.
    """
    estimate, truth = np.asarray(estimate), np.asarray(truth)
    if estimate.shape[0] != truth.shape[0]:
        raise ValueError(f"estimate has {estimate.shape[0]} frames, truth {truth.shape[0]}")
    return np.linalg.norm(estimate[:, :3] - truth[:, :3], axis=1)


def yaw_errors_deg(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Absolute heading error per frame, degrees, from (T, 4) states."""
    return np.degrees(np.abs(wrap_angle(np.asarray(estimate)[:, 3] - np.asarray(truth)[:, 3])))


def error_stats(pos_err: np.ndarray, yaw_err_deg: np.ndarray | None = None) -> dict:
    """Summary of position errors (metres) and yaw errors (degrees).

    Returns:
        dict with mean_position_error_m, median_m, rmse_m, p95_m, max_m and, when given,
        mean_yaw_error_deg.
    """
    e = np.asarray(pos_err, dtype=np.float64).ravel()
    if e.size == 0:
        raise ValueError("no frames to compute errors on")
    out = {
        "mean_position_error_m": float(e.mean()),
        "median_m": float(np.median(e)),
        "rmse_m": float(np.sqrt(np.mean(e ** 2))),
        "p95_m": float(np.percentile(e, 95)),
        "max_m": float(e.max()),
    }
    if yaw_err_deg is not None:
        out["mean_yaw_error_deg"] = float(np.mean(yaw_err_deg))
    return out


def convergence_frame(pos_err: np.ndarray, threshold: float) -> int | None:
    """First frame from which the error stays below ``threshold`` until the end.

    Returns:
        The frame index, or None if the last frame's error is not below the threshold.
    """
    below = np.asarray(pos_err) < threshold
    if len(below) == 0 or not below[-1]:
        return None
    above = np.flatnonzero(~below)
    return int(above[-1] + 1) if len(above) else 0


def lost_track(pos_err: np.ndarray, timestamps: np.ndarray, threshold_m: float,
               longer_than_s: float) -> bool:
    """Whether a run lost track: its error stayed above ``threshold_m`` for longer than
    ``longer_than_s`` (from the first frame above to the last of the stretch).

    Args:
        pos_err: (T,) metres.
        timestamps: (T,) seconds.
    """
    above = np.asarray(pos_err) > threshold_m
    t = np.asarray(timestamps, dtype=np.float64)
    if len(above) != len(t):
        raise ValueError(f"{len(above)} errors for {len(t)} timestamps")
    edges = np.flatnonzero(np.diff(np.r_[0, above.astype(np.int8), 0]))
    starts, ends = edges[::2], edges[1::2] - 1  # each stretch's first and last frame
    return bool(np.any(t[ends] - t[starts] > longer_than_s))


def health_stats(status: Sequence[str], confidence: Sequence[float]) -> dict:
    """The filter's own view of a run (``Estimate.status``, ``.confidence`` per frame): the
    share of coasting frames, the losses it declared and its mean confidence."""
    n = len(status)
    return {"coasting_rate": list(status).count("coasting") / max(n, 1),
            "losses_declared": list(status).count("lost"),
            "mean_confidence": float(np.mean(confidence)) if n else None}


def timing_stats(samples_ms: Sequence[float] | np.ndarray) -> dict:
    """min / avg / max of per-frame times in milliseconds."""
    a = np.asarray(samples_ms, dtype=np.float64).ravel()
    if a.size == 0:
        return {"min": 0.0, "avg": 0.0, "max": 0.0}
    return {"min": float(a.min()), "avg": float(a.mean()), "max": float(a.max())}
