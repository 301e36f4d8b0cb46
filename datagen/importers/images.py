"""The image textures of building files: read, shrunk and made linear RGB."""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import cv2
import numpy as np

from core.imaging.colour import srgb_to_linear

log = logging.getLogger(__name__)
#: Longest side (pixels) an image texture is shrunk to (memory: 3 MB per image as float32).
TEXTURE_MAX_PX = 512


def linear_image(rgb: np.ndarray, max_px: int = TEXTURE_MAX_PX) -> np.ndarray:
    """An 8-bit sRGB image (H, W, 3 or 4; grey (H, W)) as (h, w, 3) float32 linear RGB, row 0
    at the top, its longest side at most ``max_px`` (area-averaged)."""
    img = np.asarray(rgb)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    img = img[..., :3]
    if img.dtype != np.uint8:
        img = np.clip(img.astype(np.float64) * (255.0 / max(float(img.max()), 1.0)), 0, 255)
    scale = max_px / max(img.shape[:2])
    if scale < 1:
        size = (max(1, round(img.shape[1] * scale)), max(1, round(img.shape[0] * scale)))
        img = cv2.resize(np.ascontiguousarray(img), size, interpolation=cv2.INTER_AREA)
    return srgb_to_linear(np.asarray(img, np.float64) / 255.0).astype(np.float32)


@functools.lru_cache(maxsize=256)
def load_image(path: str, max_px: int = TEXTURE_MAX_PX) -> np.ndarray | None:
    """An image file as ``linear_image`` (one array per file: callers share it), None (and a
    warning) if it is missing or unreadable."""
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED) if Path(path).is_file() else None
    if img is None:
        log.warning("%s: image texture missing or unreadable; the faces keep their colour",
                    path)
        return None
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2RGB)
    return linear_image(img, max_px)
