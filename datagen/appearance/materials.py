"""Materials: the floor's gloss and the distractors' colours and reflectances, drawn from
``appearance`` settings, in linear RGB."""

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
from datagen.config import AppearanceConfig


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
