"""Colours, noise and the drawing primitives textures are painted with (boxes, rectangles,
circles, lines, text) on (H, W, 3) float32 sRGB canvases, and their 8-bit linearization."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np

from core.imaging.colour import LINEAR_LUT


def _hsv(rng: np.random.Generator, h: tuple[float, float], s: tuple[float, float],
         v: tuple[float, float]) -> np.ndarray:
    """Random sRGB colour (3,) with hue, saturation and value drawn in the given ranges."""
    hh, ss, vv = rng.uniform(h[0], h[1]) % 1.0, rng.uniform(*s), rng.uniform(*v)
    return np.array(colorsys.hsv_to_rgb(hh, ss, vv), dtype=np.float32)


def _neutral(rng: np.random.Generator, v: tuple[float, float], s_max: float = 0.25) -> np.ndarray:
    """A paint-like low-saturation colour."""
    return _hsv(rng, (0.0, 1.0), (0.0, s_max), v)


def _wood_colour(rng: np.random.Generator) -> np.ndarray:
    return _hsv(rng, (0.04, 0.11), (0.35, 0.7), (0.3, 0.8))


def _metal_colour(rng: np.random.Generator) -> np.ndarray:
    kind = rng.integers(3)
    if kind == 0:  # steel / aluminium
        return np.full(3, rng.uniform(0.55, 0.8), dtype=np.float32)
    if kind == 1:  # dark
        return np.full(3, rng.uniform(0.08, 0.2), dtype=np.float32)
    return _hsv(rng, (0.1, 0.14), (0.4, 0.6), (0.55, 0.75))  # brass


def _divisor(size: int, limit: float) -> int:
    """Largest divisor of size that is <= limit (at least 1)."""
    return max(k for k in range(1, max(1, int(limit)) + 1) if size % k == 0)


def _noise(rng: np.random.Generator, h: int, w: int, sigma: tuple[float, float]) -> np.ndarray:
    """Periodic smooth noise, zero mean and unit std (Gaussian-filtered white noise).

    Smooth fields are made on a coarser grid (a divisor of the size, so the result still
    tiles), blurred with wrap-around borders and upsampled bilinearly.

    Args:
        rng: random generator.
        h, w: output size (pixels).
        sigma: (sigma_rows, sigma_cols) correlation length in pixels.

    Returns:
        (h, w) float32 noise that tiles seamlessly in both directions.
    """
    dy, dx = _divisor(h, sigma[0] / 2), _divisor(w, sigma[1] / 2)
    hs, ws = h // dy, w // dx
    sy, sx = max(sigma[0] / dy, 0.3), max(sigma[1] / dx, 0.3)
    py, px = min(hs, int(np.ceil(4 * sy)) + 1), min(ws, int(np.ceil(4 * sx)) + 1)
    white = rng.random((hs, ws), dtype=np.float32)
    n = cv2.GaussianBlur(np.pad(white, ((py, py), (px, px)), mode="wrap"), (0, 0), sigmaX=sx,
                         sigmaY=sy, borderType=cv2.BORDER_REFLECT)[py:py + hs, px:px + ws]
    n = n - n.mean()
    n /= n.std() + 1e-12
    if dy > 1 or dx > 1:  # wrap-pad one sample, upsample, crop: keeps the period exact
        up = cv2.resize(np.pad(n, 1, mode="wrap"), ((ws + 2) * dx, (hs + 2) * dy),
                        interpolation=cv2.INTER_LINEAR)
        n = up[dy:dy + h, dx:dx + w]
    return np.ascontiguousarray(n, dtype=np.float32)


def _speckle(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """(h, w) float32 white noise with zero mean and unit std (uniform, cheap)."""
    return (rng.random((h, w), dtype=np.float32) - np.float32(0.5)) * np.float32(12**0.5)


def _to_linear(img: np.ndarray) -> np.ndarray:
    """Quantize an sRGB float image to 8 bits (like any texture file) and linearize it.

    Args:
        img: (H, W, 3) float32 sRGB values (clipped to [0, 1]).

    Returns:
        (H, W, 3) float32 linear values in [0, 1].
    """
    u8 = cv2.convertScaleAbs(np.maximum(img, 0), alpha=255.0)  # rounds, saturates to 0..255
    return cv2.LUT(u8, LINEAR_LUT)


def _c(colour: np.ndarray | float) -> np.ndarray:
    """A colour (3,) as a (3, 1, 1) float32 array that broadcasts over a (3, H, W) image."""
    return np.broadcast_to(np.asarray(colour, dtype=np.float32), (3,)).reshape(3, 1, 1)


def _solid(colour: np.ndarray, factor: np.ndarray | float, shape: tuple[int, int]
           ) -> np.ndarray:
    """(3, H, W) float32 image of one colour times a brightness factor ((H, W) or scalar)."""
    f = np.broadcast_to(np.asarray(factor, dtype=np.float32), shape)
    return f[None] * _c(colour)


def _fill(img: np.ndarray, mask: np.ndarray, colour: np.ndarray) -> None:
    """Set the pixels of an (H, W) mask (bool, or [0, 1] weights) to a colour, in place.

    img is (3, H, W); channel-first keeps masked writes fast.
    """
    if mask.dtype == bool:
        np.copyto(img, _c(colour), where=mask[None])
    else:
        img += mask[None].astype(np.float32) * (_c(colour) - img)


def _fill_grid(img: np.ndarray, rows: np.ndarray, cols: np.ndarray, colour: np.ndarray) -> None:
    """Set whole rows ((H,) bool) and whole columns ((W,) bool) of (3, H, W) to a colour."""
    c = _c(colour)
    img[:, np.asarray(rows).reshape(-1)] = c
    img[:, :, np.asarray(cols).reshape(-1)] = c


def _box(img: np.ndarray, r0: float, c0: float, r1: float, c1: float
         ) -> tuple[int, int, int, int]:
    h, w = img.shape[1:]
    return (min(max(round(r0), 0), h), min(max(round(c0), 0), w),
            min(max(round(r1), 0), h), min(max(round(c1), 0), w))


def _rect(img: np.ndarray, r0: float, c0: float, r1: float, c1: float,
          colour: np.ndarray, outline: int = 0) -> None:
    """Fill pixel rows [r0, r1) and columns [c0, c1) (clipped) of (3, H, W) with a colour.

    outline > 0 draws only a border that many pixels wide.
    """
    r0, c0, r1, c1 = _box(img, r0, c0, r1, c1)
    if r1 <= r0 or c1 <= c0:
        return
    c = _c(colour)
    if outline <= 0:
        img[:, r0:r1, c0:c1] = c
        return
    t = outline
    img[:, r0:min(r0 + t, r1), c0:c1] = c
    img[:, max(r1 - t, r0):r1, c0:c1] = c
    img[:, r0:r1, c0:min(c0 + t, c1)] = c
    img[:, r0:r1, max(c1 - t, c0):c1] = c


def _circle(img: np.ndarray, row: float, col: float, radius: float, colour: np.ndarray) -> None:
    """Filled disc on a (3, H, W) image."""
    mask = np.zeros(img.shape[1:], np.uint8)
    cv2.circle(mask, (round(col), round(row)), max(1, round(radius)), 1, -1)
    _fill(img, mask.view(bool), colour)


def _polyline(img: np.ndarray, pts: np.ndarray, colour: np.ndarray, thickness: int) -> None:
    """Anti-aliased open polyline through (K, 2) [col, row] points on a (3, H, W) image."""
    mask = np.zeros(img.shape[1:], np.uint8)
    cv2.polylines(mask, [np.round(pts).astype(np.int32)], False, 255, thickness, cv2.LINE_AA)
    _fill(img, mask.astype(np.float32) / 255.0, colour)


def _text(img: np.ndarray, text: str, r0: float, c0: float, r1: float, c1: float,
          colour: np.ndarray) -> None:
    """Write text (anti-aliased, centred) into the pixel box [r0, r1) x [c0, c1)."""
    r0, c0, r1, c1 = _box(img, r0, c0, r1, c1)
    bh, bw = r1 - r0, c1 - c0
    if bh < 4 or bw < 4:
        return
    font = cv2.FONT_HERSHEY_SIMPLEX
    (tw, th), base = cv2.getTextSize(text, font, 1.0, 2)
    scale = min(0.85 * bw / tw, 0.7 * bh / (th + base))
    thickness = max(1, round(2 * scale))
    (tw, th), base = cv2.getTextSize(text, font, scale, thickness)
    mask = np.zeros((bh, bw), np.uint8)
    org = (int((bw - tw) / 2), int((bh + th) / 2))
    cv2.putText(mask, text, org, font, scale, 255, thickness, cv2.LINE_AA)
    _fill(img[:, r0:r1, c0:c1], mask.astype(np.float32) / 255.0, colour)


def _text_bars(img: np.ndarray, rng: np.random.Generator, r0: float, c0: float, r1: float,
               c1: float, colour: np.ndarray, line_px: float) -> None:
    """Rows of text-like bars (lines of 'print') inside a pixel box."""
    pitch = max(2.0, 2.0 * line_px)
    rows = np.arange(r0, r1 - line_px, pitch)
    for r in rows:
        length = (c1 - c0) * rng.uniform(0.4, 1.0)
        # break the line into words
        gaps = np.sort(rng.uniform(c0, c0 + length, size=rng.integers(0, 5)))
        starts = np.concatenate([[c0], gaps + max(1.0, line_px)])
        ends = np.concatenate([gaps, [c0 + length]])
        for a, b in zip(starts, ends, strict=True):
            _rect(img, r, a, r + max(1.0, line_px), b, colour)
