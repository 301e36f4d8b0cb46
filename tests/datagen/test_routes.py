"""datagen.flights.routes: routes planned through an occupancy map, waypoints, motion, turns."""

from __future__ import annotations

import functools
import logging

import numpy as np
import pytest
import yaml

from core.config import CONF, as_config
from core.occupancy import OccupancyMap
from datagen.config import FlightConfig
from datagen.flights.routes import (
    count_turns,
    find_turns,
    plan_route,
    route_at,
    route_from_waypoints,
    route_length,
    route_to_trajectory,
)
from datagen.flights.trajectories import flight_route, flight_trajectory
from tests.buildings import BAND, MARGIN, THICK, assemble, corridor_with_room, occupancy


def _check_route(occ: OccupancyMap, route: np.ndarray, spacing: float = 0.05) -> None:
    assert route.ndim == 2 and route.shape[1] == 2
    assert occ.contains(route).all()
    step = np.linalg.norm(np.diff(route, axis=0), axis=1)
    np.testing.assert_allclose(step, step[0], rtol=0.01)  # chords of arcs: a bit short
    assert step[0] <= spacing + 1e-9


class TestPlanRoute:
    def test_ring_gives_a_long_route_with_two_right_angle_turns(self):
        ring_map = occupancy("ring")
        for seed in range(3):
            route = plan_route(ring_map, np.random.default_rng(seed), {"min_turns": 2})
            _check_route(ring_map, route)
            assert route_length(route) >= 12.0  # half the 32 m centre line, less the ends
            turns = find_turns(route)
            assert len(turns) >= 2
            np.testing.assert_allclose(np.abs(turns[:, 1]), 90.0, atol=15.0)

    def test_route_keeps_to_the_middle(self):
        ring_map = occupancy("ring")
        route = plan_route(ring_map, np.random.default_rng(0))
        s = np.cumsum(np.linalg.norm(np.diff(route, axis=0), axis=1))
        turn_s = find_turns(route)[:, 0]
        straight = np.all(np.abs(s[:, None] - turn_s[None]) > 2.5, axis=1)  # off the corners
        straight &= (s > 1.0) & (s < s[-1] - 1.0)
        assert np.median(ring_map.distance(route[1:][straight])) >= 0.9  # 2 m wide: 1 m

    def test_ell_turns_once(self):
        ell_map = occupancy("ell")
        route = plan_route(ell_map, np.random.default_rng(0))
        _check_route(ell_map, route)
        assert route_length(route) >= 10.0
        turns = find_turns(route)
        assert len(turns) == 1 and abs(turns[0, 1]) == pytest.approx(90.0, abs=10.0)

    def test_extra_margin_keeps_routes_out_of_narrow_doors(self):
        occ = OccupancyMap.from_mesh(*corridor_with_room(door=0.9), BAND, MARGIN, 0.05)
        assert occ.contains(np.array([[16.1, 1.0], [18.0, 1.0]])).all()  # door, room
        for seed in range(3):
            route = plan_route(occ, np.random.default_rng(seed))
            assert route[:, 0].max() < 16.0  # stays in the corridor
            assert occ.distance(route).min() >= MARGIN + 0.3 - 0.05
            assert route_length(route) >= 13.0
        route = plan_route(occ, np.random.default_rng(0), {"extra_margin": 0.0})
        assert route[:, 0].max() > 17.0  # through the door into the room
        with pytest.raises(ValueError, match="lower route.extra_margin"):
            plan_route(occ, np.random.default_rng(0), {"extra_margin": 2.0})

    def test_seeded(self):
        ring_map = occupancy("ring")
        a = plan_route(ring_map, np.random.default_rng(5))
        np.testing.assert_array_equal(a, plan_route(ring_map, np.random.default_rng(5)))
        others = [plan_route(ring_map, np.random.default_rng(s)) for s in (6, 7)]
        assert any(len(o) != len(a) or not np.allclose(o, a) for o in others)

    def test_impossible_demand_is_a_clear_error_when_not_fitted(self):
        ell_map = occupancy("ell")
        with pytest.raises(ValueError, match=r"no route of >= 100.0 m .* in 2 tries \(best: "):
            plan_route(ell_map, np.random.default_rng(0), {"min_length": 100.0, "tries": 2},
                       fit=False)
        with pytest.raises(ValueError, match="far_fraction"):
            plan_route(ell_map, np.random.default_rng(0), {"far_fraction": 0.0})


