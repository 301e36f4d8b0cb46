"""Distractor presets (``distractors``, conf/distractors/): their checks, the counts a
scene draws from one and the clutter kinds drawn."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from core.config import as_config
from datagen.config import DistractorPreset
from datagen.distractors.meshes import (
    CLUTTER_KINDS,
)


def check_preset(preset: DistractorPreset, where: str = "distractors preset") -> None:
    """Raise ValueError, naming ``where`` (e.g. ``distractor_presets.paper``), if a preset's
    counts are not 0 <= min <= max, its kinds are not a non-empty subset of CLUTTER_KINDS, a
    probability is outside [0, 1] or near_camera_m is negative."""
    for key in ("clutter", "people"):
        lo, hi = getattr(preset, key).min, getattr(preset, key).max
        if not 0 <= lo <= hi:
            raise ValueError(f"{where}: need 0 <= {key}.min <= {key}.max, got {lo}, {hi}")
    if not preset.kinds or set(preset.kinds) - set(CLUTTER_KINDS):
        raise ValueError(f"{where}: kinds must be a non-empty subset of {list(CLUTTER_KINDS)}, "
                         f"got {list(preset.kinds)}")
    for key in ("against_walls", "aligned"):
        if not 0.0 <= getattr(preset, key) <= 1.0:
            raise ValueError(f"{where}.{key} = {getattr(preset, key)} must be a probability "
                             "in [0, 1]")
    if preset.near_camera_m < 0:
        raise ValueError(f"{where}.near_camera_m = {preset.near_camera_m} must be >= 0 m "
                         "(0: anywhere on the floor)")


def preset_counts(rng: np.random.Generator, preset: DistractorPreset | Mapping[str, Any]
                  ) -> tuple[int, int]:
    """Number of clutter objects and people for one image or flight.

    Args:
        preset: a distractors preset (``DistractorPreset``, or a mapping of the keys that
            differ from its defaults).

    Returns:
        (num_clutter, num_people), uniform in the preset's [min, max] ranges.
    """
    preset = as_config(DistractorPreset, preset, "distractors preset")
    check_preset(preset)
    return (int(rng.integers(preset.clutter.min, preset.clutter.max + 1)),
            int(rng.integers(preset.people.min, preset.people.max + 1)))


def sample_kinds(rng: np.random.Generator, n: int,
                 preset: DistractorPreset | Mapping[str, Any]) -> list[str]:
    """n clutter kinds drawn from the preset's ``kinds`` list (uniformly)."""
    preset = as_config(DistractorPreset, preset, "distractors preset")
    check_preset(preset)
    kinds = list(preset.kinds)
    return [kinds[i] for i in rng.integers(0, len(kinds), n)]
