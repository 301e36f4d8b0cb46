"""The textures a scene has and the styles each is drawn in (``TEXTURE_SPECS``,
``*_STYLES``), and the helpers that read ``appearance`` settings to draw among them (ranges,
probability tables, chances), each naming its key when it is wrong."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from datagen.config import AppearanceConfig

#: name -> (extent_u, extent_v) in metres of surface covered by one copy of the texture.
TEXTURE_SPECS: dict[str, tuple[float, float]] = {
    "floor": (2.0, 2.0),  # repeats; tiles, planks or carpet tiles
    "ceiling": (2.0, 2.0),  # repeats; suspended-ceiling tile grid
    "wall": (4.0, 2.8),  # repeats every 4 m along the wall; v = 0 at the floor, full height
    "door": (0.9, 2.1),  # one door panel, 1:1 (u across, v up)
    "frame": (0.5, 0.5),  # door frame / jamb
    "window_frame": (0.5, 0.5),  # window frame, mullion, reveal, sill (a procedural floor's)
    "window": (1.2, 1.0),  # one window, 1:1 (outside view with mullions)
}

FLOOR_STYLES: tuple[str, ...] = ("tiles", "wood", "carpet", "vinyl", "concrete", "terrazzo")
WALL_STYLES: tuple[str, ...] = ("paint", "wallpaper", "block", "brick", "panels", "tiles")
CEILING_STYLES: tuple[str, ...] = ("tiles", "plaster")
DOOR_STYLES: tuple[str, ...] = ("wood", "painted", "metal")
SIGN_WORDS: tuple[str, ...] = (
    "EXIT", "FIRE EXIT", "WC", "LAB", "OFFICE", "STAIRS", "MEETING", "NO SMOKING",
    "PRIVATE", "KITCHEN", "SERVER", "LIFT", "INFO", "PUSH", "STAFF ONLY",
)  # fmt: skip
_LUMA = np.array([0.2126, 0.7152, 0.0722])




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
