"""realism.timing (dropped frames, timestamp jitter, odometry at its own rate with jumps) and
realism.flight (harder flights): seeded per frame, written as a recording's files, read back
with the odometry interpolated at the image timestamps."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import datagen.generate as gen
from core.config import compose_config
from core.dataset import Dataset
from core.imaging.realism import HarderFlightConfig, TimingConfig
from core.poses import read_tum, xyzyaw_from_pose
from datagen.dataset_writer import write_metadata
from datagen.flights import trajectories as TR
from datagen.job import check_inside, prepare, rng_for
from datagen.realism import timing as TM

FPS = 10.0
FLIGHT = ["splits.train=0", "splits.val=0", "splits.test=0", "render_flights=[paper]",
          "val_flights=[]"]


def frame_rngs(seed: int):
    return lambda i: rng_for(seed, 77, 10, i)


class TestFrameDelivery:
    def test_per_frame_streams(self):
        """Frame i's drop and stamp do not depend on how many frames the flight has."""
        c = TimingConfig(drop_rate=0.2, jitter_ms=4.0)
        d50, s50 = TM.frame_delivery(frame_rngs(1), 50, FPS, c)
        d20, s20 = TM.frame_delivery(frame_rngs(1), 20, FPS, c)
        np.testing.assert_array_equal(d50[:20], d20)
        np.testing.assert_array_equal(s50[:20], s20)
        d_other, _ = TM.frame_delivery(frame_rngs(2), 50, FPS, c)
        assert not np.array_equal(d50, d_other)

    def test_rates_and_order(self):
        c = TimingConfig(drop_rate=0.1, jitter_ms=5.0)
        delivered, stamps = TM.frame_delivery(frame_rngs(3), 3000, FPS, c)
        assert delivered[0] and 0.085 < 1 - delivered.mean() < 0.115
        err = (stamps - np.arange(3000) / FPS) * 1e3
        assert 4.5 < err.std() < 5.5 and np.abs(err).max() <= 15.0 + 1e-9
        assert np.all(np.diff(stamps) > 0)

    def test_off_is_the_capture_clock(self):
        delivered, stamps = TM.frame_delivery(frame_rngs(3), 30, FPS, TimingConfig())
        assert delivered.all()
        np.testing.assert_array_equal(stamps, TR.timestamps(30, FPS))
        assert not TM.is_active(TimingConfig())


class TestOdometry:
    def test_times_cover_the_flight(self):
        t = TM.odometry_times(30, FPS, TimingConfig(odometry_hz=37.0))
        assert t[0] == 0 and t[-1] >= 2.9 and np.allclose(np.diff(t), 1 / 37.0)
        np.testing.assert_array_equal(TM.odometry_times(30, FPS, TimingConfig()),
                                      TR.timestamps(30, FPS))

    def test_jumps(self):
        t = np.arange(600) / 30.0
        odo = np.tile(np.eye(4), (600, 1, 1))
        odo[:, 0, 3] = 0.5 * t
        c = TimingConfig(jump_per_min=6.0, jump_m=0.05, jump_deg=2.0)
        out, jumps = TM.odometry_jumps(np.random.default_rng(0), t, odo, c)
        assert jumps, "6 per minute over 20 s"
        # the motion between samples is the odometry's except across a jump
        rel = np.linalg.inv(out[:-1]) @ out[1:]
        rel0 = np.linalg.inv(odo[:-1]) @ odo[1:]
        off = np.abs(rel - rel0).max(axis=(1, 2)) > 1e-9
        np.testing.assert_array_equal(np.flatnonzero(off) + 1, [j["sample"] for j in jumps])
        for j in jumps:
            assert 0.025 - 1e-9 <= j["m"] <= 0.05 and 1.0 - 1e-9 <= abs(j["deg"]) <= 2.0
            k = j["sample"]
            dyaw = np.rad2deg(np.arctan2(rel[k - 1, 1, 0], rel[k - 1, 0, 0]))
            assert dyaw == pytest.approx(j["deg"], abs=1e-6)
        same, none = TM.odometry_jumps(np.random.default_rng(0), t, odo, TimingConfig())
        np.testing.assert_array_equal(same, odo)
        assert none == []

    def test_noise_per_second_is_rate_free(self):
        from datagen.config import OdometryConfig

        c = TM.odometry_at_rate(OdometryConfig(), FPS, 40.0)
        assert c.trans_noise_m == pytest.approx(OdometryConfig().trans_noise_m / 2)
        assert c.scale_walk == OdometryConfig().scale_walk


class TestSettings:
    @pytest.mark.parametrize("override,key", [
        ("realism.timing.drop_rate=-0.1", "realism.timing.drop_rate"),
        ("realism.timing.drop_rate=0.9", "realism.timing.drop_rate"),
        ("realism.timing.jitter_ms=-1", "realism.timing.jitter_ms"),
        ("realism.timing.jitter_ms=40", "realism.timing.jitter_ms"),
        ("realism.timing.odometry_hz=0", "realism.timing.odometry_hz"),
        ("realism.timing.jump_per_min=-2", "realism.timing.jump_per_min"),
        ("realism.timing.jump_m=5", "realism.timing.jump_m"),
        ("realism.flight.speed=[-1,1]", "realism.flight.speed"),
        ("realism.flight.turn_s=-1", "realism.flight.turn_s"),
    ])
    def test_bad_settings_stop_before_anything(self, tmp_path, override, key):
        out = tmp_path / "bad"
        cfg = compose_config("datagen", [*FLIGHT, "realism=real", override, f"out_dir={out}"])
        with pytest.raises(ValueError, match=key.replace(".", r"\.")):
            gen.run(cfg, progress=False)
        assert not out.exists()