def walled_room(size_x: float, size_y: float, blocks: tuple = ()) -> OccupancyMap:
    """The free space (BAND, MARGIN, 5 cm cells) of a closed room [0, size_x] x [0, size_y] m
    with solid blocks ((B, 4) m [x0, y0, x1, y1]) in it."""
    X, Y, t = size_x, size_y, THICK
    walls = [(-t, -t, X + t, 0), (-t, Y, X + t, Y + t), (-t, 0, 0, Y), (X, 0, X + t, Y)]
    mesh = assemble([(-t, -t, X + t, Y + t)], walls + list(blocks))
    return OccupancyMap.from_mesh(*mesh, BAND, MARGIN, 0.05)


@functools.cache
def cafe() -> OccupancyMap:
    """A 10 x 24 m open room (a cafe) with tables, a counter against a wall and a pillar."""
    tables = [(3, 5, 4, 6), (6, 5, 7, 6), (3, 12, 4, 13), (6, 12, 7.5, 13)]
    return walled_room(10.0, 24.0, (*tables, (0, 18, 2, 20.5), (8.8, 8, 10, 10)))


def floor_preset() -> FlightConfig:
    """conf/flights/floor.yaml's ``paper``: 1150 frames at 10 fps, 0.35-0.45 m/s."""
    preset = yaml.safe_load((CONF / "flights" / "floor.yaml").read_text())["paper"]
    return as_config(FlightConfig, preset, "flights.paper")


class TestFittedRoutes:
    """Where no route holds min_length / min_turns, one fitted to the free space."""

    def test_open_room_flies_laps_of_a_loop(self, caplog):
        occ = cafe()
        routes = []
        for seed in range(2):
            with caplog.at_level(logging.WARNING, "datagen.flights.routes"):
                route = plan_route(occ, np.random.default_rng(seed),
                                   {"min_length": 100.0, "min_turns": 2})
            assert "lap(s) of a" in caplog.text and "loop around the free space" in caplog.text
            _check_route(occ, route)
            assert route_length(route) >= 100.0
            assert count_turns(route) >= 2 * 4  # twice round the room at least
            assert occ.distance(route).min() >= MARGIN + 0.3 - 0.05  # route.extra_margin
            routes.append(route)
        assert not np.allclose(routes[0][0], routes[1][0])  # each seed starts elsewhere
        with pytest.raises(ValueError, match="no route of >= 100.0 m"):
            plan_route(occ, np.random.default_rng(0), {"min_length": 100.0}, fit=False)

    def test_open_room_gets_a_floor_flight(self):
        occ, preset = cafe(), floor_preset()
        duration = (preset.num_frames - 1) / preset.fps
        route = flight_route(preset, occ, None, np.random.default_rng(0), "flights.paper")
        _check_route(occ, route)
        assert route_length(route) >= preset.trajectory.speed[1] * duration  # ~52 m
        assert occ.distance(route).min() >= MARGIN + 0.3 - 0.05
        assert count_turns(route) >= preset.route_settings.min_turns
        poses = flight_trajectory(np.random.default_rng(1), preset.num_frames, preset.fps,
                                  route, occ, np.array(BAND), preset.trajectory)
        xy = poses[:, :2, 3]
        assert occ.contains(xy).all()
        flown = np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()
        assert flown >= 0.9 * preset.trajectory.speed[0] * duration  # not flown slower

    def test_long_enough_route_with_fewer_turns(self, caplog):
        ell_map = occupancy("ell")
        with caplog.at_level(logging.WARNING, "datagen.flights.routes"):
            route = plan_route(ell_map, np.random.default_rng(0),
                               {"min_length": 10.0, "min_turns": 2})
        assert "min_turns relaxed" in caplog.text
        assert route_length(route) >= 10.0 and count_turns(route) == 1  # the L's one turn

    def test_tiny_room_is_a_clear_error(self):
        occ = walled_room(1.8, 1.8)  # 1.2 x 1.2 m free
        with pytest.raises(ValueError, match=r"free space is too small for a flight: "
                           r"1\.\d x 1\.\d m.*lower route\.extra_margin"):
            plan_route(occ, np.random.default_rng(0))
        preset = floor_preset()
        with pytest.raises(ValueError, match=r"flights\.paper\.route: .* too small"):
            flight_route(preset, occ, None, np.random.default_rng(0), "flights.paper")
        assert route_length(plan_route(walled_room(3.0, 3.0), np.random.default_rng(0),
                                       {"min_length": 46.0})) >= 46.0  # loops a 3 m room


