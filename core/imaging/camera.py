"""Pinhole camera in the OpenCV convention and the one conversion to Mitsuba's frame.

OpenCV camera frame: x right, y down, z forward; pixel centres at integer coordinates,
so a W-pixel-wide image spans u in [-0.5, W - 0.5]. Mitsuba's camera frame: x left, y up,
z forward. ``mitsuba_from_opencv`` is the only place the two meet.
"""

from __future__ import annotations

import math

import numpy as np

#: Maps points in the OpenCV camera frame to Mitsuba's camera frame (x and y flip).
MITSUBA_FROM_OPENCV = np.diag([-1.0, -1.0, 1.0, 1.0])
#: m, body frame: where the forward camera sits by default (datagen's ``camera.mount.xyz``; a
#: recording localized in a building file that gives no mount): 10 cm ahead of the body centre.
FORWARD_MOUNT_XYZ = (0.10, 0.0, 0.0)
#: The forward camera's axes (x right, y down, z forward: OpenCV) as columns in the body frame
#: (x forward, y left, z up).
BODY_FROM_FORWARD_CAM = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def intrinsics(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """Intrinsic matrix of a centred pinhole camera with square pixels.

    Args:
        width, height: image size in pixels.
        hfov_deg: horizontal field of view in degrees, across the full image width.

    Returns:
        K, (3, 3) float64.
    """
    if width <= 0 or height <= 0:
        raise ValueError(f"camera size must be positive, got {width}x{height}")
    if not 0.0 < hfov_deg < 180.0:
        raise ValueError(f"camera.hfov_deg must be in (0, 180), got {hfov_deg}")
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
    return np.array(
        [[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]]
    )


def forward_mount(xyz=FORWARD_MOUNT_XYZ, pitch_deg: float = 0.0) -> np.ndarray:
    """body_from_cam of a camera looking along the body's x axis, tilted down by ``pitch_deg``.

    Args:
        xyz: (3,) m, the camera centre in the body frame (x forward, y left, z up).
        pitch_deg: degrees; positive tilts the camera down.

    Returns:
        (4, 4) body_from_cam, the camera in OpenCV axes.
    """
    p = math.radians(pitch_deg)
    tilt = np.array([[math.cos(p), 0.0, math.sin(p)], [0.0, 1.0, 0.0],
                     [-math.sin(p), 0.0, math.cos(p)]])  # Ry(pitch): x forward turns down
    out = np.eye(4)
    out[:3, :3] = tilt @ BODY_FROM_FORWARD_CAM
    out[:3, 3] = np.asarray(xyz, dtype=np.float64)
    return out


def mitsuba_to_world(world_from_cam: np.ndarray) -> np.ndarray:
    """Mitsuba sensor ``to_world`` for an OpenCV-convention camera pose.

    Args:
        world_from_cam: (4, 4) pose of the OpenCV camera in the world.

    Returns:
        (4, 4) world_from_mitsubacam, to pass as the sensor's ``to_world``.
    """
    return np.asarray(world_from_cam, dtype=np.float64) @ np.linalg.inv(MITSUBA_FROM_OPENCV)


def project(
    K: np.ndarray, cam_from_world: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project world points into the image.

    Args:
        K: (3, 3) intrinsics.
        cam_from_world: (..., 4, 4) camera poses (leading dims broadcast against points).
        points: (..., N, 3) world points in metres.

    Returns:
        uv: (..., N, 2) pixel coordinates (undefined where depth <= 0).
        depth: (..., N) z in the camera frame, metres.
    """
    R = cam_from_world[..., :3, :3]
    t = cam_from_world[..., :3, 3]
    pc = np.einsum("...ij,...nj->...ni", R, points) + t[..., None, :]
    depth = pc[..., 2]
    z = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
    uv = np.einsum("ij,...nj->...ni", K[:2, :2], pc[..., :2] / z[..., None]) + K[:2, 2]
    return uv, depth
