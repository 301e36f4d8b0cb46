"""Tests of datagen.realism.ahrs: the AHRS's roll and pitch, and the realism presets that put them
into the flights' odometry."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest
import yaml
from hydra.errors import ConfigCompositionException
from scipy.spatial.transform import Rotation

import datagen.generate as gen
from core.config import CONF, compose_config, typed
from core.dataset import Dataset
from core.imaging.realism import AhrsConfig, RealismConfig
from core.poses import pose_from_xyz_rpy, read_tum
from datagen.config import DatagenConfig
from datagen.dataset_writer import write_metadata
from datagen.flights import trajectories as TR
from datagen.job import flight_stream, prepare, rng_for
from datagen.realism import ahrs

FPS = 10.0
N_LONG = 200_000  # samples: 20,000 s at 10 fps, 2,000 drift correlation times
NO_SPLITS = ["splits.train=0", "splits.val=0", "splits.test=0",
             "flights.paper.num_frames=40", "flights.cluttered.num_frames=40"]
#: realism=real without its timing and harder flights: the trajectories and clocks of ideal
AHRS_ONLY = ["realism.timing.drop_rate=0", "realism.timing.jitter_ms=0",
             "realism.timing.odometry_hz=null", "realism.timing.jump_per_min=0",
             "realism.flight.enabled=false"]


def error_deg(settings, n=N_LONG, seed=0, fps=FPS) -> np.ndarray:
    """(n, 2) AHRS roll and pitch minus a moving truth, degrees."""
    t = np.arange(n) / fps
    roll, pitch = 0.1 * np.sin(0.5 * t), 0.05 * np.cos(0.3 * t)
    r, p = ahrs.ahrs_attitude(np.random.default_rng(seed), roll, pitch, fps, settings)
    return np.rad2deg(np.stack([r - roll, p - pitch], 1))


def autocorrelation(x: np.ndarray, lag: int) -> np.ndarray:
    """(2,) autocorrelation of each column of x (n, 2) at a lag in samples."""
    x = x - x.mean(0)
    return (x[:-lag] * x[lag:]).mean(0) / x.var(0)


def rpy(T: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz")


def real_settings() -> AhrsConfig:
    return AhrsConfig(**yaml.safe_load((CONF / "realism" / "real.yaml").read_text())["ahrs"])


class TestModel:
    def test_same_seed_same_output(self):
        a = error_deg(real_settings(), n=500, seed=3)
        np.testing.assert_array_equal(a, error_deg(real_settings(), n=500, seed=3))
        assert not np.allclose(a, error_deg(real_settings(), n=500, seed=4))

    def test_off_is_the_truth(self):
        roll, pitch = np.linspace(-0.1, 0.1, 50), np.linspace(0.05, -0.02, 50)
        for settings in (None, AhrsConfig(), {"drift_time_s": 3.0}):
            r, p = ahrs.ahrs_attitude(np.random.default_rng(0), roll, pitch, FPS, settings)
            np.testing.assert_array_equal(r, roll)
            np.testing.assert_array_equal(p, pitch)

    def test_white_noise(self):
        e = error_deg({"noise_deg": 0.2})
        np.testing.assert_allclose(e.std(0), 0.2, rtol=0.02)
        np.testing.assert_allclose(e.mean(0), 0.0, atol=0.002)
        assert np.abs(autocorrelation(e, 1)).max() < 0.01

    def test_bias_is_constant_per_flight(self):
        c = AhrsConfig(bias_deg=0.3)
        biases = np.stack([error_deg(c, n=20, seed=s) for s in range(1000)])
        assert np.all(biases.std(axis=1) < 1e-12), "one value over a flight"
        np.testing.assert_allclose(biases[:, 0].std(0), 0.3, rtol=0.08)
        assert abs(np.corrcoef(biases[:, 0, 0], biases[:, 0, 1])[0, 1]) < 0.1, \
            "roll's and pitch's biases are drawn apart"

    def test_drift_std_and_correlation_time(self):
        e = error_deg({"drift_deg": 0.5, "drift_time_s": 10.0})
        np.testing.assert_allclose(e.std(0), 0.5, rtol=0.08)
        np.testing.assert_allclose(autocorrelation(e, 1), np.exp(-0.1 / 10.0), atol=0.01)
        np.testing.assert_allclose(autocorrelation(e, 100), np.exp(-1.0), atol=0.06)
        assert np.abs(autocorrelation(e, 1000)).max() < 0.06

    def test_drift_stays_bounded(self):
        """A stationary process: the last stretch spreads as much as the first, never far."""
        e = error_deg({"drift_deg": 0.5, "drift_time_s": 10.0})
        tenth = N_LONG // 10
        np.testing.assert_allclose(e[:tenth].std(0), 0.5, rtol=0.2)
        np.testing.assert_allclose(e[-tenth:].std(0), 0.5, rtol=0.2)
        assert np.abs(e).max() < 6 * 0.5

    def test_real_magnitudes(self):
        """realism=real: per axis about 0.6 deg RMS over flights, within a small drone's
        0.5-1 deg dynamic error; a flight's mean error is its bias."""
        c = real_settings()
        e = np.stack([error_deg(c, n=2400, seed=s) for s in range(300)])  # (flights, n, 2)
        total = np.sqrt(c.bias_deg**2 + c.noise_deg**2 + c.drift_deg**2)
        assert 0.5 <= total <= 1.0
        np.testing.assert_allclose(np.sqrt((e**2).mean((0, 1))), total, rtol=0.1)
        within = np.sqrt(c.noise_deg**2 + c.drift_deg**2 * (1 - 10.0 / 240.0 * 2))
        np.testing.assert_allclose(e.std(1).mean(0), within, rtol=0.15)

    @pytest.mark.parametrize("key,value,match", [
        ("bias_deg", -0.1, "realism.ahrs.bias_deg = -0.1 must be"),
        ("noise_deg", float("nan"), "realism.ahrs.noise_deg"),
        ("drift_deg", 20.0, r"realism.ahrs.drift_deg = 20.0 .* \[0, 10.0\]"),
        ("drift_time_s", 0.0, "realism.ahrs.drift_time_s = 0.0 must be > 0 s"),
        ("drift_time_s", -5.0, "set drift_deg: 0 to turn the drift off"),
    ])
    def test_bad_settings(self, key, value, match):
        with pytest.raises(ValueError, match=match):
            ahrs.ahrs_attitude(np.random.default_rng(0), np.zeros(5), np.zeros(5), FPS,
                               {key: value})

    def test_bad_input(self):
        rng = np.random.default_rng(0)
        with pytest.raises(ValueError, match="one length"):
            ahrs.ahrs_attitude(rng, np.zeros(5), np.zeros(4), FPS, real_settings())
        with pytest.raises(ValueError, match="fps = 0"):
            ahrs.ahrs_attitude(rng, np.zeros(5), np.zeros(5), 0.0, real_settings())
        with pytest.raises(ValueError, match="realism.ahrs.noise: "):
            ahrs.ahrs_attitude(rng, np.zeros(5), np.zeros(5), FPS, {"noise": 0.1})
        with pytest.raises(ValueError, match=r"\(N, 4, 4\)"):
            ahrs.ahrs_odometry(rng, np.tile(np.eye(4), (5, 1, 1)), np.tile(np.eye(4), (4, 1, 1)),
                               FPS, real_settings())


