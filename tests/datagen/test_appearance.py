"""Tests of datagen.appearance: procedural textures, lights and materials."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from omegaconf import OmegaConf

from core.imaging import colour
from datagen.appearance import floors, walls
from datagen.appearance.choices import CEILING_STYLES, FLOOR_STYLES, TEXTURE_SPECS, WALL_STYLES
from datagen.appearance.drawing import _noise
from datagen.appearance.lights import kelvin_to_rgb, sample_lights
from datagen.appearance.materials import object_colours, sample_floor_gloss, sample_materials
from datagen.appearance.textures import sample_textures
from datagen.config import AppearanceConfig


@pytest.fixture(scope="module")
def cfg():
    """The appearance defaults, as a DictConfig to merge test values onto."""
    return OmegaConf.structured(AppearanceConfig)


def edge_fraction(img: np.ndarray) -> float:
    """Fraction of Canny edge pixels (strong: thresholds 50 / 150) of a linear texture."""
    u8 = (colour.linear_to_srgb(img) * 255 + 0.5).astype(np.uint8)
    return float((cv2.Canny(cv2.cvtColor(u8, cv2.COLOR_RGB2GRAY), 50, 150) > 0).mean())


class TestSampleTextures:
    @pytest.mark.parametrize("resolution", [32, 96])
    def test_shapes_dtype_range(self, resolution, cfg):
        for seed in range(6):
            tex = sample_textures(np.random.default_rng(seed), resolution, cfg)
            assert set(tex) == set(TEXTURE_SPECS)
            for name, img in tex.items():
                assert img.shape == (resolution, resolution, 3), name
                assert img.dtype == np.float32, name
                assert np.isfinite(img).all() and img.min() >= 0 and img.max() <= 1, name

    def test_resolution_from_config(self, cfg):
        small = OmegaConf.merge(cfg, {"resolution": 40})
        tex = sample_textures(np.random.default_rng(0), None, small)
        assert tex["wall"].shape == (40, 40, 3)

    def test_deterministic(self, cfg):
        a = sample_textures(np.random.default_rng(7), 64, cfg)
        b = sample_textures(np.random.default_rng(7), 64, cfg)
        for name in a:
            np.testing.assert_array_equal(a[name], b[name])

    def test_seeds_differ(self, cfg):
        a = sample_textures(np.random.default_rng(1), 64, cfg)
        b = sample_textures(np.random.default_rng(2), 64, cfg)
        for name in a:
            assert np.abs(a[name] - b[name]).mean() > 1e-3, name

    def test_strong_edges(self, cfg):
        """Floors and walls carry many strong (non-model) edges: grout, seams, posters."""
        for seed in range(12):
            tex = sample_textures(np.random.default_rng(seed), 256, cfg)
            assert edge_fraction(tex["floor"]) > 0.01, seed
            assert edge_fraction(tex["wall"]) > 0.005, seed
            assert edge_fraction(tex["ceiling"]) > 0.01, seed

    def test_every_floor_style_has_edges(self, cfg):
        """Grout, seams, saw cuts, flecks or chips; plain sheet vinyl has its welded seams
        only (one or two lines per 2 m)."""
        for style in FLOOR_STYLES:
            only = OmegaConf.merge(cfg, {"floor_styles": {s: float(s == style)
                                                          for s in FLOOR_STYLES}})
            for seed in range(3):
                tex = sample_textures(np.random.default_rng(seed), 128, only)
                least = 0.005 if style == "vinyl" else 0.01
                assert edge_fraction(tex["floor"]) > least, (style, seed)

    def test_skirting_at_the_bottom(self, cfg):
        """Wall v = 0 is the last row: a skirting band differs from the paint above it."""
        for seed in range(5):
            wall = sample_textures(np.random.default_rng(seed), 256, cfg)["wall"]
            rows = wall.mean(axis=(1, 2))
            jump = np.abs(np.diff(rows[-int(0.2 / 2.8 * 256):]))  # the lowest 0.2 m
            assert jump.max() > 0.02, seed

    def test_extents_override(self, cfg):
        tex = sample_textures(np.random.default_rng(0), 64, cfg,
                                extents={"door": (1.0, 2.2), "wall": (4.0, 3.0)})
        assert tex["door"].shape == (64, 64, 3)

    def test_bad_input(self, cfg):
        rng = np.random.default_rng(0)
        with pytest.raises(ValueError, match="resolution"):
            sample_textures(rng, 8, cfg)
        with pytest.raises(ValueError, match="unknown texture"):
            sample_textures(rng, 32, cfg, extents={"roof": (1, 1)})
        with pytest.raises(ValueError, match="floor_styles"):
            sample_textures(rng, 32, OmegaConf.merge(cfg, {"floor_styles": {"lava": 1.0}}))


class TestNoise:
    def test_periodic_and_normalized(self):
        n = _noise(np.random.default_rng(0), 128, 96, (6.0, 3.0))
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
            on, radiance = sample_lights(np.random.default_rng(seed), slots, cfg)
            assert on.shape == (slots,) and on.dtype == bool and on.any()
            assert radiance.shape == (slots, 3) and radiance.dtype == np.float32
            assert np.all(radiance[~on] == 0) and np.all(radiance[on] > 0)

    def test_intensity_range(self, cfg):
        fixed = OmegaConf.merge(cfg, {"lights": {"jitter": 0.0, "intensity": [2.0, 3.0]}})
        for seed in range(10):
            on, radiance = sample_lights(np.random.default_rng(seed), 6, fixed)
            lum = radiance[on] @ np.array([0.2126, 0.7152, 0.0722])
            assert np.all((lum > 2.0 - 1e-4) & (lum < 3.0 + 1e-4))
            np.testing.assert_allclose(lum, lum[0], rtol=1e-4)

    def test_count_varies(self, cfg):
        counts = {int(sample_lights(np.random.default_rng(s), 8, cfg)[0].sum())
                  for s in range(40)}
        assert len(counts) >= 3

    def test_kelvin(self):
        rgb = kelvin_to_rgb(np.array([2700.0, 6500.0]))
        np.testing.assert_allclose(rgb @ np.array([0.2126, 0.7152, 0.0722]), 1.0, rtol=1e-9)
        assert rgb[0, 0] > rgb[0, 2] * 2  # warm white is red-heavy
        np.testing.assert_allclose(rgb[1], 1.0, atol=0.1)  # 6500 K is about white

    def test_bad_input(self, cfg):
        with pytest.raises(ValueError, match="num_slots"):
            sample_lights(np.random.default_rng(0), 0, cfg)
        with pytest.raises(ValueError, match="intensity"):
            sample_lights(np.random.default_rng(0), 3,
                            OmegaConf.merge(cfg, {"lights": {"intensity": [5.0, 1.0]}}))


class TestMaterials:
    def test_ranges(self, cfg):
        for seed in range(10):
            mats = sample_materials(np.random.default_rng(seed), cfg)
            for name, m in mats.items():
                lo, hi = cfg.materials.roughness[name]
                assert lo <= m["roughness"] <= hi
                assert m["tint"].shape == (3,)
                assert np.all((m["tint"] >= 0) & (m["tint"] <= 1)), name

    def test_object_colours(self):
        c = object_colours(np.random.default_rng(0), 20)
        assert c.shape == (20, 3) and c.dtype == np.float32
        assert c.min() >= 0.02 and c.max() <= 0.8


def test_srgb_round_trip():
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(colour.linear_to_srgb(colour.srgb_to_linear(x)), x, atol=1e-9)


# --------------------------------------------------------------------------- wider variety

#: Per seed (0, 1, 2): the mean of each 64 px texture drawn with the defaults, then the sum of
#: 7 lights' radiance, then the generator's next integers(2**62), recorded with the code before
#: the new families (commit f19dcf6): the defaults must draw the same and use the same numbers.
DEFAULTS_BEFORE = {
    0: ({"ceiling": 0.556268, "door": 0.308316, "floor": 0.278247, "frame": 0.0062,
         "wall": 0.444285, "window": 0.270618}, 173.25844, 2692973135460151501),
    1: ({"ceiling": 0.565675, "door": 0.330828, "floor": 0.182123, "frame": 0.374281,
         "wall": 0.362368, "window": 0.107949}, 83.13773, 2400676973750190249),
    2: ({"ceiling": 0.404304, "door": 0.182266, "floor": 0.30802, "frame": 0.876372,
         "wall": 0.322912, "window": 0.242941}, 138.51382, 3416784385091159729),
}
NEW_FAMILIES = {"floor_styles": ("_vinyl", "_concrete", "_terrazzo"),
                "wall_styles": ("_wall_cover", "_wall_lower"), "ceiling_styles": ("_plaster",)}
#: The module of each: its callers look it up there.
MODULE_OF = {"_vinyl": floors, "_concrete": floors, "_terrazzo": floors, "_plaster": floors,
             "_wall_cover": walls, "_wall_lower": walls}


@pytest.fixture(scope="module")
def varied(cfg):
    """The conf/appearance/varied.yaml preset over the defaults."""
    from core.config import CONF

    return OmegaConf.merge(cfg, OmegaConf.load(CONF / "appearance" / "varied.yaml"))


def only(cfg, key: str, names: tuple[str, ...], style: str):
    """cfg with all of the ``key`` table's weight on one style."""
    return OmegaConf.merge(cfg, {key: {n: float(n == style) for n in names}})


