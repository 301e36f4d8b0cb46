"""benchmarks/flight_shape.py: the figures of one flight along its route."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.flight_shape import NAMES, flight_figures
from core.poses import pose_from_xyz_rpy


def test_straight_flight_figures():
    n, fps = 101, 10.0
    y = np.linspace(1.0, 6.0, n)  # 5 m along +Y in 10 s
    across = 0.2 * np.sin(np.linspace(0, 4 * np.pi, n))
    yaw = np.pi / 2 + np.deg2rad(10) * np.sin(np.linspace(0, 2 * np.pi, n))
    poses = pose_from_xyz_rpy(np.column_stack([across, y, np.full(n, 1.2)]),
                              np.column_stack([np.zeros(n), np.zeros(n), yaw]))
    route = np.array([[0.0, 0.0], [0.0, 10.0]])
    got = dict(zip(NAMES, flight_figures(route, poses, fps), strict=True))
    assert got["flown m"] == pytest.approx(5.0, abs=0.03)
    assert got["start m"] == pytest.approx(1.0, abs=0.03)
    assert got["mean |across| m"] == pytest.approx(0.2 * 2 / np.pi, abs=0.01)
    assert got["height m"] == pytest.approx(1.2) and got["height ptp m"] == pytest.approx(0.0)
    assert got["yaw dev max deg"] == pytest.approx(10.0, abs=0.1)
    assert got["tilt max deg"] == pytest.approx(0.0, abs=1e-6)
    assert got["turns >= 60 deg"] == 0