class TestOdometry:
    def test_only_roll_and_pitch_change(self):
        t = np.arange(300) / FPS
        xyz = np.stack([np.sin(0.2 * t), 0.4 * t, 1.2 + 0.1 * np.cos(t)], 1)
        gt_rpy = np.stack([0.05 * np.sin(t), 0.08 * np.cos(0.7 * t), 3.0 * np.sin(0.1 * t)], 1)
        gt = pose_from_xyz_rpy(xyz, gt_rpy)
        odo = TR.noisy_odometry(np.random.default_rng(1), gt, FPS)
        out = ahrs.ahrs_odometry(np.random.default_rng(2), odo, gt, FPS, real_settings())
        np.testing.assert_array_equal(out[:, :3, 3], odo[:, :3, 3])
        yaw_diff = rpy(out)[:, 2] - rpy(odo)[:, 2]
        assert np.abs(np.angle(np.exp(1j * yaw_diff))).max() < 1e-12
        r, p = ahrs.ahrs_attitude(np.random.default_rng(2), gt_rpy[:, 0], gt_rpy[:, 1], FPS,
                                  real_settings())
        np.testing.assert_allclose(rpy(out)[:, :2], np.stack([r, p], 1), atol=1e-12)
        assert np.abs(rpy(out)[:, :2] - gt_rpy[:, :2]).max() > np.deg2rad(0.2)
        off = ahrs.ahrs_odometry(np.random.default_rng(2), odo, gt, FPS, None)
        np.testing.assert_array_equal(off, odo)


