"""Flights, training poses, distractors and people on the occupancy maps of whole floors:
tests/buildings.py's ring and L, and the AWS hospital (../shared/worlds, skipped where
absent)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from core.occupancy import OccupancyMap
from core.poses import xyzyaw_from_pose
from datagen.config import FlightConfig, TrajectoryConfig
from datagen.distractors.crowd import person_tracks
from datagen.distractors.placement import place_objects
from datagen.flights import training_views as TV
from datagen.flights import trajectories as TR
from datagen.flights.routes import find_turns, route_at, route_length
from tests.buildings import BAND, MARGIN, assemble, occupancy, ring

#: a 30 s flight (300 frames at 10 fps) at 0.3-0.35 m/s: 9-10.5 m, fits the test buildings
PRESET = FlightConfig(num_frames=300, trajectory=TrajectoryConfig(speed=[0.3, 0.35]))
DURATION = (PRESET.num_frames - 1) / PRESET.fps
HOSPITAL = (Path(__file__).resolve().parents[2] / ".." / "shared" / "worlds" / "aws_hospital"
            / "worlds" / "hospital.world")


def along(route: np.ndarray, xy: np.ndarray, step: float = 0.02) -> np.ndarray:
    """(N,) m along the route of the route point nearest each position (N, 2)."""
    s = np.arange(0.0, route_length(route), step)
    dense = route_at(route, s)[0]
    return s[np.argmin(np.linalg.norm(xy[:, None] - dense[None], axis=-1), axis=1)]


def fly(occ: OccupancyMap, seed: int, preset: FlightConfig = PRESET
        ) -> tuple[np.ndarray, np.ndarray]:
    """(route, poses) of one flight of ``preset`` through ``occ``."""
    route = TR.flight_route(preset, occ, None, np.random.default_rng(seed), "flights.test")
    poses = TR.flight_trajectory(np.random.default_rng(seed + 100), preset.num_frames,
                                 preset.fps, route, occ, np.array(occ.band), preset.trajectory)
    return route, poses


def flown_turns(route: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(T, 2) the route's turns (``find_turns``) between the first and last arc lengths s."""
    turns = find_turns(route)
    return turns[(turns[:, 0] > s.min()) & (turns[:, 0] < s.max())]


class TestFlights:
    @pytest.mark.parametrize("building", ["ring", "ell"])
    @pytest.mark.parametrize("seed", [0, 1, 2])
    def test_flown_through_the_floor(self, building, seed):
        occ = occupancy(building)
        route, T = fly(occ, seed)
        state = xyzyaw_from_pose(T)
        assert occ.contains(state[:, :2]).all()  # every camera centre in a free cell
        assert np.all((state[:, 2] >= BAND[0]) & (state[:, 2] <= BAND[1]))
        s = along(route, state[:, :2])
        assert np.all(np.diff(s) >= -0.05)  # forward along the route
        assert s.max() - s.min() >= PRESET.trajectory.speed[0] * DURATION - 0.1
        assert len(flown_turns(route, s)) >= 1
        # yaw swings about the direction of travel, through the turns too
        xy, tangent = route_at(route, s)
        dev = np.angle(np.exp(1j * (state[:, 3] - np.arctan2(tangent[:, 1], tangent[:, 0]))))
        assert np.abs(dev).max() <= np.deg2rad(PRESET.trajectory.yaw_amplitude_deg[1] + 2)
        yaw_rate = np.abs(np.angle(np.exp(1j * np.diff(state[:, 3])))) * PRESET.fps
        assert yaw_rate.max() < np.deg2rad(60)
        across = np.linalg.norm(state[:, :2] - xy, axis=1)
        assert np.ptp(across) > 0.1  # it sways

    def test_reverse(self):
        occ = occupancy("ring")
        preset = replace(PRESET, trajectory=replace(PRESET.trajectory, reverse=True))
        route, T = fly(occ, 0, preset)
        s = along(route, T[:, :2, 3])
        assert s[-1] < s[0] - 5
        assert occ.contains(T[:, :2, 3]).all()

    def test_same_seed_same_flight(self):
        occ = occupancy("ell")
        a, b = fly(occ, 3), fly(occ, 3)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])

    def test_waypoints(self):
        occ = occupancy("ring")
        preset = replace(PRESET, route=[[1.0, 1.0], [1.0, 9.0], [9.0, 9.0]])
        route, T = fly(occ, 0, preset)
        np.testing.assert_allclose(route[[0, -1]], [[1.0, 1.0], [9.0, 9.0]], atol=1e-9)
        assert occ.contains(T[:, :2, 3]).all()
        s = along(route, T[:, :2, 3])
        turns = flown_turns(route, s)
        assert len(turns) == 1 and turns[0, 1] == pytest.approx(-90, abs=5)

    def test_route_through_a_wall(self):
        preset = replace(PRESET, route=[[1.0, 1.0], [9.0, 9.0]])
        with pytest.raises(ValueError, match=r"flights\.test\.route: .*blocked at"):
            fly(occupancy("ring"), 0, preset)
        with pytest.raises(ValueError, match=r"flights\.test\.route must be 'auto'"):
            fly(occupancy("ring"), 0, replace(PRESET, route="spiral"))

    def test_flight_views(self):
        occ = occupancy("ring")
        route = TR.flight_route(PRESET, occ, None, np.random.default_rng(0), "flights.test")
        T = TR.sample_flight_views(np.random.default_rng(1), 40, occ, BAND, [PRESET], [route])
        assert T.shape == (40, 4, 4) and occ.contains(T[:, :2, 3]).all()
        again = TR.sample_flight_views(np.random.default_rng(1), 40, occ, BAND, [PRESET],
                                       [route])
        np.testing.assert_array_equal(T, again)


