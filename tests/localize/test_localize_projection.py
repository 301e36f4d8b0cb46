"""Model edge samples, their projection into many cameras, and occlusion, against renders."""

from __future__ import annotations

import numpy as np
import pytest

from core.imaging.camera import project
from core.imaging.outline import seen_pairs
from core.imaging.rays import RayCaster
from localize.config import VisibilityConfig
from localize.filter.projection import (
    ModelSamples,
    cam_from_world,
    camera_centres,
    corrected_tilts,
    image_directions,
    pixel_index,
    project_samples,
    projection_matrices,
    sample_segments,
    tilt_from_pose,
)
from localize.filter.visibility import (
    build_visibility,
    free_bounds,
    grid_layout,
    load_or_build,
    occluded,
)
from tests.localize.conftest import BODY_FROM_CAM

#: A pose inside the small corridor looking along +Y past the side opening, slightly tilted.
STATE = np.array([[0.3, 0.6, 1.3, np.deg2rad(95.0)]])


def tilt(roll_deg: float = 2.0, pitch_deg: float = -3.0) -> np.ndarray:
    from core.poses import pose_from_xyz_rpy

    return tilt_from_pose(pose_from_xyz_rpy(np.zeros((1, 3)),
                                            np.deg2rad([[roll_deg, pitch_deg, 40.0]]))[0])


def test_corrected_tilts_add_to_roll_and_pitch():
    corr = np.deg2rad([[0.0, 0.0], [0.7, -1.2], [-2.0, 0.5]])
    got = corrected_tilts(tilt(2.0, -3.0), corr)
    for c, R in zip(np.rad2deg(corr), got, strict=True):
        np.testing.assert_allclose(R, tilt(2.0 + c[0], -3.0 + c[1]), atol=1e-12)
    np.testing.assert_allclose(corrected_tilts(None, corr[1:2])[0], tilt(0.7, -1.2), atol=1e-12)
    # one tilt per particle gives each particle's camera the shared tilt's pose
    states = np.repeat(STATE, 3, axis=0)
    per = cam_from_world(states, BODY_FROM_CAM, got)
    for i in range(3):
        np.testing.assert_allclose(per[i], cam_from_world(STATE, BODY_FROM_CAM, got[i])[0],
                                   atol=1e-12)


class TestSampleSegments:
    def test_spacing_and_ids(self):
        seg = np.array([[[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 0.05, 0]],
                        [[1, 1, 1], [1, 1, 1]]], dtype=float)
        s = sample_segments(seg, 0.1)
        assert isinstance(s, ModelSamples)
        assert len(s) == 12  # 10 + min 2, the zero-length segment skipped
        np.testing.assert_array_equal(s.starts, [0, 10])
        np.testing.assert_allclose(s.points[:10, 0], np.arange(10) * 0.1 + 0.05, atol=1e-6)
        np.testing.assert_allclose(s.dirs[:10], [[1, 0, 0]] * 10)
        assert s.points_h.shape == (4, 12)
        np.testing.assert_array_equal(s.run, [0] * 10 + [1] * 2)

    def test_bad_input(self):
        with pytest.raises(ValueError, match=r"\(M, 2, 3\)"):
            sample_segments(np.zeros((3, 3)), 0.1)
        with pytest.raises(ValueError, match="spacing"):
            sample_segments(np.zeros((1, 2, 3)) + [[0, 0, 0], [1, 0, 0]], 0.0)

    def test_select_and_thin(self, small_world):
        s = sample_segments(small_world.segments, 0.1)
        keep = small_world.segment_classes[:, 0] != small_world.segment_classes[:, 1]
        sub, cols = s.select(keep)
        np.testing.assert_array_equal(sub.points, s.points[cols])
        assert keep[sub.segment].all() and len(sub) < len(s)
        thin, cols = s.thin(3)
        assert set(np.unique(thin.segment)) == set(np.unique(s.segment))  # every segment kept
        assert len(s) / 4 < len(thin) < len(s) / 2
        np.testing.assert_array_equal(thin.points, s.points[cols])


