"""benchmarks/boundary_distance.py: per class pair, true boundary pixels to the cnn's."""

from __future__ import annotations

import numpy as np

from benchmarks.boundary_distance import frame_edges, pair_distances, signed_offsets
from datagen import classes as C
from localize.edges import EdgeExtractor, pair_code

CFG = {"labels": {"dilate_px": 0, "median": 0}, "cnn": {"snap_px": 0, "prior_correction": 0.0}}


class ShiftedSegmenter:
    """Predicts the true wall | door split moved ``shift`` columns right."""

    def __init__(self, shift: int):
        self.shift = shift

    def labels(self, rgb: np.ndarray) -> np.ndarray:
        return split(30 + self.shift)


def split(col: int) -> np.ndarray:
    """(20, 60) wall left of ``col``, door from it, ceiling in the top 4 rows."""
    lab = np.full((20, 60), C.WALL, dtype=np.uint8)
    lab[:, col:] = C.DOOR
    lab[:4] = C.CEILING
    return lab


def test_distances_per_pair():
    rgb = np.zeros((20, 60, 3), np.uint8)
    oracle = EdgeExtractor("oracle", CFG)
    exact = pair_distances(EdgeExtractor("cnn", CFG, ShiftedSegmenter(0)), oracle, rgb,
                           split(30), cap=10.0)
    wall_door, wall_ceiling = pair_code(C.WALL, C.DOOR), pair_code(C.WALL, C.CEILING)
    assert set(exact) == {wall_door, wall_ceiling, pair_code(C.DOOR, C.CEILING)}
    for d in exact.values():
        np.testing.assert_array_equal(d, 0)
    moved = pair_distances(EdgeExtractor("cnn", CFG, ShiftedSegmenter(3)), oracle, rgb,
                           split(30), cap=10.0)
    # true columns 29, 30 against predicted 32, 33: 3 and 2 px (rows below the ceiling)
    np.testing.assert_array_equal(np.unique(moved[wall_door]), [2.0, 3.0])
    far = pair_distances(EdgeExtractor("cnn", CFG, ShiftedSegmenter(20)), oracle, rgb,
                         split(30), cap=10.0)
    assert far[wall_door].max() == 10.0  # capped


def test_signed_offsets_name_the_side():
    rgb = np.zeros((20, 60, 3), np.uint8)
    oracle = EdgeExtractor("oracle", CFG)
    wall_door = pair_code(C.WALL, C.DOOR)
    for shift, want in ((0, [0.0]), (3, [2.0, 3.0]), (-3, [-3.0, -2.0])):
        ec, eo = frame_edges(EdgeExtractor("cnn", CFG, ShiftedSegmenter(shift)), oracle, rgb,
                             split(30))
        s = signed_offsets(ec, eo, split(30), cap=10.0)
        # door (the higher id) starts 3 px late: the boundary lies inside the true door, +
        np.testing.assert_array_equal(np.unique(s[wall_door]), want)
