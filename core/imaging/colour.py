"""sRGB <-> linear light (IEC 61966-2-1), for float images and 8-bit ones.

Renders are in linear light; images on disk and textures in 8-bit sRGB. ``LINEAR_LUT`` is the
one lookup table from an 8-bit sRGB level to its linear value.
"""

from __future__ import annotations

import numpy as np


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] (any shape; clipped) to linear values."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] (any shape; clipped) to sRGB-encoded values."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


#: (256,) float32 linear value of each 8-bit sRGB level.
LINEAR_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def to_linear(rgb: np.ndarray) -> np.ndarray:
    """uint8 sRGB (any shape, e.g. (H, W, 3)) -> float32 linear light in [0, 1], same shape."""
    return LINEAR_LUT[rgb]


def linear_to_srgb8(img: np.ndarray) -> np.ndarray:
    """Linear RGB (any shape, float; NaN as 0, clipped to [0, 1]) to 8-bit sRGB."""
    return np.rint(linear_to_srgb(np.nan_to_num(img, nan=0.0)) * 255.0).astype(np.uint8)
