"""Edge sources: where a frame's class labels come from, and the edge mode they are made
into edges in (``localize.frontend.extractor``, the ``edges`` config):

- ``CannyEdges`` (mode ``none``): no labels; Canny + Hough on the image.
- ``SegmenterLabels`` (mode ``cnn``): the ONNX SegNet's labels
  (``localize.frontend.segmenter.LabelPredictor``).
- ``TrueLabels`` (mode ``oracle``): the frame's true labels, given to ``frame``/``step``.
- ``LabelFunction`` (mode ``cnn``): any callable ``rgb -> labels (H, W) uint8`` (or, with
  ``needs_truth``, ``(rgb, true_labels) -> labels``); its labels are made into edges as the
  SegNet's are. A benchmark's altered segmentation is one of these, not a patch.

Any object with the attributes ``mode``, ``needs_image``, ``needs_truth`` and a method
``labels(rgb, true_labels) -> labels | None`` is an edge source (``EdgeSource``);
``edge_source`` turns a mode name or a callable into one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from localize.config import MODES, CnnConfig
from localize.frontend.segmenter import LabelPredictor


@runtime_checkable
class EdgeSource(Protocol):
    """Where a frame's labels come from.

    Attributes:
        mode: how the front end makes edges of them: ``none`` (no labels: Canny + Hough),
            ``cnn`` (predicted labels: boundaries snapped to the image, image edges beside
            them) or ``oracle`` (exact labels: their boundaries).
        needs_image: ``labels`` (or the mode's edges) read the RGB image.
        needs_truth: ``labels`` reads the frame's true labels.
    """

    mode: str
    needs_image: bool
    needs_truth: bool

    def labels(self, rgb: np.ndarray | None, true_labels: np.ndarray | None
               ) -> np.ndarray | None:
        """(H, W) uint8 labels of a frame (None for mode ``none``)."""


@dataclass(frozen=True)
class CannyEdges:
    """Mode ``none``: no labels, the image's Canny edges (and their Hough segments)."""

    mode: str = "none"
    needs_image: bool = True
    needs_truth: bool = False

    def labels(self, rgb, true_labels):
        return None


@dataclass(frozen=True)
class TrueLabels:
    """Mode ``oracle``: the frame's true labels (the upper bound of what segmentation gives)."""

    mode: str = "oracle"
    needs_image: bool = False
    needs_truth: bool = True

    def labels(self, rgb, true_labels):
        if true_labels is None:
            raise ValueError("edge source 'oracle' needs the frame's true labels: pass "
                             "labels=(H, W) uint8 class ids to step() / FrontEnd.frame()")
        return true_labels


class SegmenterLabels:
    """Mode ``cnn``: the SegNet's labels of the image.

    Args:
        segmenter: an ``OnnxSegmenter`` (``segmenter.load_segmenter``).
        cnn: the ``edges.cnn`` settings (its prior correction; None: the defaults).
    """

    mode = "cnn"
    needs_image = True
    needs_truth = False

    def __init__(self, segmenter, cnn: CnnConfig | None = None):
        cnn = cnn or CnnConfig()
        self.predictor = LabelPredictor(segmenter, cnn.prior_correction)

    def labels(self, rgb, true_labels):
        return self.predictor(rgb)


class LabelFunction:
    """Any labelling function as an edge source (its labels made into edges as ``mode``'s).

    Args:
        fn: ``rgb (H, W, 3) uint8 -> labels (H, W)`` class ids, or with ``needs_truth``
            ``(rgb, true_labels) -> labels``.
        mode: ``cnn`` (predicted labels) or ``oracle`` (exact ones: not snapped).
        needs_truth: ``fn`` takes the frame's true labels as its second argument.
    """

    needs_image = True

    def __init__(self, fn: Callable, mode: str = "cnn", needs_truth: bool = False):
        if mode not in ("cnn", "oracle"):
            raise ValueError(f"LabelFunction mode {mode!r}: use 'cnn' or 'oracle' (labels are "
                             "made into edges as that mode's)")
        self.fn, self.mode, self.needs_truth = fn, mode, bool(needs_truth)

    def labels(self, rgb, true_labels):
        if self.needs_truth and true_labels is None:
            raise ValueError("this LabelFunction needs the frame's true labels: pass labels= "
                             "to step() / FrontEnd.frame()")
        labels = np.asarray(self.fn(rgb, true_labels) if self.needs_truth else self.fn(rgb))
        if labels.shape != rgb.shape[:2]:
            raise ValueError(f"the label function returned {labels.shape} for an image "
                             f"{rgb.shape[:2]}; it must return (H, W) class ids")
        return labels.astype(np.uint8, copy=False)


def edge_source(spec, segmenter=None, cnn: CnnConfig | None = None) -> EdgeSource:
    """An edge source from a mode name, a labelling callable or an edge source (returned as is).

    Args:
        spec: ``"none"`` | ``"cnn"`` | ``"oracle"``, an ``EdgeSource``, or a callable ``rgb ->
            labels`` (``LabelFunction``).
        segmenter: the SegNet for ``"cnn"`` (``segmenter.load_segmenter``).
        cnn: ``edges.cnn`` settings for ``"cnn"``.
    """
    if isinstance(spec, EdgeSource):
        return spec
    if callable(spec):
        return LabelFunction(spec)
    if spec == "none":
        return CannyEdges()
    if spec == "oracle":
        return TrueLabels()
    if spec == "cnn":
        if segmenter is None:
            raise ValueError("edge source 'cnn' needs a segmenter: use FrontEnd('cnn', "
                             "edges_cfg, segmenter=localize.frontend.segmenter.load_segmenter("
                             "path, dataset classes)) or SegmenterLabels(segmenter)")
        return SegmenterLabels(segmenter, cnn)
    raise ValueError(f"unknown edge source {spec!r}; use one of {MODES}, an EdgeSource or a "
                     "callable rgb -> labels")