def straight(length: float = 12.0, width: float = 2.0):
    """A closed straight corridor [0, width] x [0, length] (tests/buildings.assemble)."""
    t = 0.2
    return assemble([(-t, -t, width + t, length + t)],
                    [(-t, -t, width + t, 0), (-t, length, width + t, length + t),
                     (-t, 0, 0, length), (width, 0, width + t, length)])


class TestTrainingPoses:
    def test_along_a_straight_corridor(self):
        occ = OccupancyMap.from_mesh(*straight(), BAND, MARGIN, 0.05)
        T = TV.sample_training_poses(np.random.default_rng(0), 2000, occ, BAND, 5.0,
                                     along_fraction=1.0, along_spread_deg=20.0)
        s = xyzyaw_from_pose(T)
        assert occ.contains(s[:, :2]).all()
        assert np.all((s[:, 2] >= BAND[0]) & (s[:, 2] <= BAND[1]))
        off_axis = np.abs(np.abs(s[:, 3]) - np.pi / 2)  # from the nearest of +Y, -Y
        assert off_axis.max() <= np.deg2rad(20) + 1e-6
        assert (s[:, 3] > 0).mean() == pytest.approx(0.5, abs=0.05)
        # over the whole free space, ends included
        assert s[:, 1].min() < MARGIN + 0.2 and s[:, 1].max() > 12 - MARGIN - 0.2

    def test_along_each_leg_of_the_ell(self):
        occ = occupancy("ell")
        T = TV.sample_training_poses(np.random.default_rng(1), 2000, occ, BAND, 0.0,
                                     along_fraction=1.0, along_spread_deg=0.0)
        s = xyzyaw_from_pose(T)
        assert occ.contains(s[:, :2]).all()
        x_leg = s[:, 0] > 4  # the leg along +X, away from the corner
        y_leg = s[:, 1] > 4
        assert x_leg.sum() > 100 and y_leg.sum() > 100
        np.testing.assert_allclose(np.sin(s[x_leg, 3]), 0.0, atol=1e-6)
        np.testing.assert_allclose(np.cos(s[y_leg, 3]), 0.0, atol=1e-6)

    def test_uniform_yaw_and_deterministic(self):
        occ = occupancy("ring")
        T = TV.sample_training_poses(np.random.default_rng(2), 4000, occ, BAND,
                                     along_fraction=0.0)
        hist = np.histogram(xyzyaw_from_pose(T)[:, 3], bins=8, range=(-np.pi, np.pi))[0]
        assert hist.min() > 0.7 * 4000 / 8
        again = TV.sample_training_poses(np.random.default_rng(2), 4000, occ, BAND,
                                         along_fraction=0.0)
        np.testing.assert_array_equal(T, again)


@pytest.fixture(scope="module")
def ring_floor() -> OccupancyMap:
    """Where things stand in the ring building (margin 0)."""
    return OccupancyMap.from_mesh(*ring(), band=BAND, margin=0.0, cell=0.05)


def ring_wall_distance(xy: np.ndarray) -> np.ndarray:
    """(N,) m from points in the ring's corridor to its walls (the outer walls around
    [0, 10]^2, the inner block [2, 8]^2)."""
    x, y = xy[:, 0], xy[:, 1]
    outer = np.minimum.reduce([x, 10 - x, y, 10 - y])
    dx = np.maximum.reduce([2 - x, np.zeros_like(x), x - 8])
    dy = np.maximum.reduce([2 - y, np.zeros_like(y), y - 8])
    return np.minimum(outer, np.hypot(dx, dy))


