"""Door, door-frame and window textures, drawn as float32 sRGB canvases
(``textures.sample_textures`` linearizes them)."""

from __future__ import annotations

import numpy as np

from datagen.appearance.choices import (
    DOOR_STYLES,
    _chance,
    _probs,
)
from datagen.appearance.drawing import (
    _c,
    _circle,
    _fill,
    _hsv,
    _metal_colour,
    _neutral,
    _noise,
    _rect,
    _solid,
    _speckle,
    _text,
    _wood_colour,
)
from datagen.config import AppearanceConfig


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
    elif style == "metal":  # brushed steel or aluminium, or a dark powder coat
        base = (np.full(3, rng.uniform(0.45, 0.8), np.float32) if rng.random() < 0.7
                else _neutral(rng, (0.08, 0.3), 0.15))
        img = _solid(base, 1 + 0.04 * _noise(rng, h, w, (60.0, 0.5)), (h, w))
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


def _window_frame(rng: np.random.Generator, n: int) -> np.ndarray:
    """Window frame, mullion, reveal and sill: white or off-white, anthracite, metal or wood,
    one colour with a little noise."""
    kind = rng.choice(4, p=[0.4, 0.25, 0.2, 0.15])
    colour = (_neutral(rng, (0.8, 0.97), 0.06) if kind == 0 else
              _neutral(rng, (0.06, 0.25), 0.1) if kind == 1 else
              _metal_colour(rng) if kind == 2 else _wood_colour(rng))
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
