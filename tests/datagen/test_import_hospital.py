"""The AWS RoboMaker hospital (../shared/worlds, third-party, read in place; skipped where
absent): imported as it is, with its ~40 online-library models missing."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from core import classes as C
from datagen.importers import load_building

HOSPITAL = (Path(__file__).resolve().parents[2] / ".." / "shared" / "worlds" / "aws_hospital"
            / "worlds" / "hospital.world")

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def hospital():
    if not HOSPITAL.is_file():
        pytest.skip(f"{HOSPITAL} is absent (../shared/worlds not here)")
    t0 = time.perf_counter()
    b = load_building(HOSPITAL)
    return b, time.perf_counter() - t0


def named(b, text: str) -> np.ndarray:
    return np.array([text in n for n in b.names])[b.face_name]


def test_hospital_import(hospital):
    b, seconds = hospital
    assert seconds <= 120
    missing = b.info["missing_models"]
    assert 35 <= len(missing) <= 50 and missing["PotatoChipChair"] == 16
    assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW, C.CLUTTER} <= set(b.face_class)
    # door frames and windows by the name rules on the walls' COLLADA materials
    assert (b.face_class[named(b, "floor_01_doorframes")] == C.DOOR).all()
    assert (b.face_class[named(b, "floor_01_windows")] == C.WINDOW).all()
    assert (b.face_class[named(b, "floor_01_walls/link/visual/ID43")] == C.WALL).all()
    # extent about 25 x 57 m (the shell: floor, walls, ceiling)
    shell = named(b, "hospital_floor_01_")
    size = np.ptp(b.vertices[np.unique(b.faces[shell])], axis=0)
    assert abs(size[0] - 25) < 1.5 and abs(size[1] - 57) < 2
    # its own ceiling at 3 m covers the floor: nothing added
    ceiling = b.vertices[b.faces[named(b, "floor_01_ceiling")]][:, :, 2]
    np.testing.assert_allclose(ceiling, 3.0, atol=0.02)
    assert (b.face_class[named(b, "floor_01_ceiling")] == C.CEILING).all()
    assert b.info["ceiling_added"] == 0 and abs(b.info["floor_z"]) < 0.05
    assert abs(b.info["wall_top_z"] - 3.0) < 0.1
    # names decide everywhere (the material first); geometry overrules none of them
    assert b.info["classed_by"]["geometry_over_name"] == 0
    # its own furniture is named; the elevator cars (2.5 m) and portals stay walls
    assert b.info["classed_by"]["furniture"] == 0
    shares = b.info["class_shares"]
    for name, share in {"floor": 0.216, "wall": 0.483, "ceiling": 0.216, "door": 0.011,
                        "window": 0.002, "clutter": 0.072}.items():
        assert abs(shares[name] - share) < 0.002, shares


def test_hospital_summary(hospital):
    from datagen.importers.summary import import_summary

    s = import_summary(hospital[0], 1021.0, 1)
    assert s["up_axis"]["axis"] == "+z" and s["up_axis"].get("check") == "+z"
    assert s["wall_height_m"] == pytest.approx(3.0, abs=0.05)
    assert {f["key"] for f in s["flags"]} == {"world.model_path"}  # the online models


def test_hospital_plan(hospital):
    from datagen.mesh.plan import plan_labels

    labels, _, res = plan_labels(hospital[0], metres_per_px=0.1)
    counts = np.bincount(labels.ravel(), minlength=256)
    assert counts[C.FLOOR] * res**2 > 900  # m^2 of floor seen from above at the 1.5 m cut
    assert min(counts[C.WALL], counts[C.DOOR], counts[C.WINDOW], counts[C.CLUTTER]) > 0


def test_hospital_free_space_and_route(hospital):
    """The issue's flight target: a route of >= 40 m with >= 2 turns of >= 60 deg."""
    from datagen.importers.__main__ import free_space_and_route

    occ, route, figures = free_space_and_route(hospital[0], 40.0, seed=0)
    assert route is not None, figures
    assert 700 < figures["free_area_m2"] < 1300  # the floor less walls and the camera margin
    assert figures["route_m"] >= 40 and len(figures["route_turns_deg"]) >= 2
    assert all(abs(a) >= 60 for a in figures["route_turns_deg"])
    assert occ.contains(route).all()
