"""Overlay of model edges at estimated poses (localize/viewers/overlay.py)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from core import classes as C
from core.atomic import read_png
from core.dataset import Camera, Dataset
from core.imaging.camera import intrinsics, project
from core.poses import xyzyaw_from_pose
from localize.viewers.overlay import (
    camera_poses,
    clip_segments,
    draw_segments,
    overlay_strip,
    project_segments,
    tile,
)

CAM = Camera(intrinsics(80, 60, 90.0), 80, 60, np.eye(4))


class TestClipSegments:
    def test_values(self):
        a = np.array([[-1.0, 0.5], [0.2, 0.2], [2.0, 2.0], [0.5, -1.0]])
        b = np.array([[2.0, 0.5], [0.8, 0.6], [3.0, 3.0], [0.5, 0.5]])
        ca, cb, keep = clip_segments(a, b, np.zeros(2), np.ones(2))
        np.testing.assert_array_equal(keep, [True, True, False, True])
        np.testing.assert_allclose(ca[keep], [[0, 0.5], [0.2, 0.2], [0.5, 0]])
        np.testing.assert_allclose(cb[keep], [[1, 0.5], [0.8, 0.6], [0.5, 0.5]])

    def test_parallel_outside_is_dropped(self):
        _, _, keep = clip_segments(np.array([[-1.0, 2.0]]), np.array([[3.0, 2.0]]),
                                   np.zeros(2), np.ones(2))
        assert not keep.any()


class TestProjectSegments:
    def test_matches_the_pinhole_projection(self):
        seg = np.array([[[-0.2, -0.1, 2.0], [0.3, 0.1, 3.0]]])
        lines = project_segments(CAM, np.eye(4), seg)
        uv, _ = project(CAM.K, np.eye(4), seg[0])
        np.testing.assert_allclose(lines[0], uv, atol=1e-9)

    def test_behind_and_across_the_camera(self):
        seg = np.array([[[0.0, 0.0, -2.0], [0.1, 0.0, -1.0]],  # behind: dropped
                        [[0.0, 0.2, -1.0], [0.0, 0.2, 1.0]],  # through the near plane
                        [[-5.0, 0.0, 1.0], [5.0, 0.0, 1.0]]])  # wider than the image
        lines = project_segments(CAM, np.eye(4), seg)
        assert lines.shape == (2, 2, 2)
        assert np.all(lines[..., 0] >= -0.5) and np.all(lines[..., 0] <= CAM.width - 0.5)
        assert np.all(lines[..., 1] >= -0.5) and np.all(lines[..., 1] <= CAM.height - 0.5)
        np.testing.assert_allclose(lines[0, :, 0], CAM.K[0, 2])  # stays on the centre column
        np.testing.assert_allclose(sorted(lines[1, :, 0]), [-0.5, CAM.width - 0.5])

    def test_bad_shape(self):
        with pytest.raises(ValueError, match=r"\(M, 2, 3\)"):
            project_segments(CAM, np.eye(4), np.zeros((3, 3)))


def test_draw_and_tile():
    img = np.zeros((60, 80, 3), np.uint8)
    out = draw_segments(img, np.array([[[10.0, 30.0], [70.0, 30.0]]]), (0, 255, 0))
    assert out[30, 40, 1] > 200 and out[10, 40, 1] == 0 and img.max() == 0
    t = tile([out, img, out], columns=2, gap=2)
    assert t.shape == (122, 162, 3)
    np.testing.assert_array_equal(t[:60, :80], out)
    np.testing.assert_array_equal(t[62:, :80], out)


def test_strip_lines_up_with_the_true_labels(tiny_dataset, tmp_path):
    """At the true poses the drawn edges lie on the label image's class boundaries (median
    distance under 1.2 pixels; creases inside a class and hidden edges are drawn too); 20 cm
    and 5 degrees off the median distance is more than 1.5 times that."""
    ds = Dataset(tiny_dataset)
    f, cam, world = ds.flight("paper"), ds.camera, ds.world()
    idx = [3, 15, 27]
    labels = [C.colorize(read_png(f.label[i], rgb=False)) for i in idx]
    truth = xyzyaw_from_pose(f.groundtruth[idx])
    poses = {"truth": camera_poses(truth, f.groundtruth[idx], cam),
             "off": camera_poses(truth + [0.2, 0.0, 0.0, np.deg2rad(5)], f.groundtruth[idx],
                                 cam)}
    blank = [np.zeros_like(im) for im in labels]
    score = {}
    for key, P in poses.items():
        drawn = overlay_strip(None, blank, cam, world.segments, P, columns=3)
        edges = tile([cv2.Canny(im, 10, 30) for im in labels], 3)
        dist = cv2.distanceTransform((edges == 0).astype(np.uint8), cv2.DIST_L2, 3)
        score[key] = float(np.median(dist[drawn[..., 1] > 128]))
    assert score["truth"] < 1.2 and score["off"] > 1.5 * score["truth"]
    path = tmp_path / "strip.png"
    pic = overlay_strip(path, labels, cam, world.segments, poses["off"], poses["truth"],
                        [f"frame {i}" for i in idx], columns=2)
    assert pic.shape == (2 * cam.height + 2, 2 * cam.width + 2, 3)
    np.testing.assert_array_equal(read_png(path), pic)


def test_strip_bad_input():
    with pytest.raises(ValueError, match="one estimate per frame"):
        overlay_strip(None, [np.zeros((60, 80, 3), np.uint8)], CAM, np.zeros((1, 2, 3)),
                      np.zeros((2, 4, 4)))
    with pytest.raises(ValueError, match=r"frame 0 is \(10, 10, 3\)"):
        overlay_strip(None, [np.zeros((10, 10, 3), np.uint8)], CAM, np.zeros((1, 2, 3)),
                      np.eye(4)[None])