class TestWaypoints:
    def test_around_the_ring(self):
        ring_map = occupancy("ring")
        wp = [[1.0, 1.0], [9.0, 1.0], [9.0, 9.0], [1.0, 9.0]]
        route = route_from_waypoints(ring_map, wp)
        _check_route(ring_map, route)
        np.testing.assert_allclose(route[[0, -1]], [wp[0], wp[-1]])
        assert route_length(route) == pytest.approx(24.0, abs=1.0)  # corners cut
        assert count_turns(route) == 2

    def test_segment_through_a_wall_is_named(self):
        ring_map = occupancy("ring")
        where = (r"segment 1 -> 2 \(9.00, 1.00\) -> \(1.00, 9.00\) is blocked at "
                 r"\(8.2\d, 1.7\d\), 1.1\d m after waypoint 1")
        with pytest.raises(ValueError, match=where):
            route_from_waypoints(ring_map, [[1.0, 1.0], [9.0, 1.0], [1.0, 9.0]])

    def test_waypoint_outside_is_named(self):
        ring_map = occupancy("ring")
        with pytest.raises(ValueError, match=r"waypoint 1 \(5.00, 5.00\) is not in the free"):
            route_from_waypoints(ring_map, [[1.0, 1.0], [5.0, 5.0]])
        with pytest.raises(ValueError, match="at least two"):
            route_from_waypoints(ring_map, [[1.0, 1.0]])

    def test_tight_corner_is_rounded_less(self):
        ell_map = occupancy("ell")
        wp = [[9.0, 1.0], [1.0, 1.0], [1.0, 7.0]]
        route = route_from_waypoints(ell_map, wp, {"turn_radius": 5.0})
        _check_route(ell_map, route)


class TestMotion:
    def test_route_at_gives_position_and_direction(self):
        route = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
        xy, t = route_at(route, np.array([-1.0, 1.0, 5.0, 99.0]))
        np.testing.assert_allclose(xy, [[0, 0], [1, 0], [4, 1], [4, 3]])
        np.testing.assert_allclose(t[[0, 1, 3]], [[1, 0], [1, 0], [0, 1]], atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0)

    def test_whole_route_at_speed(self):
        ell_map = occupancy("ell")
        route = plan_route(ell_map, np.random.default_rng(0))
        xy, heading, s = route_to_trajectory(route, speed=0.4, fps=10.0, ramp_s=2.0)
        np.testing.assert_allclose(xy[[0, -1]], route[[0, -1]], atol=1e-9)
        assert s[-1] == pytest.approx(route_length(route))
        v = np.diff(s) * 10.0
        assert v.max() == pytest.approx(0.4, rel=0.02) and (v >= 0).all()
        # heading = direction of travel
        d = np.diff(xy, axis=0)
        moving = np.linalg.norm(d, axis=1) > 0.02
        travel = np.arctan2(d[moving, 1], d[moving, 0])
        err = np.angle(np.exp(1j * (travel - heading[:-1][moving])))
        assert np.abs(err).max() < np.deg2rad(10)

    def test_short_route_is_flown_slower(self):
        route = np.array([[0.0, 0.0], [2.0, 0.0]])
        xy, heading, s = route_to_trajectory(route, speed=0.4, fps=10.0, num_frames=100)
        assert s[-1] == pytest.approx(2.0)
        np.testing.assert_allclose(heading, 0.0)
        xy, _, s = route_to_trajectory(np.array([[0.0, 0.0], [50.0, 0.0]]), 0.4, 10.0, 100)
        assert s[-1] == pytest.approx(0.4 * (9.9 - 2.0), rel=0.01)  # ramps: half speed


class TestTurns:
    def test_square_path_and_straight_line(self):
        square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
        turns = find_turns(square)
        np.testing.assert_allclose(turns, [[10.0, 90.0], [20.0, 90.0]], atol=0.1)
        assert count_turns(square[::-1]) == 2
        assert find_turns(square[::-1])[0, 1] == pytest.approx(-90.0)
        assert count_turns(np.array([[0.0, 0.0], [30.0, 1.0]])) == 0

    def test_gentle_bend_is_not_a_turn(self):
        bend = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 5.0]])  # 27 deg
        assert count_turns(bend) == 0
        assert count_turns(bend, min_angle_deg=20.0) == 1