def draw(cfg, seed: int, resolution: int = 64) -> dict[str, np.ndarray]:
    return sample_textures(np.random.default_rng(seed), resolution, cfg)


class TestDefaultsUnchanged:
    def test_same_draw_as_before(self, cfg):
        for seed, (means, radiance, after) in DEFAULTS_BEFORE.items():
            rng = np.random.default_rng(seed)
            tex = sample_textures(rng, 64, cfg)
            rad = sample_lights(rng, 7, cfg)[1]
            for name, mean in means.items():
                assert tex[name].mean() == pytest.approx(mean, abs=2e-6), (seed, name)
            assert rad.sum() == pytest.approx(radiance, abs=1e-3), seed
            assert int(rng.integers(2**62)) == after, seed  # no extra or missing draw

    def test_zero_weights_draw_nothing(self, cfg):
        """The new table entries at weight 0 and the new chances at 0 are as if absent."""
        old = AppearanceConfig(floor_styles={"tiles": 0.45, "wood": 0.3, "carpet": 0.25},
                               wall_styles={"paint": 1.0}, ceiling_styles={"tiles": 1.0})
        for seed in range(4):
            a, b = draw(cfg, seed), draw(old, seed)
            for name in a:
                np.testing.assert_array_equal(a[name], b[name])

    def test_preset_default_is_the_defaults(self, cfg):
        from core.config import compose_config

        plain = compose_config("datagen")["appearance"]
        named = compose_config("datagen", ["appearance=default"])["appearance"]
        assert plain == named == OmegaConf.to_container(cfg)
        for seed in range(2):
            a, b = draw(plain, seed), draw(named, seed)
            for name in a:
                np.testing.assert_array_equal(a[name], b[name])

    def test_new_families_not_drawn(self, cfg, monkeypatch):
        called = []
        for fns in NEW_FAMILIES.values():
            for fn in fns:
                monkeypatch.setattr(MODULE_OF[fn], fn, lambda *a, _fn=fn, **k: called.append(_fn))
        for seed in range(20):
            draw(cfg, seed, 32)
        assert called == []


