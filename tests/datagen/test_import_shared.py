"""The AWS bookstore and the ICL office scan (../shared/worlds, third-party, read in place;
skipped where absent) import with the defaults: no name rule, axis, unit or path set."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from core import classes as C
from datagen.config import FileWorldConfig
from datagen.importers import load_building
from datagen.importers.summary import import_summary
from datagen.mesh.building import face_areas_normals
from datagen.worlds.site import camera_free_space

WORLDS = Path(__file__).resolve().parents[2] / ".." / "shared" / "worlds"
BOOKSTORE = WORLDS / "aws_bookstore" / "worlds" / "bookstore.world"
SCAN = WORLDS / "icl_office_scan" / "of_kt2_planeopt.obj"


def imported(path: Path):
    if not path.is_file():
        pytest.skip(f"{path} is absent (../shared/worlds not here)")
    b = load_building(path)
    free = camera_free_space(b, FileWorldConfig(path=str(path)))
    return b, free, import_summary(b, free.area)


@pytest.fixture(scope="module")
def bookstore():
    return imported(BOOKSTORE)


@pytest.fixture(scope="module")
def scan():
    return imported(SCAN)


@pytest.mark.slow
def test_bookstore_imports_with_the_defaults(bookstore):
    """Its models name their meshes ``file://models/...`` (from the repository root, as
    Gazebo's resource path); only the one visual mesh absent from the copy is missing."""
    b, free, summary = bookstore
    assert list(b.info["missing_meshes"]) == [
        "file://models/aws_robomaker_retail_BookshelfA_01/meshes/aws_BookshelfA_01_visual.DAE"]
    assert all(n.startswith("BookE_01_009/") for n in b.info["far_parts"])  # at z = 343 km
    shares = b.info["class_shares"]
    assert 0.15 < shares["floor"] < 0.22 and shares["clutter"] > 0.2
    assert min(shares["door"], shares["window"]) > 0.01
    assert 3.2 < summary["wall_height_m"] < 3.7 and abs(b.info["floor_z"]) < 0.05
    assert 80 < free.area < 200
    assert b.info["classed_by"]["furniture"] == 0  # names class all its pieces
    keys = {f["key"] for f in summary["flags"]}
    assert keys <= {"world.model_path", None}, summary["flags"]


def test_scan_imports_with_the_defaults(scan):
    """Y points down in the scanner's frame: the axis is found, the walls ~2.4 m high."""
    b, free, summary = scan
    assert b.info["up_axis"] == "-y" and b.info["up_axis_from"] == "auto"
    assert 2.3 < summary["wall_height_m"] < 2.5
    assert b.info["class_shares"]["floor"] > 0.1
    assert free.area > 3.2
    keys = {f["key"] for f in summary["flags"]}
    assert not keys & {"world.up_axis", "world.units", "world.name_rules"}, summary["flags"]
    floor = b.face_class == C.FLOOR
    np.testing.assert_allclose(b.vertices[b.faces[floor]][:, :, 2].mean(), b.info["floor_z"],
                               atol=0.1)


def test_scan_desks_are_clutter(scan):
    """The scan's desks, fused with its floor and walls, are its own furniture (clutter): the
    desk tops (up-facing, 0.6-1.0 m above the floor), not the walls above 1.9 m."""
    b = scan[0]
    area, normal = face_areas_normals(b.vertices, b.faces)
    h = b.vertices[b.faces][:, :, 2].mean(axis=1) - b.info["floor_z"]
    clutter = b.face_class == C.CLUTTER
    tops = (normal[:, 2] > 0.9) & (h > 0.6) & (h < 1.0)
    assert area[tops].sum() > 2.5 and area[tops & clutter].sum() > 0.95 * area[tops].sum()
    high = (np.abs(normal[:, 2]) < 0.3) & (h > 1.9)
    assert area[high].sum() > 4 and (b.face_class[high] == C.WALL).all()
    assert b.info["class_shares"]["clutter"] > 0.1 and b.info["class_shares"]["wall"] > 0.3
