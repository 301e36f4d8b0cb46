"""The corridor generator and the 3D edge extraction."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from core import classes as C
from core.config import compose_config
from datagen.mesh.edges import extract_edges
from datagen.worlds.corridor import MAIN, Box, boundary_mesh, build_world, classify_faces


@pytest.fixture(scope="module")
def spec() -> dict:
    return compose_config("datagen")["world"]


@pytest.fixture(scope="module")
def model(spec):
    return build_world(spec)


class TestBoundaryMesh:
    def test_single_box_is_closed_with_inward_normals(self):
        v, f, owner, normal = boundary_mesh([Box((0, 0, 0), (1, 2, 3), MAIN)])
        mesh = trimesh.Trimesh(v, f, process=False)
        assert mesh.is_watertight
        assert len(f) == 12
        np.testing.assert_allclose(mesh.volume, -6.0)  # normals point into the free space
        assert (owner == 0).all()

    def test_single_box_has_twelve_edges(self):
        v, f, owner, normal = boundary_mesh([Box((0, 0, 0), (1, 2, 3), MAIN)])
        cls = classify_faces([Box((0, 0, 0), (1, 2, 3), MAIN)], owner, normal)
        seg, pairs, crease, _ = extract_edges(v, f, cls)
        assert len(seg) == 12  # diagonals dropped
        np.testing.assert_allclose(crease, 90.0)
        lengths = np.sort(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1))
        np.testing.assert_allclose(lengths, [1] * 4 + [2] * 4 + [3] * 4)
        assert {tuple(p) for p in pairs.tolist()} == {(1, 2), (2, 2), (2, 3)}


class TestCorridor:
    def test_watertight_and_sized(self, model, spec):
        w = model.world
        mesh = trimesh.Trimesh(w.vertices, w.faces, process=False)
        assert mesh.is_watertight
        lo, hi = w.vertices.min(0), w.vertices.max(0)
        assert lo[2] == 0.0 and hi[2] == spec["height"]
        assert lo[1] == 0.0 - spec["door"]["depth"] and hi[1] > spec["length"]

    def test_classes(self, model, spec):
        w = model.world
        assert set(np.unique(w.face_class)) == {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW}
        normals = trimesh.Trimesh(w.vertices, w.faces, process=False).face_normals
        np.testing.assert_allclose(normals[w.face_class == C.FLOOR] - [0, 0, 1], 0, atol=1e-9)
        np.testing.assert_allclose(normals[w.face_class == C.CEILING] - [0, 0, -1], 0, atol=1e-9)

    def test_frames_add_jambs_and_head_to_the_door(self, model, spec):
        w = model.world
        area = trimesh.Trimesh(w.vertices, w.faces, process=False).area_faces
        d = spec["door"]
        leaf = d["width"] * d["height"]
        frame = d["depth"] * (2 * d["height"] + d["width"])
        np.testing.assert_allclose(area[w.face_class == C.DOOR].sum(),
                                   len(spec["doors"]) * (leaf + frame))

    def test_frames_put_the_boundary_on_the_outer_edge(self, model, spec):
        w = model.world
        seg, pairs = w.segments, np.sort(w.segment_classes, axis=1)
        is_wd = (pairs == [C.WALL, C.DOOR]).all(axis=1)
        # a wall | door line lies in a corridor wall's plane (x = +-width/2 or y = 0), not
        # a recess's depth behind it
        x = np.abs(seg[is_wd][..., 0])
        on_side = np.isclose(x, spec["width"] / 2).all(axis=1)
        on_back = np.isclose(seg[is_wd][..., 1], 0.0).all(axis=1)
        assert is_wd.any() and (on_side | on_back).all()

    def test_edges_are_model_edges(self, model):
        w = model.world
        seg = w.segments
        d = seg[:, 1] - seg[:, 0]
        # axis-aligned, no zero-length pieces, no coplanar same-class seams
        assert (np.count_nonzero(np.abs(d) > 1e-9, axis=1) == 1).all()
        same = w.segment_classes[:, 0] == w.segment_classes[:, 1]
        assert (w.crease_deg[same] > 20).all()
        assert (w.segment_classes[~same] > 0).all()
        # merged: long floor-wall lines exist
        lengths = np.linalg.norm(d, axis=1)
        assert lengths.max() > 5.0

    def test_door_outline(self, model, spec):
        """Each door is outlined by wall | door lines (top, two sides) and floor | door lines
        (the leaf's bottom and the two door-class jambs' bottoms)."""
        w = model.world
        pairs = np.sort(w.segment_classes, axis=1)
        n = len(spec["doors"])
        assert (pairs == [C.WALL, C.DOOR]).all(axis=1).sum() == 3 * n
        assert (pairs == [C.FLOOR, C.DOOR]).all(axis=1).sum() == 3 * n
        windows = (pairs == [C.WALL, C.WINDOW]).all(axis=1).sum()
        assert windows == 4 * len(spec["windows"])

    def test_free_space_inside_corridor(self, model, spec):
        b = model.free_boxes
        assert b[0].tolist() == pytest.approx([-0.7, 0.3, 0.7, 9.7])
        assert (b[:, 2] > b[:, 0]).all() and (b[:, 3] > b[:, 1]).all()
        free = model.world.free  # its free cells' centres span the boxes
        np.testing.assert_allclose(free.free_bounds[[0, 2]], [b[:, 0].min(), b[:, 2].max()])
        np.testing.assert_allclose(free.free_bounds[[1, 3]], [b[:, 1].min(), b[:, 3].max()])
        assert free.band == (0.5, 2.2) and free.margin == 0.3

    @pytest.mark.parametrize("key,value", [("width", -1.0), ("height", 0.0)])
    def test_bad_sizes(self, spec, key, value):
        with pytest.raises(ValueError, match=f"world.{key}"):
            build_world({**spec, key: value})

    def test_unknown_key_names_it(self, spec):
        with pytest.raises(ValueError, match="world.frames: Key 'frames' not in 'WorldConfig'"):
            build_world({**spec, "frames": "opening"})

    def test_door_outside_wall(self, spec):
        with pytest.raises(ValueError, match="outside the wall"):
            build_world({**spec, "doors": [{"side": "left", "at": 9.9}]})

    def test_unknown_side(self, spec):
        with pytest.raises(ValueError, match="unknown wall side"):
            build_world({**spec, "doors": [{"side": "up", "at": 2.0}]})


def test_render_surfaces_cover_every_face_once_with_its_class(model):
    """Each face is in exactly one textured surface, whose class is the face's; the frames
    keep the frame texture whatever their class."""
    from datagen.worlds.scene import corridor_scene

    w = model.world
    surf = corridor_scene(model).surfaces
    assert sum(len(s.vertices) for s in surf) == 3 * len(w.faces)
    tri = w.vertices[w.faces]
    for s in surf:
        # map each surface triangle back to its face by its vertices
        v = s.vertices.reshape(-1, 3, 3)
        idx = [int(np.flatnonzero(np.abs(tri - t).sum(axis=(1, 2)) < 1e-9)[0]) for t in v]
        assert (w.face_class[idx] == s.class_id).all(), s.name
    frames_by_class = {s.class_id for s in surf if s.texture == "frame"}
    assert frames_by_class == {C.DOOR, C.WINDOW}
