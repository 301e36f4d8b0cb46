"""Wall textures: paint, wallpaper, block, brick, panels or tiles, with skirting, dado rails,
posters and signs, drawn as float32 sRGB canvases (``textures.sample_textures`` linearizes
them)."""

from __future__ import annotations

import numpy as np

from datagen.appearance.choices import (
    SIGN_WORDS,
    WALL_STYLES,
    _chance,
    _maybe,
    _style,
)
from datagen.appearance.drawing import (
    _c,
    _circle,
    _fill,
    _hsv,
    _metal_colour,
    _neutral,
    _noise,
    _polyline,
    _rect,
    _solid,
    _speckle,
    _text,
    _text_bars,
    _wood_colour,
)
from datagen.config import AppearanceConfig


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
