"""Seeded appearance randomization: procedural textures, materials and ceiling lights.

Textures are what the localizer has to learn to ignore, so they are made of strong image
edges that are not model edges: tile grout, plank seams, carpet-tile seams, ceiling T-bars,
skirting boards, dado rails, posters, signs, door panels, handles and window mullions.

Every texture is a ``(R, R, 3)`` float32 array of *linear* RGB values in [0, 1] (reflectance,
or emitted radiance for ``window``), row 0 at the TOP of the surface (highest v) and column
0 at u = 0. A texture covers ``TEXTURE_SPECS[name]`` metres of its surface (u, v); ``floor``,
``ceiling`` and ``wall`` tile seamlessly along u (and ``floor``/``ceiling`` along v). Each
texture is drawn on a canvas with square pixels (the long side ``R`` pixels) and resized to
``R x R``, so shapes never depend on the random draw and scenes can update textures in place.
"""

from __future__ import annotations

import colorsys
from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any

import cv2
import numpy as np

from core.colour import LINEAR_LUT, srgb_to_linear
from core.config import as_config
from datagen.config import AppearanceConfig

#: name -> (extent_u, extent_v) in metres of surface covered by one copy of the texture.
TEXTURE_SPECS: dict[str, tuple[float, float]] = {
    "floor": (2.0, 2.0),  # repeats; tiles, planks or carpet tiles
    "ceiling": (2.0, 2.0),  # repeats; suspended-ceiling tile grid
    "wall": (4.0, 2.8),  # repeats every 4 m along the wall; v = 0 at the floor, full height
    "door": (0.9, 2.1),  # one door panel, 1:1 (u across, v up)
    "frame": (0.5, 0.5),  # door frame / jamb
    "window": (1.2, 1.0),  # one window, 1:1 (outside view with mullions)
}

FLOOR_STYLES: tuple[str, ...] = ("tiles", "wood", "carpet", "vinyl", "concrete", "terrazzo")
WALL_STYLES: tuple[str, ...] = ("paint", "wallpaper", "block", "brick", "panels", "tiles")
CEILING_STYLES: tuple[str, ...] = ("tiles", "plaster")
DOOR_STYLES: tuple[str, ...] = ("wood", "painted")
SIGN_WORDS: tuple[str, ...] = (
    "EXIT", "FIRE EXIT", "WC", "LAB", "OFFICE", "STAIRS", "MEETING", "NO SMOKING",
    "PRIVATE", "KITCHEN", "SERVER", "LIFT", "INFO", "PUSH", "STAFF ONLY",
)  # fmt: skip
_LUMA = np.array([0.2126, 0.7152, 0.0722])


# --------------------------------------------------------------------------- config helpers


def _range(value: Sequence[float], key: str) -> tuple[float, float]:
    """A [min, max] pair of the appearance config (``key``, for messages)."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError) as err:
        raise ValueError(f"appearance.{key} must be a [min, max] pair, got {value!r}") from err
    if hi < lo:
        raise ValueError(f"appearance.{key} = [{lo}, {hi}] has max < min; swap them")
    return lo, hi


def _probs(table: Mapping[str, float], key: str, names: tuple[str, ...]) -> np.ndarray:
    """Normalized probabilities of ``names`` from the appearance config's ``key`` table."""
    unknown = set(table) - set(names)
    if unknown:
        raise ValueError(f"appearance.{key} has unknown entries {sorted(unknown)}; "
                         f"use {list(names)}")
    p = np.array([float(table.get(n, 0.0)) for n in names])
    if (p < 0).any() or p.sum() <= 0:
        raise ValueError(f"appearance.{key} must be non-negative with a positive sum, "
                         f"got {dict(table)}")
    return p / p.sum()


def _chance(rng: np.random.Generator, cfg: AppearanceConfig, key: str) -> bool:
    """True with the probability ``appearance.prob.<key>``."""
    return bool(rng.random() < getattr(cfg.prob, key))


def _maybe(rng: np.random.Generator, p: float, key: str) -> bool:
    """True with the probability p (``appearance.<key>``); p = 0 draws nothing, so a setting
    that is off leaves the random sequence of the rest unchanged."""
    p = float(p)
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"appearance.{key} = {p} is a probability; give a value in [0, 1]")
    return p > 0.0 and bool(rng.random() < p)


def _style(rng: np.random.Generator, table: Mapping[str, float], key: str,
           names: tuple[str, ...]) -> str:
    """A style drawn from the ``appearance.<key>`` table; none drawn (no random number used)
    when the first name, today's style, has all the weight."""
    p = _probs(table, key, names)
    if p[0] == 1.0:
        return names[0]
    return names[rng.choice(len(names), p=p)]


# --------------------------------------------------------------------------- colour & noise


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


# --------------------------------------------------------------------------- textures


