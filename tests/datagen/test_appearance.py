"""Tests of datagen.appearance: procedural textures, lights and materials."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from omegaconf import OmegaConf

from datagen import appearance as A
from datagen.config import AppearanceConfig


@pytest.fixture(scope="module")
def cfg():
    """The appearance defaults, as a DictConfig to merge test values onto."""
    return OmegaConf.structured(AppearanceConfig)


def edge_fraction(img: np.ndarray) -> float:
    """Fraction of Canny edge pixels (strong: thresholds 50 / 150) of a linear texture."""
    u8 = (A.linear_to_srgb(img) * 255 + 0.5).astype(np.uint8)
    return float((cv2.Canny(cv2.cvtColor(u8, cv2.COLOR_RGB2GRAY), 50, 150) > 0).mean())


class TestSampleTextures:
    @pytest.mark.parametrize("resolution", [32, 96])
    def test_shapes_dtype_range(self, resolution, cfg):
        for seed in range(6):
            tex = A.sample_textures(np.random.default_rng(seed), resolution, cfg)
            assert set(tex) == set(A.TEXTURE_SPECS)
            for name, img in tex.items():
                assert img.shape == (resolution, resolution, 3), name
                assert img.dtype == np.float32, name
                assert np.isfinite(img).all() and img.min() >= 0 and img.max() <= 1, name

    def test_resolution_from_config(self, cfg):
        small = OmegaConf.merge(cfg, {"resolution": 40})
        tex = A.sample_textures(np.random.default_rng(0), None, small)
        assert tex["wall"].shape == (40, 40, 3)

    def test_deterministic(self, cfg):
        a = A.sample_textures(np.random.default_rng(7), 64, cfg)
        b = A.sample_textures(np.random.default_rng(7), 64, cfg)
        for name in a:
            np.testing.assert_array_equal(a[name], b[name])

    def test_seeds_differ(self, cfg):
        a = A.sample_textures(np.random.default_rng(1), 64, cfg)
        b = A.sample_textures(np.random.default_rng(2), 64, cfg)
        for name in a:
            assert np.abs(a[name] - b[name]).mean() > 1e-3, name

    def test_strong_edges(self, cfg):
        """Floors and walls carry many strong (non-model) edges: grout, seams, posters."""
        for seed in range(12):
            tex = A.sample_textures(np.random.default_rng(seed), 256, cfg)
            assert edge_fraction(tex["floor"]) > 0.01, seed
            assert edge_fraction(tex["wall"]) > 0.005, seed
            assert edge_fraction(tex["ceiling"]) > 0.01, seed

    def test_every_floor_style_has_edges(self, cfg):
        for style in A.FLOOR_STYLES:
            only = OmegaConf.merge(cfg, {"floor_styles": {s: float(s == style)
                                                          for s in A.FLOOR_STYLES}})
            for seed in range(3):
                tex = A.sample_textures(np.random.default_rng(seed), 128, only)
                assert edge_fraction(tex["floor"]) > 0.01, (style, seed)

    def test_skirting_at_the_bottom(self, cfg):
        """Wall v = 0 is the last row: a skirting band differs from the paint above it."""
        for seed in range(5):
            wall = A.sample_textures(np.random.default_rng(seed), 256, cfg)["wall"]
            rows = wall.mean(axis=(1, 2))
            jump = np.abs(np.diff(rows[-int(0.2 / 2.8 * 256):]))  # the lowest 0.2 m
            assert jump.max() > 0.02, seed

    def test_extents_override(self, cfg):
        tex = A.sample_textures(np.random.default_rng(0), 64, cfg,
                                extents={"door": (1.0, 2.2), "wall": (4.0, 3.0)})
        assert tex["door"].shape == (64, 64, 3)

    def test_bad_input(self, cfg):
        rng = np.random.default_rng(0)
        with pytest.raises(ValueError, match="resolution"):
            A.sample_textures(rng, 8, cfg)
        with pytest.raises(ValueError, match="unknown texture"):
            A.sample_textures(rng, 32, cfg, extents={"roof": (1, 1)})
        with pytest.raises(ValueError, match="floor_styles"):
            A.sample_textures(rng, 32, OmegaConf.merge(cfg, {"floor_styles": {"lava": 1.0}}))


class TestNoise:
    def test_periodic_and_normalized(self):
        n = A._noise(np.random.default_rng(0), 128, 96, (6.0, 3.0))
        assert n.shape == (128, 96) and n.dtype == np.float32
        np.testing.assert_allclose([n.mean(), n.std()], [0.0, 1.0], atol=0.05)
        inner = np.abs(np.diff(n, axis=1)).max()
        seam = np.abs(n[:, 0] - n[:, -1]).max()
        assert seam <= 1.5 * inner
        inner = np.abs(np.diff(n, axis=0)).max()
        assert np.abs(n[0] - n[-1]).max() <= 1.5 * inner


class TestLights:
    @pytest.mark.parametrize("slots", [1, 2, 5, 9])
    def test_at_least_one_on(self, slots, cfg):
        for seed in range(30):
            on, radiance = A.sample_lights(np.random.default_rng(seed), slots, cfg)
            assert on.shape == (slots,) and on.dtype == bool and on.any()
            assert radiance.shape == (slots, 3) and radiance.dtype == np.float32
            assert np.all(radiance[~on] == 0) and np.all(radiance[on] > 0)

    def test_intensity_range(self, cfg):
        fixed = OmegaConf.merge(cfg, {"lights": {"jitter": 0.0, "intensity": [2.0, 3.0]}})
        for seed in range(10):
            on, radiance = A.sample_lights(np.random.default_rng(seed), 6, fixed)
            lum = radiance[on] @ np.array([0.2126, 0.7152, 0.0722])
            assert np.all((lum > 2.0 - 1e-4) & (lum < 3.0 + 1e-4))
            np.testing.assert_allclose(lum, lum[0], rtol=1e-4)

    def test_count_varies(self, cfg):
        counts = {int(A.sample_lights(np.random.default_rng(s), 8, cfg)[0].sum())
                  for s in range(40)}
        assert len(counts) >= 3

    def test_kelvin(self):
        rgb = A.kelvin_to_rgb(np.array([2700.0, 6500.0]))
        np.testing.assert_allclose(rgb @ np.array([0.2126, 0.7152, 0.0722]), 1.0, rtol=1e-9)
        assert rgb[0, 0] > rgb[0, 2] * 2  # warm white is red-heavy
        np.testing.assert_allclose(rgb[1], 1.0, atol=0.1)  # 6500 K is about white

    def test_bad_input(self, cfg):
        with pytest.raises(ValueError, match="num_slots"):
            A.sample_lights(np.random.default_rng(0), 0, cfg)
        with pytest.raises(ValueError, match="intensity"):
            A.sample_lights(np.random.default_rng(0), 3,
                            OmegaConf.merge(cfg, {"lights": {"intensity": [5.0, 1.0]}}))


class TestMaterials:
    def test_ranges(self, cfg):
        for seed in range(10):
            mats = A.sample_materials(np.random.default_rng(seed), cfg)
            for name, m in mats.items():
                lo, hi = cfg.materials.roughness[name]
                assert lo <= m["roughness"] <= hi
                assert m["tint"].shape == (3,)
                assert np.all((m["tint"] >= 0) & (m["tint"] <= 1)), name

    def test_object_colours(self):
        c = A.object_colours(np.random.default_rng(0), 20)
        assert c.shape == (20, 3) and c.dtype == np.float32
        assert c.min() >= 0.02 and c.max() <= 0.8


def test_srgb_round_trip():
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(A.linear_to_srgb(A.srgb_to_linear(x)), x, atol=1e-9)
