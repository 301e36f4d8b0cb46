"""The roll and pitch a small drone's AHRS reports (``realism.ahrs``, ``AhrsConfig``).

A multirotor's flight controller estimates roll and pitch from a MEMS IMU (InvenSense
MPU-6000 / ICM-20689 or Bosch BMI088 class) with a complementary filter or an EKF (PX4,
ArduPilot). Its error on each axis is modelled as the sum of

- a constant bias, drawn once per flight (``bias_deg``): the accelerometer's zero-g offset
  left after calibration and the board's mounting misalignment; an offset of b tilts the
  estimate by b / g (5 mg: 0.29 deg);
- white noise, drawn per frame (``noise_deg``): sensor noise the filter lets through;
- a slow drift (``drift_deg``, ``drift_time_s``): a stationary first-order Gauss-Markov
  process, the filter's error while the drone accelerates (the accelerometer measures the
  specific force, not gravity) and the gyro bias changing with temperature. It stays bounded,
  unlike a random walk, because the filter keeps pulling the estimate to gravity.

The errors are added to the extrinsic x-y-z Euler roll and pitch of ``core.poses`` (degrees
in the settings, radians in and out of the functions). Magnitudes of ``realism=real`` and
their source: docs/datagen.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from core.config import as_config
from core.imaging.realism import AhrsConfig
from core.poses import pose_from_xyz_rpy

WHERE = "realism.ahrs"
STD_KEYS = ("bias_deg", "noise_deg", "drift_deg")
MAX_STD_DEG = 10.0  # an attitude filter off by more is broken, not imperfect


def check_settings(settings: AhrsConfig | Mapping | None, where: str = WHERE) -> AhrsConfig:
    """The settings typed (``AhrsConfig``, or a mapping of the keys that differ from its
    defaults; None: the defaults) and checked.

    Raises:
        ValueError: a std outside [0, ``MAX_STD_DEG``] or not finite, or ``drift_time_s``
            not > 0, naming ``where.<key>``.
    """
    c = as_config(AhrsConfig, settings, where)
    for key in STD_KEYS:
        value = float(getattr(c, key))
        if not 0.0 <= value <= MAX_STD_DEG:
            raise ValueError(f"{where}.{key} = {value} must be a standard deviation in degrees "
                             f"in [0, {MAX_STD_DEG}]; 0 turns it off")
    tau = float(c.drift_time_s)
    if not (tau > 0.0 and math.isfinite(tau)):
        raise ValueError(f"{where}.drift_time_s = {tau} must be > 0 s (the drift's correlation "
                         "time); set drift_deg: 0 to turn the drift off")
    return c


def is_active(settings: AhrsConfig) -> bool:
    """Whether the AHRS changes anything (some std > 0)."""
    return any(float(getattr(settings, key)) > 0.0 for key in STD_KEYS)


def gauss_markov(rng: np.random.Generator, shape: tuple[int, ...], dt: float, std: float,
                 time_s: float) -> np.ndarray:
    """A stationary first-order Gauss-Markov process sampled every ``dt`` along axis 0:
    x_0 ~ N(0, std^2), x_k = a x_(k-1) + sqrt(1 - a^2) std e_k with a = exp(-dt / time_s) and
    e_k ~ N(0, 1), so every sample has std ``std`` and the autocorrelation at lag t is
    exp(-t / time_s).

    Args:
        rng: random generator.
        shape: (N, ...) samples, N along time; every other index is its own process.
        dt: s between samples (> 0).
        std: stationary standard deviation, in the unit of the output.
        time_s: correlation time in seconds (> 0).

    Returns:
        an array of ``shape``.
    """
    a = math.exp(-dt / time_s)
    e = rng.normal(0.0, std, shape)
    e[1:] *= math.sqrt(-math.expm1(-2.0 * dt / time_s))  # sqrt(1 - a^2), exact for small dt
    return lfilter([1.0], [1.0, -a], e, axis=0)


def ahrs_attitude(rng: np.random.Generator, roll: np.ndarray, pitch: np.ndarray, fps: float,
                  settings: AhrsConfig | Mapping | None = None,
                  where: str = WHERE) -> tuple[np.ndarray, np.ndarray]:
    """The roll and pitch an AHRS reports for a true attitude sampled at the frame rate.

    Draws, in this order, the bias (2,), the white noise (N, 2) and the drift (N, 2) (roll,
    pitch), each a normal of its configured std (zero std: zeros, the draws still made).

    Args:
        rng: random generator.
        roll: (N,) true roll, radians.
        pitch: (N,) true pitch, radians.
        fps: frame rate (Hz) of the samples.
        settings: ``AhrsConfig``, or a mapping of the keys that differ from its defaults
            (None: the defaults, every std 0).
        where: the settings' config key, for messages.

    Returns:
        (roll, pitch), each (N,) radians; copies of the truth when every std is 0.

    Raises:
        ValueError: bad settings (``check_settings``), shapes or frame rate.
    """
    c = check_settings(settings, where)
    roll = np.array(roll, dtype=np.float64)
    pitch = np.array(pitch, dtype=np.float64)
    if roll.ndim != 1 or roll.shape != pitch.shape:
        raise ValueError(f"roll and pitch must be (N,) arrays of one length, got {roll.shape} "
                         f"and {pitch.shape}")
    if not fps > 0:
        raise ValueError(f"fps = {fps} must be > 0")
    if not is_active(c):
        return roll, pitch
    n = len(roll)
    bias = rng.normal(0.0, c.bias_deg, 2)
    white = rng.normal(0.0, c.noise_deg, (n, 2))
    drift = gauss_markov(rng, (n, 2), 1.0 / float(fps), c.drift_deg, c.drift_time_s)
    error = np.deg2rad(bias + white + drift)
    return roll + error[:, 0], pitch + error[:, 1]


def ahrs_odometry(rng: np.random.Generator, odometry: np.ndarray, groundtruth: np.ndarray,
                  fps: float, settings: AhrsConfig | Mapping | None = None,
                  where: str = WHERE) -> np.ndarray:
    """Odometry poses whose roll and pitch are the AHRS's (``ahrs_attitude`` of the true roll
    and pitch), their yaw and translation kept.

    Args:
        rng: random generator (its own stream: the odometry's yaw and translation do not
            depend on whether the AHRS is on).
        odometry: (N, 4, 4) world_from_body odometry (``trajectories.noisy_odometry``).
        groundtruth: (N, 4, 4) world_from_body true poses.
        fps: frame rate (Hz).
        settings: ``AhrsConfig`` or a mapping (None: the defaults, every std 0).
        where: the settings' config key, for messages.

    Returns:
        (N, 4, 4) world_from_body; a copy of ``odometry`` when every std is 0.
    """
    odo = np.array(odometry, dtype=np.float64)
    gt = np.asarray(groundtruth, dtype=np.float64)
    if odo.ndim != 3 or odo.shape[1:] != (4, 4) or gt.shape != odo.shape:
        raise ValueError(f"odometry and groundtruth must be (N, 4, 4) of one length, got "
                         f"{odo.shape} and {gt.shape}")
    c = check_settings(settings, where)
    if not is_active(c) or not len(odo):
        return odo
    true = Rotation.from_matrix(gt[:, :3, :3]).as_euler("xyz")
    roll, pitch = ahrs_attitude(rng, true[:, 0], true[:, 1], fps, c, where)
    yaw = Rotation.from_matrix(odo[:, :3, :3]).as_euler("xyz")[:, 2]
    return pose_from_xyz_rpy(odo[:, :3, 3], np.stack([roll, pitch, yaw], 1))
