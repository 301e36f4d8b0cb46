"""Model edges drawn over frames at estimated poses, tiled into one picture.

The world's 3D edge segments are moved into the camera, clipped at the near plane and at the
image border, projected with the pinhole model and drawn as anti-aliased lines: a wireframe
(edges hidden behind walls are drawn too). Where the estimate is right, the lines lie on the
image's corridor edges.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from core.atomic import write_png
from core.dataset import Camera
from localize.filter.projection import cam_from_world, tilt_from_pose

#: Fixed-point bits of the line coordinates given to OpenCV (1/16 pixel).
SHIFT = 4


def clip_segments(a: np.ndarray, b: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clip segments to an axis-aligned box (Liang-Barsky), any dimension D.

    Args:
        a, b: (M, D) segment endpoints.
        lo, hi: (D,) box corners.

    Returns:
        The clipped endpoints (M, D) each and keep (M,) bool, False where nothing is inside.
    """
    d = b - a
    t0, t1 = np.zeros(len(a)), np.ones(len(a))
    keep = np.ones(len(a), dtype=bool)
    for p, q in ((-d, a - lo), (d, hi - a)):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = q / p
        keep &= ~((p == 0) & (q < 0)).any(axis=1)
        t0 = np.maximum(t0, np.where(p < 0, r, -np.inf).max(axis=1))
        t1 = np.minimum(t1, np.where(p > 0, r, np.inf).min(axis=1))
    keep &= t0 <= t1
    return a + t0[:, None] * d, a + t1[:, None] * d, keep


def project_segments(camera: Camera, cam_from_world: np.ndarray, segments: np.ndarray,
                     near: float = 0.05) -> np.ndarray:
    """Image segments of 3D segments seen from one camera.

    Args:
        camera: intrinsics and size.
        cam_from_world: (4, 4) camera pose.
        segments: (M, 2, 3) world endpoints, metres.
        near: depth (metres) the segments are clipped at.

    Returns:
        (K, 2, 2) pixel endpoints (u, v) of the K segments with a part in view, clipped to the
        image.
    """
    segments = np.asarray(segments, dtype=np.float64)
    if segments.ndim != 3 or segments.shape[1:] != (2, 3):
        raise ValueError(f"segments must be (M, 2, 3), got {segments.shape}")
    T = np.asarray(cam_from_world, dtype=np.float64)
    pc = segments @ T[:3, :3].T + T[:3, 3]  # (M, 2, 3)
    a, b, keep = clip_segments(pc[:, 0], pc[:, 1], np.array([-np.inf, -np.inf, near]),
                               np.full(3, np.inf))
    a, b = a[keep], b[keep]
    K = np.asarray(camera.K, dtype=np.float64)
    uv = [(p @ K.T)[:, :2] / p[:, 2:] for p in (a, b)]
    lo, hi = np.array([-0.5, -0.5]), np.array([camera.width - 0.5, camera.height - 0.5])
    ua, ub, keep = clip_segments(uv[0], uv[1], lo, hi)
    return np.stack([ua[keep], ub[keep]], axis=1)


def draw_segments(image: np.ndarray, lines: np.ndarray, color: Sequence[int],
                  thickness: int = 1) -> np.ndarray:
    """Draw (K, 2, 2) pixel segments on a copy of an (H, W, 3) uint8 image."""
    out = np.ascontiguousarray(image).copy()
    pts = np.round(np.asarray(lines) * (1 << SHIFT)).astype(np.int32)
    if len(pts):
        cv2.polylines(out, list(pts), False, tuple(int(c) for c in color), thickness,
                      cv2.LINE_AA, SHIFT)
    return out


def camera_poses(states: np.ndarray, odometry: np.ndarray, camera: Camera) -> np.ndarray:
    """cam_from_world of filter estimates, with roll and pitch from the frames' odometry.

    Args:
        states: (F, 4) x, y, z (metres), yaw (radians) of the body.
        odometry: (F, 4, 4) world_from_body odometry of the same frames (its attitude).
        camera: gives body_from_cam.

    Returns:
        (F, 4, 4) cam_from_world.
    """
    states = np.asarray(states, dtype=np.float64).reshape(-1, 4)
    return np.stack([cam_from_world(s[None], camera.body_from_cam, tilt_from_pose(T))[0]
                     for s, T in zip(states, odometry, strict=True)])


def tile(images: Sequence[np.ndarray], columns: int, gap: int = 2) -> np.ndarray:
    """Tile equally sized (H, W[, C]) uint8 images row by row, ``gap`` black pixels apart."""
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    cols = min(columns, len(images))
    out = np.zeros((rows * (h + gap) - gap, cols * (w + gap) - gap, *images[0].shape[2:]),
                   dtype=np.uint8)
    for k, im in enumerate(images):
        r, c = divmod(k, columns)
        out[r * (h + gap):r * (h + gap) + h, c * (w + gap):c * (w + gap) + w] = im
    return out


def overlay_strip(path: str | Path | None, images: Sequence[np.ndarray], camera: Camera,
                  segments: np.ndarray, estimates: np.ndarray, truth: np.ndarray | None = None,
                  labels: Sequence[str] | None = None, columns: int = 4) -> np.ndarray:
    """Frames with the model's edges at the estimated (and true) poses, tiled into one PNG.

    Args:
        path: PNG to write (atomically), or None to only return the picture.
        images: F frames, (H, W, 3) uint8 RGB, of ``camera``'s size.
        camera: the frames' camera.
        segments: (M, 2, 3) world edge segments (``World.segments``), metres.
        estimates: (F, 4, 4) cam_from_world at the estimates (``camera_poses``); drawn green.
        truth: (F, 4, 4) cam_from_world at the true poses, or None; drawn magenta, beneath.
        labels: F captions (e.g. frame index and error), or None.
        columns: frames per row.

    Returns:
        The tiled picture, (rows * H, columns * W, 3) uint8 plus 2-pixel gaps.
    """
    if len(images) == 0 or len(images) != len(estimates):
        raise ValueError(f"need one estimate per frame and at least one frame, got "
                         f"{len(images)} frames and {len(estimates)} estimates")
    shown = []
    for i, image in enumerate(images):
        if image.shape != (camera.height, camera.width, 3):
            raise ValueError(f"frame {i} is {image.shape}, the camera is "
                             f"({camera.height}, {camera.width}, 3)")
        if truth is not None:
            image = draw_segments(image, project_segments(camera, truth[i], segments),
                                  (255, 0, 255))
        image = draw_segments(image, project_segments(camera, estimates[i], segments),
                              (0, 255, 0))
        if labels is not None:
            cv2.putText(image, str(labels[i]), (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (255, 255, 0), 1, cv2.LINE_AA)
        shown.append(image)
    picture = tile(shown, columns)
    if path is not None:
        write_png(path, picture)
    return picture
