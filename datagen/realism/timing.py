"""The clocks of a drone's camera and odometry (``realism.timing``, ``TimingConfig``).

A flight's frame i is captured at i / fps (its rendered pose is the ground truth's at that
time). Under ``realism.timing``:

- a share ``drop_rate`` of the frames is dropped: never delivered (and not rendered);
  flight.json lists them (``timing.dropped``) and the flight's images.txt lists the
  delivered frames only;
- a delivered frame's timestamp is its capture time plus a normal error of std
  ``jitter_ms`` (clipped to +/- 3 std), the stamp a driver or a video link gives;
- the odometry is sampled at its own rate (``odometry_hz``: k / odometry_hz over the flight,
  the true motion resampled there, ``resample_poses``), with its white noise scaled so its
  error per second is the frame-rate odometry's (``odometry_at_rate``), and jumps
  (``odometry_jumps``) at ``jump_per_min``.

The flight's reader (``core.dataset.Dataset.flight``) then interpolates the odometry at each
delivered frame's timestamp, as it does for a user's recording (``core.poses.interpolate_poses``).
A frame's drop and jitter come from that frame's own generator, so they do not depend on
sharding or resuming. Magnitudes of ``realism=real`` and their source: docs/datagen.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from core.config import as_config
from core.imaging.realism import TimingConfig
from core.poses import pose_from_xyz_rpy
from datagen.config import OdometryConfig

WHERE = "realism.timing"
MAX_DROP_RATE = 0.5  # a link that loses more than half its frames is broken, not imperfect
JITTER_CLIP = 3.0  # a timestamp's error is clipped to +/- this many std
MAX_JUMP_M = 1.0  # m; a larger odometry jump is a lost track, not an outlier
MAX_JUMP_DEG = 45.0


def _number(c: TimingConfig, key: str, where: str, lo: float, hi: float, fix: str) -> float:
    value = float(getattr(c, key))
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{where}.{key} = {value} must be in [{lo}, {hi}]; {fix}")
    return value


def check_settings(settings: TimingConfig | Mapping | None, where: str = WHERE) -> TimingConfig:
    """The settings typed (``TimingConfig``, or a mapping of the keys that differ from its
    defaults; None: the defaults) and checked.

    Raises:
        ValueError: a bad setting, naming ``where.<key>`` and the fix.
    """
    c = as_config(TimingConfig, settings, where)
    _number(c, "drop_rate", where, 0.0, MAX_DROP_RATE, "a share of frames; 0 turns drops off")
    _number(c, "jitter_ms", where, 0.0, math.inf, "a standard deviation in ms; 0 turns it off")
    _number(c, "jump_per_min", where, 0.0, math.inf, "a rate per minute; 0 turns jumps off")
    _number(c, "jump_m", where, 0.0, MAX_JUMP_M, "metres")
    _number(c, "jump_deg", where, 0.0, MAX_JUMP_DEG, "degrees")
    if c.odometry_hz is not None:
        hz = float(c.odometry_hz)
        if not (math.isfinite(hz) and 0.0 < hz <= 1000.0):
            raise ValueError(f"{where}.odometry_hz = {hz} must be a rate in (0, 1000] Hz, or "
                             "null for the odometry at the camera's frame times")
    return c


def check_flight(c: TimingConfig, fps: float, where: str = WHERE) -> None:
    """Raise if the timestamp jitter could reorder a flight's frames at ``fps`` Hz (the
    clipped errors of two neighbours must stay under one frame interval) or the odometry is
    too slow to interpolate (at least 1 Hz)."""
    limit_ms = 1e3 / float(fps) / (2 * JITTER_CLIP)
    if float(c.jitter_ms) >= limit_ms:
        raise ValueError(f"{where}.jitter_ms = {c.jitter_ms} could reorder frames at {fps} fps; "
                         f"keep it under {limit_ms:.2f} ms (1 / (6 fps))")
    if c.odometry_hz is not None and float(c.odometry_hz) < 1.0:
        raise ValueError(f"{where}.odometry_hz = {c.odometry_hz} is below 1 Hz; a VIO or "
                         "flight controller reports at 10-200 Hz")


def is_active(c: TimingConfig) -> bool:
    """Whether timing changes a flight's files (else they are as under ``realism=ideal``)."""
    return (c.drop_rate > 0 or c.jitter_ms > 0 or c.odometry_hz is not None
            or (c.jump_per_min > 0 and (c.jump_m > 0 or c.jump_deg > 0)))


