"""Ceiling lights: black-body colours (``kelvin_to_rgb``) and each slot's drawn radiance
(``sample_lights``), in linear RGB."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from core.config import as_config
from core.imaging.colour import srgb_to_linear
from datagen.appearance.choices import (
    _LUMA,
    _maybe,
    _range,
)
from datagen.config import AppearanceConfig


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