def _floor(rng: np.random.Generator, n: int, cfg: AppearanceConfig) -> np.ndarray:
    """Floor texture covering 2 x 2 m (n x n px), periodic in u and v."""
    p = _probs(cfg.floor_styles, "floor_styles", FLOOR_STYLES)
    style = FLOOR_STYLES[rng.choice(len(FLOOR_STYLES), p=p)]
    px_m = n / TEXTURE_SPECS["floor"][0]
    y = np.arange(n, dtype=np.float32)[:, None]  # (n, 1) rows
    x = np.arange(n, dtype=np.float32)[None, :]  # (1, n) columns
    if style == "tiles":
        k = int(rng.choice([3, 4, 5, 6, 8]))  # tiles per 2 m
        tile = n / k
        iv, iu = (y // tile).astype(np.intp) % k, (x // tile).astype(np.intp) % k
        a = _neutral(rng, (0.45, 0.9), 0.3)
        b = np.clip(a * rng.uniform(0.35, 0.7) + rng.uniform(0, 0.15, 3), 0, 1)
        pattern = rng.integers(3)
        if pattern == 0:  # checkerboard
            which = (np.add.outer(np.arange(k), np.arange(k)) % 2).astype(bool)
        elif pattern == 1:  # random mix of two tones
            which = rng.random((k, k)) < 0.3
        else:  # one tone with strong per-tile variation
            which = np.zeros((k, k), bool)
        jitter = 1.0 + rng.normal(0.0, 0.1 if pattern == 2 else 0.05, (k, k))
        tile_rgb = (np.where(which[..., None], b, a) * jitter[..., None]).astype(np.float32)
        tile_rgb = np.ascontiguousarray(tile_rgb.transpose(2, 0, 1))  # (3, k, k)
        img = tile_rgb[:, iv, iu] * (1.0 + 0.05 * _noise(rng, n, n, (6, 6))
                                     + 0.03 * _speckle(rng, n, n))[None]
        gw = max(1.0, rng.uniform(0.004, 0.012) * px_m)
        grout = (_neutral(rng, (0.15, 0.4), 0.1) if rng.random() < 0.7
                 else _neutral(rng, (0.85, 0.95), 0.05))
        _fill_grid(img, (y % tile) < gw, (x % tile) < gw, grout)
    elif style == "wood":
        m = int(rng.choice([8, 10, 12, 16]))  # plank rows per 2 m
        q = int(rng.choice([1, 2]))  # planks per row per 2 m
        pw, pl = n / m, n / q
        row = (y // pw).astype(np.intp) % m  # (n, 1)
        along = (x + rng.uniform(0, pl, m).astype(np.float32)[row]) % n  # (n, n)
        plank = row * q + (along // pl).astype(np.intp) % q
        base = _wood_colour(rng)
        jitter = (1.0 + rng.normal(0.0, 0.12, m * q)).astype(np.float32)
        grain = _noise(rng, n, n, (1.0, 30.0)) + 0.5 * _noise(rng, n, n, (0.6, 8.0))
        shift = rng.integers(0, n, m * q)
        g = grain[np.arange(n)[:, None], (along.astype(np.intp) + shift[plank]) % n]
        img = _solid(base, jitter[plank] * (1 + 0.08 * g), (n, n))
        seam_w = max(1.0, 0.003 * px_m)
        _fill(img, ((y % pw) < seam_w) | ((along % pl) < seam_w), base * rng.uniform(0.25, 0.45))
        if rng.random() < 0.5:  # planks along v instead of u
            img = np.ascontiguousarray(img.transpose(0, 2, 1))
    elif style == "carpet":  # carpet tiles with alternating pile direction and a seam
        k = int(rng.choice([4, 5]))  # 0.5 m or 0.4 m carpet tiles
        tile = n / k
        iv, iu = (y // tile).astype(np.intp) % k, (x // tile).astype(np.intp) % k
        hues = [(0.55, 0.7), (0.03, 0.1), (0.0, 1.0)]
        base = _hsv(rng, hues[rng.integers(len(hues))], (0.05, 0.4), (0.2, 0.55))
        quarter = ((iu + iv) % 2).astype(bool)
        period = max(2.5, rng.uniform(0.008, 0.02) * px_m)
        stripes = np.where(quarter, np.sin(2 * np.pi * x / period),
                           np.sin(2 * np.pi * y / period))
        fuzz = 0.5 * _noise(rng, n, n, (1.2, 1.2)) + 0.5 * _speckle(rng, n, n)
        tile_gain = np.where(quarter, 1.0, rng.uniform(0.7, 0.85)).astype(np.float32)
        img = _solid(base, tile_gain * (1 + 0.12 * stripes + 0.12 * fuzz), (n, n))
        seam_rows, seam_cols = (y % tile) < 1, (x % tile) < 1
        _fill_grid(img, seam_rows, seam_cols, base * 0.4)
        if rng.random() < 0.6:  # accent pattern: a band of a contrasting colour per tile row
            accent = _hsv(rng, (0.0, 1.0), (0.3, 0.8), (0.3, 0.8))
            lo = rng.uniform(0.1, 0.6) * tile
            ly = y % tile
            band = (ly > lo) & (ly < lo + rng.uniform(0.05, 0.2) * tile)
            _fill(img, band & ~seam_rows & ~seam_cols, accent)
    elif style == "vinyl":
        img = _vinyl(rng, n, px_m, y, x)
    elif style == "concrete":
        img = _concrete(rng, n, px_m, y, x)
    else:
        img = _terrazzo(rng, n, px_m, y, x)
    if _maybe(rng, cfg.prob.dark_floor, "prob.dark_floor"):
        img = img * np.float32(rng.uniform(0.15, 0.45))
    return img


def _flecks(rng: np.random.Generator, img: np.ndarray, n: int, sigma: float | None,
            share: float, colour: np.ndarray) -> None:
    """Scatter periodic flecks (blobs of about sigma px; None: single pixels) of one colour
    over a share of the (3, n, n) image, in place."""
    field = _speckle(rng, n, n) if sigma is None else _noise(rng, n, n, (sigma, sigma))
    _fill(img, field > np.quantile(field, 1.0 - share), colour)


def _vinyl(rng: np.random.Generator, n: int, px_m: float, y: np.ndarray, x: np.ndarray
           ) -> np.ndarray:
    """Sheet vinyl, 2 x 2 m (n x n px): plain or flecked, welded seams every 1 or 2 m (along
    u or v), sometimes an inlaid border strip; periodic."""
    base = (_hsv(rng, (0.0, 1.0), (0.15, 0.6), (0.3, 0.8)) if rng.random() < 0.4
            else _neutral(rng, (0.25, 0.85), 0.15))
    img = _solid(base, 1 + 0.03 * _noise(rng, n, n, (12, 12)) + 0.02 * _speckle(rng, n, n),
                 (n, n))
    if rng.random() < 0.6:  # flecked: two fleck colours, a few % of the surface each
        for _ in range(2):
            tone = np.clip(base * rng.uniform(0.3, 1.6) + rng.uniform(-0.1, 0.1, 3), 0, 1)
            _flecks(rng, img, n, None, rng.uniform(0.01, 0.05), tone)
    sheet = n / int(rng.choice([1, 2]))  # a 2 m or 1 m wide roll
    weld = max(1.0, 0.004 * px_m)
    seam = (y % sheet) < weld
    if rng.random() < 0.5:
        _fill_grid(img, seam[:, 0], np.zeros(n, bool), base * rng.uniform(0.3, 0.6))
    else:
        _fill_grid(img, np.zeros(n, bool), seam[:, 0], base * rng.uniform(0.3, 0.6))
    if rng.random() < 0.3:  # an inlaid border strip of a contrasting colour
        width = rng.uniform(0.05, 0.15) * px_m
        at = rng.uniform(0, n - width)
        _rect(img, at, 0, at + width, n, _hsv(rng, (0.0, 1.0), (0.3, 0.9), (0.2, 0.8)))
    return img


def _concrete(rng: np.random.Generator, n: int, px_m: float, y: np.ndarray, x: np.ndarray
              ) -> np.ndarray:
    """Polished concrete, 2 x 2 m: mottled grey, exposed aggregate specks, dark saw cuts every
    1 or 2 m (or 0.67 m), sometimes a sealed (tinted) finish; periodic."""
    base = _neutral(rng, (0.35, 0.75), 0.08)
    if rng.random() < 0.25:  # tinted sealer
        base = np.clip(base * _hsv(rng, (0.0, 1.0), (0.1, 0.4), (0.85, 1.0)), 0, 1)
    mottle = (0.08 * _noise(rng, n, n, (30, 30)) + 0.05 * _noise(rng, n, n, (6, 6))
              + 0.03 * _speckle(rng, n, n))
    img = _solid(base, 1 + mottle, (n, n))
    _flecks(rng, img, n, 0.7, rng.uniform(0.01, 0.05), base * rng.uniform(0.5, 0.8))
    _flecks(rng, img, n, 0.7, rng.uniform(0.005, 0.02), np.clip(base * 1.3, 0, 1))
    k = int(rng.choice([1, 2, 3]))  # saw-cut joints per 2 m
    cut = max(1.0, 0.005 * px_m)
    _fill_grid(img, (y[:, 0] % (n / k)) < cut, (x[0] % (n / k)) < cut,
               base * rng.uniform(0.2, 0.45))
    return img


def _terrazzo(rng: np.random.Generator, n: int, px_m: float, y: np.ndarray, x: np.ndarray
              ) -> np.ndarray:
    """Terrazzo, 2 x 2 m: a light or coloured matrix with chips of 2-4 colours, sometimes
    brass or zinc divider strips every 1 or 2 m; periodic."""
    matrix = (_neutral(rng, (0.55, 0.9), 0.12) if rng.random() < 0.7
              else _hsv(rng, (0.0, 1.0), (0.2, 0.6), (0.3, 0.8)))
    img = _solid(matrix, 1 + 0.03 * _noise(rng, n, n, (10, 10)), (n, n))
    for _ in range(int(rng.integers(2, 5))):
        chip = (_neutral(rng, (0.05, 0.95), 0.2) if rng.random() < 0.6
                else _hsv(rng, (0.0, 1.0), (0.3, 0.8), (0.2, 0.8)))
        _flecks(rng, img, n, rng.uniform(0.6, 2.5) * max(1.0, px_m / 128),
                rng.uniform(0.03, 0.12), chip)
    if rng.random() < 0.6:
        k = int(rng.choice([1, 2]))
        strip = max(1.0, 0.004 * px_m)
        _fill_grid(img, (y[:, 0] % (n / k)) < strip, (x[0] % (n / k)) < strip,
                   _metal_colour(rng))
    return img


def _ceiling(rng: np.random.Generator, n: int, cfg: AppearanceConfig) -> np.ndarray:
    """Suspended ceiling covering 2 x 2 m: tiles, T-bar grid, vents, stains; periodic."""
    px_m = n / TEXTURE_SPECS["ceiling"][0]
    y = np.arange(n, dtype=np.float32)[:, None]
    x = np.arange(n, dtype=np.float32)[None, :]
    if _style(rng, cfg.ceiling_styles, "ceiling_styles", CEILING_STYLES) == "plaster":
        return _plaster(rng, n, px_m, y, x)
    k = int(rng.choice([2, 3, 4]))
    tile = n / k
    colour = _neutral(rng, (0.75, 0.95), 0.06)
    fissures = np.clip(_noise(rng, n, n, (0.8, 0.8)) - 1.2, 0, None)
    img = _solid(colour, 1 - 0.15 * fissures - 0.02 * _noise(rng, n, n, (20, 20)), (n, n))
    ly, lx = y % tile, x % tile
    if _chance(rng, cfg, "ceiling_vent"):  # a ventilation grille tile
        vi, vu = rng.integers(k, size=2)
        inset = 0.15 * tile
        in_y = ((y // tile).astype(np.intp) % k == vi) & (ly > inset) & (ly < tile - inset)
        in_x = ((x // tile).astype(np.intp) % k == vu) & (lx > inset) & (lx < tile - inset)
        slats = (ly // max(2.0, 0.02 * px_m)) % 2 == 0
        _fill(img, in_y & in_x, colour * 0.8)
        _fill(img, in_y & in_x & slats, colour * 0.35)
    if _chance(rng, cfg, "ceiling_stain"):
        cy, cx = rng.uniform(0, n, 2)
        r = rng.uniform(0.05, 0.2) * px_m
        blob = np.clip(1.5 - np.hypot(y - cy, x - cx) / r + 0.3 * _noise(rng, n, n, (4, 4)),
                       0, 1)
        _fill(img, blob * 0.6, _hsv(rng, (0.08, 0.12), (0.3, 0.6), (0.4, 0.7)))
    bar_w = max(2.0, rng.uniform(0.015, 0.03) * px_m)
    bar_colour = (_neutral(rng, (0.9, 1.0), 0.03) if rng.random() < 0.5
                  else _neutral(rng, (0.25, 0.6), 0.05))
    lip = max(1.0, 0.25 * bar_w)
    _fill_grid(img, (ly >= bar_w) & (ly < bar_w + lip), (lx >= bar_w) & (lx < bar_w + lip),
               colour * 0.55)
    _fill_grid(img, ly < bar_w, lx < bar_w, bar_colour)
    return img


def _plaster(rng: np.random.Generator, n: int, px_m: float, y: np.ndarray, x: np.ndarray
             ) -> np.ndarray:
    """Plain plasterboard ceiling, 2 x 2 m: painted, faint board seams every 1.2 m-ish (1 or
    2 per 2 m, one direction), sometimes an access hatch or a round fitting; periodic."""
    colour = _neutral(rng, (0.75, 0.97), 0.05)
    img = _solid(colour, 1 + 0.015 * _noise(rng, n, n, (30, 30)) + 0.01 * _speckle(rng, n, n),
                 (n, n))
    seams = (y[:, 0] % (n / int(rng.choice([1, 2])))) < max(1.0, 0.004 * px_m)
    tone = colour * rng.uniform(0.8, 0.93)
    if rng.random() < 0.5:
        _fill_grid(img, seams, np.zeros(n, bool), tone)
    else:
        _fill_grid(img, np.zeros(n, bool), seams, tone)
    if rng.random() < 0.5:  # access hatch, 0.6 m square
        side = 0.6 * px_m
        r0, c0 = rng.uniform(0.05 * n, n - side - 0.05 * n, 2)
        _rect(img, r0, c0, r0 + side, c0 + side, colour * 0.6, outline=max(1, round(0.01 * px_m)))
    if rng.random() < 0.4:  # a round vent or detector
        cy, cx = rng.uniform(0.1 * n, 0.9 * n, 2)
        rad = rng.uniform(0.05, 0.12) * px_m
        _circle(img, cy, cx, rad, _neutral(rng, (0.5, 0.95), 0.05))
        _circle(img, cy, cx, 0.6 * rad, colour * rng.uniform(0.3, 0.7))
    return img


def _poster(img: np.ndarray, rng: np.random.Generator, px_m: float) -> None:
    """Draw a poster, sign, notice, pin board or whiteboard filling img (in place)."""
    h, w = img.shape[1:]
    kind = rng.choice(["photo", "notice", "sign", "board", "whiteboard"])
    line = max(1.0, 0.008 * px_m)
    if kind == "photo":
        top, bottom = _hsv(rng, (0, 1), (0.2, 0.9), (0.2, 1.0)), _hsv(rng, (0, 1), (0.2, 0.9),
                                                                       (0.1, 0.8))
        t = np.linspace(0, 1, h, dtype=np.float32)[None, :, None]
        img[:] = _c(top) * (1 - t) + _c(bottom) * t
        for _ in range(rng.integers(2, 7)):
            colour = _hsv(rng, (0, 1), (0.3, 1.0), (0.1, 1.0))
            r0, c0 = rng.uniform(0, h), rng.uniform(0, w)
            if rng.random() < 0.5:
                _rect(img, r0, c0, r0 + rng.uniform(0.1, 0.5) * h, c0 + rng.uniform(0.1, 0.5) * w,
                      colour)
            else:
                _circle(img, r0, c0, rng.uniform(0.05, 0.3) * min(h, w) + 1, colour)
        if rng.random() < 0.6:  # a caption
            _rect(img, 0.8 * h, 0, h, w, _neutral(rng, (0.0, 1.0), 0.1))
            _text(img, str(rng.choice(SIGN_WORDS)), 0.8 * h, 0.05 * w, h, 0.95 * w,
                  _neutral(rng, (0.0, 1.0), 0.8))
        _rect(img, 0, 0, h, w, _metal_colour(rng), outline=max(1, round(1.5 * line)))
    elif kind == "notice":
        img[:] = _c(_neutral(rng, (0.85, 1.0), 0.1))
        head = _hsv(rng, (0, 1), (0.5, 1.0), (0.3, 0.9))
        _rect(img, 0, 0, 0.2 * h, w, head)
        _text(img, str(rng.choice(SIGN_WORDS)), 0.02 * h, 0.05 * w, 0.18 * h, 0.95 * w,
              np.ones(3, np.float32) if head.mean() < 0.5 else np.zeros(3, np.float32))
        _text_bars(img, rng, 0.27 * h, 0.08 * w, 0.92 * h, 0.92 * w, np.full(3, 0.1, np.float32),
                   line)
    elif kind == "sign":
        plate = _hsv(rng, (0, 1), (0.6, 1.0), (0.35, 0.8)) if rng.random() < 0.7 else \
            np.full(3, 0.95, np.float32)
        img[:] = _c(plate)
        ink = np.ones(3, np.float32) if plate.mean() < 0.6 else np.zeros(3, np.float32)
        word = str(rng.choice(SIGN_WORDS)) if rng.random() < 0.6 else \
            f"{rng.choice(list('ABCD'))}-{rng.integers(100, 400)}"
        _text(img, word, 0.1 * h, 0.05 * w, 0.9 * h, 0.95 * w, ink)
        _rect(img, 0, 0, h, w, ink, outline=max(1, round(line)))
    elif kind == "board":
        cork = _hsv(rng, (0.06, 0.1), (0.4, 0.6), (0.45, 0.7))
        img[:] = _c(cork) * (1 + 0.12 * _speckle(rng, h, w))[None]
        for _ in range(rng.integers(3, 9)):
            ph, pw = rng.uniform(0.15, 0.4) * h, rng.uniform(0.15, 0.35) * w
            r0, c0 = rng.uniform(0, h - ph), rng.uniform(0, w - pw)
            _rect(img, r0, c0, r0 + ph, c0 + pw, _neutral(rng, (0.8, 1.0), 0.3))
            _text_bars(img, rng, r0 + 0.15 * ph, c0 + 0.1 * pw, r0 + 0.9 * ph, c0 + 0.9 * pw,
                       np.full(3, 0.15, np.float32), max(1.0, 0.6 * line))
        _rect(img, 0, 0, h, w, _wood_colour(rng), outline=max(2, round(2.5 * line)))
    else:  # whiteboard with marker scribbles
        img[:] = np.float32(rng.uniform(0.85, 0.97))
        for _ in range(rng.integers(2, 8)):
            pts = np.stack([rng.uniform(0.1, 0.9, 6) * w, rng.uniform(0.1, 0.9, 6) * h], 1)
            ink = _hsv(rng, rng.choice([(0.55, 0.7), (0.95, 1.0), (0.3, 0.4)]), (0.6, 1.0),
                       (0.1, 0.6))
            _polyline(img, pts, ink, max(1, round(line)))
        _rect(img, 0, 0, h, w, np.full(3, 0.7, np.float32), outline=max(2, round(2 * line)))


def _wall_cover(rng: np.random.Generator, style: str, paint: np.ndarray, uu: np.ndarray,
                vv: np.ndarray, eu: float) -> np.ndarray:
    """A wall covering of the full height: wallpaper, painted concrete block or brick.

    Args:
        style: 'wallpaper', 'block' or 'brick'.
        paint: (3,) the wall's sRGB colour (wallpaper ground, block paint).
        uu: (1, w) metres along the wall; vv: (h, 1) metres above the floor.
        eu: metres of wall one texture covers (patterns repeat an integer number of times).

    Returns:
        (3, h, w) float32 sRGB.
    """
    h, w = vv.shape[0], uu.shape[1]
    px = float(uu[0, 1] - uu[0, 0])  # metres per pixel: joints and lines are >= 1 px wide
    if style == "wallpaper":
        img = _solid(paint, 1 + 0.015 * _speckle(rng, h, w), (h, w))
        second = (np.clip(paint * rng.uniform(0.55, 0.9) + rng.uniform(-0.08, 0.08, 3), 0, 1)
                  if rng.random() < 0.6 else _hsv(rng, (0.0, 1.0), (0.2, 0.7), (0.3, 0.9)))
        kind = int(rng.integers(3))
        if kind < 2:  # broad stripes or pinstripes
            pitch = eu / max(1, round(eu / rng.uniform(0.04, 0.3)))
            duty = rng.uniform(0.25, 0.6) if kind == 0 else rng.uniform(0.04, 0.12)
            mask = np.broadcast_to((uu % pitch) < max(duty * pitch, px), (h, w))
        else:  # a small repeating motif (dots or diamonds), half-drop
            pu = eu / max(1, round(eu / rng.uniform(0.06, 0.25)))
            pv = rng.uniform(0.06, 0.25)
            col = (uu // pu) % 2
            du = (uu % pu) / pu - 0.5
            dv = ((vv + col * pv / 2) % pv) / pv - 0.5
            r = rng.uniform(0.15, 0.35)
            mask = (np.abs(du) + np.abs(dv) < r) if rng.random() < 0.5 else (du**2 + dv**2 < r**2)
        _fill(img, mask, second)
        return img
    # block: 0.4 x 0.2 m, brick: 0.225 x 0.075 m; running bond
    course, length, joint = ((0.2, 0.4, rng.uniform(0.008, 0.014)) if style == "block"
                             else (0.075, 0.225, rng.uniform(0.008, 0.012)))
    count = max(1, round(eu / length))
    bw = eu / count
    ri = (vv // course).astype(np.intp)  # (h, 1) course index from the floor
    shifted = uu + (ri % 2) * (bw / 2)  # (h, w) m along the wall, every other course by half
    if style == "block":  # painted (joints shaded)
        base = paint if rng.random() < 0.8 else _neutral(rng, (0.35, 0.65), 0.05)
        rough = 0.04 * _noise(rng, h, w, (1.0, 1.0)) + 0.04 * _speckle(rng, h, w)
        img = _solid(base, 1 + rough, (h, w))
        mortar = base * rng.uniform(0.55, 0.8)
    else:  # brick: per-brick colour, light mortar
        base = (_hsv(rng, (0.0, 0.07), (0.4, 0.75), (0.3, 0.65)) if rng.random() < 0.7
                else _neutral(rng, (0.75, 0.95), 0.05))  # red-brown or painted
        ci = (shifted // bw).astype(np.intp) % count
        jitter = (1 + rng.normal(0, 0.12, (int(ri.max()) + 1, count))).astype(np.float32)
        img = _solid(base, jitter[ri, ci] * (1 + 0.05 * _speckle(rng, h, w)), (h, w))
        mortar = _neutral(rng, (0.45, 0.8), 0.08)
    joint = max(joint, px)
    _fill(img, ((vv % course) < joint) | ((shifted % bw) < joint), mortar)
    return img


def _wall_lower(rng: np.random.Generator, img: np.ndarray, style: str, uu: np.ndarray,
                vv: np.ndarray, eu: float, ev: float) -> None:
    """Wood or laminate panelling, or glazed wall tiles, from the floor to a height (or the
    full height), over (3, h, w) img in place (uu, vv, eu as for ``_wall_cover``)."""
    h, w = vv.shape[0], uu.shape[1]
    px = float(uu[0, 1] - uu[0, 0])  # metres per pixel: grooves and grout are >= 1 px wide
    full = rng.random() < 0.4
    if style == "panels":
        top = ev if full else rng.uniform(0.9, 1.5)
        pitch = eu / max(1, round(eu / rng.uniform(0.12, 0.6)))
        if rng.random() < 0.6:  # wood
            colour = _wood_colour(rng)
            grain = _noise(rng, h, w, (40.0, 0.8)) + 0.5 * _noise(rng, h, w, (12.0, 0.5))
            cover = _solid(colour, 1 + 0.1 * grain, (h, w))
        else:  # laminate
            colour = (_neutral(rng, (0.4, 0.95), 0.15) if rng.random() < 0.6
                      else _hsv(rng, (0.0, 1.0), (0.2, 0.6), (0.3, 0.8)))
            cover = _solid(colour, 1 + 0.01 * _speckle(rng, h, w), (h, w))
        groove = max(rng.uniform(0.004, 0.01), px)
        _fill(cover, np.broadcast_to((uu % pitch) < groove, (h, w)), colour * 0.35)
        cap = (vv >= top - 0.04) & (vv < top)
        _fill(cover, np.broadcast_to(cap, (h, w)), colour * rng.uniform(0.5, 0.8))
    else:  # glazed wall tiles, 0.1-0.2 m squares, grout lines, sometimes a coloured band
        top = ev if full else rng.uniform(1.2, 2.1)
        size = float(rng.choice([0.1, 0.15, 0.2]))
        count = max(1, round(eu / size))
        su = eu / count
        colour = (_neutral(rng, (0.75, 0.97), 0.08) if rng.random() < 0.6
                  else _hsv(rng, (0.0, 1.0), (0.1, 0.45), (0.55, 0.95)))
        ri = (vv // size).astype(np.intp)
        ci = (uu // su).astype(np.intp) % count
        jitter = (1 + rng.normal(0, 0.03, (int(ri.max()) + 1, count))).astype(np.float32)
        cover = _solid(colour, jitter[ri, ci] * (1 + 0.01 * _speckle(rng, h, w)), (h, w))
        if rng.random() < 0.4:  # a band of coloured tiles
            band = int(rng.integers(0, max(1, int(top / size))))
            _fill(cover, np.broadcast_to(ri == band, (h, w)),
                  _hsv(rng, (0.0, 1.0), (0.4, 0.9), (0.2, 0.8)))
        grout = max(rng.uniform(0.003, 0.006), px)
        _fill(cover, ((vv % size) < grout) | ((uu % su) < grout),
              _neutral(rng, (0.35, 0.85), 0.05))
    r = int(np.searchsorted(-vv[:, 0], -top))  # first row at or below the top (vv falls)
    img[:, r:] = cover[:, r:]


def _wall(rng: np.random.Generator, n: int, cfg: AppearanceConfig,
          extent: tuple[float, float]) -> np.ndarray:
    """Wall covering 4 m (u, periodic) x full height (v up from the floor)."""
    eu, ev = extent
    px_m = n / max(eu, ev)
    w, h = round(eu * px_m), round(ev * px_m)

    def row(v: float) -> float:  # v in metres above the floor -> canvas row
        return h - v * px_m

    paint = _neutral(rng, (0.55, 0.95), 0.35)
    img = _solid(paint, 1 + 0.02 * _noise(rng, h, w, (25, 25)) + 0.015 * _speckle(rng, h, w),
                 (h, w))
    style = _style(rng, cfg.wall_styles, "wall_styles", WALL_STYLES)
    if _maybe(rng, cfg.prob.accent_wall, "prob.accent_wall"):
        paint = _hsv(rng, (0.0, 1.0), (0.45, 0.95), (0.3, 0.85))
        img = _solid(paint, 1 + 0.015 * _speckle(rng, h, w), (h, w))
    uu = np.arange(w, dtype=np.float32)[None, :] / np.float32(px_m)  # (1, w) m along the wall
    vv = (h - np.arange(h, dtype=np.float32)[:, None]) / np.float32(px_m)  # (h, 1) m up
    if style in ("wallpaper", "block", "brick"):
        img = _wall_cover(rng, style, paint, uu, vv, eu)

    dado = rng.uniform(0.8, 1.05)
    if _chance(rng, cfg, "two_tone"):
        lower = np.clip(paint * rng.uniform(0.4, 0.8) + rng.uniform(-0.1, 0.1, 3), 0, 1)
        _rect(img, row(dado), 0, h, w, lower)
    if _chance(rng, cfg, "dado"):
        _rect(img, row(dado + rng.uniform(0.03, 0.07)), 0, row(dado), w,
              _wood_colour(rng) if rng.random() < 0.5 else _neutral(rng, (0.1, 1.0), 0.2))
    if style in ("panels", "tiles"):
        _wall_lower(rng, img, style, uu, vv, eu, ev)
    skirt_h = rng.uniform(0.06, 0.15)
    skirt = (_wood_colour(rng) if rng.random() < 0.3 else
             _neutral(rng, (0.05, 0.3), 0.2) if rng.random() < 0.7 else
             np.clip(paint * 0.5, 0, 1))
    _rect(img, row(skirt_h), 0, h, w, skirt)
    _rect(img, row(skirt_h), 0, row(skirt_h) + max(1.0, 0.008 * px_m), w, skirt * 0.5)
    # posters and signs between 1.0 and 2.0 m, left to right without overlap or wrap-around
    pmin, pmax = cfg.posters
    count = int(rng.integers(pmin, pmax + 1))
    widths = rng.uniform(0.3, 0.9, count)
    while count and widths.sum() + 0.2 * (count + 1) > eu:
        count -= 1
        widths = widths[:count]
    gaps = rng.dirichlet(np.ones(count + 1)) * (eu - widths.sum() - 0.2 * (count + 1)) + 0.2
    u = gaps[0]
    for i in range(count):
        ph = rng.uniform(0.2, 0.9)
        bottom = rng.uniform(1.0, 2.0 - ph)
        r0, r1 = row(bottom + ph), row(bottom)
        c0, c1 = u * px_m, (u + widths[i]) * px_m
        patch = img[:, round(r0):round(r1), round(c0):round(c1)]
        if patch.size:
            _poster(patch, rng, px_m)
        u += widths[i] + gaps[i + 1]
    if _chance(rng, cfg, "sockets"):  # wall sockets and a light switch
        plate = _neutral(rng, (0.85, 1.0), 0.05) if rng.random() < 0.7 else \
            _neutral(rng, (0.1, 0.3), 0.05)
        for v0, size in ((0.3, 0.08), (1.05, 0.085)):
            c = rng.uniform(0.2, eu - 0.3) * px_m
            r = row(v0 + size)
            _rect(img, r, c, r + size * px_m, c + size * px_m, plate)
            _rect(img, r, c, r + size * px_m, c + size * px_m, plate * 0.5, outline=1)
    return img


def _door(rng: np.random.Generator, n: int, cfg: AppearanceConfig,
          extent: tuple[float, float]) -> np.ndarray:
    """One door panel, 1:1 (u across, v up)."""
    eu, ev = extent
    px_m = n / max(eu, ev)
    w, h = max(8, round(eu * px_m)), max(8, round(ev * px_m))

    def row(v: float) -> float:
        return h - v * px_m

    style = DOOR_STYLES[rng.choice(len(DOOR_STYLES), p=_probs(cfg.door_styles, "door_styles",
                                                              DOOR_STYLES))]
    if style == "wood":
        base = _wood_colour(rng)
        grain = _noise(rng, h, w, (40.0, 0.8)) + 0.5 * _noise(rng, h, w, (12.0, 0.5))
        img = _solid(base, 1 + 0.1 * grain, (h, w))
    else:
        base = (_hsv(rng, (0, 1), (0.3, 0.8), (0.25, 0.8)) if rng.random() < 0.5
                else _neutral(rng, (0.3, 0.95), 0.1))
        img = _solid(base, 1 + 0.01 * _speckle(rng, h, w), (h, w))
    bevel = max(1, round(0.01 * px_m))
    if _chance(rng, cfg, "door_panels"):
        layout = [(0.15, 1.9)] if rng.random() < 0.3 else [(0.15, 0.95), (1.1, 1.9)]
        cols = [(0.12, eu - 0.12)] if rng.random() < 0.6 else [(0.1, eu / 2 - 0.04),
                                                                (eu / 2 + 0.04, eu - 0.1)]
        for v0, v1 in layout:
            for u0, u1 in cols:
                r0, r1 = row(v1 * ev / 2.1), row(v0 * ev / 2.1)
                _rect(img, r0, u0 * px_m, r1, u1 * px_m, base * 0.55, outline=bevel)
                _rect(img, r0 + bevel, u0 * px_m + bevel, r1 - bevel, u1 * px_m - bevel,
                      np.clip(base * 1.3, 0, 1), outline=bevel)
    if _chance(rng, cfg, "door_glass"):
        gw = rng.uniform(0.12, 0.35)
        u0 = rng.uniform(0.15, max(0.16, eu - gw - 0.15))
        v1 = min(ev - 0.2, rng.uniform(1.6, 1.95))
        v0 = v1 - rng.uniform(0.4, 0.8)
        r0, r1, c0, c1 = row(v1), row(v0), u0 * px_m, (u0 + gw) * px_m
        rr = np.arange(h, dtype=np.float32)[:, None]
        cc = np.arange(w, dtype=np.float32)[None, :]
        glass = _hsv(rng, (0.5, 0.65), (0.1, 0.4), (0.1, 0.35))
        _rect(img, r0, c0, r1, c1, glass)
        streak = (rr >= r0) & (rr < r1) & (cc >= c0) & (cc < c1) & \
            (np.abs((cc - c0) - 0.6 * (rr - r0) - 0.3 * (c1 - c0)) < 0.12 * (c1 - c0))
        _fill(img, streak, np.clip(glass + 0.25, 0, 1))
        _rect(img, r0, c0, r1, c1, _metal_colour(rng), outline=max(1, round(0.015 * px_m)))
    if _chance(rng, cfg, "kick_plate"):
        plate = _metal_colour(rng)
        _rect(img, row(rng.uniform(0.15, 0.3)), 0.03 * px_m, h, w - 0.03 * px_m, plate)
    if _chance(rng, cfg, "door_number"):
        plate = (_neutral(rng, (0.85, 1.0), 0.05) if rng.random() < 0.5 else _metal_colour(rng))
        pw, ph = rng.uniform(0.12, 0.2), rng.uniform(0.06, 0.1)
        u0, v0 = eu / 2 - pw / 2, rng.uniform(1.45, 1.65) * ev / 2.1
        r0, c0 = row(v0 + ph), u0 * px_m
        _rect(img, r0, c0, r0 + ph * px_m, c0 + pw * px_m, plate)
        ink = np.zeros(3, np.float32) if plate.mean() > 0.4 else np.ones(3, np.float32)
        _text(img, f"{rng.integers(1, 5)}{rng.integers(0, 40):02d}", r0, c0, r0 + ph * px_m,
              c0 + pw * px_m, ink)
    # handle: rose and lever on the latch side at ~1 m
    metal = _metal_colour(rng)
    side = rng.integers(2)
    cu = (0.08 + rng.uniform(0, 0.03)) * px_m
    cu = cu if side == 0 else w - cu
    cv = row(rng.uniform(0.95, 1.08))
    rose = max(2, round(0.03 * px_m))
    _circle(img, cv, cu, rose, metal * 0.6)
    _circle(img, cv, cu, max(1, rose - 1), metal)
    lever = 0.13 * px_m * (1 if side == 0 else -1)
    _rect(img, cv - 0.012 * px_m, min(cu, cu + lever), cv + 0.012 * px_m, max(cu, cu + lever),
          metal)
    _rect(img, cv + 0.07 * px_m, cu - 0.008 * px_m, cv + 0.1 * px_m, cu + 0.008 * px_m,
          metal * 0.4)
    return img


def _frame(rng: np.random.Generator, n: int, door_base: np.ndarray | None) -> np.ndarray:
    """Door frame / jamb: one colour with a little noise."""
    if door_base is not None:
        colour = door_base
    else:
        colour = (_neutral(rng, (0.6, 0.98), 0.08) if rng.random() < 0.4 else _wood_colour(rng)
                  if rng.random() < 0.5 else _metal_colour(rng))
    return _solid(colour, 1 + 0.03 * _noise(rng, n, n, (2.0, 30.0)), (n, n))


def _window(rng: np.random.Generator, n: int, extent: tuple[float, float]) -> np.ndarray:
    """Outside view (sky, clouds, skyline or trees, ground) behind a frame with mullions."""
    eu, ev = extent
    px_m = n / max(eu, ev)
    w, h = max(8, round(eu * px_m)), max(8, round(ev * px_m))
    rr = np.arange(h, dtype=np.float32)[None, :, None]
    horizon = rng.uniform(0.45, 0.75) * h  # row of the horizon
    overcast = rng.random() < 0.35
    zenith = (np.full(3, rng.uniform(0.6, 0.85), np.float32) if overcast
              else _hsv(rng, (0.55, 0.62), (0.35, 0.7), (0.7, 1.0)))
    low = np.clip(zenith + rng.uniform(0.1, 0.3), 0, 1)
    t = np.clip(rr / max(horizon, 1.0), 0, 1)
    img = np.broadcast_to(_c(zenith) * (1 - t) + _c(low) * t, (3, h, w)).copy()
    clouds = np.clip(_noise(rng, h, w, (10, 25)) * 0.7 - rng.uniform(-0.2, 0.8), 0, 1)
    _fill(img, clouds * 0.8, np.full(3, rng.uniform(0.85, 1.0), np.float32))
    ground = _hsv(rng, (0.15, 0.35), (0.1, 0.5), (0.2, 0.5))
    _rect(img, horizon, 0, h, w, ground)
    if rng.random() < 0.6:  # buildings with lit windows
        x = 0.0
        while x < w:
            bw = rng.uniform(0.1, 0.35) * w
            top = horizon - rng.uniform(0.05, 0.45) * h
            colour = _neutral(rng, (0.2, 0.7), 0.2)
            _rect(img, top, x, horizon, x + bw, colour)
            step = max(3.0, 0.04 * px_m)
            for r in np.arange(top + step, horizon - step, 2 * step):
                for c in np.arange(x + step, x + bw - step, 2 * step):
                    _rect(img, r, c, r + step, c + step, colour * rng.uniform(0.5, 1.5))
            x += bw + rng.uniform(0, 0.1) * w
    else:  # trees
        for _ in range(rng.integers(2, 7)):
            c, rad = rng.uniform(0, w), rng.uniform(0.08, 0.25) * h
            _circle(img, horizon - 0.5 * rad, c, rad,
                    _hsv(rng, (0.22, 0.38), (0.4, 0.8), (0.15, 0.5)))
    img = np.clip(img * rng.uniform(0.6, 1.0), 0, 1)
    mull = (np.full(3, rng.uniform(0.8, 0.95), np.float32) if rng.random() < 0.4
            else _neutral(rng, (0.05, 0.5), 0.05))
    fw = rng.uniform(0.03, 0.07) * px_m
    _rect(img, 0, 0, h, w, mull, outline=max(2, round(fw)))
    for c in np.linspace(0, w, int(rng.integers(1, 4)) + 1)[1:-1]:
        _rect(img, 0, c - fw / 2, h, c + fw / 2, mull)
    if rng.random() < 0.5:
        r = rng.uniform(0.25, 0.4) * h
        _rect(img, r - fw / 2, 0, r + fw / 2, w, mull)
    return img


def sample_textures(rng: np.random.Generator, resolution: int | None = None,
                    cfg: AppearanceConfig | Mapping | None = None,
                    extents: Mapping[str, tuple[float, float]] | None = None
                    ) -> dict[str, np.ndarray]:
    """Draw one random set of surface textures.

    Args:
        rng: random generator (the only source of randomness).
        resolution: R, the side of every texture in pixels (>= 16); None: the config's
            ``resolution``.
        cfg: appearance config (``AppearanceConfig``, or a mapping of the keys that differ
            from its defaults; None: the defaults).
        extents: optional overrides of TEXTURE_SPECS (metres), e.g. the world's door size or
            wall height; they only change the aspect of what is drawn, not the output shape.

    Returns:
        name -> (R, R, 3) float32 linear RGB in [0, 1], row 0 at the top of the surface,
        for every name in TEXTURE_SPECS; in a daylight scene (``lights.daylight``) the
        window's radiance is scaled by ``lights.daylight_gain`` (values up to that gain).
    """
    cfg = as_config(AppearanceConfig, cfg, "appearance")
    n = int(cfg.resolution if resolution is None else resolution)
    if n < 16:
        raise ValueError(f"texture resolution must be >= 16 px, got {resolution}")
    ext = dict(TEXTURE_SPECS)
    if extents:
        for name, value in extents.items():
            if name not in TEXTURE_SPECS:
                raise ValueError(f"unknown texture {name!r}; use one of {list(TEXTURE_SPECS)}")
            eu, ev = (float(v) for v in value)
            if eu <= 0 or ev <= 0:
                raise ValueError(f"texture extent of {name!r} must be positive, got {value}")
            ext[name] = (eu, ev)
    out = {
        "floor": _floor(rng, n, cfg),
        "ceiling": _ceiling(rng, n, cfg),
        "wall": _wall(rng, n, cfg, ext["wall"]),
        "door": _door(rng, n, cfg, ext["door"]),
    }
    door_base = (out["door"][:, out["door"].shape[1] // 2, 2].copy()
                 if _chance(rng, cfg, "frame_matches_door") else None)
    out["frame"] = _frame(rng, n, door_base)
    out["window"] = _window(rng, n, ext["window"])
    for name, chw in out.items():
        img = cv2.merge(list(chw))  # (H, W, 3)
        if img.shape[:2] != (n, n):
            img = cv2.resize(img, (n, n), interpolation=cv2.INTER_LINEAR)
        out[name] = _to_linear(img)
    if _maybe(rng, cfg.lights.daylight, "lights.daylight"):
        lo, hi = _range(cfg.lights.daylight_gain, "lights.daylight_gain")
        if lo < 0:
            raise ValueError(f"appearance.lights.daylight_gain = [{lo}, {hi}] must be >= 0")
        out["window"] = out["window"] * np.float32(rng.uniform(lo, hi))
    return out


# --------------------------------------------------------------------------- lights, materials


def kelvin_to_rgb(kelvin: np.ndarray) -> np.ndarray:
    """Approximate linear-RGB colour of a black body (Tanner Helland's fit), luminance 1.

    Args:
        kelvin: (N,) colour temperatures, 1000-40000 K.

    Returns:
        (N, 3) float64 linear RGB with Rec.709 luminance 1.
    """
    t = np.clip(np.asarray(kelvin, dtype=np.float64), 1000, 40000) / 100.0
    r = np.where(t <= 66, 255.0, 329.698727446 * np.power(np.maximum(t - 60, 1e-6), -0.1332047592))
    g = np.where(t <= 66, 99.4708025861 * np.log(t) - 161.1195681661,
                 288.1221695283 * np.power(np.maximum(t - 60, 1e-6), -0.0755148492))
    b = np.where(t >= 66, 255.0,
                 np.where(t <= 19, 0.0, 138.5177312231 * np.log(np.maximum(t - 10, 1e-6))
                          - 305.0447927307))
    rgb = srgb_to_linear(np.clip(np.stack([r, g, b], -1) / 255.0, 0, 1))
    return rgb / (rgb @ _LUMA)[..., None]


def sample_lights(rng: np.random.Generator, num_slots: int,
                  cfg: AppearanceConfig | Mapping | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Which ceiling lights are on, and their emitted radiance.

    Args:
        rng: random generator.
        num_slots: number of light panels in the scene (>= 1).
        cfg: appearance config (as for ``sample_textures``); reads its ``lights``. A share
            ``lights.dim`` of the scenes has every panel dimmed by ``lights.dim_factor``.

    Returns:
        on: (num_slots,) bool, at least one True.
        radiance: (num_slots, 3) float32 linear RGB radiance, zero where off.
    """
    if num_slots < 1:
        raise ValueError(f"sample_lights needs num_slots >= 1, got {num_slots}")
    lights = as_config(AppearanceConfig, cfg, "appearance").lights
    f_lo, f_hi = _range(lights.on_fraction, "lights.on_fraction")
    i_lo, i_hi = _range(lights.intensity, "lights.intensity")
    k_lo, k_hi = _range(lights.temperature_k, "lights.temperature_k")
    if not (0 <= f_lo <= f_hi <= 1) or i_lo < 0:
        raise ValueError("appearance.lights.on_fraction must lie in [0, 1] and "
                         "appearance.lights.intensity must be non-negative")
    count = int(np.clip(np.ceil(rng.uniform(f_lo, f_hi) * num_slots), 1, num_slots))
    on = np.zeros(num_slots, bool)
    on[rng.permutation(num_slots)[:count]] = True
    level = rng.uniform(i_lo, i_hi)
    jitter = lights.jitter
    kelvin = rng.uniform(k_lo, k_hi) + rng.normal(0, 150, num_slots)  # same fixture type
    gain = level * np.clip(1 + jitter * rng.standard_normal(num_slots), 0.2, None)
    if _maybe(rng, lights.dim, "lights.dim"):
        d_lo, d_hi = _range(lights.dim_factor, "lights.dim_factor")
        if d_lo < 0:
            raise ValueError(f"appearance.lights.dim_factor = [{d_lo}, {d_hi}] must be >= 0")
        gain = gain * rng.uniform(d_lo, d_hi)
    radiance = kelvin_to_rgb(kelvin) * gain[:, None] * on[:, None]
    return on, radiance.astype(np.float32)


def sample_floor_gloss(rng: np.random.Generator, cfg: AppearanceConfig | Mapping | None = None
                       ) -> tuple[float, float] | None:
    """The floor's gloss for one scene (``appearance.prob.glossy_floor``; ``cfg`` as for
    ``sample_textures``).

    Returns:
        None where the floor is never glossy (probability 0: no random number drawn, the
        renderer keeps its diffuse floor), else (weight, alpha): the weight in [0, 1] of a
        rough plastic lobe over the diffuse texture (0: not glossy this time; else drawn in
        ``materials.floor_gloss``) and its GGX roughness alpha (drawn in
        ``materials.roughness.floor``).
    """
    cfg = as_config(AppearanceConfig, cfg, "appearance")
    if cfg.prob.glossy_floor == 0:
        return None
    if not _maybe(rng, cfg.prob.glossy_floor, "prob.glossy_floor"):
        return 0.0, 0.1
    w_lo, w_hi = _range(cfg.materials.floor_gloss, "materials.floor_gloss")
    a_lo, a_hi = _range(cfg.materials.roughness.floor, "materials.roughness.floor")
    if not (0 <= w_lo and w_hi <= 1) or a_lo <= 0:
        raise ValueError("appearance.materials.floor_gloss must lie in [0, 1] and "
                         "appearance.materials.roughness.floor must be > 0")
    return float(rng.uniform(w_lo, w_hi)), float(rng.uniform(a_lo, a_hi))


def object_colours(rng: np.random.Generator, n: int) -> np.ndarray:
    """Base colours of clutter objects or clothes.

    Returns:
        (n, 3) float32 linear RGB reflectances in [0.02, 0.8].
    """
    hue = rng.random(n)
    sat = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 0.2, n), rng.uniform(0.3, 0.9, n))
    val = rng.uniform(0.15, 0.9, n)
    rgb = np.array([colorsys.hsv_to_rgb(*c) for c in zip(hue, sat, val, strict=True)])
    return np.clip(srgb_to_linear(rgb.reshape(n, 3)), 0.02, 0.8).astype(np.float32)


def sample_materials(rng: np.random.Generator, cfg: AppearanceConfig | Mapping | None = None
                     ) -> dict[str, dict[str, Any]]:
    """Material parameters per surface (``appearance.materials``; ``cfg`` as for
    ``sample_textures``).

    Returns:
        name -> {'roughness': float in [0, 1], 'tint': (3,) float32}. For textured surfaces
        (floor, wall, ceiling, door, frame) 'tint' is a multiplier close to 1 applied to the
        texture; for 'clutter' and 'person' it is a base reflectance colour.
    """
    materials = as_config(AppearanceConfig, cfg, "appearance").materials
    jitter = materials.tint_jitter
    out: dict[str, dict[str, Any]] = {}
    for f in fields(materials.roughness):
        name = f.name
        lo, hi = _range(getattr(materials.roughness, name), f"materials.roughness.{name}")
        out[name] = {"roughness": float(rng.uniform(lo, hi))}
        if name in ("clutter", "person"):
            out[name]["tint"] = object_colours(rng, 1)[0]
        else:
            shift = jitter * (rng.standard_normal(3) - 1.0)  # mostly darker, never > 1
            out[name]["tint"] = np.clip(1 + shift, 0.5, 1.0).astype(np.float32)
    return out