def frame_delivery(frame_rng: Callable[[int], np.random.Generator], num_frames: int,
                   fps: float, c: TimingConfig) -> tuple[np.ndarray, np.ndarray]:
    """Which frames are delivered and their timestamps.

    Args:
        frame_rng: frame index -> that frame's own generator (a drop draw, then a jitter
            draw, each only when its setting is on).
        num_frames: N.
        fps: frame rate, Hz.
        c: the settings.

    Returns:
        (N,) bool, True for a delivered frame (frame 0 always is: the flight starts with a
        frame); (N,) float64 s, each frame's timestamp (capture time i / fps plus the
        jitter), strictly increasing.
    """
    n = int(num_frames)
    delivered = np.ones(n, dtype=bool)
    stamps = np.arange(n) / float(fps)
    if c.drop_rate <= 0 and c.jitter_ms <= 0:
        return delivered, stamps
    jitter = np.zeros(n)
    for i in range(n):  # one generator per frame: independent of shards and resumes
        rng = frame_rng(i)
        if c.drop_rate > 0:
            delivered[i] = i == 0 or rng.random() >= c.drop_rate
        if c.jitter_ms > 0:
            jitter[i] = np.clip(rng.normal(), -JITTER_CLIP, JITTER_CLIP) * c.jitter_ms * 1e-3
    return delivered, stamps + jitter


def odometry_times(num_frames: int, fps: float, c: TimingConfig) -> np.ndarray:
    """(M,) s, the odometry's sample times: k / odometry_hz over [0, (N - 1) / fps] plus one
    sample past the end (so the last frame lies inside), or the frame times when
    ``odometry_hz`` is None."""
    if c.odometry_hz is None:
        return np.arange(int(num_frames)) / float(fps)
    end = (int(num_frames) - 1) / float(fps)
    m = int(math.ceil(end * float(c.odometry_hz) - 1e-9)) + 1
    return np.arange(max(m, 2)) / float(c.odometry_hz)


def resample_poses(poses: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """Smooth poses at other times: a cubic spline through the positions and a rotation
    spline (scipy ``RotationSpline``) through the attitudes sampled at i / fps.

    Args:
        poses: (N, 4, 4) world_from_body at i / fps, N >= 2.
        fps: Hz.
        times: (M,) s, clamped to [0, (N - 1) / fps].

    Returns:
        (M, 4, 4) world_from_body.
    """
    poses = np.asarray(poses, dtype=np.float64)
    t = np.arange(len(poses)) / float(fps)
    q = np.clip(np.asarray(times, dtype=np.float64), t[0], t[-1])
    out = np.tile(np.eye(4), (len(q), 1, 1))
    out[:, :3, :3] = RotationSpline(t, Rotation.from_matrix(poses[:, :3, :3]))(q).as_matrix()
    out[:, :3, 3] = CubicSpline(t, poses[:, :3, 3], axis=0)(q)
    return out


def odometry_at_rate(odometry: OdometryConfig, fps: float, rate_hz: float) -> OdometryConfig:
    """The odometry settings for samples at ``rate_hz`` whose error per second matches the
    frame-rate odometry's: the white per-sample noises scaled by sqrt(fps / rate_hz) (their
    sum over a second keeps its variance); the random walks are per sqrt(s) already."""
    k = math.sqrt(float(fps) / float(rate_hz))
    return replace(odometry, trans_noise_m=odometry.trans_noise_m * k,
                   yaw_noise_deg=odometry.yaw_noise_deg * k)


def odometry_jumps(rng: np.random.Generator, times: np.ndarray, odometry: np.ndarray,
                   c: TimingConfig) -> tuple[np.ndarray, list[dict]]:
    """Odometry with jumps: at Poisson times (``jump_per_min``) the reported pose jumps by a
    horizontal translation (its direction uniform, its size uniform in [0.5, 1] x ``jump_m``)
    and a yaw change (sign drawn, size uniform in [0.5, 1] x ``jump_deg``) about the current
    pose, and every later pose moves with it (the odometry's frame is off from then on).

    Args:
        rng: random generator (the flight's own stream).
        times: (M,) s, the odometry's sample times.
        odometry: (M, 4, 4) world_from_body.
        c: the settings.

    Returns:
        (M, 4, 4) the odometry with its jumps; the jumps as ``{"time_s", "sample", "m",
        "deg"}`` (the first sample at or after the jump, its translation and yaw change).
    """
    odo = np.array(odometry, dtype=np.float64)
    if c.jump_per_min <= 0 or len(times) < 2:
        return odo, []
    span = float(times[-1] - times[0])
    gaps = rng.exponential(60.0 / c.jump_per_min, int(span * c.jump_per_min / 60.0 * 3) + 10)
    at = times[0] + np.cumsum(gaps)
    at = at[at < times[-1]]
    jumps = []
    for when in at:
        k = int(np.searchsorted(times, when))
        k = max(k, 1)
        direction = rng.uniform(0.0, 2 * np.pi)
        size = c.jump_m * rng.uniform(0.5, 1.0)
        dyaw = np.deg2rad(c.jump_deg * rng.uniform(0.5, 1.0)) * rng.choice([-1.0, 1.0])
        # J moves the pose at k by (dx, dy) and turns it by dyaw about its own position
        p = odo[k, :3, 3]
        J = pose_from_xyz_rpy(np.zeros(3), np.array([0.0, 0.0, dyaw]))[0]
        J[:3, 3] = p - J[:3, :3] @ p + size * np.array([np.cos(direction), np.sin(direction),
                                                         0.0])
        odo[k:] = J @ odo[k:]
        jumps.append({"time_s": float(when), "sample": k, "m": float(size),
                      "deg": float(np.rad2deg(dyaw))})
    return odo, jumps
