"""benchmarks/boundary_distance.py: per class pair, true boundary pixels to the cnn's."""

from __future__ import annotations

import numpy as np

from benchmarks.boundary_distance import (
    decision_scores,
    distance_bands,
    frame_edges,
    logit_crossings,
    pair_distances,
    signed_offsets,
)
from core import classes as C
from core.classes import pair_code
from localize.frontend.extractor import edge_settings
from localize.frontend.front_end import FrontEnd
from localize.frontend.segmenter import LabelPredictor
from localize.frontend.sources import SegmenterLabels

CFG = {"labels": {"dilate_px": 0, "median": 0},
       "cnn": {"snap_px": 0, "prior_correction": 0.0, "refine": "none"}}


def cnn_front(segmenter) -> FrontEnd:
    """The cnn mode's front end of a segmenter, with CFG."""
    return FrontEnd(SegmenterLabels(segmenter, edge_settings(CFG).cnn), CFG)


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
    oracle = FrontEnd("oracle", CFG)
    exact = pair_distances(cnn_front(ShiftedSegmenter(0)), oracle, rgb,
                           split(30), cap=10.0)
    wall_door, wall_ceiling = pair_code(C.WALL, C.DOOR), pair_code(C.WALL, C.CEILING)
    assert set(exact) == {wall_door, wall_ceiling, pair_code(C.DOOR, C.CEILING)}
    for d in exact.values():
        np.testing.assert_array_equal(d, 0)
    moved = pair_distances(cnn_front(ShiftedSegmenter(3)), oracle, rgb,
                           split(30), cap=10.0)
    # true columns 29, 30 against predicted 32, 33: 3 and 2 px (rows below the ceiling)
    np.testing.assert_array_equal(np.unique(moved[wall_door]), [2.0, 3.0])
    far = pair_distances(cnn_front(ShiftedSegmenter(20)), oracle, rgb,
                         split(30), cap=10.0)
    assert far[wall_door].max() == 10.0  # capped


def test_signed_offsets_name_the_side():
    rgb = np.zeros((20, 60, 3), np.uint8)
    oracle = FrontEnd("oracle", CFG)
    wall_door = pair_code(C.WALL, C.DOOR)
    for shift, want in ((0, [0.0]), (3, [2.0, 3.0]), (-3, [-3.0, -2.0])):
        ec, eo = frame_edges(cnn_front(ShiftedSegmenter(shift)), oracle, rgb,
                             split(30))
        s = signed_offsets(ec, eo, split(30), cap=10.0)
        # door (the higher id) starts 3 px late: the boundary lies inside the true door, +
        np.testing.assert_array_equal(np.unique(s[wall_door]), want)


class RampSegmenter:
    """Logits of the ``split`` layout whose wall | door decision crosses at column ``c`` (a
    ramp, sub-pixel), ceiling in the top 4 rows, or of its mirror image; class weights give
    wall ``e`` (log 1)."""

    def __init__(self, c: float, mirror: bool = False):
        self.c, self.mirror = c, mirror
        self.classes = C.as_json()
        self.metadata = {"class_weights": {k["name"]: (np.e if k["id"] == C.WALL else 1.0)
                                           for k in self.classes}}
        self.path = "ramp.onnx"

    def logits(self, rgb: np.ndarray) -> np.ndarray:
        z = np.full((len(self.classes), 20, 60), -20.0, np.float32)
        f = np.arange(60, dtype=np.float32) - np.float32(self.c)
        z[C.DOOR] = f / 2
        z[C.WALL] = -f / 2
        z[C.CEILING, :4] = 20.0
        return z[..., ::-1] if self.mirror else z


def test_logit_crossings_place_the_decision_to_the_pixel():
    # wall columns 0-29, door from 30 (mirrored: door 0-29, wall from 30): the true change
    # lies between columns 29 and 30
    wall_door = pair_code(C.WALL, C.DOOR)
    for mirror in (False, True):
        truth = split(30)[:, ::-1] if mirror else split(30)
        for c, want in ((29.5, 0), (29.1, 0), (30.9, 1), (28.5, -1)):
            ex = LabelPredictor(RampSegmenter(c, mirror), prior_correction=0.0)
            got = logit_crossings(decision_scores(ex, None), truth, C.STRUCTURAL)
            # +: the boundary lies inside the true door (the higher id), which comes out small
            np.testing.assert_array_equal(np.unique(got[wall_door]), [want])
            assert len(got[wall_door]) == 16  # one per row below the ceiling
            np.testing.assert_array_equal(got[pair_code(C.WALL, C.CEILING)], 0)
    truth = split(30)
    # the prior correction takes log w_wall = 1 off the wall's score: the door's ramp wins one
    # pixel earlier (30.9 -> 29.9 lies between the two pixels again)
    ex = LabelPredictor(RampSegmenter(30.9), prior_correction=1.0)
    got = logit_crossings(decision_scores(ex, None), truth, C.STRUCTURAL)
    np.testing.assert_array_equal(np.unique(got[wall_door]), [0])


def test_distance_bands():
    """Shares by |offset| band: on the band, 1 px, 2 px, 2.5-5, 5-10, capped at 10."""
    shares = distance_bands(np.array([0.0, -1.0, 1.41, 2.0, -2.24, 3.0, 5.0, -9.9, 10.0, 10.0]))
    np.testing.assert_allclose(shares, [0.1, 0.2, 0.2, 0.1, 0.2, 0.2])
    np.testing.assert_array_equal(distance_bands(np.zeros(0)), np.zeros(6))
