"""Localization at floor scale (issue 55): visibility lists that grow with what a camera can
see, the likelihood's culling by them, and which model edges are sampled."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from core.dataset import World
from core.occupancy import OccupancyMap
from datagen.mesh.edges import extract_edges
from localize.config import LikelihoodConfig, LocalizerConfig, VisibilityConfig
from localize.edge_model import EdgeModel, scored_segments
from localize.filter.likelihood import EdgeLikelihood
from localize.filter.projection import (
    cam_from_world,
    camera_centres,
    in_view_cone,
    pixel_index,
    projection_matrices,
    sample_segments,
    tilt_from_pose,
    view_half_width,
)
from localize.filter.visibility import build_visibility
from tests.buildings import BAND, MARGIN, THICK, assemble

TRUE = np.array([0.2, 0.8, 1.2, np.deg2rad(80.0)])


def straight(length: float, width: float = 2.0) -> World:
    """A walled corridor ``length`` x ``width`` m along +X (no ceiling) as a World."""
    t = THICK
    v, f, cls = assemble([(-t, -t, length + t, width + t)],
                         [(-t, -t, length + t, 0), (-t, width, length + t, width + t),
                          (-t, 0, 0, width), (length, 0, length + t, width)])
    seg, seg_cls, crease, _ = extract_edges(v, f, cls, 20.0)
    free = OccupancyMap.from_mesh(v, f, cls, BAND, MARGIN, 0.1)
    return World(v, f, cls, seg, seg_cls, crease, free, {})


def test_memory_grows_with_the_cells_not_the_building():
    """Per stored cell the lists hold what lies within max_range, however long the building:
    tripling the corridor triples the bytes (the dense grid: nine times)."""
    out = {}
    for length in (15.0, 45.0):
        world = straight(length)
        s = sample_segments(world.segments, 0.2)
        vis = build_visibility(world, s.points, world.free,
                               settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6, max_range=4.0))
        c = vis.centres()
        in_range = (np.linalg.norm(c[:, None] - s.points[None], axis=2) <= 4.0).sum(axis=1)
        assert (vis.counts() <= in_range).all()
        out[length] = (vis.nbytes / len(c), len(c), len(s))
    (b15, n15, p15), (b45, n45, p45) = out[15.0], out[45.0]
    assert n45 > 2.5 * n15 and p45 > 2 * p15
    assert b45 < 1.25 * b15  # bytes per cell: the same


@pytest.fixture(scope="module")
def model(small_world):
    s = sample_segments(small_world.segments, 0.05)
    sc = small_world.segment_classes
    s, _ = s.select(sc[:, 0] != sc[:, 1])
    return s, build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.3, cell_z=0.4))


def test_view_cone_keeps_every_sample_in_view(model, camera):
    """No sample a particle of a block projects into its image is culled by the block's
    cone (particles spread 0.5 m and 20 deg, the IMU tilted)."""
    s, _ = model
    rng = np.random.default_rng(0)
    from core.poses import pose_from_xyz_rpy

    tilt = tilt_from_pose(pose_from_xyz_rpy(np.zeros(3), np.deg2rad([4.0, -6.0, 30.0]))[0])
    culled = []
    for spread, yaw_deg in ((0.0, 2.0), (0.2, 10.0), (0.5, 20.0)):
        states = TRUE + rng.normal(0, 1, (64, 4)) * [spread, spread, 0.1, np.deg2rad(yaw_deg)]
        P = projection_matrices(cam_from_world(states, camera.body_from_cam, tilt), camera.K)
        _, valid, _ = pixel_index(P, s.points_h, camera.width, camera.height)
        half = view_half_width(camera.K, camera.width, camera.height, camera.body_from_cam,
                               tilt)
        keep = in_view_cone(s.points, camera_centres(states, camera.body_from_cam, tilt),
                            states[:, 3], half)
        assert not (valid & ~keep).any()
        culled.append(1 - keep.mean())
    assert culled[0] > 0.3  # it culls


def test_half_width_is_everything_looking_straight_up(camera):
    up = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # pitch 90 deg
    assert view_half_width(camera.K, camera.width, camera.height, camera.body_from_cam,
                           up) == pytest.approx(np.pi)
    level = view_half_width(camera.K, camera.width, camera.height, camera.body_from_cam)
    assert np.deg2rad(35.0) < level < np.deg2rad(40.0)  # 70 deg hfov + 2 deg margin


def test_culled_scores_equal_unculled(model, camera, renderer, monkeypatch):
    """Scoring only the samples the block's cells see and its cameras face gives the scores
    of scoring all samples against the same lists (up to float64 summation order)."""
    import localize.filter.likelihood as L
    from localize.frontend.boundaries import label_edges

    s, vis = model
    rng = np.random.default_rng(1)
    states = TRUE + rng.normal(0, 1, (300, 4)) * [0.3, 0.3, 0.1, 0.3]
    labels, _ = renderer.render(np.linalg.inv(cam_from_world(TRUE[None],
                                                             camera.body_from_cam)[0]))
    params = LikelihoodConfig(orientation_bins=8, chunk=64, workers=1)
    lik = EdgeLikelihood(s, camera, params, vis)
    obs = lik.observe(label_edges(labels))
    culled, q_culled = lik.scores(states, obs)
    monkeypatch.setattr(L, "in_view_cone", lambda p, *a: np.ones(len(p), bool))
    monkeypatch.setattr(type(vis), "union", lambda self, rows: np.ones(self.num_samples, bool))
    full, q_full = lik.scores(states, obs)
    np.testing.assert_allclose(culled, full, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q_culled, q_full, rtol=0, atol=1e-12)


def test_clutter_and_short_segments_are_not_sampled(small_world):
    sc = np.array([[C.WALL, C.FLOOR], [C.CLUTTER, C.CLUTTER], [C.VOID, C.CLUTTER],
                   [C.VOID, C.WALL], [C.PERSON, C.DOOR], [C.WALL, C.WALL]], np.uint8)
    seg = np.zeros((6, 2, 3))
    seg[:, 1, 0] = [1.0, 1.0, 1.0, 1.0, 1.0, 0.01]
    world = World(small_world.vertices, small_world.faces, small_world.face_class, seg, sc,
                  np.zeros(6), small_world.free, {})
    np.testing.assert_array_equal(scored_segments(world), [1, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(scored_segments(world, 0.05), [1, 0, 0, 1, 1, 0])
    model = EdgeModel.build(world, LocalizerConfig(), occlusion=False)  # min_length 0.05 by default
    assert set(np.unique(model.samples.segment)) == {0, 3, 4}