class TestVaried:
    def test_shapes_range_deterministic(self, varied):
        for seed in range(12):
            tex = draw(varied, seed)
            again = draw(varied, seed)
            assert set(tex) == set(TEXTURE_SPECS)
            for name, img in tex.items():
                assert img.shape == (64, 64, 3) and img.dtype == np.float32, name
                top = varied.lights.daylight_gain[1] if name == "window" else 1.0
                assert np.isfinite(img).all() and img.min() >= 0 and img.max() <= top, name
                np.testing.assert_array_equal(img, again[name])

    def test_every_family_drawn(self, varied, monkeypatch):
        """Over a few dozen seeds the preset draws every new family (and today's)."""
        seen = set()
        for fns in NEW_FAMILIES.values():
            for fn in fns:
                real = getattr(MODULE_OF[fn], fn)
                monkeypatch.setattr(MODULE_OF[fn], fn, lambda *a, _fn=fn, _real=real, **k:
                                    seen.add(_fn) or _real(*a, **k))
        for seed in range(40):
            draw(varied, seed, 32)
        assert seen == {fn for fns in NEW_FAMILIES.values() for fn in fns}

    @pytest.mark.parametrize("style", WALL_STYLES[1:])
    def test_wall_styles(self, cfg, style):
        """Each wall style draws another wall than paint from the same seed, strong edges for
        block, brick and tiles (joints and grout)."""
        for seed in range(3):
            mine = draw(only(cfg, "wall_styles", WALL_STYLES, style), seed, 128)["wall"]
            paint = draw(cfg, seed, 128)["wall"]
            assert np.abs(mine - paint).mean() > 1e-3, (style, seed)
            if style in ("block", "brick"):
                assert edge_fraction(mine) > 0.02, (style, seed)

    def test_wall_tiles_from_the_floor(self, cfg):
        """Wall tiles: a grout grid in the lowest metre (rows of pixels darker or lighter than
        the tiles at a fixed pitch)."""
        tiles = only(cfg, "wall_styles", WALL_STYLES, "tiles")
        for seed in range(3):
            wall = draw(tiles, seed, 256)["wall"]
            low = wall[-int(1.0 / 2.8 * 256):-int(0.2 / 2.8 * 256)].mean(axis=(1, 2))
            assert np.abs(np.diff(low)).max() > 0.01, seed

    def test_plaster_ceiling_is_plain(self, cfg):
        plaster = only(cfg, "ceiling_styles", CEILING_STYLES, "plaster")
        for seed in range(4):
            assert edge_fraction(draw(plaster, seed, 256)["ceiling"]) < \
                edge_fraction(draw(cfg, seed, 256)["ceiling"]), seed

    def test_dark_floor(self, cfg):
        dark = OmegaConf.merge(cfg, {"prob": {"dark_floor": 1.0}})
        for seed in range(4):
            assert draw(dark, seed)["floor"].mean() < 0.5 * draw(cfg, seed)["floor"].mean()

    def test_accent_wall_saturated(self, cfg):
        accent = OmegaConf.merge(cfg, {"prob": {"accent_wall": 1.0}, "posters": [0, 0]})
        plain = OmegaConf.merge(cfg, {"posters": [0, 0]})

        def saturation(img):
            u8 = (colour.linear_to_srgb(img[:64]) * 255).astype(np.uint8)  # above the dado
            return float(cv2.cvtColor(u8, cv2.COLOR_RGB2HSV)[..., 1].mean())

        s_accent = [saturation(draw(accent, s, 128)["wall"]) for s in range(8)]
        s_plain = [saturation(draw(plain, s, 128)["wall"]) for s in range(8)]
        assert np.mean(s_accent) > 1.5 * np.mean(s_plain)

    def test_daylight_scales_the_window(self, cfg):
        day = OmegaConf.merge(cfg, {"lights": {"daylight": 1.0, "daylight_gain": [5.0, 5.0]}})
        for seed in range(3):
            a, b = draw(day, seed), draw(cfg, seed)
            np.testing.assert_allclose(a["window"], 5.0 * b["window"], rtol=1e-6)
            for name in set(a) - {"window"}:
                np.testing.assert_array_equal(a[name], b[name])

    def test_window_frame_colour(self, cfg):
        """Window frames take the door frame's texture, or with prob.window_frame_colour one of
        their own, drawn last: every other texture stays as drawn without it."""
        own = OmegaConf.merge(cfg, {"prob": {"window_frame_colour": 1.0}})
        for seed in range(4):
            a, b = draw(own, seed), draw(cfg, seed)
            np.testing.assert_array_equal(b["window_frame"], b["frame"])
            assert np.abs(a["window_frame"] - a["frame"]).mean() > 1e-3, seed
            for name in set(a) - {"window_frame"}:
                np.testing.assert_array_equal(a[name], b[name])

    def test_metal_doors(self, cfg):
        """A metal door is grey (steel, aluminium or a dark coat), unlike the painted ones."""
        from datagen.appearance.choices import DOOR_STYLES

        metal = only(cfg, "door_styles", DOOR_STYLES, "metal")
        painted = only(cfg, "door_styles", DOOR_STYLES, "painted")

        def saturation(img):
            u8 = (colour.linear_to_srgb(img) * 255).astype(np.uint8)
            return float(np.median(cv2.cvtColor(u8, cv2.COLOR_RGB2HSV)[..., 1]))

        s_metal = [saturation(draw(metal, s, 64)["door"]) for s in range(8)]
        s_painted = [saturation(draw(painted, s, 64)["door"]) for s in range(8)]
        assert max(s_metal) < 45 and np.mean(s_metal) < np.mean(s_painted)

    def test_dim_scenes(self, cfg):
        dim = OmegaConf.merge(cfg, {"lights": {"dim": 1.0, "dim_factor": [0.1, 0.1]}})
        for seed in range(5):
            on_a, a = sample_lights(np.random.default_rng(seed), 6, dim)
            on_b, b = sample_lights(np.random.default_rng(seed), 6, cfg)
            np.testing.assert_array_equal(on_a, on_b)
            np.testing.assert_allclose(a, 0.1 * b, rtol=1e-5)

    def test_share_of_dim_scenes(self, cfg):
        dim = OmegaConf.merge(cfg, {"lights": {"dim": 0.3, "dim_factor": [0.1, 0.1],
                                               "intensity": [5.0, 5.0], "jitter": 0.0}})
        lum = np.array([sample_lights(np.random.default_rng(s), 3, dim)[1].max()
                        for s in range(200)])
        assert 0.2 < float((lum < 1.0).mean()) < 0.4

    def test_floor_gloss(self, cfg):
        rng = np.random.default_rng(0)
        state = rng.bit_generator.state
        assert sample_floor_gloss(rng, cfg) is None  # never glossy: the renderer's plain
        assert rng.bit_generator.state == state  # and no number drawn
        glossy = OmegaConf.merge(cfg, {"prob": {"glossy_floor": 1.0},
                                       "materials": {"floor_gloss": [0.4, 0.6],
                                                     "roughness": {"floor": [0.05, 0.1]}}})
        for seed in range(10):
            weight, alpha = sample_floor_gloss(np.random.default_rng(seed), glossy)
            assert 0.4 <= weight <= 0.6 and 0.05 <= alpha <= 0.1
        some = OmegaConf.merge(glossy, {"prob": {"glossy_floor": 0.3}})
        weights = [sample_floor_gloss(np.random.default_rng(s), some)[0] for s in range(100)]
        assert 0.15 < np.mean(np.array(weights) > 0) < 0.45
        with pytest.raises(ValueError, match="materials.floor_gloss"):
            sample_floor_gloss(rng, OmegaConf.merge(glossy, {"materials": {
                "floor_gloss": [0.5, 1.5]}}))

    def test_bad_settings(self, cfg):
        rng = np.random.default_rng(0)
        with pytest.raises(ValueError, match="prob.accent_wall"):
            sample_textures(rng, 32, OmegaConf.merge(cfg, {"prob": {"accent_wall": 1.5}}))
        with pytest.raises(ValueError, match="wall_styles"):
            sample_textures(rng, 32, OmegaConf.merge(cfg, {"wall_styles": {"marble": 1.0}}))
        with pytest.raises(ValueError, match="ceiling_styles"):
            sample_textures(rng, 32, OmegaConf.merge(cfg, {"ceiling_styles": {"tiles": 0.0}}))
        with pytest.raises(ValueError, match="lights.daylight_gain"):
            sample_textures(rng, 32, OmegaConf.merge(
                cfg, {"lights": {"daylight": 1.0, "daylight_gain": [9.0, 2.0]}}))
        with pytest.raises(ValueError, match="lights.dim_factor"):
            sample_lights(rng, 3, OmegaConf.merge(
                cfg, {"lights": {"dim": 1.0, "dim_factor": [-1.0, 0.5]}}))


