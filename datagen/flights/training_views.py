"""Camera body poses spread over a building's free space, for training images.

All poses are (N, 4, 4) world_from_body (body x forward, y left, z up; world Z up). Positions
are uniform over the free cells of an occupancy map (core.occupancy); yaws follow the local axis
of the free space (``free_axes``) or are uniform; heights and tilts come from the training
settings (``TrainingConfig``). The poses of images taken as the flights fly are
``trajectories.sample_flight_views``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import pose_from_xyz_rpy, wrap_angle
from datagen.config import TrainingConfig
from datagen.flights.free_axes import axis_at


def check_z(z_range: np.ndarray) -> np.ndarray:
    """(2,) heights [lo, hi] (m) of ``z_range``, checked: lo < hi."""
    z = np.asarray(z_range, dtype=np.float64).reshape(-1)
    if z.shape != (2,) or not z[0] < z[1]:
        raise ValueError(f"z_range must be [lo, hi] with lo < hi, got {z.tolist()}")
    return z


def sample_training_poses(rng: np.random.Generator, n: int, free: OccupancyMap,
                          z_range: np.ndarray,
                          max_roll_pitch_deg: float = TrainingConfig.max_roll_pitch_deg,
                          along_fraction: float = TrainingConfig.yaw_along_corridor,
                          along_spread_deg: float = TrainingConfig.yaw_spread_deg,
                          min_view_m: float = TrainingConfig.min_view_m,
                          tries: int = 20, handheld: float = TrainingConfig.handheld,
                          handheld_deg: tuple[float, float] = (
                              TrainingConfig.handheld_pitch_deg,
                              TrainingConfig.handheld_roll_deg),
                          top: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Camera body poses spread over the free space, for training images.

    Args:
        rng: random generator.
        n: number of poses.
        free: where a camera may be; positions are uniform over its free cells.
        z_range: (2,) heights (m), uniform (below ``top``).
        max_roll_pitch_deg: roll and pitch are uniform in +/- this.
        along_fraction: share of poses whose yaw is drawn around the local axis of the free
            space (``free_axes``: the longest free chord through the cell; in a corridor its
            long axis), either way, uniform within +/- ``along_spread_deg``, as a copter flying
            there looks; the others have a uniform yaw. In a 2 m corridor a uniform yaw
            mostly faces a wall from less than a metre, a close-up that a flight rarely sees.
        along_spread_deg: half-width of the along-axis yaw range, degrees.
        min_view_m: a pose whose free space ahead (``view_depth``) is shorter is drawn again,
            up to ``tries`` times (the last draw is kept); 0: no check, no extra draws.
        handheld: share of poses whose pitch and roll are uniform in +/- ``handheld_deg``
            (pitch, roll) instead; 0: none (no draw).
        top: (N, 2) m -> (N,) m, the highest a pose may be at each position (the ceiling's
            headroom, ``Site.camera_top``), or None: ``z_range`` everywhere; the heights are
            uniform in [z_range min, min(z_range max, top)], within the free space's band
            where top is lower.

    Returns:
        (n, 4, 4) world_from_body.
    """
    draw = functools.partial(_draw_training_poses, free=free, z_range=z_range,
                             max_roll_pitch_deg=max_roll_pitch_deg, along_fraction=along_fraction,
                             along_spread_deg=along_spread_deg, handheld=handheld,
                             handheld_deg=handheld_deg, top=top)
    poses = draw(rng, n)
    if min_view_m <= 0:
        return poses
    for _ in range(tries):
        short = view_depth(free, poses, min_view_m) < min_view_m
        if not short.any():
            break
        poses[short] = draw(rng, int(short.sum()))
    return poses


def view_depth(free: OccupancyMap, poses: np.ndarray, reach: float) -> np.ndarray:
    """(N,) m of free space straight ahead of each pose, along its yaw, up to ``reach``.

    Args:
        free: the free space (its cells).
        poses: (N, 4, 4) world_from_body; the body's +x looks ahead.
        reach: m, the farthest distance looked at.

    Returns:
        (N,) m: the distance of the last step (steps half a cell apart) before the first
        outside the free space; 0 when the first is outside, about ``reach`` when none is.
    """
    step = free.cell / 2
    d = np.arange(1, int(np.ceil(reach / step)) + 1) * step  # (K,)
    ahead = poses[:, :2, 0] / np.linalg.norm(poses[:, :2, 0], axis=1, keepdims=True)
    pts = poses[:, None, :2, 3] + d[None, :, None] * ahead[:, None, :]  # (N, K, 2)
    inside = free.contains(pts.reshape(-1, 2)).reshape(len(poses), len(d))
    first_out = np.where(inside.all(axis=1), len(d), np.argmin(inside, axis=1))
    return np.minimum(np.concatenate([[0.0], d])[first_out], reach)


def _draw_training_poses(rng: np.random.Generator, n: int, free: OccupancyMap,
                         z_range: np.ndarray, max_roll_pitch_deg: float, along_fraction: float,
                         along_spread_deg: float, handheld: float,
                         handheld_deg: tuple[float, float],
                         top: Callable[[np.ndarray], np.ndarray] | None) -> np.ndarray:
    """``sample_training_poses``'s draw of (n, 4, 4) poses, unchecked."""
    if not 0.0 <= along_fraction <= 1.0:
        raise ValueError(f"training.yaw_along_corridor must be in [0, 1], got {along_fraction}")
    if not 0.0 <= handheld <= 1.0:
        raise ValueError(f"training.handheld must be a share in [0, 1], got {handheld}")
    z = check_z(z_range)
    xy = free.sample(rng, n)
    hi = z[1] if top is None else np.clip(top(xy), min(free.band[1], z[1]), z[1])
    height = rng.uniform(z[0], hi, n)
    tilt = np.deg2rad(max_roll_pitch_deg) * rng.uniform(-1, 1, (n, 2))
    yaw = rng.uniform(-np.pi, np.pi, n)
    along = rng.random(n) < along_fraction
    axis = axis_at(free, xy) + np.where(rng.random(n) < 0.5, 0.0, np.pi)
    yaw_along = axis + np.deg2rad(along_spread_deg) * rng.uniform(-1, 1, n)
    yaw = np.where(along, wrap_angle(yaw_along), yaw)
    if handheld > 0:  # columns roll, pitch
        held = rng.random(n) < handheld
        hand = np.deg2rad([handheld_deg[1], handheld_deg[0]]) * rng.uniform(-1, 1, (n, 2))
        tilt = np.where(held[:, None], hand, tilt)
    return pose_from_xyz_rpy(np.column_stack([xy, height]), np.column_stack([tilt, yaw]))
