"""benchmarks/occupancy_build.py: the synthetic hospital-sized floor and its routes."""

from __future__ import annotations

import numpy as np

from benchmarks.occupancy_build import BAND, MARGIN, SIZE, floor_plan
from core.occupancy import OccupancyMap
from datagen.flights.routes import count_turns, plan_route, route_length


def test_floor_plan_size_and_a_hospital_flight_route():
    v, f, cls = floor_plan(triangles=4000)
    assert abs(len(f) - 4000) <= 3 and len(cls) == len(f)
    np.testing.assert_allclose(v[:, :2].max(0) - v[:, :2].min(0), np.add(SIZE, 0.4))
    occ = OccupancyMap.from_mesh(v, f, cls, BAND, MARGIN, 0.2)
    assert not occ.contains(np.array([[12.5, 28.5]]))[0]  # the solid core
    assert occ.contains(np.array([[6.2, 28.5], [2.5, 28.5]])).all()  # corridor, a room
    route = plan_route(occ, np.random.default_rng(0), {"min_length": 40.0, "min_turns": 2})
    assert route_length(route) >= 40.0 and count_turns(route) >= 2