class TestProjection:
    def test_matches_datagen_project(self, camera):
        rng = np.random.default_rng(0)
        states = np.column_stack([rng.uniform(-1, 1, (5, 3)), rng.uniform(-np.pi, np.pi, 5)])
        pts = rng.uniform(-5, 5, (50, 3))
        T = cam_from_world(states, BODY_FROM_CAM, tilt())
        uv, depth = project(camera.K, T, np.broadcast_to(pts, (5, 50, 3)))
        pr = project_samples(camera.K, camera.width, camera.height, T, pts)
        np.testing.assert_allclose(pr.depth, depth, rtol=1e-5, atol=1e-5)
        ok = depth > 0.1
        np.testing.assert_allclose(pr.u[ok], uv[..., 0][ok], rtol=1e-4, atol=1e-3)
        idx, valid, _ = pixel_index(projection_matrices(T, camera.K), np.vstack(
            [pts.T, np.ones(50)]).astype(np.float32), camera.width, camera.height)
        inside = ok & (uv[..., 0] > 0) & (uv[..., 0] < camera.width - 1) & (uv[..., 1] > 0) & (
            uv[..., 1] < camera.height - 1)
        np.testing.assert_array_equal(valid[inside], True)
        np.testing.assert_array_equal(valid[~ok], False)
        v, u = np.divmod(idx[inside], camera.width)
        np.testing.assert_array_equal(u, np.rint(uv[..., 0][inside]))
        np.testing.assert_array_equal(v, np.rint(uv[..., 1][inside]))

    def test_camera_pose(self):
        T = cam_from_world(STATE, BODY_FROM_CAM)
        world_from_cam = np.linalg.inv(T[0])
        # the camera looks along the body x axis (yaw 95 deg: mostly +Y)
        np.testing.assert_allclose(world_from_cam[:3, 2], [np.cos(np.deg2rad(95)),
                                                           np.sin(np.deg2rad(95)), 0], atol=1e-9)
        np.testing.assert_allclose(world_from_cam[:3, 3], camera_centres(STATE, BODY_FROM_CAM)[0])

    def test_image_directions_finite_difference(self, camera):
        rng = np.random.default_rng(1)
        pts = rng.uniform([-1, 2, 0], [1, 4, 2], (20, 3))
        dirs = rng.normal(size=(20, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        T = cam_from_world(STATE, BODY_FROM_CAM, tilt())
        P = projection_matrices(T, camera.K)
        ph = np.vstack([pts.T, np.ones(20)]).astype(np.float32)
        _, _, xh = pixel_index(P, ph, camera.width, camera.height)
        du, dv = image_directions(P, dirs, xh)
        a = project_samples(camera.K, 160, 120, T, pts)
        b = project_samples(camera.K, 160, 120, T, pts + 1e-3 * dirs)
        fd = np.stack([b.u - a.u, b.v - a.v], -1)[0]
        an = np.stack([du, dv], -1)[0]
        cos = (fd * an).sum(-1) / np.linalg.norm(fd, axis=-1) / np.linalg.norm(an, axis=-1)
        np.testing.assert_allclose(cos, 1.0, atol=1e-3)

    def test_image_direction_same_along_a_line(self, camera):
        """A 3D line projects onto one image line: (du, dv) at any point of it, even behind the
        camera, equals that at another (the likelihood finds a segment's bin once)."""
        rng = np.random.default_rng(2)
        p0 = rng.uniform([-1, 2, 0], [1, 4, 2], (10, 3))
        dirs = rng.normal(size=(10, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        P = projection_matrices(cam_from_world(STATE, BODY_FROM_CAM, tilt()), camera.K)
        out = []
        for t in (0.0, 0.7, -3.0):
            pts = p0 + t * dirs
            ph = np.vstack([pts.T, np.ones(10)]).astype(np.float32)
            _, _, xh = pixel_index(P, ph, camera.width, camera.height)
            out.append(np.stack(image_directions(P, dirs, xh), -1)[0])
        for other in out[1:]:
            np.testing.assert_allclose(other, out[0], rtol=1e-3, atol=1e-3 * np.abs(out[0]).max())


def assert_same_rays(got: np.ndarray, want: np.ndarray) -> None:
    """Equal visibility but for a few rays in 10^4: Mitsuba's ray_test may answer a ray that
    grazes a surface (samples lie on edges) differently in another batch of rays."""
    assert (got != want).mean() < 1e-4, f"{(got != want).sum()} of {got.size} rays differ"


def _scene(small_world, camera, renderer, class_change_only: bool):
    s = sample_segments(small_world.segments, 0.05)
    if class_change_only:
        s, _ = s.select(small_world.segment_classes[:, 0] != small_world.segment_classes[:, 1])
    R = tilt()
    T = cam_from_world(STATE, BODY_FROM_CAM, R)
    labels, depth = renderer.render(np.linalg.inv(T[0]))
    eye = camera_centres(STATE, BODY_FROM_CAM, R)
    hidden = occluded(small_world, eye, s.points)[0]
    # a crease seen with one face turned away may show one class only (the lists' test too)
    w = small_world
    if class_change_only:
        hidden |= seen_pairs(w.segment_classes[s.segment], w.normals[s.segment], s.points,
                             np.broadcast_to(eye[0], s.points.shape),
                             RayCaster(w.vertices, w.faces), w.face_class) == 0
    pr = project_samples(camera.K, camera.width, camera.height, T, s.points)
    return s, labels, depth, hidden, pr


@pytest.fixture(scope="module")
def scene(small_world, camera, renderer):
    """Class-change samples (what a label image shows), the rendered labels and depth at
    STATE, direct occlusion, the projection."""
    return _scene(small_world, camera, renderer, class_change_only=True)


@pytest.fixture(scope="module")
def scene_all(small_world, camera, renderer):
    """The same with every model edge, creases inside one class too (door jamb | leaf)."""
    return _scene(small_world, camera, renderer, class_change_only=False)


class TestAgainstRender:
    """Projected, visible edge samples land on the rendered class boundaries and depths."""

    def test_render_sees_the_corridor(self, scene):
        _, labels, depth, _, _ = scene
        assert set(np.unique(labels)) >= {1, 2, 3}
        assert (depth > 0).all()  # closed model: every pixel hits it

    def test_visible_samples_on_rendered_boundaries(self, scene):
        from localize.filter.likelihood import distance_to
        from localize.frontend.boundaries import label_edges

        s, labels, depth, hidden, pr = scene
        vis = pr.in_view[0] & ~hidden
        assert vis.sum() > 100
        d = distance_to(label_edges(labels, dilate_px=0).edges)
        u, v = np.rint(pr.u[0][vis]).astype(int), np.rint(pr.v[0][vis]).astype(int)
        assert np.median(d[v, u]) <= 1.0
        assert np.mean(d[v, u] <= 2.0) > 0.9

    def test_visible_depth_matches_hidden_is_behind(self, scene_all):
        s, labels, depth, hidden, pr = scene_all
        u, v = np.rint(pr.u[0]).astype(int), np.rint(pr.v[0]).astype(int)
        iv = pr.in_view[0]
        # the nearest rendered depth in a 3x3 window (samples sit on depth edges)
        pad = np.pad(depth, 1, mode="edge")
        win = np.stack([pad[1 + dy:1 + dy + depth.shape[0], 1 + dx:1 + dx + depth.shape[1]]
                        for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
        near, far = win.min(axis=0), win.max(axis=0)
        z = pr.depth[0]
        vis, hid = iv & ~hidden, iv & hidden
        assert hid.sum() > 10, "the pose must see something hidden (jambs, the side opening)"
        ok_vis = (near[v[vis], u[vis]] <= z[vis] + 0.05) & (far[v[vis], u[vis]] >= z[vis] - 0.05)
        assert ok_vis.mean() > 0.95
        assert (near[v[hid], u[hid]] < z[hid] - 0.05).mean() > 0.9

    def test_lists_agree_with_direct_rays(self, small_world, scene):
        """Each stored cell lists exactly the samples a ray from its centre reaches (the
        dense grid of before, one row per cell), here with every sample within range."""
        s = scene[0]
        vis = build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.3, cell_z=0.4))
        centres = vis.centres()
        pick = np.random.default_rng(0).choice(len(centres), 20, replace=False)
        direct = ~occluded(small_world, centres[pick], s.points)
        got = vis.mask(centres[pick])
        assert_same_rays(got, direct)
        np.testing.assert_array_equal(vis.rows(centres[pick]), pick)
        np.testing.assert_array_equal(vis.counts()[pick], got.sum(axis=1))

    def test_range_culls_far_samples(self, small_world, scene):
        s = scene[0]
        full = build_visibility(small_world, s.points,
                                settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6))
        near = build_visibility(small_world, s.points,
                                settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6, max_range=2.0))
        c = full.centres()
        far = np.linalg.norm(c[:, None] - s.points[None], axis=2) > 2.0
        got = near.mask(c)
        assert not got[far].any()
        assert_same_rays(got, full.mask(c) & ~far)
        assert near.nbytes < full.nbytes

    def test_outside_cells_use_the_nearest_stored_one(self, small_world, scene):
        s = scene[0]
        vis = build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6))
        grid = np.stack(np.meshgrid(*[vis.origin[a] + vis.cell[a] * np.arange(vis.shape[a])
                                      for a in range(3)], indexing="ij"), -1).reshape(-1, 3)
        outside = np.setdiff1d(np.arange(len(grid)), vis.flat)
        assert len(outside) > 0, "the L-shaped free space leaves grid cells unstored"
        rows = vis.rows(grid[outside])
        d = np.linalg.norm(grid[outside][:, None] - vis.centres()[None], axis=2)
        np.testing.assert_allclose(d[np.arange(len(rows)), rows], d.min(axis=1))
        np.testing.assert_array_equal(vis.rows(grid[vis.flat]), np.arange(len(vis.flat)))

    def test_select_keeps_the_subsets_lists(self, small_world, scene):
        s = scene[0]
        vis = build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6))
        cols = np.flatnonzero(np.arange(len(s)) % 3 == 1)
        sub = vis.select(cols)
        c = vis.centres()
        np.testing.assert_array_equal(sub.mask(c), vis.mask(c)[:, cols])
        assert sub.num_samples == len(cols)
        small = vis.select(cols, chunk=7)  # chunk borders inside and between rows
        np.testing.assert_array_equal(small.indptr, sub.indptr)
        np.testing.assert_array_equal(small.ids, sub.ids)

    def test_cache_round_trip(self, small_world, scene, tmp_path):
        s = scene[0]
        a = load_or_build(small_world, s.points, None, tmp_path,
                          VisibilityConfig(cell_xy=0.5, cell_z=0.5))
        assert len(list(tmp_path.glob("visibility_*.npz"))) == 1
        b = load_or_build(small_world, s.points, None, tmp_path,
                          VisibilityConfig(cell_xy=0.5, cell_z=0.5))
        for key in ("origin", "cell", "shape", "row_of", "flat", "indptr", "ids"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        assert (a.num_samples, a.max_range) == (b.num_samples, b.max_range)
        load_or_build(small_world, s.points, None, tmp_path,
                      VisibilityConfig(cell_xy=0.5, cell_z=0.5, max_range=3.0))
        assert len(list(tmp_path.glob("visibility_*.npz"))) == 2  # another range, another key

    def test_grid_covers_free_space(self, small_world):
        origin, cell, shape = grid_layout(*free_bounds(small_world.free), 0.2, 0.25, 0.3)
        hi = origin + cell * (shape - 1)
        b = small_world.free.free_bounds
        assert (origin[:2] <= b[:2]).all() and (hi[:2] >= b[2:]).all()
        assert origin[2] <= small_world.z_range[0] and hi[2] >= small_world.z_range[1]


def test_model_renderer_needs_a_centred_principal_point(camera):
    """A calibrated K (principal point off centre) is refused by the paper-faithful renderer;
    ``centred`` tells the runner to skip that comparison instead."""
    from dataclasses import replace

    from localize.paper.render import centred

    assert centred(camera)
    K = camera.K.copy()
    K[1, 2] += 6.3
    assert not centred(replace(camera, K=K))
