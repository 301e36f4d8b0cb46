"""core.poses.interpolate_poses: between samples, clamped or extrapolated beyond them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.poses import interpolate_poses


def _poses() -> np.ndarray:
    """Three poses: yaw 0, 20, 50 deg at (0, 0, 0), (1, 0, 0), (1, 2, 0)."""
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("z", [[0.0], [20.0], [50.0]], degrees=True).as_matrix()
    poses[:, :3, 3] = [[0, 0, 0], [1, 0, 0], [1, 2, 0]]
    return poses


def _yaw(poses: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(poses[:, :3, :3]).as_euler("zyx", degrees=True)[:, 0]


def test_extrapolated_beyond_the_ends():
    poses = _poses()
    out = interpolate_poses(np.array([0.0, 0.05, 0.1, 0.15, -0.05, 0.25]),
                            np.array([0.0, 0.1, 0.2]), poses, extrapolate=True)
    np.testing.assert_allclose(out[[0, 2]], poses[:2], atol=1e-12)
    np.testing.assert_allclose(_yaw(out), [0, 10, 20, 35, -10, 65], atol=1e-9)
    np.testing.assert_allclose(out[:, :3, 3], [[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 1, 0],
                                               [-0.5, 0, 0], [1, 3, 0]], atol=1e-12)


def test_clamped_and_uneven_stamps():
    poses = _poses()
    out = interpolate_poses(np.array([-1.0, 0.25, 2.0, 5.0]), np.array([0.0, 1.0, 3.0]), poses)
    np.testing.assert_allclose(out[0], poses[0], atol=1e-12)
    np.testing.assert_allclose(out[3], poses[2], atol=1e-12)
    np.testing.assert_allclose(_yaw(out), [0, 5, 35, 50], atol=1e-9)
    np.testing.assert_allclose(out[2, :3, 3], [1, 1, 0], atol=1e-12)


def test_one_sample_and_bad_shapes():
    one = interpolate_poses(np.array([-1.0, 3.0]), np.array([0.5]), _poses()[1:2],
                            extrapolate=True)
    np.testing.assert_array_equal(one, np.repeat(_poses()[1:2], 2, axis=0))
    with pytest.raises(ValueError, match="M >= 1 matching"):
        interpolate_poses(np.array([0.0]), np.array([0.0, 1.0]), _poses())
