"""Floor and ceiling textures: tiles, planks, carpet, vinyl, concrete, terrazzo; suspended-
ceiling grids and plaster, drawn as float32 sRGB canvases (``textures.sample_textures``
linearizes them)."""

from __future__ import annotations

import numpy as np

from datagen.appearance.choices import (
    CEILING_STYLES,
    FLOOR_STYLES,
    TEXTURE_SPECS,
    _chance,
    _maybe,
    _probs,
    _style,
)
from datagen.appearance.drawing import (
    _circle,
    _fill,
    _fill_grid,
    _hsv,
    _metal_colour,
    _neutral,
    _noise,
    _rect,
    _solid,
    _speckle,
    _wood_colour,
)
from datagen.config import AppearanceConfig


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
