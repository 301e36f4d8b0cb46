"""Image edge maps for the three edge modes, each with a mask of where edges are known.

- ``none``: Canny on the grey image, reduced to its Hough line segments (the paper's pipeline
  without segmentation). Every pixel is "known".
- ``cnn``: labels from the ONNX SegNet (``sources.SegmenterLabels``), the structural ones
  with the training's class weights taken out (``segmenter.structural_prior_labels``); edges
  are the boundaries between two *different structural* classes (floor, wall, ceiling, door,
  window); pixels of clutter, person, void or ignore, dilated by a few pixels, are *unknown*:
  an object that is not in the model may hide a model edge, so a model line falling there is
  neither confirmed nor contradicted (the likelihood scores such samples with the image's
  chance level). The boundaries are then snapped onto the image
  (``boundaries.snap_to_image_edges``): the network places them at its quarter resolution,
  the image's gradient to a pixel. With ``edges.cnn.refine: union`` the colour image's Canny
  edges beside the boundaries join them.
- ``oracle``: the same from the true label images (not snapped), the upper bound of what
  segmentation gives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict

import numpy as np

from core import classes as C
from core.config import as_config
from localize.config import MODES, EdgesConfig
from localize.frontend.boundaries import dilate, label_edges, snap_to_image_edges
from localize.frontend.canny import canny_edges
from localize.frontend.edge_image import EdgeImage


def edge_settings(edges: EdgesConfig | Mapping | None) -> EdgesConfig:
    """The ``edges`` settings: ``edges`` itself, or a (partial) mapping of them over the
    defaults (``localize.config.EdgesConfig``; a typo raises naming the key)."""
    return as_config(EdgesConfig, edges, "edges")


class EdgeExtractor:
    """Edge images of frames in one mode, from their labels (the labels come from the edge
    source, ``localize.frontend.sources``).

    Args:
        mode: ``none`` | ``cnn`` | ``oracle``.
        edges: the ``edges`` settings (``edge_settings``: an ``EdgesConfig`` or a partial
            mapping of them).
    """

    def __init__(self, mode: str, edges: EdgesConfig | Mapping | None = None):
        if mode not in MODES:
            raise ValueError(f"unknown edge mode {mode!r}; expected one of {MODES}")
        self.mode, self.settings = mode, edge_settings(edges)
        self.cnn = self.settings.cnn

    def edges(self, rgb: np.ndarray, labels: np.ndarray | None = None) -> EdgeImage:
        """Edge image of a frame.

        Args:
            rgb: (H, W, 3) uint8 (used by mode none, and by cnn with ``cnn.snap_px`` > 0 or
                ``cnn.refine: union``).
            labels: (H, W) uint8 class ids (true labels for oracle, predicted for cnn).
        """
        if self.mode == "none":
            c = self.settings.canny
            edges = canny_edges(rgb, c.low, c.high, c.blur, asdict(self.settings.hough)).edges
            return EdgeImage(edges, np.ones(rgb.shape[:2], dtype=bool))
        if labels is None:
            raise ValueError(f"edge mode {self.mode!r} needs a label map")
        lc = self.settings.labels
        if self.mode == "oracle":
            return label_edges(labels, C.STRUCTURAL, lc.dilate_px, 0)
        cc = self.cnn
        out = label_edges(labels, C.STRUCTURAL, lc.dilate_px, lc.median)
        known = out.known
        edges = out.edges & known
        out = snap_to_image_edges(EdgeImage(edges, known, np.where(edges, out.pairs, np.uint8(0))),
                                  rgb, cc.snap_px, cc.snap_min_gradient, cc.snap_nearest)
        if cc.refine == "union":  # image edges beside the boundaries join them (no pair)
            near = dilate(edges, cc.refine_px) & known
            canny = canny_edges(rgb, cc.refine_low, cc.refine_high, self.settings.canny.blur,
                                colour=True).edges
            out = EdgeImage(out.edges | (canny & near), known, out.pairs)
        return out
