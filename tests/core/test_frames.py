"""core.frames: the frames of a source, their odometry increments and dropped frames."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from core.frames import delivered_frames, frame_count
from core.poses import odometry_increment, pose_from_xyzyaw


@dataclass
class Source:
    name: str
    timestamps: np.ndarray
    odometry: np.ndarray
    groundtruth: np.ndarray | None

    def __len__(self) -> int:
        return len(self.timestamps)


def source(n: int = 5, truth: bool = True) -> Source:
    states = np.stack([np.arange(n) * 0.3, np.arange(n) * 0.1, np.full(n, 1.2),
                       np.arange(n) * 0.2], axis=1)
    odo = pose_from_xyzyaw(states)
    return Source("s", np.arange(n) / 10, odo, odo.copy() if truth else None)


class TestOdometryIncrement:
    def test_forward_left_up_yaw_in_the_earlier_heading(self):
        a = pose_from_xyzyaw([1.0, 2.0, 0.5, np.pi / 2])[0]
        b = pose_from_xyzyaw([1.0, 3.0, 0.7, np.pi / 2 + 0.1])[0]
        np.testing.assert_allclose(odometry_increment(a, b), [1.0, 0.0, 0.2, 0.1], atol=1e-12)

    def test_yaw_change_wraps(self):
        a = pose_from_xyzyaw([0, 0, 0, np.pi - 0.05])[0]
        b = pose_from_xyzyaw([0, 0, 0, -np.pi + 0.05])[0]
        assert odometry_increment(a, b)[3] == pytest.approx(0.1)


class TestDeliveredFrames:
    def test_every_frame_with_its_increment(self):
        s = source()
        images = [np.full((2, 3, 3), i, np.uint8) for i in range(5)]
        frames = list(delivered_frames(s, None, images))
        assert [f.index for f in frames] == [0, 1, 2, 3, 4]
        assert frames[0].odometry_increment is None and frames[0].labels is None
        for f in frames[1:]:
            np.testing.assert_array_equal(
                f.odometry_increment, odometry_increment(s.odometry[f.index - 1],
                                                         s.odometry[f.index]))
        assert frames[2].image[0, 0, 0] == 2 and frames[2].timestamp == pytest.approx(0.2)
        np.testing.assert_array_equal(frames[3].attitude, s.odometry[3])
        np.testing.assert_array_equal(frames[3].truth, s.groundtruth[3])

    def test_limit_and_no_images(self):
        frames = list(delivered_frames(source(), 3, None))
        assert [f.index for f in frames] == [0, 1, 2] and frames[1].image is None
        assert frame_count(source(), None) == 5 and frame_count(source(), 9) == 5

    def test_unreadable_frame_is_dropped_and_spanned(self):
        s = source(truth=False)
        images = [np.zeros((2, 3, 3), np.uint8), None, None, np.zeros((2, 3, 3), np.uint8),
                  np.zeros((2, 3, 3), np.uint8)]
        labels = [np.full((2, 3), i, np.uint8) for i in range(5)]
        frames = list(delivered_frames(s, None, images, labels))
        assert [f.index for f in frames] == [0, 3, 4]
        assert frames[1].labels[0, 0] == 3 and frames[1].truth is None
        np.testing.assert_allclose(frames[1].odometry_increment,
                                   odometry_increment(s.odometry[0], s.odometry[3]))