class TestHarderFlights:
    def test_faster_quicker_both_ways(self):
        job = prepare(compose_config("datagen", FLIGHT))
        free, route = job.site.world.free, job.site.route
        h = HarderFlightConfig(enabled=True)
        peak_v, peak_yaw, first_dir = [], [], []
        for seed in range(6):
            gt = TR.flight_trajectory(np.random.default_rng(seed), 240, FPS, route, free,
                                      job.site.world.z_range, None, h,
                                      np.random.default_rng(100 + seed))
            check_inside(job.site, job.camera, gt, "harder")
            s = xyzyaw_from_pose(gt)
            v = np.linalg.norm(np.diff(s[:, :2], axis=0), axis=1) * FPS
            peak_v.append(v.max())
            peak_yaw.append(np.rad2deg(np.abs(np.angle(np.exp(1j * np.diff(s[:, 3])))).max())
                            * FPS)
            moving = np.flatnonzero(v > 0.3)[0]
            first_dir.append(np.sign(s[moving + 1, 1] - s[moving, 1]))
        assert 1.0 < max(peak_v) < 1.8, peak_v
        assert min(peak_yaw) > 30 and max(peak_yaw) < 90, peak_yaw
        assert {-1.0, 1.0} <= set(first_dir), "flown either way"
        # off: the preset's flight, bit for bit, whatever the harder generator
        a = TR.flight_trajectory(np.random.default_rng(0), 40, FPS, route, free,
                                 job.site.world.z_range)
        b = TR.flight_trajectory(np.random.default_rng(0), 40, FPS, route, free,
                                 job.site.world.z_range, None, HarderFlightConfig(),
                                 np.random.default_rng(5))
        np.testing.assert_array_equal(a, b)


def test_flight_files_and_reader(tmp_path):
    """A rendered 9-frame flight under realism.timing: dropped frames are neither rendered nor
    listed, images.txt has the jittered stamps, odometry.txt its own rate, and the reader's
    odometry is the odometry interpolated at the stamps: with noise-free odometry, the truth
    at the stamp, not at the capture."""
    out = tmp_path / "ds"
    zero = [f"flights.paper.odometry.{k}=0" for k in (
        "trans_noise_m", "yaw_noise_deg", "scale_error", "scale_walk", "yaw_bias_deg_s",
        "yaw_bias_walk_deg_s", "velocity_bias_walk")]
    cfg = compose_config("datagen", [
        *FLIGHT, "camera.width=48", "camera.height=36", "flights.paper.num_frames=9",
        "realism.timing.drop_rate=0.3", "realism.timing.jitter_ms=15",
        "realism.timing.odometry_hz=37", *zero, f"out_dir={out}"])
    gen.run(cfg, progress=False)
    job = prepare(cfg)
    f = job.flights["paper"]
    d = out / "flights" / "paper"
    dropped = np.flatnonzero(~f["delivered"])
    assert len(dropped), "seed 0 drops some of 9 frames at 30 %"
    info = json.loads((d / "flight.json").read_text())
    assert info["timing"]["dropped"] == dropped.tolist() and info["set"] == "test"
    for i in range(9):
        assert (d / "rgb" / f"{i:06d}.png").exists() == bool(f["delivered"][i])
    odo_t, _ = read_tum(d / "odometry.txt")
    np.testing.assert_allclose(np.diff(odo_t), 1 / 37.0, atol=1e-9)

    flight = Dataset(out).flight("paper")
    keep = np.flatnonzero(f["delivered"])
    np.testing.assert_array_equal(flight.frames, keep)
    np.testing.assert_allclose(flight.timestamps, f["stamps"][keep], atol=1e-9)
    assert np.abs(flight.timestamps - keep / FPS).max() > 0.005  # jittered
    np.testing.assert_allclose(flight.groundtruth, f["groundtruth"][keep], atol=1e-6)
    assert [p.name for p in flight.rgb] == [f"{i:06d}.png" for i in keep]
    truth_at_stamp = TM.resample_poses(f["groundtruth"], FPS, flight.timestamps)
    np.testing.assert_allclose(flight.odometry[:, :3, 3], truth_at_stamp[:, :3, 3], atol=2e-3)
    angle = (Rotation.from_matrix(flight.odometry[:, :3, :3]).inv()
             * Rotation.from_matrix(truth_at_stamp[:, :3, :3])).magnitude()
    assert np.rad2deg(angle).max() < 0.2


def test_ideal_clocks_are_todays(tmp_path):
    """realism=ideal: every frame delivered at i / fps, the odometry at the frame times, no
    images.txt and no flight.json timing; the reader gives the files' poses as they are."""
    out = tmp_path / "ds"
    job = prepare(compose_config("datagen", [*FLIGHT, "flights.paper.num_frames=20",
                                                 f"out_dir={out}"]))
    f = job.flights["paper"]
    assert f["delivered"].all() and f["jumps"] == []
    np.testing.assert_array_equal(f["stamps"], TR.timestamps(20, FPS))
    np.testing.assert_array_equal(f["odometry_times"], TR.timestamps(20, FPS))
    write_metadata(job, "scalar_rgb")
    d = out / "flights" / "paper"
    assert not (d / "images.txt").exists()
    assert "timing" not in json.loads((d / "flight.json").read_text())
    t, odo = read_tum(d / "odometry.txt")
    np.testing.assert_array_equal(t, TR.timestamps(20, FPS))
    np.testing.assert_allclose(odo, f["odometry"], atol=1e-6)
