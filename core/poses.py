"""Rigid poses (4x4, ``a_from_b``), the x-y-z-yaw body state, and TUM trajectory files.

Body frame: x forward, y left, z up. TUM lines: ``timestamp tx ty tz qx qy qz qw`` giving
world_from_body.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from core.atomic import atomic_write_text


def pose_from_xyz_rpy(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """Poses from positions and roll-pitch-yaw (extrinsic x-y-z = intrinsic Z-Y-X).

    Args:
        xyz: (N, 3) translations in metres.
        rpy: (N, 3) roll, pitch, yaw in radians.

    Returns:
        (N, 4, 4) float64 poses.
    """
    xyz = np.atleast_2d(np.asarray(xyz, dtype=np.float64))
    rpy = np.atleast_2d(np.asarray(rpy, dtype=np.float64))
    T = np.tile(np.eye(4), (len(xyz), 1, 1))
    T[:, :3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:, :3, 3] = xyz
    return T


def pose_from_xyzyaw(state: np.ndarray) -> np.ndarray:
    """Poses from the filter state.

    Args:
        state: (N, 4) x, y, z (metres), yaw (radians).

    Returns:
        (N, 4, 4) float64 world_from_body with zero roll and pitch.
    """
    state = np.atleast_2d(np.asarray(state, dtype=np.float64))
    c, s = np.cos(state[:, 3]), np.sin(state[:, 3])
    T = np.tile(np.eye(4), (len(state), 1, 1))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, :3, 3] = state[:, :3]
    return T


def xyzyaw_from_pose(T: np.ndarray) -> np.ndarray:
    """Filter state of poses: position and heading of the body x axis.

    Args:
        T: (N, 4, 4) world_from_body.

    Returns:
        (N, 4) x, y, z, yaw (radians, in (-pi, pi]).
    """
    T = np.asarray(T, dtype=np.float64).reshape(-1, 4, 4)
    yaw = np.arctan2(T[:, 1, 0], T[:, 0, 0])
    return np.concatenate([T[:, :3, 3], yaw[:, None]], axis=1)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap angles (radians) to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def odometry_increment(prev: np.ndarray, cur: np.ndarray) -> np.ndarray:
    """Motion between two odometry poses in the earlier pose's heading frame.

    Args:
        prev, cur: (4, 4) world_from_body.

    Returns:
        (4,) forward, left, up (metres), yaw change (radians).
    """
    a, b = xyzyaw_from_pose(np.stack([prev, cur]))
    c, s = np.cos(a[3]), np.sin(a[3])
    d = b[:3] - a[:3]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2], wrap_angle(b[3] - a[3])])


def interpolate_poses(times: np.ndarray, stamps: np.ndarray, poses: np.ndarray,
                      extrapolate: bool = False) -> np.ndarray:
    """Poses at given times: linear in translation, slerp in rotation, between the two samples
    around each time.

    Args:
        times: (N,) query times, seconds.
        stamps: (M,) strictly increasing sample times, seconds, M >= 1.
        poses: (M, 4, 4) rigid poses sampled at ``stamps``.
        extrapolate: before the first or after the last sample, continue the first or last
            interval's motion (a camera's exposure reaching past a trajectory's ends); False
            clamps the times to ``[stamps[0], stamps[-1]]`` (odometry read at image times).

    Returns:
        (N, 4, 4) float64 poses; with M = 1, that pose at every time.
    """
    stamps = np.asarray(stamps, dtype=np.float64).reshape(-1)
    poses = np.asarray(poses, dtype=np.float64)
    if poses.shape != (len(stamps), 4, 4) or len(stamps) < 1:
        raise ValueError(f"need (M, 4, 4) poses with M >= 1 matching (M,) stamps, got "
                         f"{poses.shape} and {stamps.shape}")
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if len(stamps) == 1:
        return np.repeat(poses, len(t), axis=0)
    if not extrapolate:
        t = np.clip(t, stamps[0], stamps[-1])
    k = np.clip(np.searchsorted(stamps, t, side="right") - 1, 0, len(stamps) - 2)
    u = (t - stamps[k]) / (stamps[k + 1] - stamps[k])
    a, b = poses[k], poses[k + 1]
    out = np.tile(np.eye(4), (len(t), 1, 1))
    out[:, :3, 3] = a[:, :3, 3] + u[:, None] * (b[:, :3, 3] - a[:, :3, 3])
    ra = Rotation.from_matrix(a[:, :3, :3])
    rel = (ra.inv() * Rotation.from_matrix(b[:, :3, :3])).as_rotvec()
    out[:, :3, :3] = (ra * Rotation.from_rotvec(u[:, None] * rel)).as_matrix()
    return out


def write_tum(path: str | Path, timestamps: np.ndarray, poses: np.ndarray) -> None:
    """Write poses as a TUM trajectory file (atomically).

    Args:
        path: output file.
        timestamps: (N,) seconds.
        poses: (N, 4, 4) world_from_body.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x, y, z, w
    rows = np.concatenate([np.asarray(timestamps)[:, None], poses[:, :3, 3], q], axis=1)
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    lines += [" ".join(f"{v:.9f}" for v in row) for row in rows]
    atomic_write_text(path, "\n".join(lines) + "\n")


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file.

    Returns:
        timestamps: (N,) seconds; poses: (N, 4, 4) world_from_body.

    Raises:
        FileNotFoundError, ValueError: with the file name and what is wrong.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"trajectory file not found: {path}")
    try:
        data = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as err:
        raise ValueError(f"{path}: not a TUM file (timestamp tx ty tz qx qy qz qw): {err}") from err
    if data.shape[1] != 8:
        raise ValueError(f"{path}: expected 8 columns (TUM), found {data.shape[1]}")
    T = np.tile(np.eye(4), (len(data), 1, 1))
    T[:, :3, :3] = Rotation.from_quat(data[:, 4:8]).as_matrix()
    T[:, :3, 3] = data[:, 1:4]
    return data[:, 0], T
