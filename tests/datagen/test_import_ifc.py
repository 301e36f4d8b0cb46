"""IFC import (a file written with ifcopenshell.api): classes from IFC types, storeys, door
leaves left out with their openings kept, the ceiling from the storey above."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from datagen.importers import load_building
from tests.datagen.building_files import SPACES, write_ifc

pytest.importorskip("ifcopenshell")


@pytest.fixture(scope="module")
def ifc_file(tmp_path_factory):
    return write_ifc(tmp_path_factory.mktemp("ifc") / "house.ifc")


def centres(b, mask):
    return b.vertices[b.faces[mask]].mean(axis=1)


def test_ifc_classes_and_storeys(ifc_file):
    b = load_building(ifc_file)
    assert b.info["format"] == "ifc" and b.info["storey"] == "Ground"
    assert b.info["storeys"] == {"Ground": 0.0, "Level 1": 3.0}
    assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW} <= set(b.face_class)
    np.testing.assert_allclose(b.vertices[:, :2].min(axis=0), [0, 0], atol=1e-9)
    np.testing.assert_allclose(b.vertices[:, :2].max(axis=0), [6, 4], atol=1e-9)
    assert b.info["floor_z"] == pytest.approx(0.0)
    # the ceiling: the underside of Level 1's slab, nothing added
    assert b.info["ceiling_added"] == 0
    high = centres(b, b.face_class == C.CEILING)[:, 2] > 1
    assert high.any() and np.allclose(centres(b, b.face_class == C.CEILING)[high, 2], 2.8)
    # doors open: no door leaf, the opening's reveals (in the y = 0 wall) are door
    assert not any(n.startswith("IfcDoor") for n in b.names)
    door = centres(b, b.face_class == C.DOOR)
    assert len(door) and (door[:, 0] > 1.99).all() and (door[:, 0] < 2.91).all()
    assert (door[:, 1] <= 0.21).all() and (door[:, 2] <= 2.11).all()
    # the opening is cut: no wall face inside the door's hole
    wall = centres(b, b.face_class == C.WALL)
    hole = (wall[:, 0] > 2.05) & (wall[:, 0] < 2.85) & (wall[:, 1] < 0.2) & (wall[:, 2] < 2.0)
    assert not hole.any()
    window = centres(b, b.face_class == C.WINDOW)
    assert (window[:, 0] > 5.7).all() and (window[:, 2] > 0.89).all()


def test_ifc_spaces_are_the_rooms_footprints(ifc_file):
    """The storey's IfcSpace outlines, by name, in world.json's ``spaces`` (``hint.space``):
    the same corners (any start and direction), the L-shaped room's six included."""
    spaces = load_building(ifc_file).info["spaces"]
    assert set(spaces) == set(SPACES)
    for name, corners in SPACES.items():
        got = {tuple(np.round(c, 3)) for c in spaces[name]}
        assert got == {tuple(map(float, c)) for c in corners}, name


def test_ifc_doors_closed_and_storey_choice(ifc_file):
    closed = load_building(ifc_file, {"doors": "closed"})
    assert any(n.startswith("IfcDoor") for n in closed.names)
    leaf = np.array([n.startswith("IfcDoor") for n in closed.names])[closed.face_name]
    assert (closed.face_class[leaf] == C.DOOR).all()
    with pytest.raises(ValueError, match="no storey named 'Basement'.*'Ground' \\(0.00 m\\)"):
        load_building(ifc_file, {"storey": "Basement"})
    with pytest.raises(ValueError, match="house.ifc: no floor found below the walls"):  # Level 1
        # (chosen case-insensitively) holds only its slab: no room
        load_building(ifc_file, {"storey": "level 1"})


def test_ifc_top_storey_gets_auto_ceiling(tmp_path):
    b = load_building(write_ifc(tmp_path / "one.ifc", upper=False))
    assert b.info["ceiling_added"] > 0
    added = b.face_name == b.names.index("auto_ceiling")
    np.testing.assert_allclose(centres(b, added)[:, 2], 3.0)


def test_ifc_broken_file(tmp_path):
    bad = tmp_path / "bad.ifc"
    bad.write_text("ISO-10303-21;\nnonsense\n")
    with pytest.raises(ValueError, match="bad.ifc"):
        load_building(bad)
