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


def false_convergence(pos_err: np.ndarray, timestamps: np.ndarray, status: Sequence[str],
                      threshold_m: float, longer_than_s: float) -> bool:
    """Whether a run declared convergence falsely: its status was ``tracking`` while its error
    stayed above ``threshold_m`` for longer than ``longer_than_s`` (one unbroken stretch of
    such frames, ``lost_track``'s measure).

    Args:
        pos_err: (T,) metres.
        timestamps: (T,) seconds.
        status: (T,) the filter's status per frame (``Estimate.status``).
    """
    tracking = np.asarray(status) == "tracking"
    if len(tracking) != len(pos_err):
        raise ValueError(f"{len(pos_err)} errors for {len(tracking)} statuses")
    return lost_track(np.where(tracking, pos_err, 0.0), timestamps, threshold_m, longer_than_s)


def health_stats(status: Sequence[str], confidence: Sequence[float]) -> dict:
    """The filter's own view of a run (``Estimate.status``, ``.confidence`` per frame): the
    share of coasting and of ambiguous frames, the losses it declared and its mean
    confidence."""
    n = len(status)
    return {"coasting_rate": list(status).count("coasting") / max(n, 1),
            "ambiguous_rate": list(status).count("ambiguous") / max(n, 1),
            "losses_declared": list(status).count("lost"),
            "mean_confidence": float(np.mean(confidence)) if n else None}


#: Confidence bins of ``calibration``: [0, 0.5), [0.5, 0.7), [0.7, 0.9), [0.9, 1].
CONFIDENCE_BINS = (0.0, 0.5, 0.7, 0.9, 1.0)
#: The confidence the calibration target speaks of, and the share of such frames that must
#: lie within the error bound (issue 69: when it says >= 0.9, within 0.3 m in >= 95 %).
HIGH_CONFIDENCE = 0.9
CALIBRATION_TARGET = 0.95


def calibration(pos_err: np.ndarray, confidence: np.ndarray, within_m: float,
                bins: Sequence[float] = CONFIDENCE_BINS,
                high: float = HIGH_CONFIDENCE) -> dict:
    """How well the filter's confidence tells its error: per confidence bin, the share of
    frames in it and the share of those within ``within_m`` of the truth.

    Args:
        pos_err: (T,) position errors, metres.
        confidence: (T,) the filter's confidence per frame, in [0, 1].
        within_m: the error bound, metres.
        bins: increasing bin edges; each bin is [lo, hi), the last [lo, hi].
        high: the confidence of the headline figure.

    Returns:
        dict with within_m; bins: [{confidence: [lo, hi], frame_share, within_share}];
        high_confidence: {min_confidence, frame_share, within_share} over the frames with
        confidence >= ``high``. A share over no frames is None.
    """
    e = np.asarray(pos_err, dtype=np.float64).ravel()
    c = np.asarray(confidence, dtype=np.float64).ravel()
    if e.shape != c.shape:
        raise ValueError(f"{e.size} errors for {c.size} confidences")
    edges = np.asarray(bins, dtype=np.float64)
    n_bins = len(edges) - 1
    idx = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, n_bins - 1)
    within = e < within_m
    count = np.bincount(idx, minlength=n_bins)
    hits = np.bincount(idx, weights=within, minlength=n_bins)
    n = max(e.size, 1)
    high_frames = c >= high

    def share(k: float, of: int) -> float | None:
        return float(k / of) if of else None

    return {
        "within_m": float(within_m),
        "bins": [{"confidence": [float(lo), float(hi)], "frame_share": float(k / n),
                  "within_share": share(h, int(k))}
                 for lo, hi, k, h in zip(edges[:-1], edges[1:], count, hits, strict=True)],
        "high_confidence": {"min_confidence": float(high),
                            "frame_share": float(high_frames.sum() / n),
                            "within_share": share(within[high_frames].sum(),
                                                  int(high_frames.sum()))},
    }


def timing_stats(samples_ms: Sequence[float] | np.ndarray) -> dict:
    """min / avg / max of per-frame times in milliseconds."""
    a = np.asarray(samples_ms, dtype=np.float64).ravel()
    if a.size == 0:
        return {"min": 0.0, "avg": 0.0, "max": 0.0}
    return {"min": float(a.min()), "avg": float(a.mean()), "max": float(a.max())}
