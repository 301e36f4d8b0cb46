"""Materials: the floor's gloss and the distractors' colours (their parts' too) and
reflectances, drawn from ``appearance`` settings, in linear RGB."""

from __future__ import annotations

import colorsys
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from core.config import as_config
from core.imaging.colour import srgb_to_linear
from datagen.appearance.choices import (
    _maybe,
    _range,
)
from datagen.appearance.drawing import _hsv, _metal_colour, _neutral, _wood_colour
from datagen.config import AppearanceConfig

#: Tones of a distractor's parts (a mesh's ``metadata["tones"]``,
#: datagen.distractors.primitives ``_painted``): how ``part_colours`` draws each part's colour.
#: body: the object's own colour (``object_colours``); frame: wood or laminate (white, grey,
#: black); metal: steel, dark metal or brass; dark: near black (screens, keyboards, casters);
#: light: white or pale (mattresses, paper); item: a colour of its own per part (books, boxes).
TONES: tuple[str, ...] = ("body", "frame", "metal", "dark", "light", "item")
BODY, FRAME, METAL, DARK, LIGHT, ITEM = range(len(TONES))


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


def part_colours(rng: np.random.Generator, tones: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Colours of one object's parts, drawn per image.

    Args:
        tones: (P,) each part's tone (``TONES``).
        body: (3,) linear RGB, the object's own colour (tone body).

    Returns:
        (P, 3) float32 linear RGB reflectances in [0.02, 0.8]: one frame, metal, dark and
        light colour shared by the parts of that tone, and a colour per item part.
    """
    tones = np.asarray(tones, dtype=np.int64).reshape(-1)
    if tones.size and not 0 <= tones.min() <= tones.max() < len(TONES):
        raise ValueError(f"part tones must be indices of {list(TONES)}, got {tones.tolist()}")
    look = rng.random()
    frame = (_wood_colour(rng) if look < 0.5 else _neutral(rng, (0.75, 0.92), 0.08)
             if look < 0.75 else _neutral(rng, (0.06, 0.5), 0.1))
    by_tone = np.stack([np.zeros(3, np.float32), frame, _metal_colour(rng),  # sRGB, per tone
                        _neutral(rng, (0.04, 0.18), 0.1),
                        _hsv(rng, (0, 1), (0, 0.15), (0.78, 0.95)), np.zeros(3, np.float32)])
    out = np.clip(srgb_to_linear(by_tone), 0.02, 0.8).astype(np.float32)[tones]
    out[tones == BODY] = np.asarray(body, np.float32).reshape(3)
    items = tones == ITEM
    if items.any():
        out[items] = object_colours(rng, int(items.sum()))
    return out


def part_palettes(rng: np.random.Generator, colours: np.ndarray,
                  tones: list[np.ndarray | None]) -> list[np.ndarray]:
    """The colours of n distractors: (3,) ``colours[i]`` each, or for an object whose parts
    have tones (``tones[i]`` (P,), not None) its (P, 3) ``part_colours`` around that colour
    (drawn in order; none are drawn when no object has tones)."""
    return [c if t is None else part_colours(rng, t, c)
            for c, t in zip(np.asarray(colours, np.float32), tones, strict=True)]


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
