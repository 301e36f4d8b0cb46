"""Statistics of a weighted pose set (N, 4) x, y, z (m), yaw (rad): normalized log-weights,
the weighted mean pose and its spread, from log-weights (``estimate``, ``spread``) or from
weights summing to one (``mean_pose``, ``pose_spread``). Shared by the particle filter, the
global search and the pose hypotheses."""

from __future__ import annotations

import numpy as np


def log_sum_exp(a: np.ndarray) -> float:
    """``log(sum(exp(a)))`` of log-weights (N,), its largest term taken out so that none
    overflows: scipy's ``logsumexp`` without its per-call overhead (~0.2 ms, called several
    times a frame); -inf when N = 0 or every entry is -inf."""
    if len(a) == 0:
        return -np.inf
    m = float(np.max(a))
    if not np.isfinite(m):
        return m
    return m + float(np.log(np.sum(np.exp(a - m))))


def normalize_log_weights(logw: np.ndarray) -> np.ndarray:
    """Log-weights shifted so that the weights sum to one."""
    return logw - log_sum_exp(logw)


def mean_pose(poses: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted mean pose (4,) of poses (N, 4), weights (N,) summing to one: mean x, y, z;
    circular mean yaw."""
    xyz = w @ poses[:, :3]
    yaw = np.arctan2(w @ np.sin(poses[:, 3]), w @ np.cos(poses[:, 3]))
    return np.concatenate([xyz, [yaw]])


def pose_spread(poses: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """Weighted horizontal position std (metres) and circular yaw std (radians) of poses
    (N, 4), weights (N,) summing to one."""
    m = w @ poses[:, :2]
    pos = float(np.sqrt(w @ ((poses[:, :2] - m) ** 2).sum(axis=1)))
    r = np.hypot(w @ np.sin(poses[:, 3]), w @ np.cos(poses[:, 3]))
    return pos, float(np.sqrt(max(-2.0 * np.log(max(r, 1e-12)), 0.0)))


def estimate(particles: np.ndarray, logw: np.ndarray) -> np.ndarray:
    """Weighted mean pose (4,) from log-weights (any scale): ``mean_pose``."""
    return mean_pose(particles, np.exp(normalize_log_weights(logw)))


def spread(particles: np.ndarray, logw: np.ndarray) -> tuple[float, float]:
    """Weighted horizontal position std (metres) and circular yaw std (radians) from
    log-weights (any scale): ``pose_spread``."""
    return pose_spread(particles, np.exp(normalize_log_weights(logw)))
