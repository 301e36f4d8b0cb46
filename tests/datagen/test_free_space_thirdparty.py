"""Free space of buildings others made (../shared/worlds, third-party, read in place; skipped
where absent): the ICL-NUIM office scan (holes, noise, furniture fused with the floor) gets
its room, the AWS hospital gains no cell through a wall."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import classes as C
from core.occupancy import OccupancyMap
from datagen.config import FileWorldConfig
from datagen.importers import load_building
from datagen.importers.config import ImportConfig
from datagen.worlds.site import camera_free_space

WORLDS = Path(__file__).resolve().parents[2] / ".." / "shared" / "worlds"
SCAN = WORLDS / "icl_office_scan" / "of_kt2_planeopt.obj"
HOSPITAL = WORLDS / "aws_hospital" / "worlds" / "hospital.world"


def plain_free_space(b, spec: FileWorldConfig) -> OccupancyMap:
    """The free space with every surface in the band an obstacle and the floor alone."""
    return OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class,
                                  float(b.info["floor_z"]) + np.asarray(spec.z_range),
                                  spec.camera_margin, spec.free_cell)


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    """The scan turned z-up (its frame has y pointing down: x' = x, y' = z, z' = -y) and
    imported."""
    if not SCAN.is_file():
        pytest.skip(f"{SCAN} is absent (../shared/worlds not here)")
    mesh = trimesh.load(SCAN, force="mesh", process=False)
    up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    path = tmp_path_factory.mktemp("scan") / "office_zup.obj"
    trimesh.Trimesh(np.asarray(mesh.vertices) @ up.T, mesh.faces, process=False).export(path)
    return load_building(settings=ImportConfig(path=str(path), up_axis="z"))


def test_scan_gets_its_room(scan):
    """The room is ~5 m x 7 m with ~23 m2 of ceiling; every surface an obstacle and the
    floor alone, its free space is under 6 m2; with the defaults most of the room."""
    spec = FileWorldConfig(path="office_zup.obj")
    plain, robust = plain_free_space(scan, spec), camera_free_space(scan, spec)
    assert plain.area < 6.0
    assert 15.0 <= robust.area <= 24.0
    assert robust.contains(plain.centres(np.nonzero(plain.free))).all()  # it only grows
    lo, hi = scan.vertices[:, :2].min(0), scan.vertices[:, :2].max(0)
    b = robust.free_bounds
    assert (b[:2] >= lo + spec.camera_margin - spec.free_cell).all()
    assert (b[2:] <= hi - spec.camera_margin + spec.free_cell).all()


@pytest.mark.slow
def test_hospital_gains_nothing_through_walls():
    """The hospital with the defaults: at most 10 % more free space than with every surface
    an obstacle (stairwells, low furniture), the plain map kept, and no free cell within the
    margin (less a cell and a half: cells are rounded) of a wall that spans the band."""
    if not HOSPITAL.is_file():
        pytest.skip(f"{HOSPITAL} is absent (../shared/worlds not here)")
    b = load_building(HOSPITAL)
    spec = FileWorldConfig(path=str(HOSPITAL))
    plain, robust = plain_free_space(b, spec), camera_free_space(b, spec)
    assert plain.area <= robust.area <= 1.1 * plain.area
    assert robust.contains(plain.centres(np.nonzero(plain.free))).all()
    # full-height walls alone, grown by the margin less 1.5 cells: the robust map's free
    # cells are all free there
    z = b.vertices[b.faces][:, :, 2]
    band = float(b.info["floor_z"]) + np.asarray(spec.z_range)
    tall = (b.face_class == C.WALL) & (z.min(1) <= band[0]) & (z.max(1) >= band[1])
    keep = tall | np.isin(b.face_class, (C.FLOOR, C.CEILING))
    walls = OccupancyMap.from_mesh(b.vertices, b.faces[keep], b.face_class[keep], band,
                                   spec.camera_margin - 1.5 * spec.free_cell, spec.free_cell,
                                   exclude_solids=False, ceiling_classes=(C.CEILING,),
                                   close=spec.free_close, max_hole=spec.free_max_hole)
    assert walls.contains(robust.centres(np.nonzero(robust.free))).all()