def test_tiny_render_varied(tmp_path):
    """A 64x48 dataset rendered with appearance=varied (daylight and a glossy floor in every
    scene): images and labels written, the preset recorded with the dataset, the same seed
    the same images."""
    from core.atomic import read_png
    from core.config import compose_config
    from core.dataset import Dataset
    from datagen.generate import run

    def render(out):
        cfg = compose_config("datagen", [
            "appearance=varied", "appearance.lights.daylight=1.0", "appearance.resolution=64",
            "appearance.prob.glossy_floor=1.0",
            "camera.width=64", "camera.height=48", "splits.train=3", "splits.val=0",
            "splits.test=0", "render.spp=1", "training.chunk=3", "render_flights=[]",
            "val_flights=[]", f"out_dir={out}"])
        return Dataset(run(cfg, progress=False))

    ds = render(tmp_path / "a")
    rgb, lab = ds.split("train")
    assert len(rgb) == 3
    images = [read_png(p) for p in rgb]
    assert all(img.shape == (48, 64, 3) and img.std() > 1 for img in images)
    assert {read_png(p, rgb=False).shape for p in lab} == {(48, 64)}
    assert ds.meta["generator"]["appearance"]["wall_styles"]["tiles"] > 0
    again = render(tmp_path / "b")
    for a, b in zip(ds.split("train")[0], again.split("train")[0], strict=True):
        # LLVM's threads may move a pixel by one level (docs/datagen.md)
        np.testing.assert_allclose(read_png(a).astype(int), read_png(b).astype(int), atol=1)
