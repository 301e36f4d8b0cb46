"""Tests of datagen.flights.trajectories: training poses, flights and noisy odometry."""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.config import compose_config
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyz_rpy, xyzyaw_from_pose
from datagen.config import OdometryConfig
from datagen.flights import training_views as TV
from datagen.flights import trajectories as TR

CONF = Path(__file__).resolve().parents[2] / "conf"
BOXES = np.array([[-0.7, 0.3, 0.7, 9.7], [-2.7, 5.7, -0.7, 6.7]])
Z = np.array([0.5, 2.2])
FREE = OccupancyMap.from_boxes(BOXES, Z, cell=0.05, margin=0.3)  # the corridor's free space
ROUTE = np.array([[0.0, 0.3], [0.0, 9.7]])  # its own route, the centre line


@pytest.fixture(scope="module")
def flights():
    """The composed config's flight presets (``FlightConfig``)."""
    from core.config import typed
    from datagen.config import DatagenConfig

    return typed(DatagenConfig, compose_config("datagen"), "datagen").flights


def rpy(T: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz")


def assert_rigid(T: np.ndarray) -> None:
    R = T[:, :3, :3]
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    np.testing.assert_array_equal(T[:, 3], np.broadcast_to([0, 0, 0, 1], (len(T), 4)))


class TestTrainingPoses:
    def test_inside_and_bounded(self):
        T = TV.sample_training_poses(np.random.default_rng(0), 4000, FREE, Z, 5.0,
                                     along_fraction=0.0)
        assert T.shape == (4000, 4, 4)
        assert_rigid(T)
        p = T[:, :3, 3]
        assert FREE.contains(p[:, :2]).all()
        assert np.all((p[:, 2] >= Z[0]) & (p[:, 2] <= Z[1]))
        angles = rpy(T)
        assert np.abs(angles[:, :2]).max() <= np.deg2rad(5.0) + 1e-9
        # yaw all around, positions area-weighted over the boxes
        hist = np.histogram(angles[:, 2], bins=8, range=(-np.pi, np.pi))[0]
        assert hist.min() > 0.7 * 4000 / 8
        area = np.prod(BOXES[:, 2:] - BOXES[:, :2], axis=1)
        in_opening = (p[:, 0] < -0.725).mean()
        assert in_opening == pytest.approx(area[1] / area.sum(), abs=0.02)

    def test_along_corridor_share(self):
        main = OccupancyMap.from_boxes(BOXES[:1], Z, cell=0.05, margin=0.3)
        T = TV.sample_training_poses(np.random.default_rng(1), 4000, main, Z, 5.0,
                                     along_fraction=0.75, along_spread_deg=30.0)
        yaw = rpy(T)[:, 2]
        off_axis = np.abs(np.abs(yaw) - np.pi / 2)  # angle from the nearest of +Y, -Y
        near = off_axis <= np.deg2rad(30.0) + 1e-9
        # 75 % along the axis plus the uniform quarter's share of that range (1/3)
        assert near.mean() == pytest.approx(0.75 + 0.25 / 3, abs=0.03)
        assert (yaw > 0).mean() == pytest.approx(0.5, abs=0.04)  # both directions
        with pytest.raises(ValueError, match="yaw_along_corridor"):
            TV.sample_training_poses(np.random.default_rng(0), 3, FREE, Z, along_fraction=1.5)

    def test_deterministic(self):
        a = TV.sample_training_poses(np.random.default_rng(4), 10, FREE, Z)
        b = TV.sample_training_poses(np.random.default_rng(4), 10, FREE, Z)
        np.testing.assert_array_equal(a, b)

    def test_bad_input(self):
        with pytest.raises(ValueError, match="z_range"):
            TV.sample_training_poses(np.random.default_rng(0), 3, FREE, [2.0, 1.0])

    def test_view_depth(self):
        """The free space ahead, to the edges of its box: along the corridor (+Y from y = 1)
        8.7 m, across it (+X from x = 0) 0.7 m."""
        along = pose_from_xyz_rpy(np.array([[0.0, 1.0, 1.0]]), np.array([[0, 0, np.pi / 2]]))
        across = pose_from_xyz_rpy(np.array([[0.0, 1.0, 1.0]]), np.array([[0, 0, 0.0]]))
        d = TV.view_depth(FREE, np.concatenate([along, across]), 20.0)
        np.testing.assert_allclose(d, [8.7, 0.7], atol=0.05)
        assert TV.view_depth(FREE, along, 3.0)[0] == pytest.approx(3.0)

    def test_min_view(self):
        """min_view_m draws again the poses that see less free space ahead; 0 draws exactly
        what no check draws."""
        free = TV.view_depth(FREE, TV.sample_training_poses(
            np.random.default_rng(2), 500, FREE, Z, along_fraction=0.0), 3.0)
        assert (free < 1.0).mean() > 0.3  # a uniform yaw in a 2 m corridor faces the walls
        T = TV.sample_training_poses(np.random.default_rng(2), 500, FREE, Z, along_fraction=0.0,
                                     min_view_m=1.0)
        assert (TV.view_depth(FREE, T, 3.0) >= 1.0).all()
        np.testing.assert_array_equal(
            TV.sample_training_poses(np.random.default_rng(3), 20, FREE, Z, min_view_m=0.0),
            TV.sample_training_poses(np.random.default_rng(3), 20, FREE, Z))


class TestFlightViews:
    def test_posed_as_the_flights(self, flights):
        presets = [flights["paper"], flights["cluttered"]]
        T = TR.sample_flight_views(np.random.default_rng(0), 300, FREE, Z, presets, [ROUTE] * 2)
        assert T.shape == (300, 4, 4)
        assert_rigid(T)
        s = xyzyaw_from_pose(T)
        # in the main corridor, at the presets' heights (+- sway), both directions
        assert np.all((s[:, 0] > -0.7) & (s[:, 0] < 0.7) & (s[:, 1] > 0.3) & (s[:, 1] < 9.7))
        assert np.all((s[:, 2] >= 1.0 - 0.2 - 1e-9) & (s[:, 2] <= 1.5 + 0.2 + 1e-9))
        off_axis = np.abs(np.abs(s[:, 3]) - np.pi / 2)
        assert off_axis.max() <= np.deg2rad(40.0) + 1e-9  # the presets' largest yaw swing
        assert (s[:, 3] > 0).mean() == pytest.approx(0.5, abs=0.1)
        assert np.abs(rpy(T)[:, :2]).max() <= np.deg2rad(8.0) + 1e-9
        again = TR.sample_flight_views(np.random.default_rng(0), 300, FREE, Z, presets,
                                       [ROUTE] * 2)
        np.testing.assert_array_equal(T, again)

    def test_needs_a_preset(self):
        with pytest.raises(ValueError, match="flight_views"):
            TR.sample_flight_views(np.random.default_rng(0), 2, FREE, Z, [], [])


class TestFlight:
    @pytest.mark.parametrize("preset", ["paper", "cluttered"])
    def test_inside_smooth_forward(self, preset, flights):
        cfg = flights[preset]
        fps, n = cfg.fps, cfg.num_frames
        for seed in range(5):
            T = TR.flight_trajectory(np.random.default_rng(seed), n, fps, ROUTE, FREE, Z,
                                     cfg.trajectory)
            assert T.shape == (n, 4, 4)
            assert_rigid(T)
            s = xyzyaw_from_pose(T)
            main = BOXES[0]
            assert np.all((s[:, 0] >= main[0]) & (s[:, 0] <= main[2]))
            assert np.all((s[:, 1] >= main[1]) & (s[:, 1] <= main[3]))
            assert np.all((s[:, 2] >= Z[0]) & (s[:, 2] <= Z[1]))
            # forward along the route (+Y, or -Y reversed) over most of the corridor, never
            # backwards
            way = -1.0 if cfg.trajectory.reverse else 1.0
            assert way * (s[-1, 1] - s[0, 1]) > 0.6 * (main[3] - main[1])
            assert np.all(way * np.diff(s[:, 1]) >= -1e-9)
            speed = np.linalg.norm(np.diff(s[:, :3], axis=0), axis=1) * fps
            assert speed.max() < 1.2
            # smooth: bounded accelerations and yaw rate
            acc = np.linalg.norm(np.diff(s[:, :3], 2, axis=0), axis=1) * fps**2
            assert acc.max() < 1.5
            yaw_rate = np.abs(np.angle(np.exp(1j * np.diff(s[:, 3])))) * fps
            assert yaw_rate.max() < np.deg2rad(60)
            # looking along the corridor, with real swings
            off = np.abs(np.angle(np.exp(1j * (s[:, 3] - way * np.pi / 2))))
            assert off.max() <= np.deg2rad(cfg.trajectory.yaw_amplitude_deg[1]) + 1e-9
            assert off.max() >= np.deg2rad(cfg.trajectory.yaw_amplitude_deg[0]) - 1e-9
            tilt = np.abs(rpy(T)[:, :2])
            assert tilt.max() <= np.deg2rad(cfg.trajectory.max_tilt_deg) + 1e-9
            # sway happens
            assert np.ptp(s[:, 0]) > 0.2 and np.ptp(s[:, 2]) > 0.1

    def test_pitch_follows_acceleration(self, flights):
        cfg = replace(flights["paper"].trajectory, tilt_noise_deg=0.0)
        T = TR.flight_trajectory(np.random.default_rng(0), 240, 10.0, ROUTE, FREE, Z, cfg)
        s = xyzyaw_from_pose(T)
        acc = np.gradient(np.gradient(s[:, :2], 0.1, axis=0), 0.1, axis=0)
        a_fwd = np.cos(s[:, 3]) * acc[:, 0] + np.sin(s[:, 3]) * acc[:, 1]
        np.testing.assert_allclose(rpy(T)[:, 1], np.arctan(a_fwd / TR.GRAVITY), atol=1e-9)

    def test_reverse(self, flights):
        cfg = replace(flights["paper"].trajectory, reverse=True)
        s = xyzyaw_from_pose(TR.flight_trajectory(np.random.default_rng(0), 100, 10.0, ROUTE,
                                                  FREE, Z, cfg))
        assert s[-1, 1] < s[0, 1]

    def test_deterministic(self, flights):
        cfg = flights["paper"].trajectory
        a = TR.flight_trajectory(np.random.default_rng(3), 50, 10.0, ROUTE, FREE, Z, cfg)
        b = TR.flight_trajectory(np.random.default_rng(3), 50, 10.0, ROUTE, FREE, Z, cfg)
        np.testing.assert_array_equal(a, b)

    def test_defaults_and_bad_input(self):
        T = TR.flight_trajectory(np.random.default_rng(0), 30, 10.0, ROUTE, FREE, Z, None)
        assert T.shape == (30, 4, 4)
        with pytest.raises(ValueError, match="num_frames"):
            TR.flight_trajectory(np.random.default_rng(0), 0, 10.0, ROUTE, FREE, Z, None)
        with pytest.raises(ValueError, match="speed"):
            TR.flight_trajectory(np.random.default_rng(0), 30, 10.0, ROUTE, FREE, Z,
                                 {"speed": [0.8, 0.2]})
        with pytest.raises(ValueError, match="leaves the free space"):
            TR.flight_trajectory(np.random.default_rng(0), 30, 10.0, ROUTE + [1.5, 0.0], FREE,
                                 Z, None)


class TestOdometry:
    def make(self, flights, seed):
        cfg = flights["paper"]
        rng = np.random.default_rng(seed)
        gt = TR.flight_trajectory(rng, cfg.num_frames, cfg.fps, ROUTE, FREE, Z, cfg.trajectory)
        return gt, TR.noisy_odometry(rng, gt, cfg.fps, cfg.odometry)

    def test_starts_at_truth_keeps_roll_pitch(self, flights):
        gt, od = self.make(flights, 0)
        assert od.shape == gt.shape
        assert_rigid(od)
        np.testing.assert_allclose(od[0], gt[0], atol=1e-9)
        np.testing.assert_allclose(rpy(od)[:, :2], rpy(gt)[:, :2], atol=1e-9)

    def test_drifts_but_relative_motion_is_close(self, flights):
        end, start = [], []
        for seed in range(6):
            gt, od = self.make(flights, seed)
            err = np.linalg.norm(od[:, :3, 3] - gt[:, :3, 3], axis=1)
            start.append(err[:24].mean())
            end.append(err[-24:].mean())
            # frame-to-frame motions stay close to the truth's
            rel_gt = np.linalg.inv(gt[:-1]) @ gt[1:]
            rel_od = np.linalg.inv(od[:-1]) @ od[1:]
            dt = np.linalg.norm(rel_gt[:, :3, 3] - rel_od[:, :3, 3], axis=1)
            assert dt.max() < 0.03
            dyaw = xyzyaw_from_pose(rel_gt)[:, 3] - xyzyaw_from_pose(rel_od)[:, 3]
            assert np.abs(np.angle(np.exp(1j * dyaw))).max() < np.deg2rad(1.0)
        assert np.mean(end) > 3 * np.mean(start)  # error grows
        distance = 8.0
        assert 0.005 * distance < np.mean(end) < 0.15 * distance  # a few % of the distance

    def test_noise_free_is_exact(self, flights):
        zero = OdometryConfig(**{f.name: 0.0 for f in fields(OdometryConfig)})
        gt = TR.flight_trajectory(np.random.default_rng(1), 60, 10.0, ROUTE, FREE, Z,
                                  flights["paper"].trajectory)
        od = TR.noisy_odometry(np.random.default_rng(1), gt, 10.0, zero)
        np.testing.assert_allclose(od, gt, atol=1e-9)

    def test_deterministic_and_bad_input(self, flights):
        paper = flights["paper"]
        gt = TR.flight_trajectory(np.random.default_rng(1), 30, 10.0, ROUTE, FREE, Z,
                                  paper.trajectory)
        a = TR.noisy_odometry(np.random.default_rng(2), gt, paper.fps, paper.odometry)
        b = TR.noisy_odometry(np.random.default_rng(2), gt, paper.fps, paper.odometry)
        np.testing.assert_array_equal(a, b)
        with pytest.raises(ValueError, match="groundtruth"):
            TR.noisy_odometry(np.random.default_rng(0), gt[:, :3], paper.fps, paper.odometry)


def test_flight_presets(flights):
    """Both presets exist and name a distractors preset that exists."""
    assert {"paper", "cluttered"} <= set(flights)
    for name, preset in flights.items():
        assert (CONF / "distractors" / f"{preset.distractors}.yaml").is_file(), name
        assert preset.num_frames > 0 and preset.fps > 0
