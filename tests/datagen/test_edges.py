"""Model edges where separate meshes meet: boundary probes, covered faces, merging."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from datagen.mesh.edges import extract_edges, merge_collinear
from datagen.worlds.corridor import build_world
from tests.buildings import HEIGHT, assemble, ring


def _sheet(corners, cls) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One quad (4, 3) corners in order, as two triangles of class ``cls``."""
    return np.asarray(corners, float), np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, cls)


def _join(*parts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vs, fs, cs, n = [], [], [], 0
    for v, f, c in parts:
        vs.append(v), fs.append(f + n), cs.append(c)
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(cs).astype(np.uint8)


def _length(seg, classes, crease, pair, z=None, angle=None) -> float:
    """Metres of segments with class pair ``pair`` (at height ``z``, crease ``angle``)."""
    m = (classes == sorted(pair)).all(axis=1)
    if z is not None:
        m &= (np.abs(seg[:, :, 2] - z) < 1e-6).all(axis=1)
    if angle is not None:
        m &= np.abs(crease - angle) < 0.5
    return float(np.linalg.norm(seg[m, 1] - seg[m, 0], axis=1).sum())


FLOOR_SHEET = _sheet([(-1, -1, 0), (5, -1, 0), (5, 5, 0), (-1, 5, 0)], C.FLOOR)


class TestSeparateMeshes:
    def test_wall_blocks_on_a_slab_meet_the_floor(self):
        t = 0.2  # a 4 m x 4 m room walled by blocks on a 6 m x 6 m slab
        walls = [(-t, -t, 4 + t, 0), (-t, 4, 4 + t, 4 + t), (-t, 0, 0, 4), (4, 0, 4 + t, 4)]
        room = assemble([(-1, -1, 5, 5)], walls)
        seg, cls, crease, _ = extract_edges(*room)
        # foot lines of the walls, outside (4.4 x 4.4) and inside (4 x 4); the inner faces of
        # the two full-width blocks run on 0.2 m into the side blocks at both ends (a face
        # covered in part keeps its edges): + 4 x 0.2 m
        assert _length(seg, cls, crease, (C.FLOOR, C.WALL), z=0.0, angle=90) == pytest.approx(
            17.6 + 16 + 0.8, abs=1e-6)
        assert _length(seg, cls, crease, (C.WALL, C.WALL), z=0.0) == 0.0
        assert _length(seg, cls, crease, (C.VOID, C.WALL), z=0.0) == 0.0
        # the room's inner corners: one wall|wall crease each, floor to top
        vertical = np.abs(seg[:, 1, 2] - seg[:, 0, 2]) > 1e-6
        inner = vertical & (np.abs(seg[:, 0, :2] - [2, 2]) < 2 + 1e-6).all(axis=1)
        assert inner.sum() == 4
        assert (cls[inner] == [C.WALL, C.WALL]).all() and np.allclose(crease[inner], 90)

    def test_a_slab_covered_in_part_stays(self):
        # the ring's slab top: two triangles whose centres lie under the inner block
        seg, cls, crease, _ = extract_edges(*ring(10.0, 10.0, 2.0))
        # the outer walls' inner feet (4 x 10 m) and the inner block's (4 x 6 m), at least
        assert _length(seg, cls, crease, (C.FLOOR, C.WALL), z=0.0, angle=90) >= 64

    @pytest.mark.parametrize("flip", [False, True])
    def test_one_sided_wall_sheet_on_a_floor_sheet(self, flip):
        corners = [(0, 1, 0), (4, 1, 0), (4, 1, HEIGHT), (0, 1, HEIGHT)]
        wall = _sheet(corners[::-1] if flip else corners, C.WALL)
        seg, cls, crease, _ = extract_edges(*_join(FLOOR_SHEET, wall))
        assert _length(seg, cls, crease, (C.FLOOR, C.WALL), z=0.0, angle=90) == pytest.approx(4)
        assert _length(seg, cls, crease, (C.VOID, C.WALL), z=HEIGHT) == pytest.approx(4)

    def test_an_edge_meeting_a_surface_in_part_is_split(self):
        # the wall runs from x = 3 to 7, the floor ends at x = 5
        wall = _sheet([(3, 1, 0), (7, 1, 0), (7, 1, HEIGHT), (3, 1, HEIGHT)], C.WALL)
        seg, cls, crease, _ = extract_edges(*_join(FLOOR_SHEET, wall))
        assert _length(seg, cls, crease, (C.FLOOR, C.WALL), z=0.0) == pytest.approx(2, abs=0.25)
        assert _length(seg, cls, crease, (C.VOID, C.WALL), z=0.0) == pytest.approx(2, abs=0.25)
        assert _length(seg, cls, crease, (C.VOID, C.WALL), z=0.0) + _length(
            seg, cls, crease, (C.FLOOR, C.WALL), z=0.0) == pytest.approx(4)

    def test_free_standing_panel_keeps_void(self):
        panel = _sheet([(1, 2, 1), (3, 2, 1), (3, 2, 2), (1, 2, 2)], C.WALL)
        seg, cls, crease, _ = extract_edges(*_join(FLOOR_SHEET, panel))
        mine = (np.abs(seg[:, :, 1] - 2) < 1e-9).all(axis=1)
        assert mine.sum() == 4
        assert (cls[mine] == [C.VOID, C.WALL]).all() and np.allclose(crease[mine], 90)

    def test_door_sheet_in_a_wall_plane_is_a_flat_class_change(self):
        # a wall sheet with a door-sized gap and a door sheet in it, coplanar
        wall = _join(_sheet([(0, 1, 0), (1, 1, 0), (1, 1, HEIGHT), (0, 1, HEIGHT)], C.WALL),
                     _sheet([(2, 1, 0), (4, 1, 0), (4, 1, HEIGHT), (2, 1, HEIGHT)], C.WALL))
        door = _sheet([(1, 1, 0), (2, 1, 0), (2, 1, 2.1), (1, 1, 2.1)], C.DOOR)
        seg, cls, crease, _ = extract_edges(*_join(FLOOR_SHEET, wall, door))
        assert _length(seg, cls, crease, (C.WALL, C.DOOR), angle=0) == pytest.approx(2 * 2.1)
        assert _length(seg, cls, crease, (C.FLOOR, C.DOOR), z=0.0, angle=90) == pytest.approx(1)


def test_the_corridor_gains_no_contact_line():
    """Its surfaces share their vertices: every contact a cut finds is an edge it has."""
    w = build_world().world
    assert len(w.segments) == 132


def test_merge_collinear_joins_overlapping_and_touching_pieces():
    x = np.array([1.0, 0, 0])
    seg = np.array([[0, 1], [0.5, 2], [2, 2.5], [3, 4], [0, 1]])[:, :, None] * x
    cls = np.array([[1, 2]] * 4 + [[2, 3]], dtype=np.uint8)
    out, out_cls, out_ang = merge_collinear(seg, cls, np.zeros(5))
    lengths = sorted(np.linalg.norm(out[:, 1] - out[:, 0], axis=1).round(6).tolist())
    assert lengths == [1.0, 1.0, 2.5]
    assert out_cls.dtype == np.uint8 and len(out_ang) == 3
