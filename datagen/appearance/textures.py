"""Seeded procedural textures of a scene (``sample_textures``).

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

from collections.abc import Mapping

import cv2
import numpy as np

from core.config import as_config
from datagen.appearance.choices import (
    TEXTURE_SPECS,
    _chance,
    _maybe,
    _range,
)
from datagen.appearance.drawing import (
    _to_linear,
)
from datagen.appearance.floors import (
    _ceiling,
    _floor,
)
from datagen.appearance.openings import _door, _frame, _window, _window_frame
from datagen.appearance.walls import _wall
from datagen.config import AppearanceConfig


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
        ``window_frame`` is the door frame's unless ``prob.window_frame_colour`` draws one
        (last, so the other textures are drawn as without it).
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
    if _maybe(rng, cfg.prob.window_frame_colour, "prob.window_frame_colour"):
        out["window_frame"] = _to_linear(cv2.merge(list(_window_frame(rng, n))))
    else:
        out["window_frame"] = out["frame"]
    return out
