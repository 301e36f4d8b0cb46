"""Tests of core.imaging.camera_effects: sensor noise, exposure changes, JPEG and dropouts on the
flights' images, and their wiring into datagen (realism=real)."""

from __future__ import annotations

import json
from dataclasses import asdict

import cv2
import numpy as np
import pytest
import yaml

import datagen.generate as gen
from core.atomic import read_png
from core.config import CONF, compose_config, typed
from core.imaging import camera_effects as E
from core.imaging import colour
from core.imaging.realism import (
    DropoutConfig,
    ExposureConfig,
    JpegConfig,
    RealismConfig,
    SensorNoiseConfig,
)
from datagen.config import DatagenConfig
from datagen.job import prepare
from datagen.rendering.flight import flight_effect

FPS = 10.0


#: realism=real without its timing and harder flights: ideal's poses and frames
IMAGES_ONLY = ["realism.timing.drop_rate=0", "realism.timing.jitter_ms=0",
               "realism.timing.odometry_hz=null", "realism.timing.jump_per_min=0",
               "realism.flight.enabled=false"]


def real_settings() -> RealismConfig:
    return typed(RealismConfig, yaml.safe_load((CONF / "realism" / "real.yaml").read_text()),
                 "realism")


def textured(seed: int = 0, h: int = 48, w: int = 64) -> np.ndarray:
    """(h, w, 3) uint8: smooth gradients, a few edges and some fine texture."""
    r = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    base = np.stack([0.3 + 0.4 * x, 0.2 + 0.5 * y, 0.5 + 0.3 * np.sin(6 * x + 3 * y)], -1)
    base[h // 3:2 * h // 3, w // 4:w // 2] *= 0.4
    base += 0.02 * r.standard_normal((h, w, 3))
    return np.clip(base * 255, 0, 255).astype(np.uint8)


def flat(level: int, h: int = 64, w: int = 64) -> np.ndarray:
    return np.full((h, w, 3), level, np.uint8)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return 10 * np.log10(255.0**2 / mse)


class TestFrames:
    def test_same_seed_same_output(self):
        img, c = textured(), real_settings()
        a = E.apply_effects(img, np.random.default_rng(3), c, ev=0.4, dropout="covered")
        b = E.apply_effects(img, np.random.default_rng(3), c, ev=0.4, dropout="covered")
        np.testing.assert_array_equal(a, b)
        assert not np.array_equal(
            a, E.apply_effects(img, np.random.default_rng(4), c, ev=0.4, dropout="covered"))

    @pytest.mark.parametrize("settings", [None, RealismConfig(), {"name": "x"},
                                          {"exposure": {"drift_time_s": 9.0}}])
    def test_off_is_identity(self, settings):
        img = textured()
        out = E.apply_effects(img, np.random.default_rng(0), settings)
        assert out is img
        c = E.check_settings(settings)
        assert not E.is_active(c)
        np.testing.assert_array_equal(E.exposure_ev(np.random.default_rng(0), 50, FPS,
                                                    c.exposure), np.zeros(50))
        assert E.dropout_stretches(np.random.default_rng(0), 50, FPS, c.dropout) == []

    def test_zero_noise_and_exposure_round_trip(self):
        """Through linear light and back without a change: every 8-bit level comes back."""
        from core.imaging.colour import linear_to_srgb8

        levels = np.arange(256, dtype=np.uint8).reshape(16, 16, 1).repeat(3, axis=2)
        np.testing.assert_array_equal(linear_to_srgb8(colour.to_linear(levels)), levels)
        np.testing.assert_array_equal(E.sensor_noise(np.random.default_rng(0),
                                                     colour.to_linear(levels), None),
                                      colour.to_linear(levels))

    @pytest.mark.parametrize("full_well,read", [(500.0, 3.0), (2000.0, 0.0), (200.0, 4.0)])
    def test_noise_variance_is_poisson_gaussian(self, full_well, read):
        """Measured per-pixel variance in linear light against x / FW + (read / FW)^2."""
        c = SensorNoiseConfig(full_well_e=full_well, read_noise_e=read)
        levels = np.array([0.1, 0.2, 0.3, 0.5, 0.7])
        x = np.broadcast_to(levels[:, None, None, None], (5, 64, 64, 3)).astype(np.float32)
        y = E.sensor_noise(np.random.default_rng(0), x, c)
        measured = y.reshape(5, -1).var(axis=1)
        model = levels / full_well + (read / full_well) ** 2
        np.testing.assert_allclose(measured, model, rtol=0.06)
        np.testing.assert_allclose(y.reshape(5, -1).mean(axis=1), levels,
                                   atol=4 * np.sqrt(model / y[0].size).max())
        assert np.all(np.diff(measured) > 0), "variance grows with brightness"

    def test_noise_on_8bit_images(self):
        """End to end on uint8 sRGB: variance of the linearized output follows the model
        (plus the 8-bit step's), and grows with brightness."""
        c = RealismConfig(noise=SensorNoiseConfig(full_well_e=300.0, read_noise_e=2.0))
        measured, model = [], []
        for level in (40, 90, 140, 200):
            out = E.apply_effects(flat(level), np.random.default_rng(level), c)
            x = float(colour.LINEAR_LUT[level])
            step = colour.LINEAR_LUT[min(level + 1, 255)] - colour.LINEAR_LUT[level]
            measured.append(colour.to_linear(out).var())
            model.append(x / 300.0 + (2.0 / 300.0) ** 2 + step**2 / 12)
        np.testing.assert_allclose(measured, model, rtol=0.15)
        assert np.all(np.diff(measured) > 0)

    def test_exposure_gain(self):
        """ev = 1 doubles linear light, ev = -1 halves it."""
        img = flat(90)
        x = colour.LINEAR_LUT[90]
        for ev, factor in ((1.0, 2.0), (-1.0, 0.5)):
            out = E.apply_effects(img, np.random.default_rng(0), None, ev=ev)
            np.testing.assert_allclose(colour.to_linear(out).mean(), factor * x, rtol=0.02)

    def test_jpeg_quality(self):
        img = textured(1, 96, 128)
        scores = [psnr(img, E.jpeg(img, q)) for q in (95, 85, 75, 50, 20)]
        assert all(np.isfinite(scores)), "each quality changes the image"
        assert np.all(np.diff(scores) < 0), f"PSNR falls with the quality: {scores}"
        assert scores[0] > 30 and scores[-1] < scores[0] - 2
        out = E.apply_effects(img, np.random.default_rng(0), {"jpeg": {"quality": 85}})
        np.testing.assert_array_equal(out, E.jpeg(img, 85))

    def test_dropout_kinds_look_their_kind(self):
        img, rng = textured(2, 96, 128), np.random.default_rng(0)
        black = E.apply_effects(img, rng, real_settings(), ev=0.3, dropout="black")
        assert black.shape == img.shape and black.max() == 0
        noise = E.apply_effects(img, rng, None, dropout="noise")
        assert abs(noise.mean() - 127.5) < 2 and abs(noise.std() - 73.9) < 2
        assert abs(np.corrcoef(noise.ravel(), img.ravel())[0, 1]) < 0.05
        covered = E.apply_effects(img, rng, None, dropout="covered")
        assert covered.mean() < 0.4 * img.mean()
        sharp = cv2.Laplacian(img.astype(np.float32), cv2.CV_32F).var()
        assert cv2.Laplacian(covered.astype(np.float32), cv2.CV_32F).var() < 0.01 * sharp


class TestFlightSeries:
    def test_exposure_drift(self):
        c = ExposureConfig(drift_ev=0.2, drift_time_s=2.0, max_ev=8.0)
        ev = np.stack([E.exposure_ev(np.random.default_rng(s), 200, FPS, c) for s in range(300)])
        np.testing.assert_allclose(ev.std(), 0.2, rtol=0.05)
        lag = 20  # frames: 2 s, one drift_time_s
        corr = (ev[:, :-lag] * ev[:, lag:]).mean() / ev.var()
        np.testing.assert_allclose(corr, np.exp(-0.5), atol=0.05)
        step = np.abs(np.diff(ev, axis=1)).mean()
        assert step < 0.05 * 0.2 * 4, "smooth: a frame's change is a small part of the std"

    def test_exposure_steps_and_bound(self):
        c = ExposureConfig(steps_per_min=6.0, step_ev=1.0, settle_s=0.5, max_ev=1.2)
        ev = np.stack([E.exposure_ev(np.random.default_rng(s), 600, FPS, c) for s in range(50)])
        assert np.abs(ev).max() <= 1.2
        jumps = np.abs(np.diff(ev, axis=1))
        assert jumps.max() > 0.5, "steps are sudden"
        big = (jumps > 0.5).sum() / 50
        np.testing.assert_allclose(big, 6.0, rtol=0.3)  # steps per 60 s flight
        one = E.exposure_ev(np.random.default_rng(1), 600, FPS, c)
        k = int(np.argmax(np.abs(np.diff(one)))) + 1
        decay = one[k + 5] / one[k]  # 0.5 s later: exp(-1), give or take a second step
        assert 0.2 < decay < 0.5

    def test_dropout_at_given_times(self):
        c = DropoutConfig(at_s=[3.0, 0.55], duration_s=[2.0, 2.0], kinds=["noise"])
        d = E.dropout_stretches(np.random.default_rng(0), 100, FPS, c)
        assert [(x.first, x.stop, x.kind) for x in d] == [(6, 26, "noise"), (30, 50, "noise")]
        assert [i for i in range(100) if E.dropout_kind(d, i)] == [*range(6, 26), *range(30, 50)]
        end = E.dropout_stretches(np.random.default_rng(0), 40, FPS,
                                  DropoutConfig(at_s=[3.0], duration_s=[2.0, 2.0]))
        assert (end[0].first, end[0].stop, end[0].duration_s) == (30, 40, 1.0)

    def test_dropout_rate(self):
        c = DropoutConfig(per_min=3.0, duration_s=[1.0, 3.0])
        flights = [E.dropout_stretches(np.random.default_rng(s), 600, FPS, c) for s in range(400)]
        count = np.mean([len(f) for f in flights])
        np.testing.assert_allclose(count, 60.0 / (20.0 + 2.0) * 1.0, rtol=0.12)
        lengths = np.concatenate([[x.duration_s for x in f if x.stop < 600] for f in flights])
        assert 1.0 <= lengths.min() and lengths.max() <= 3.0
        for f in flights:
            for a, b in zip(f[:-1], f[1:], strict=True):
                assert a.stop <= b.first
        kinds = [x.kind for f in flights for x in f]
        assert {k: kinds.count(k) / len(kinds) > 0.25 for k in E.KINDS} == dict.fromkeys(
            E.KINDS, True)


class TestSettings:
    @pytest.mark.parametrize("settings,match", [
        ({"noise": {"full_well_e": -1.0}}, r"realism.noise.full_well_e = -1.0 must be"),
        ({"noise": {"full_well_e": 100.0, "read_noise_e": float("nan")}},
         "realism.noise.read_noise_e = nan"),
        ({"noise": {"read_noise_e": 2.0}}, "needs realism.noise.full_well_e > 0"),
        ({"jpeg": {"quality": 0}}, r"realism.jpeg.quality = 0 must be an integer in \[1, 100\]"),
        ({"jpeg": {"quality": 101}}, "realism.jpeg.quality = 101"),
        ({"exposure": {"drift_ev": -0.1}}, "realism.exposure.drift_ev = -0.1"),
        ({"exposure": {"drift_time_s": 0.0}}, "realism.exposure.drift_time_s = 0.0 must be"),
        ({"exposure": {"settle_s": -1.0}}, "realism.exposure.settle_s"),
        ({"exposure": {"max_ev": 0.0}}, "realism.exposure.max_ev"),
        ({"exposure": {"steps_per_min": -2.0}}, "realism.exposure.steps_per_min"),
        ({"dropout": {"duration_s": [0.0, 1.0]}}, r"realism.dropout.duration_s = \[0.0, 1.0\]"),
        ({"dropout": {"duration_s": [3.0, 1.0]}}, "0 < min <= max"),
        ({"dropout": {"duration_s": [1.0]}}, "realism.dropout.duration_s"),
        ({"dropout": {"kinds": ["fog"]}}, "realism.dropout.kinds"),
        ({"dropout": {"kinds": []}}, "non-empty"),
        ({"dropout": {"per_min": -1.0}}, "realism.dropout.per_min = -1.0"),
        ({"dropout": {"at_s": [-1.0]}}, "realism.dropout.at_s = -1.0"),
        ({"dropout": {"at_s": [2.0], "per_min": 1.0}}, "not both"),
    ])
    def test_bad_settings(self, settings, match):
        with pytest.raises(ValueError, match=match):
            E.check_settings(settings)
        with pytest.raises(ValueError, match=match):
            E.apply_effects(textured(), np.random.default_rng(0), settings)

    @pytest.mark.parametrize("settings,match", [
        (DropoutConfig(per_min=1.0, duration_s=[1.0, 5.0]), "longer than the flight"),
        (DropoutConfig(at_s=[4.5]), r"at_s: a dropout at 4.5 s starts after"),
        (DropoutConfig(at_s=[1.0, 2.0], duration_s=[1.0, 1.5]), "may overlap"),
    ])
    def test_dropout_must_fit_the_flight(self, settings, match):
        with pytest.raises(ValueError, match=f"realism.dropout.*{match}"):
            E.dropout_stretches(np.random.default_rng(0), 40, FPS, settings)

    def test_bad_input(self):
        with pytest.raises(ValueError, match=r"\(H, W, 3\) uint8"):
            E.apply_effects(textured().astype(np.float32), np.random.default_rng(0))
        with pytest.raises(ValueError, match="dropout = 'fog'"):
            E.apply_effects(textured(), np.random.default_rng(0), dropout="fog")
        with pytest.raises(ValueError, match="realism.jpeg.qualty"):
            E.check_settings({"jpeg": {"qualty": 80}})

    def test_presets(self):
        ideal = typed(DatagenConfig, compose_config("datagen"), "datagen").realism
        assert not E.is_active(ideal)
        real = typed(DatagenConfig, compose_config("datagen", ["realism=real"]), "datagen")
        assert real.realism == real_settings() and E.is_active(real.realism)
        assert real.realism.jpeg == JpegConfig(quality=85)


#: realism=real's optics off (datagen/realism/optics.py; tests/datagen/test_optics.py): the rendered
#: frames are the ideal's, the image effects alone change them.
NO_OPTICS = ["realism.lens.k1=0", "realism.lens.k2=0", "realism.lens.p1=0", "realism.lens.p2=0",
             "realism.motion_blur.exposure_s=0", "realism.rolling_shutter.readout_s=0"]


class TestDatagen:
    FLIGHT = ["splits.train=0", "splits.val=0", "splits.test=0", "render_flights=[paper]",
              "flights.paper.num_frames=20"]

    def test_frames_independent_of_what_was_rendered(self):
        """Frame 7's effects are the same whether frames 0-6 were processed or not."""
        job = prepare(compose_config("datagen", [*self.FLIGHT, "realism=real",
                                                     "realism.dropout.per_min=0",
                                                     "realism.dropout.at_s=[0.2]",
                                                     "realism.dropout.duration_s=[0.3,0.3]"]))
        images = [textured(i) for i in range(8)]
        in_order = [flight_effect(job, "paper", i)(images[i]) for i in range(8)]
        alone = flight_effect(job, "paper", 7)(images[7])
        np.testing.assert_array_equal(alone, in_order[7])
        assert not np.array_equal(in_order[6], flight_effect(job, "paper", 7)(images[6]))
        (d,) = job.flights["paper"]["dropout"]
        assert (d.first, d.stop) == (2, 5)
        ideal = prepare(compose_config("datagen", self.FLIGHT))
        assert flight_effect(ideal, "paper", 7) is None
        assert ideal.flights["paper"]["dropout"] == []

    def test_flight_images_get_the_effects(self, tmp_path):
        """A 3-frame flight under realism (JPEG, noise, a black dropout at frame 1): labels as
        under ideal, rgb the ideal's through apply_effects, flight.json lists the dropout, a
        resumed run writes the same image."""
        small = ["camera.width=64", "camera.height=48", "splits.train=0", "splits.val=0",
                 "splits.test=0", "render.spp=1", "render_flights=[cluttered]",
                 "flights.cluttered.num_frames=3"]
        effects = ["realism=real", *IMAGES_ONLY, *NO_OPTICS, "realism.dropout.per_min=0",
                   "realism.dropout.at_s=[0.1]",
                   "realism.dropout.duration_s=[0.1,0.1]", "realism.dropout.kinds=[black]",
                   "realism.map.builtins=0"]  # real's built-in cabinet changes what is rendered
        ideal, real = tmp_path / "ideal", tmp_path / "real"
        gen.run(compose_config("datagen", [*small, f"out_dir={ideal}"]), progress=False)
        cfg = compose_config("datagen", [*small, *effects, f"out_dir={real}"])
        gen.run(cfg, progress=False)
        job = prepare(cfg)
        a, b = ideal / "flights" / "cluttered", real / "flights" / "cluttered"
        for i in range(3):
            name = f"{i:06d}.png"
            np.testing.assert_array_equal(read_png(a / "label" / name, rgb=False),
                                          read_png(b / "label" / name, rgb=False))
            rendered, written = read_png(a / "rgb" / name), read_png(b / "rgb" / name)
            expected = flight_effect(job, "cluttered", i)(rendered)
            assert (written == expected).mean() > 0.99  # LLVM: rarely one level off
            assert not np.array_equal(written, rendered)
        assert read_png(b / "rgb" / "000001.png").max() == 0
        meta = json.loads((b / "flight.json").read_text())
        assert meta["dropout"] == [{"kind": "black", "start_s": 0.1, "duration_s": 0.1,
                                    "frames": [1, 2]}]
        assert meta["realism"] == asdict(job.cfg.realism)
        assert json.loads((a / "flight.json").read_text())["dropout"] == []

        # Resumed after frame 2 was lost: the same bytes (its effects are its own).
        written = read_png(b / "rgb" / "000002.png")
        for sub in ("rgb", "label"):
            (b / sub / "000002.png").unlink()
        gen.run(cfg, progress=False)
        assert (read_png(b / "rgb" / "000002.png") == written).mean() > 0.99  # LLVM, as above

    def test_bad_settings_stop_before_anything(self, tmp_path):
        out = tmp_path / "bad"
        for override, match in (("realism.jpeg.quality=0", "realism.jpeg.quality"),
                                ("realism.dropout.duration_s=[1,5]",
                                 "flights.paper: realism.dropout.duration_s")):
            cfg = compose_config("datagen", [*self.FLIGHT, "flights.paper.num_frames=40",
                                             "realism=real", override, f"out_dir={out}"])
            with pytest.raises(ValueError, match=match):
                gen.run(cfg, progress=False)
            assert not out.exists()
