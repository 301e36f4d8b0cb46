"""The class pair each visibility entry holds (core.imaging.outline) and the modes' models."""

from __future__ import annotations

import numpy as np

from core import classes as C
from core.classes import pair_code
from core.imaging.outline import seen_pairs
from core.imaging.rays import RayCaster
from datagen.mesh.edges import extract_edges
from datagen.worlds.corridor import build_world
from localize.config import LocalizerConfig, VisibilityConfig
from localize.edge_model import EdgeModel
from localize.filter.projection import sample_segments
from localize.filter.visibility import build_visibility
from tests.buildings import HEIGHT
from tests.datagen.test_edges import _join
from tests.datagen.test_edges_construction import _ring, _slab, _solid

SETTINGS = VisibilityConfig(cell_xy=0.4, cell_z=0.6)


def _entries(vis):
    """(nnz,) row and (nnz,) sample id of every entry."""
    return np.repeat(np.arange(len(vis.flat)), vis.counts()), vis.ids.astype(np.int64)


def test_each_entry_holds_the_pair_its_cell_sees():
    """The corridor's lists: every entry's code is the class pair seen from its cell centre
    (``seen_pairs``); segments that are no crease keep their own pair."""
    w = build_world().world
    s = sample_segments(w.segments, 0.1)
    cls, nrm = w.segment_classes[s.segment], w.normals[s.segment]
    vis = build_visibility(w, s.points, settings=SETTINGS, classes=cls, normals=nrm)
    row, j = _entries(vis)
    want = seen_pairs(cls[j], nrm[j], s.points[j], vis.centres()[row],
                      RayCaster(w.vertices, w.faces), w.face_class)
    np.testing.assert_array_equal(vis.codes, want)
    plain = np.isnan(nrm[j, 0, 0])
    own = np.where(cls[j, 0] != cls[j, 1], pair_code(cls[j, 0], cls[j, 1]), 0)
    np.testing.assert_array_equal(vis.codes[plain], own[plain])
    # without classes the codes are 0; the ids are the same
    bare = build_visibility(w, s.points, settings=SETTINGS)
    np.testing.assert_array_equal(bare.ids, vis.ids)
    assert not bare.codes.any()


def test_a_wall_end_is_a_boundary_only_where_it_is_an_outline():
    """A free-standing wall (its own box) in a room: its end's vertical corners are wall|wall
    creases. The label modes' lists hold a corner's samples only from cells that see one of
    its faces turned away, against the room's floor, walls or ceiling (never as wall|wall);
    mode none's hold them from wherever they are not hidden."""
    from core.dataset import World
    from core.occupancy import OccupancyMap

    wall = _solid([((1.0, 1.9, 0.0), (2.5, 2.1, HEIGHT))], C.WALL)
    v, f, c = _join(_slab(), _ring(), _slab(HEIGHT, C.CEILING), wall)
    seg, cls, crease, nrm = extract_edges(v, f, c)
    corner = ((np.abs(seg[:, :, 0] - 2.5) < 1e-6) & (np.abs(seg[:, :, 1] - 2.1) < 1e-6)).all(
        axis=1) & (np.abs(seg[:, 1, 2] - seg[:, 0, 2]) > 1.0)
    assert corner.sum() == 1 and (cls[corner] == C.WALL).all()
    free = OccupancyMap.from_boxes(np.array([[0.2, 0.2, 3.8, 1.7], [0.2, 2.3, 3.8, 3.8],
                                             [2.7, 0.2, 3.8, 3.8]]), (0.5, 2.0), 0.1)
    world = World(v, f, c, seg, cls, crease, free, {"name": "wall end"}, nrm)
    model = EdgeModel.build(world, LocalizerConfig(), free=free)
    labels, none = model.for_mode(world, "oracle"), model.for_mode(world, "none")
    assert none is model
    row, j = _entries(labels.visibility)
    at = corner[labels.samples.segment][j]
    codes = labels.visibility.codes
    lo, hi = C.pair_classes(codes)
    assert ((lo > 0) & (lo != hi)).all() and at.any()
    lo, hi = C.pair_classes(codes[at])
    assert set(lo.tolist()) | set(hi.tolist()) <= {C.FLOOR, C.WALL, C.CEILING}
    # from straight ahead of the wall's end only the end face is turned towards the camera
    # (an outline); from the diagonal both faces are (one class: no entry)
    rows = labels.visibility.rows
    ahead, diagonal = rows(np.array([[3.5, 1.7, 1.25], [3.5, 3.5, 1.25]]))
    assert at[row == ahead].any() and not at[row == diagonal].any()
    # mode none lists the corner from both
    row_n, j_n = _entries(none.visibility)
    at_n = corner[none.samples.segment][j_n]
    assert at_n[row_n == ahead].any() and at_n[row_n == diagonal].any()


def test_mode_none_scores_every_segment():
    """Mode none samples every segment; the label modes only those that can show two
    structural classes (a crease of one class only as an outline)."""
    w = build_world().world
    model = EdgeModel.build(w, LocalizerConfig(), occlusion=False)
    assert model.for_mode(w, "none") is model
    labels = model.for_mode(w, "oracle").samples.segment
    sc = w.segment_classes[labels]
    assert (sc[:, 0] != sc[:, 1]).all()  # without lists: no outline can be told apart
