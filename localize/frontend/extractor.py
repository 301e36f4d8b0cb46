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
from dataclasses import asdict, dataclass

import numpy as np

from core import classes as C
from core.config import as_config
from localize.config import MODES, EdgesConfig
from localize.frontend.boundaries import (
    dilate,
    image_gradients,
    label_edges,
    snap_to_image_edges,
)
from localize.frontend.canny import canny_edges
from localize.frontend.edge_image import EdgeImage


@dataclass
class ImageCues:
    """Mode cnn's cues of the colour image alone (``EdgeExtractor.image_cues``).

    Attributes:
        gradients: ``boundaries.image_gradients`` of the frame, or None (no snap).
        canny: (H, W) bool Canny edges of the colour image, or None (``refine: none``).
    """

    gradients: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    canny: np.ndarray | None


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

    @property
    def reads_image(self) -> bool:
        """Whether ``image_cues`` has work: mode cnn with the snap or the union."""
        return self.mode == "cnn" and (self.cnn.snap_px > 0 or self.cnn.refine == "union")

    def image_cues(self, rgb: np.ndarray) -> ImageCues:
        """What mode cnn reads of the colour image alone (``ImageCues``), made apart from the
        labels so that it can run while the SegNet does (``FrontEnd.frame``)."""
        cc = self.cnn
        grads = image_gradients(rgb) if cc.snap_px > 0 else None
        canny = None
        if cc.refine == "union":
            canny = canny_edges(rgb, cc.refine_low, cc.refine_high, self.settings.canny.blur,
                                colour=True).edges
        return ImageCues(grads, canny)

    def edges(self, rgb: np.ndarray, labels: np.ndarray | None = None,
              cues: ImageCues | None = None) -> EdgeImage:
        """Edge image of a frame.

        Args:
            rgb: (H, W, 3) uint8 (used by mode none, and by cnn with ``cnn.snap_px`` > 0 or
                ``cnn.refine: union``).
            labels: (H, W) uint8 class ids (true labels for oracle, predicted for cnn).
            cues: mode cnn's ``image_cues(rgb)`` if the caller made them (None: made here).
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
        if cues is None and self.reads_image:
            cues = self.image_cues(rgb)
        out = label_edges(labels, C.STRUCTURAL, lc.dilate_px, lc.median)
        known = out.known
        edges = out.edges & known
        out = snap_to_image_edges(EdgeImage(edges, known, np.where(edges, out.pairs, np.uint8(0))),
                                  rgb, cc.snap_px, cc.snap_min_gradient, cc.snap_nearest,
                                  None if cues is None else cues.gradients)
        if cc.refine == "union":  # image edges beside the boundaries join them (no pair)
            near = dilate(edges, cc.refine_px) & known
            out = EdgeImage(out.edges | (cues.canny & near), known, out.pairs)
        return out
