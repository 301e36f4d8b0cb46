"""Camera body poses: training samples, smooth hand-flown flights and noisy odometry.

All poses are (N, 4, 4) world_from_body (body x forward, y left, z up; world Z up, corridor
long axis +Y). Flight and odometry parameters come from a flight preset (``FlightConfig``:
its ``trajectory`` and ``odometry``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from core.config import as_config
from core.poses import pose_from_xyz_rpy, wrap_angle
from datagen.config import FlightConfig, OdometryConfig, TrainingConfig, TrajectoryConfig
from datagen.distractors import sample_in_boxes

GRAVITY = 9.81  # m/s^2

def _pair(cfg: Any, key: str, where: str) -> tuple[float, float]:
    """The [min, max] pair ``cfg.<key>`` (a number: both), checked."""
    value = getattr(cfg, key)
    try:
        lo, hi = (float(v) for v in (value if hasattr(value, "__len__") else (value, value)))
    except (TypeError, ValueError) as err:
        raise ValueError(f"{where}.{key} must be a number or [min, max], got {value!r}") from err
    if hi < lo:
        raise ValueError(f"{where}.{key} = [{lo}, {hi}] has max < min; swap them")
    return lo, hi


def _check(boxes: np.ndarray, z_range: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    z = np.asarray(z_range, dtype=np.float64).reshape(-1)
    if len(boxes) == 0 or np.any(boxes[:, 2:] <= boxes[:, :2]):
        raise ValueError(f"free boxes must be (B, 4) [xmin, ymin, xmax, ymax] with max > min, "
                         f"got {boxes.tolist()}")
    if z.shape != (2,) or not z[0] < z[1]:
        raise ValueError(f"z_range must be [lo, hi] with lo < hi, got {z.tolist()}")
    return boxes, z


def sample_training_poses(rng: np.random.Generator, n: int, boxes: np.ndarray,
                          z_range: np.ndarray,
                          max_roll_pitch_deg: float = TrainingConfig.max_roll_pitch_deg,
                          along_fraction: float = TrainingConfig.yaw_along_corridor,
                          along_spread_deg: float = TrainingConfig.yaw_spread_deg) -> np.ndarray:
    """Camera body poses spread over the free space, for training images.

    Args:
        rng: random generator.
        n: number of poses.
        boxes: (B, 4) free boxes [xmin, ymin, xmax, ymax] (m); positions are uniform over
            their union, area-weighted.
        z_range: (2,) heights (m), uniform.
        max_roll_pitch_deg: roll and pitch are uniform in +/- this.
        along_fraction: share of poses whose yaw is drawn around the corridor axis (+Y or -Y,
            uniform within +/- ``along_spread_deg``), as a copter flying the corridor looks;
            the others have a uniform yaw. In a 2 m corridor a uniform yaw mostly faces a
            wall from less than a metre, a close-up that a flight rarely sees.
        along_spread_deg: half-width of the along-corridor yaw range, degrees.

    Returns:
        (n, 4, 4) world_from_body.
    """
    if not 0.0 <= along_fraction <= 1.0:
        raise ValueError(f"training.yaw_along_corridor must be in [0, 1], got {along_fraction}")
    boxes, z = _check(boxes, z_range)
    xy = sample_in_boxes(rng, n, boxes)
    height = rng.uniform(z[0], z[1], n)
    tilt = np.deg2rad(max_roll_pitch_deg) * rng.uniform(-1, 1, (n, 2))
    yaw = rng.uniform(-np.pi, np.pi, n)
    along = rng.random(n) < along_fraction
    axis = np.where(rng.random(n) < 0.5, np.pi / 2, -np.pi / 2)
    yaw_along = axis + np.deg2rad(along_spread_deg) * rng.uniform(-1, 1, n)
    yaw = np.where(along, wrap_angle(yaw_along), yaw)
    return pose_from_xyz_rpy(np.column_stack([xy, height]), np.column_stack([tilt, yaw]))


def sample_flight_views(rng: np.random.Generator, n: int, boxes: np.ndarray,
                        z_range: np.ndarray, presets: Sequence[FlightConfig | Mapping]
                        ) -> np.ndarray:
    """Camera body poses as the flights see the corridor, for training images.

    Each pose is a random frame of its own flight (``flight_trajectory``) of a random preset,
    flown along +Y or -Y with equal chance: heights, lateral sway, yaw swings and tilts as
    flown, over the stretch of corridor a flight covers.

    Args:
        rng: random generator.
        n: number of poses.
        boxes: (B, 4) free boxes [xmin, ymin, xmax, ymax] (m).
        z_range: (2,) allowed heights (m).
        presets: flight presets (``FlightConfig``, or mappings of the keys that differ from
            its defaults).

    Returns:
        (n, 4, 4) world_from_body.
    """
    if not presets:
        raise ValueError("training.flight_views needs at least one preset under `flights`")
    out = np.empty((n, 4, 4))
    for i in range(n):
        preset = as_config(FlightConfig, presets[rng.integers(len(presets))], "flights")
        trajectory = replace(preset.trajectory, reverse=bool(rng.random() < 0.5))
        poses = flight_trajectory(rng, preset.num_frames, preset.fps, boxes, z_range,
                                  trajectory)
        out[i] = poses[rng.integers(len(poses))]
    return out


def smooth_noise(rng: np.random.Generator, t: np.ndarray, freq_hz: tuple[float, float],
                 terms: int = 4) -> np.ndarray:
    """Smooth random signal: a sum of sinusoids with random frequencies and phases.

    Args:
        rng: random generator.
        t: (N,) times in seconds.
        freq_hz: (min, max) frequency range of the components.
        terms: number of sinusoids.

    Returns:
        (N,) signal scaled to peak exactly 1 in absolute value over t (0 if N == 0).
    """
    t = np.asarray(t, dtype=np.float64)
    f = rng.uniform(freq_hz[0], freq_hz[1], terms)
    phase = rng.uniform(0, 2 * np.pi, terms)
    amp = rng.uniform(0.5, 1.0, terms) / np.maximum(f, 1e-3)  # 1/f: slower is larger
    amp /= amp.sum()
    s = np.sin(2 * np.pi * f[None, :] * t[:, None] + phase) @ amp
    peak = np.max(np.abs(s)) if len(s) else 0.0
    return s / peak if peak > 1e-12 else s


def _main_box(boxes: np.ndarray) -> np.ndarray:
    """The box with the longest extent along Y (the corridor)."""
    return boxes[int(np.argmax(boxes[:, 3] - boxes[:, 1]))]


def flight_trajectory(rng: np.random.Generator, num_frames: int, fps: float,
                      boxes: np.ndarray, z_range: np.ndarray,
                      trajectory: TrajectoryConfig | Mapping | None = None) -> np.ndarray:
    """A smooth hand-flown copter flight along the corridor.

    The copter starts near one end of the main corridor box (the box longest along Y) and
    flies towards the other with a smooth speed profile (speed-up, random variation,
    slow-down), swaying sideways and in height and swinging its yaw about the flight
    direction; roll and pitch follow the horizontal acceleration (a multirotor tilts to
    accelerate) plus a small wobble. Position stays inside the main box and z_range.

    Args:
        rng: random generator.
        num_frames: N.
        fps: frame rate (Hz).
        boxes: (B, 4) free boxes [xmin, ymin, xmax, ymax] (m).
        z_range: (2,) allowed heights (m).
        trajectory: a flight preset's ``trajectory`` (``TrajectoryConfig``, or a mapping of
            the keys that differ from its defaults; None: the defaults).

    Returns:
        (N, 4, 4) world_from_body.
    """
    boxes, z = _check(boxes, z_range)
    if num_frames < 1 or fps <= 0:
        raise ValueError(f"need num_frames >= 1 and fps > 0, got {num_frames}, {fps}")
    c = as_config(TrajectoryConfig, trajectory, "flight.trajectory")
    where = "flight.trajectory"
    N, dt = int(num_frames), 1.0 / float(fps)
    t = np.arange(N) * dt
    T = max(t[-1], dt)
    x0, y0, x1, y1 = _main_box(boxes)

    # along the corridor: smooth monotone progress over distance D
    speed = rng.uniform(*_pair(c, "speed", where))
    start = rng.uniform(*_pair(c, "start_offset", where))
    start = min(start, 0.25 * (y1 - y0))
    D = min(speed * T, (y1 - y0) - start - 0.05 * (y1 - y0))
    ramp = min(c.ramp_s, T / 4)
    rise = np.clip(t / max(ramp, 1e-9), 0, 1)
    fall = np.clip((T - t) / max(ramp, 1e-9), 0, 1)
    envelope = (3 * rise**2 - 2 * rise**3) * (3 * fall**2 - 2 * fall**3) + 0.05
    var = min(c.speed_variation, 0.9)
    u = envelope * (1 + var * smooth_noise(rng, t, (0.03, 0.15)))
    s = np.concatenate([[0.0], np.cumsum((u[1:] + u[:-1]) / 2)])
    progress = s / s[-1] if s[-1] > 0 else np.zeros(N)
    y = (y0 + start + D * progress) if not c.reverse else (y1 - start - D * progress)

    # lateral and height sway, centred so the extremes stay inside
    f_sway = _pair(c, "sway_freq_hz", where)
    ax = min(c.sway_x, 0.45 * (x1 - x0))
    xc = rng.uniform(x0 + ax, x1 - ax)
    x = xc + ax * smooth_noise(rng, t, f_sway)
    az = min(c.sway_z, 0.45 * (z[1] - z[0]))
    h_lo, h_hi = _pair(c, "height", where)
    lo, hi = max(h_lo, z[0] + az), min(h_hi, z[1] - az)
    zc = rng.uniform(lo, hi) if lo <= hi else float(np.clip((h_lo + h_hi) / 2, z[0] + az,
                                                            z[1] - az))
    height = zc + az * smooth_noise(rng, t, f_sway)

    # yaw about the flight direction
    heading = -np.pi / 2 if c.reverse else np.pi / 2
    yaw_amp = np.deg2rad(rng.uniform(*_pair(c, "yaw_amplitude_deg", where)))
    yaw = wrap_angle(heading + yaw_amp * smooth_noise(rng, t, _pair(c, "yaw_freq_hz", where)))

    # roll / pitch from the horizontal acceleration, plus a little wobble
    if N >= 3:
        acc = np.stack([np.gradient(np.gradient(v, dt), dt) for v in (x, y)], 1)
    else:
        acc = np.zeros((N, 2))
    a_fwd = np.cos(yaw) * acc[:, 0] + np.sin(yaw) * acc[:, 1]
    a_left = -np.sin(yaw) * acc[:, 0] + np.cos(yaw) * acc[:, 1]
    wobble = np.deg2rad(c.tilt_noise_deg)
    pitch = np.arctan(a_fwd / GRAVITY) + wobble * smooth_noise(rng, t, (0.2, 1.0))
    roll = -np.arctan(a_left / GRAVITY) + wobble * smooth_noise(rng, t, (0.2, 1.0))
    max_tilt = np.deg2rad(c.max_tilt_deg)
    rpy = np.stack([np.clip(roll, -max_tilt, max_tilt), np.clip(pitch, -max_tilt, max_tilt),
                    yaw], 1)
    return pose_from_xyz_rpy(np.stack([x, y, height], 1), rpy)


def noisy_odometry(rng: np.random.Generator, groundtruth: np.ndarray, fps: float,
                   odometry: OdometryConfig | Mapping | None = None) -> np.ndarray:
    """Odometry as a copter's visual-inertial odometry would report it.

    Starts at groundtruth[0] and integrates the true frame-to-frame motion, expressed in
    the gravity-aligned heading frame (translation and yaw increment), corrupted by white
    noise, a scale error (constant plus random walk), a heading-rate bias (constant plus
    random walk) and a random-walk velocity bias, so it drifts away from the truth. Roll
    and pitch are the truth's (a real IMU observes them).

    Args:
        rng: random generator.
        groundtruth: (N, 4, 4) world_from_body.
        fps: frame rate (Hz).
        odometry: a flight preset's ``odometry`` (``OdometryConfig``, or a mapping of the keys
            that differ from its defaults; None: the defaults).

    Returns:
        (N, 4, 4) world_from_body odometry poses.
    """
    gt = np.asarray(groundtruth, dtype=np.float64)
    if gt.ndim != 3 or gt.shape[1:] != (4, 4):
        raise ValueError(f"groundtruth must be (N, 4, 4), got {gt.shape}")
    c = as_config(OdometryConfig, odometry, "flight.odometry")
    N, dt = len(gt), 1.0 / float(fps)
    if N < 2:
        return gt.copy()
    rpy = Rotation.from_matrix(gt[:, :3, :3]).as_euler("xyz")
    yaw, p = rpy[:, 2], gt[:, :3, 3]
    M = N - 1

    def walk(std_per_sqrt_s: float, shape: tuple[int, ...]) -> np.ndarray:
        return np.cumsum(rng.normal(0.0, std_per_sqrt_s * np.sqrt(dt), shape), axis=0)

    # true increments in the heading frame of the previous pose
    dp = np.diff(p, axis=0)
    cy, sy = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    d = np.stack([cy * dp[:, 0] + sy * dp[:, 1], -sy * dp[:, 0] + cy * dp[:, 1], dp[:, 2]], 1)
    dyaw = wrap_angle(np.diff(yaw))
    # corrupt them
    scale = rng.normal(0.0, c.scale_error) + walk(c.scale_walk, (M,))
    vel_bias = walk(c.velocity_bias_walk, (M, 3))
    d_odo = (d * (1 + scale)[:, None] + vel_bias * dt
             + rng.normal(0.0, c.trans_noise_m, (M, 3)))
    yaw_bias = (np.deg2rad(rng.normal(0.0, c.yaw_bias_deg_s))
                + np.deg2rad(walk(c.yaw_bias_walk_deg_s, (M,))))
    dyaw_odo = dyaw + yaw_bias * dt + np.deg2rad(rng.normal(0.0, c.yaw_noise_deg, M))
    # integrate
    yaw_odo = yaw[0] + np.concatenate([[0.0], np.cumsum(dyaw_odo)])
    co, so = np.cos(yaw_odo[:-1]), np.sin(yaw_odo[:-1])
    step = np.stack([co * d_odo[:, 0] - so * d_odo[:, 1], so * d_odo[:, 0] + co * d_odo[:, 1],
                     d_odo[:, 2]], 1)
    p_odo = p[0] + np.concatenate([np.zeros((1, 3)), np.cumsum(step, axis=0)])
    return pose_from_xyz_rpy(p_odo, np.stack([rpy[:, 0], rpy[:, 1], yaw_odo], 1))


def timestamps(num_frames: int, fps: float) -> np.ndarray:
    """(N,) frame times in seconds, starting at 0."""
    return np.arange(int(num_frames)) / float(fps)