class TestDistractorsOnFloors:
    HALF_CELL = 0.025  # m, a map's distances are within half a cell (core/occupancy)

    def test_objects_clear_of_walls_and_each_other(self, ring_floor):
        for seed in range(6):
            rng = np.random.default_rng(seed)
            radii = rng.uniform(0.15, 0.5, 10)
            xy_yaw, placed = place_objects(rng, radii, ring_floor, against_walls=0.6,
                                             wall_margin=0.05)
            assert placed.sum() >= 8
            xy, r = xy_yaw[placed, :2], radii[placed]
            assert np.all(ring_wall_distance(xy) >= r + 0.05 - self.HALF_CELL)
            gap = np.linalg.norm(xy[:, None] - xy[None], axis=-1) - r[:, None] - r[None]
            assert np.all(gap[~np.eye(len(r), dtype=bool)] >= -1e-9)
        a = place_objects(np.random.default_rng(7), [0.3, 0.2], ring_floor, against_walls=1)
        b = place_objects(np.random.default_rng(7), [0.3, 0.2], ring_floor, against_walls=1)
        np.testing.assert_array_equal(a[0], b[0])

    def test_people_walk_the_ring(self, ring_floor):
        radius, fps = 0.3, 10.0
        for seed in range(3):
            rng = np.random.default_rng(seed)
            radii = rng.uniform(0.15, 0.4, 4)
            xy_yaw, placed = place_objects(rng, radii, ring_floor, against_walls=1.0,
                                             wall_margin=0.05)
            obstacles = np.column_stack([xy_yaw[placed, :2], radii[placed]])
            tracks = person_tracks(rng, 3, 300, fps, ring_floor, radius=radius,
                                     obstacles=obstacles)
            xy = tracks[..., :2]
            assert np.all(ring_wall_distance(xy.reshape(-1, 2)) >= radius - self.HALF_CELL)
            d_obs = np.linalg.norm(xy[:, :, None] - obstacles[None, None, :, :2], axis=-1)
            assert np.all(d_obs >= obstacles[:, 2] + radius - 1e-6)
            speed = np.linalg.norm(np.diff(xy, axis=1), axis=-1) * fps
            assert speed.max() <= 1.4 + 1e-6 and speed.mean() > 0.3
            d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)[np.triu_indices(3, 1)]
            assert (d < 2 * radius - 0.05).mean() < 0.02
            # they go round: every person covers more than one side of the ring
            sides = np.stack([xy[..., 0] < 2, xy[..., 0] > 8, xy[..., 1] < 2, xy[..., 1] > 8])
            assert np.all(sides.any(axis=2).sum(axis=0) >= 2)
        a = person_tracks(np.random.default_rng(5), 2, 50, fps, ring_floor)
        b = person_tracks(np.random.default_rng(5), 2, 50, fps, ring_floor)
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_hospital_flights():
    """Flights of the paper and cluttered presets through the hospital (the free space and
    cells of ``python -m datagen.importers``), at the proposed hospital durations: >= 40 m
    with >= 2 turns of >= 60 deg."""
    if not HOSPITAL.is_file():
        pytest.skip(f"{HOSPITAL} is absent (../shared/worlds not here)")
    from core.config import compose_config, typed
    from datagen.config import DatagenConfig
    from datagen.importers import load_building
    from datagen.importers.__main__ import free_space_and_route

    occ = free_space_and_route(load_building(HOSPITAL), 40.0, 0)[0]
    flights = typed(DatagenConfig, compose_config("datagen"), "datagen").flights
    for name in ("paper", "cluttered"):
        p = flights[name]
        preset = replace(p, num_frames=1150, trajectory=replace(p.trajectory,
                                                                speed=[0.35, 0.45]))
        for seed in range(2):
            route, T = fly(occ, seed, preset)
            assert occ.contains(T[:, :2, 3]).all()
            s = along(route, T[:, :2, 3], step=0.05)
            turns = flown_turns(route, s)
            print(f"hospital {name} seed {seed}: route {route_length(route):.1f} m, flown "
                  f"{s.max() - s.min():.1f} m, turns {np.round(turns[:, 1]).tolist()}")
            assert s.max() - s.min() >= 40
            assert (np.abs(turns[:, 1]) >= 60).sum() >= 2
