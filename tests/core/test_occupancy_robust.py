"""core.occupancy: free space robust to what scans and furnished models hold (holes in the
floor, a floor seen only under the ceiling, stray triangles, tables, door heads), and never
through a wall."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from core import classes as C
from core.occupancy import OccupancyMap
from datagen.worlds.corridor import build_world
from tests.buildings import BAND, MARGIN, THICK, _box, assemble
from tests.core.test_occupancy import _iou

ROBUST = {"ceiling_classes": (C.CEILING,), "close": 0.5, "max_hole": 4.0,
          "obstacle_span": 0.25}
CELL = 0.1
WALLS = [(-0.2, -0.2, 6.2, 0.0), (-0.2, 6.0, 6.2, 6.2), (-0.2, 0.0, 0.0, 6.0),
         (6.0, 0.0, 6.2, 6.0)]  # a 6 m x 6 m room
ROOM_AREA = (6 - 2 * MARGIN + CELL) ** 2  # free cell centres, the margin's edge included


def with_parts(mesh, parts: list[tuple[tuple, tuple, int]]):
    """A mesh plus boxes (lo (3,), hi (3,), class)."""
    v, f, c = mesh
    for lo, hi, cls in parts:
        b = _box(lo, hi)
        f = np.concatenate([f, np.asarray(b.faces) + len(v)])
        v = np.concatenate([v, np.asarray(b.vertices)])
        c = np.concatenate([c, np.full(len(b.faces), cls, np.uint8)])
    return v, f, c


def build(mesh, **kw) -> OccupancyMap:
    return OccupancyMap.from_mesh(*mesh, BAND, MARGIN, CELL, **kw)


def holed_room():
    """The room's floor as slabs with 0.4 m gaps between them and a 1.6 m x 1.6 m hole in
    the middle (a scan's unseen floor)."""
    floors = [(-0.2, -0.2, 2.0, 6.2), (2.4, -0.2, 6.2, 2.2), (2.4, 3.8, 6.2, 6.2),
              (4.0, 2.2, 6.2, 3.8)]
    return assemble(floors, WALLS)


class TestSupport:
    def test_holes_and_gaps_are_closed(self):
        mesh = holed_room()
        plain, robust = build(mesh), build(mesh, **ROBUST)
        assert plain.area < 0.85 * ROOM_AREA  # the gaps and their margins cut the room up
        assert not plain.contains(np.array([[3.2, 3.0], [2.2, 1.0]])).any()
        assert robust.area == pytest.approx(ROOM_AREA, rel=0.02)
        assert robust.contains(np.array([[3.2, 3.0], [2.2, 1.0]])).all()  # hole, gap
        assert not robust.contains(np.array([[-0.1, 3.0], [6.5, 3.0]])).any()  # wall, out

    def test_large_holes_stay_unless_under_a_ceiling(self):
        """Half the floor is missing: closing does not invent it, the ceiling over it
        does."""
        mesh = assemble([(-0.2, -0.2, 6.2, 3.0)], WALLS)
        no_ceiling = build(mesh, **ROBUST)
        assert no_ceiling.area < 0.55 * ROOM_AREA
        ceiling = with_parts(mesh, [((-0.2, -0.2, 2.8), (6.2, 6.2, 3.0), C.CEILING)])
        assert build(ceiling, **ROBUST).area == pytest.approx(ROOM_AREA, rel=0.02)
        assert build(ceiling, **{**ROBUST, "ceiling_classes": ()}).area < 0.55 * ROOM_AREA


class TestObstacles:
    def test_stray_triangles_do_not_block(self):
        """Scan noise: small triangles floating in the band block only where nothing
        else is; with ``obstacle_span`` they block nothing."""
        rng = np.random.default_rng(0)
        v, f, c = assemble([(-0.2, -0.2, 6.2, 6.2)], WALLS)
        n = 60
        centre = np.column_stack([rng.uniform(0.5, 5.5, (n, 2)), rng.uniform(0.6, 2.1, n)])
        tri = centre[:, None] + rng.normal(0, 0.03, (n, 3, 3))
        noisy = (np.concatenate([v, tri.reshape(-1, 3)]),
                 np.concatenate([f, len(v) + np.arange(3 * n).reshape(n, 3)]),
                 np.concatenate([c, np.full(n, C.WALL, np.uint8)]))
        assert build(noisy).area < 0.6 * ROOM_AREA
        assert build(noisy, **ROBUST).area == pytest.approx(ROOM_AREA, rel=0.02)

    def test_furniture(self):
        """A table (a top at 0.72-0.75 m on legs) does not fill the band, a cabinet (to
        1.8 m) does; a door's head (2.0 m up) leaves the opening free."""
        mesh = assemble([(-0.2, -0.2, 6.2, 6.2)], WALLS)
        legs = [((x, y, 0.0), (x + 0.05, y + 0.05, 0.72), C.CLUTTER)
                for x in (1.0, 2.45) for y in (1.0, 1.95)]
        furnished = with_parts(mesh, [((1.0, 1.0, 0.72), (2.5, 2.0, 0.75), C.CLUTTER),
                                      *legs, ((4.0, 4.5, 0.0), (5.0, 5.0, 1.8), C.CLUTTER)])
        plain, robust = build(furnished), build(furnished, **ROBUST)
        table, cabinet = np.array([[1.75, 1.5]]), np.array([[4.5, 4.75]])
        assert not plain.contains(table)[0] and robust.contains(table)[0]
        assert not robust.contains(cabinet)[0]
        assert robust.outside_distance(cabinet)[0] >= MARGIN

    def test_door_head_leaves_the_opening(self):
        """Two rooms joined by a 1.2 m door whose head is at 2.0 m (inside the band)."""
        t = THICK
        floors = [(-t, -t, 12.2, 6.2)]
        walls = [(-t, -t, 12.2, 0.0), (-t, 6.0, 12.2, 6.2), (-t, 0.0, 0.0, 6.0),
                 (12.0, 0.0, 12.2, 6.0), (6.0, 0.0, 6.2, 2.4), (6.0, 3.6, 6.2, 6.0)]
        mesh = with_parts(assemble(floors, walls),
                          [((6.0, 2.4, 2.0), (6.2, 3.6, 2.8), C.WALL)])
        for kw, parts in (({}, 2), (ROBUST, 1)):
            _, n = ndimage.label(build(mesh, **kw).free)
            assert n == parts


class TestWalls:
    @pytest.mark.parametrize("thickness", [0.05, 0.2])
    def test_the_map_never_grows_through_a_wall(self, thickness):
        """Two closed rooms side by side: whatever the closing, no free cell lies on or
        within the margin of the wall between them, and the rooms stay apart."""
        t = THICK
        x0, x1 = 6.0, 6.0 + thickness
        walls = [(-t, -t, 12.2, 0.0), (-t, 6.0, 12.2, 6.2), (-t, 0.0, 0.0, 6.0),
                 (12.0, 0.0, 12.2, 6.0), (x0, 0.0, x1, 6.0)]
        mesh = assemble([(-t, -t, 12.2, 6.2)], walls)
        for close in (0.5, 2.0):
            occ = build(mesh, **{**ROBUST, "close": close})
            xy = occ.centres(np.nonzero(occ.free))
            gap = np.maximum(x0 - xy[:, 0], xy[:, 0] - x1)
            assert gap.min() >= MARGIN - CELL / 2
            _, n = ndimage.label(occ.free)
            assert n == 2

    def test_settings_are_checked(self):
        mesh = holed_room()
        for bad in ({"obstacle_span": 1.5}, {"close": -0.1}, {"max_hole": -1.0}):
            with pytest.raises(ValueError, match="obstacle_span must be in"):
                build(mesh, **bad)


def test_defaults_keep_any_surface_an_obstacle():
    """Without the robust settings, every surface in the band is an obstacle (the
    building tests' maps are unchanged)."""
    mesh = with_parts(assemble([(-0.2, -0.2, 6.2, 6.2)], WALLS),
                      [((2.9, 2.9, 1.0), (3.1, 3.1, 1.02), C.CLUTTER)])
    assert not build(mesh).contains(np.array([[3.0, 3.0]]))[0]
    assert build(mesh, obstacle_span=0.25).contains(np.array([[3.0, 3.0]]))[0]


def test_corridor_mesh_still_matches_its_boxes():
    """The procedural corridor: the robust settings give the free space of its boxes."""
    model = build_world()
    w = model.world
    robust = OccupancyMap.from_mesh(w.vertices, w.faces, w.face_class, w.z_range, MARGIN,
                                    CELL, **ROBUST)
    boxes = OccupancyMap.from_boxes(model.free_boxes, w.z_range, CELL, margin=MARGIN)
    assert robust.area == pytest.approx(boxes.area, rel=0.03)
    assert _iou(robust, boxes, CELL / 3) >= 0.95
