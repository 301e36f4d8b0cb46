"""Cheap denoiser for low-spp path-traced frames: albedo demodulation + segment-wise blur.

Monte Carlo noise sits in the shading (irradiance), which is smooth inside one flat surface,
while texture detail sits in the albedo, which the renderer gives noise-free. So the image is
split into albedo x shading, the shading is blurred with a normalized Gaussian inside each
segment (same shape and same normal direction, so creases and silhouettes stay sharp), and
multiplied back.
"""

from __future__ import annotations

import cv2
import numpy as np


def segment_ids(shape_index: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Segment id per pixel from the shape hit and the dominant normal direction.

    Args:
        shape_index: (H, W) integer shape ids. normal: (H, W, 3) unit normals.

    Returns:
        (H, W) int64 ids: 6 * shape_index + one of 6 axis directions.
    """
    axis = np.argmax(np.abs(normal), axis=-1)
    positive = np.take_along_axis(normal, axis[..., None], -1)[..., 0] > 0
    return shape_index.astype(np.int64) * 6 + axis * 2 + positive


def _relabel(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(segments, return_inverse=True)`` for small non-negative ids, by a lookup
    table instead of a sort (~10x faster on a 320x240 frame). Returns ids (K,) ascending and
    inverse (H, W) in [0, K)."""
    if segments.min() < 0:
        ids, inverse = np.unique(segments, return_inverse=True)
        return ids, inverse.reshape(segments.shape)
    present = np.bincount(segments.ravel()) > 0
    ids = np.flatnonzero(present)
    lookup = np.cumsum(present) - 1
    return ids, lookup[segments]


def denoise(rgb: np.ndarray, albedo: np.ndarray, segments: np.ndarray, keep: np.ndarray,
            sigma_px: float = 4.0) -> np.ndarray:
    """Denoise a linear image.

    Args:
        rgb: (H, W, 3) float linear radiance (noisy).
        albedo: (H, W, 3) float surface albedo from the same samples.
        segments: (H, W) int segment ids (see ``segment_ids``).
        keep: (H, W) bool pixels left as rendered (emitters: their radiance is not shading).
        sigma_px: Gaussian blur of the shading, pixels.

    Returns:
        (H, W, 3) float32 denoised linear radiance.
    """
    if rgb.shape != albedo.shape or rgb.shape[:2] != segments.shape:
        raise ValueError(f"denoise: shapes differ: rgb {rgb.shape}, albedo {albedo.shape}, "
                         f"segments {segments.shape}")
    a = np.maximum(albedo, 1e-3).astype(np.float32)
    shading = (rgb / a).astype(np.float32)
    out = np.zeros_like(shading)
    H, W = segments.shape
    pad = int(np.ceil(3 * sigma_px))
    ids, inverse = _relabel(segments)
    rows, cols = np.indices((H, W))
    # Bounding box of every segment, so each blur only touches its own neighbourhood.
    r0 = np.full(len(ids), H)
    r1 = np.zeros(len(ids), int)
    c0 = np.full(len(ids), W)
    c1 = np.zeros(len(ids), int)
    np.minimum.at(r0, inverse.ravel(), rows.ravel())
    np.maximum.at(r1, inverse.ravel(), rows.ravel())
    np.minimum.at(c0, inverse.ravel(), cols.ravel())
    np.maximum.at(c1, inverse.ravel(), cols.ravel())
    for k in range(len(ids)):  # a few dozen segments per frame, not pixels
        ys = slice(max(r0[k] - pad, 0), min(r1[k] + pad + 1, H))
        xs = slice(max(c0[k] - pad, 0), min(c1[k] + pad + 1, W))
        m = (inverse[ys, xs] == k).astype(np.float32)
        num = cv2.GaussianBlur(shading[ys, xs] * m[..., None], (0, 0), sigma_px,
                               borderType=cv2.BORDER_CONSTANT)
        den = cv2.GaussianBlur(m, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT)
        out[ys, xs] += (num / np.maximum(den, 1e-6)[..., None]) * m[..., None]
    result = out * a
    return np.where(keep[..., None], rgb, result).astype(np.float32)