class TestRealismPreset:
    def test_presets_compose(self):
        ideal = typed(DatagenConfig, compose_config("datagen"), "datagen").realism
        assert ideal == RealismConfig(), "realism=ideal is the default and the defaults"
        real = typed(DatagenConfig, compose_config("datagen", ["realism=real"]), "datagen")
        assert real.realism.name == "real"
        assert real.realism.ahrs == real_settings()
        assert ahrs.is_active(real.realism.ahrs) and not ahrs.is_active(ideal.ahrs)

    def test_ideal_odometry_is_todays(self):
        """Default preset: each flight's odometry is noisy_odometry's, bit for bit."""
        cfg = typed(DatagenConfig, compose_config("datagen", NO_SPLITS), "datagen")
        job = prepare(cfg)
        free = job.site.world.free
        for name, f in job.flights.items():
            preset = cfg.flights[f["preset_name"]]
            stream = flight_stream(name, preset.seed)
            route = TR.flight_route(preset, free, job.site.route,
                                    rng_for(cfg.seed, stream, 3), f"flights.{name}")
            r = rng_for(cfg.seed, stream, 0)
            gt = TR.flight_trajectory(r, preset.num_frames, preset.fps, route, free,
                                      job.site.world.z_range, preset.trajectory)
            np.testing.assert_array_equal(f["groundtruth"], gt)
            np.testing.assert_array_equal(
                f["odometry"], TR.noisy_odometry(r, gt, preset.fps, preset.odometry))

    def test_real_reaches_the_flights_odometry(self, tmp_path):
        ideal = prepare(compose_config("datagen", NO_SPLITS))
        out = tmp_path / "ds"
        job = prepare(compose_config("datagen", [*NO_SPLITS, "realism=real", *AHRS_ONLY,
                                                     f"out_dir={out}"]))
        write_metadata(job, "scalar_rgb")
        for name, f in job.flights.items():
            gt, odo = f["groundtruth"], f["odometry"]
            base = ideal.flights[name]["odometry"]
            np.testing.assert_array_equal(gt, ideal.flights[name]["groundtruth"])
            np.testing.assert_array_equal(odo[:, :3, 3], base[:, :3, 3])
            np.testing.assert_allclose(np.unwrap(rpy(odo)[:, 2]), np.unwrap(rpy(base)[:, 2]),
                                       atol=1e-12)
            tilt_error = np.rad2deg(rpy(odo)[:, :2] - rpy(gt)[:, :2])
            assert np.abs(tilt_error).min() > 0 and np.abs(tilt_error).max() < 3.0
            assert np.sqrt((tilt_error**2).mean()) > 0.05
            _, written = read_tum(out / "flights" / name / "odometry.txt")
            np.testing.assert_allclose(written, odo, atol=1e-6)
            meta = json.loads((out / "flights" / name / "flight.json").read_text())
            assert meta["realism"] == asdict(job.cfg.realism)
            assert meta["realism"]["name"] == job.cfg.realism.name
        generator = json.loads((out / "dataset.json").read_text())["generator"]
        assert generator["realism"]["name"] == job.cfg.realism.name
        # what localize's report names: the preset and what was changed in it
        assert Dataset(out).realism == ("real + timing.drop_rate, timing.jitter_ms, "
                                        "timing.odometry_hz, timing.jump_per_min, flight.enabled")

    def test_bad_settings_stop_before_anything(self, tmp_path):
        out = tmp_path / "bad"
        cfg = compose_config("datagen", [*NO_SPLITS, "realism=real",
                                         "realism.ahrs.drift_time_s=0", f"out_dir={out}"])
        with pytest.raises(ValueError, match="realism.ahrs.drift_time_s"):
            gen.run(cfg, progress=False)
        assert not out.exists()
        with pytest.raises(ConfigCompositionException, match="realism.ahrs.bias"):
            compose_config("datagen", ["realism.ahrs.bias=0.3"])
