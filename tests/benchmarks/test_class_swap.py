"""benchmarks/class_swap.py: the SegNet's labels with some classes taken from the truth."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.class_swap import report_name, swap_labels, swapped_source
from core import classes as C
from localize.frontend.extractor import edge_settings
from localize.frontend.front_end import FrontEnd
from localize.frontend.sources import SegmenterLabels

CFG = {"labels": {"dilate_px": 0, "median": 0},
       "cnn": {"snap_px": 0, "prior_correction": 0.0, "refine": "none"}}


def truth() -> np.ndarray:
    """(8, 10): ceiling rows 0-1, wall rows 2-5 with a door in columns 6-7, floor rows 6-7."""
    lab = np.full((8, 10), C.WALL, dtype=np.uint8)
    lab[:2] = C.CEILING
    lab[2:6, 6:8] = C.DOOR
    lab[6:] = C.FLOOR
    return lab


def predicted() -> np.ndarray:
    """The truth with the floor one row too high and the door one column too wide above it."""
    lab = truth()
    lab[5] = C.FLOOR
    lab[2:5, 5] = C.DOOR
    return lab


def test_swap_takes_the_classes_from_the_truth_and_keeps_the_rest():
    t, p = truth(), predicted()
    floor = swap_labels(p, t, np.array([C.FLOOR]))
    np.testing.assert_array_equal(floor[5], t[5])            # the floor row is back to wall
    np.testing.assert_array_equal(floor[2:5], p[2:5])        # the door stays too wide
    door = swap_labels(p, t, np.array([C.DOOR]))
    np.testing.assert_array_equal(door[2:5], t[2:5])
    np.testing.assert_array_equal(door[5, :5], p[5, :5])     # floor still too high left of it
    both = swap_labels(p, t, np.array([C.FLOOR, C.DOOR]))
    np.testing.assert_array_equal(both, t)
    assert both.dtype == np.uint8
    np.testing.assert_array_equal(swap_labels(p, t, np.array([C.WINDOW])), p)
    with pytest.raises(ValueError, match="differ"):
        swap_labels(p, t[:4], np.array([C.FLOOR]))


class Segmenter:
    def labels(self, rgb: np.ndarray) -> np.ndarray:
        return predicted()


def test_swapped_source_takes_the_classes_from_the_frames_truth():
    own = SegmenterLabels(Segmenter(), edge_settings(CFG).cnn)
    source = swapped_source(own, np.array([C.FLOOR]))
    assert (source.mode, source.needs_image, source.needs_truth) == ("cnn", True, True)
    rgb = np.full((8, 10, 3), 90, np.uint8)
    labels = source.labels(rgb, truth())
    np.testing.assert_array_equal(labels, swap_labels(predicted(), truth(), np.array([C.FLOOR])))
    # through a front end: the edges of the swapped labels, the cnn mode's way
    frame = FrontEnd(source, CFG).frame(rgb, truth())
    np.testing.assert_array_equal(frame.labels, labels)
    plain = FrontEnd(own, CFG).frame(rgb)
    assert not np.array_equal(frame.edge.edges, plain.edge.edges)  # the floor row moved
    with pytest.raises(ValueError, match="needs the frame's true labels"):
        FrontEnd(source, CFG).frame(rgb)


def test_report_name_keeps_swapped_runs_apart():
    assert report_name(["name=hw6", "seeds=[3]"], ["floor"]) == ["seeds=[3]",
                                                                 "name=hw6_swap_floor"]
    assert report_name(["modes=[cnn]"], ["door", "window"]) == ["modes=[cnn]",
                                                                "name=swap_door_window"]
