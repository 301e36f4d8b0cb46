"""snap_to_image_edges: class boundaries moved onto the image's own edges."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from core import classes as C
from core.classes import pair_code
from localize.frontend.boundaries import label_edges, snap_to_image_edges
from localize.frontend.extractor import EdgeExtractor
from tests.localize.test_localize_edges import EDGES_CFG, cnn


class TestSnap:
    @staticmethod
    def step(left: int, right: int, split: int = 27) -> tuple[np.ndarray, np.ndarray]:
        """(40, 60) wall | door labels split at column ``split`` and an image whose grey step
        lies between columns 29 and 30 (after the 3x3 blur, columns 28-31 see it)."""
        lab = np.full((40, 60), C.WALL, dtype=np.uint8)
        lab[:, split:] = C.DOOR
        rgb = np.full((40, 60, 3), left, dtype=np.uint8)
        rgb[:, 30:] = right
        return lab, rgb

    def test_boundary_moves_onto_the_image_step(self):
        lab, rgb = self.step(80, 160)
        edge = label_edges(lab, dilate_px=0)
        assert set(np.nonzero(edge.edges)[1]) == {26, 27}
        out = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0)
        cols = np.nonzero(out.edges)[1]
        assert set(cols) == {29}  # the nearer of the two steepest columns (29, 30)
        assert out.edges[:, 29].all()
        np.testing.assert_array_equal(out.pairs[out.edges], pair_code(C.WALL, C.DOOR))
        assert not out.pairs[~out.edges].any()
        np.testing.assert_array_equal(out.known, edge.known)

    def test_stays_on_an_edge_already(self):
        # a weak step (wall | jamb) at columns 26 | 27, where the labels split, and a strong one
        # (jamb | leaf) at 30 | 31, within reach: the boundary stays on the weak one
        lab, _ = self.step(80, 160, split=27)
        rgb = np.full((40, 60, 3), 80, dtype=np.uint8)
        rgb[:, 27:31] = 100
        rgb[:, 31:] = 200
        edge = label_edges(lab, dilate_px=0)
        kept = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0)
        np.testing.assert_array_equal(kept.edges, edge.edges)
        # a boundary off any edge still moves to the strongest
        lab, rgb = self.step(80, 160)
        off = snap_to_image_edges(label_edges(lab, dilate_px=0), rgb, radius=3,
                                  min_gradient=15.0)
        assert set(np.nonzero(off.edges)[1]) == {29}

    def test_nearest_goes_to_the_edge_beside_it_not_the_strongest(self):
        # boundary pixels at columns 24 | 25; a weaker step at 22 | 23, a stronger one at 27 | 28
        lab = np.full((40, 60), C.WALL, dtype=np.uint8)
        lab[:, 25:] = C.DOOR
        rgb = np.full((40, 60, 3), 80, dtype=np.uint8)
        rgb[:, 23:] = 110
        rgb[:, 28:] = 200
        edge = label_edges(lab, dilate_px=0)
        strongest = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0)
        assert set(np.nonzero(strongest.edges)[1]) == {27}
        near = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0, nearest=True)
        # 24 is a pixel from the weak step and moves onto it; 25 is two pixels from both and
        # takes the stronger
        assert set(np.nonzero(near.edges)[1]) == {23, 27}
        np.testing.assert_array_equal(near.pairs > 0, near.edges)
        # on an edge already: stays; no edge in reach: stays
        lab, _ = self.step(80, 160, split=27)
        rgb = np.full((40, 60, 3), 80, dtype=np.uint8)
        rgb[:, 27:31] = 100
        rgb[:, 31:] = 200
        edge = label_edges(lab, dilate_px=0)
        kept = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0, nearest=True)
        np.testing.assert_array_equal(kept.edges, edge.edges)
        flat = snap_to_image_edges(edge, np.zeros_like(rgb), radius=3, min_gradient=15.0,
                                   nearest=True)
        np.testing.assert_array_equal(flat.edges, edge.edges)

    def test_out_of_reach_or_too_weak_stays(self):
        lab, rgb = self.step(80, 160, split=25)
        far = label_edges(lab, dilate_px=0)  # columns 24, 25: the gradient starts at 28
        near = snap_to_image_edges(far, rgb, radius=1, min_gradient=15.0)
        np.testing.assert_array_equal(near.edges, far.edges)
        lab, faint = self.step(80, 82)
        edge = label_edges(lab, dilate_px=0)  # a 2-level step: Sobel ~6 < 15
        weak = snap_to_image_edges(edge, faint, radius=3, min_gradient=15.0)
        np.testing.assert_array_equal(weak.edges, edge.edges)
        flat = snap_to_image_edges(edge, np.zeros_like(rgb), radius=3, min_gradient=15.0)
        np.testing.assert_array_equal(flat.edges, edge.edges)
        assert snap_to_image_edges(edge, rgb, radius=0, min_gradient=15.0) is edge

    def test_colour_finds_a_step_of_equal_brightness(self):
        lab, _ = self.step(80, 160)
        rgb = np.zeros((40, 60, 3), dtype=np.uint8)
        rgb[:, :30] = (180, 100, 100)  # pink-ish | green-ish of the same grey level (~124)
        rgb[:, 30:] = (80, 150, 120)
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        assert abs(int(grey[0, 0]) - int(grey[0, 59])) <= 2
        edge = label_edges(lab, dilate_px=0)
        out = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0)
        assert set(np.nonzero(out.edges)[1]) == {29}
        lab, faint = self.step(80, 82)  # a faint grey step stays faint
        weak = snap_to_image_edges(label_edges(lab, dilate_px=0), faint, 3, 15.0)
        np.testing.assert_array_equal(weak.edges, label_edges(lab, dilate_px=0).edges)

    def test_stays_inside_the_known_mask(self):
        lab, rgb = self.step(80, 160)
        lab[:, 29:32] = C.PERSON  # the image step is under an object
        edge = label_edges(lab, dilate_px=1)
        out = snap_to_image_edges(edge, rgb, radius=3, min_gradient=15.0)
        np.testing.assert_array_equal(out.edges, edge.edges)  # its step is masked: stays

    def test_extractor_snaps_cnn_boundaries(self):
        lab, rgb = self.step(80, 160)
        cfg = cnn(snap_px=3, snap_min_gradient=15.0)
        e = EdgeExtractor("cnn", cfg).edges(rgb, lab)
        assert set(np.nonzero(e.edges)[1]) == {29}
        plain = EdgeExtractor("cnn", EDGES_CFG).edges(rgb, lab)
        assert set(np.nonzero(plain.edges)[1]) == {26, 27}
        oracle = EdgeExtractor("oracle", cfg).edges(rgb, lab)  # true labels: never moved
        np.testing.assert_array_equal(oracle.edges, plain.edges)

    def test_bad_input(self):
        lab, rgb = self.step(80, 160)
        edge = label_edges(lab, dilate_px=0)
        with pytest.raises(ValueError, match="differ in size"):
            snap_to_image_edges(edge, rgb[:20], radius=2, min_gradient=15.0)
        with pytest.raises(ValueError, match="RGB image"):
            snap_to_image_edges(edge, rgb[..., 0], radius=2, min_gradient=15.0)
