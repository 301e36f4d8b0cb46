"""The localizer's front end: a camera frame -> its labels -> its edge image -> score maps.

An **edge source** says where a frame's class labels come from; the front end makes the edge
image of its mode from them (``extractor.EdgeExtractor``, the ``edges`` config):

- ``CannyEdges`` (mode ``none``): no labels; Canny + Hough on the image.
- ``SegmenterLabels`` (mode ``cnn``): the ONNX SegNet's labels (``segmenter.LabelPredictor``).
- ``TrueLabels`` (mode ``oracle``): the frame's true labels, given to ``frame``/``step``.
- ``LabelFunction`` (mode ``cnn``): any callable ``rgb -> labels (H, W) uint8`` (or, with
  ``needs_truth``, ``(rgb, true_labels) -> labels``); its labels are made into edges as the
  SegNet's are. A benchmark's altered segmentation is one of these, not a patch.

Any object with the attributes ``mode``, ``needs_image``, ``needs_truth`` and a method
``labels(rgb, true_labels) -> labels | None`` is an edge source (``EdgeSource``);
``edge_source`` turns a mode name or a callable into one.

``FrontEnd.frame(image, true_labels)`` runs the source and the edge extraction once and
returns a ``Frame``; ``Frame.observation(likelihood)`` makes a likelihood's score maps of it
once and hands the same maps to every later caller with the same map settings, so filters
sharing a ``Frame`` share its segmentation, edge image and distance transforms.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import astuple, dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from localize.config import MODES, CnnSettings, EdgeSettings
from localize.frontend.edge_image import EdgeImage, check_rgb
from localize.frontend.extractor import EdgeExtractor, edge_settings
from localize.likelihood import EdgeLikelihood, Observation
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

    def __init__(self, segmenter, cnn: CnnSettings | None = None):
        cnn = cnn or CnnSettings()
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


def edge_source(spec, segmenter=None, cnn: CnnSettings | None = None) -> EdgeSource:
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
                             "edges_cfg, segmenter=localize.frontend.segmenter.load_segmenter(path, "
                             "dataset classes)) or SegmenterLabels(segmenter)")
        return SegmenterLabels(segmenter, cnn)
    raise ValueError(f"unknown edge source {spec!r}; use one of {MODES}, an EdgeSource or a "
                     "callable rgb -> labels")


@dataclass
class Frame:
    """One frame through the front end.

    Attributes:
        edge: the edge image, (H, W).
        labels: (H, W) uint8 labels the edges were made of (None for mode ``none``).
        timing_ms: ``segmentation`` (the source's labels) and ``edges`` (the edge image), ms.
    """

    edge: EdgeImage
    labels: np.ndarray | None
    timing_ms: dict[str, float]
    _maps: dict = field(default_factory=dict, repr=False)

    def observation(self, likelihood: EdgeLikelihood) -> tuple[Observation, float]:
        """The likelihood's score maps of this frame, made on the first call for its map
        settings (shared by every likelihood with the same settings and class pairs).

        Returns:
            The observation and the ms it took to make (also when made by an earlier call).
        """
        codes = likelihood.pair_codes
        key = (astuple(likelihood.params), None if codes is None else codes.tobytes())
        if key not in self._maps:
            t0 = time.perf_counter()
            obs = likelihood.observe(self.edge)
            self._maps[key] = (obs, (time.perf_counter() - t0) * 1e3)
        return self._maps[key]


class FrontEnd:
    """Frames -> edge images with one edge source and the ``edges`` config.

    Args:
        source: an edge source, a mode name or a labelling callable (``edge_source``).
        edges: the ``edges`` settings (``localize.config.EdgeSettings``, or a partial mapping
            of them; None: the defaults).
        segmenter: the SegNet when ``source`` is ``"cnn"``.
    """

    def __init__(self, source, edges: EdgeSettings | Mapping | None = None, segmenter=None):
        edges = edge_settings(edges)
        self.source = edge_source(source, segmenter, edges.cnn)
        if self.source.mode not in MODES:
            raise ValueError(f"edge source mode {self.source.mode!r}: use one of {MODES}")
        self.extractor = EdgeExtractor(self.source.mode, edges)

    @property
    def mode(self) -> str:
        """The edge mode: ``none`` | ``cnn`` | ``oracle``."""
        return self.source.mode

    def frame(self, image: np.ndarray | None, true_labels: np.ndarray | None = None) -> Frame:
        """The edge image of a frame.

        Args:
            image: (H, W, 3) uint8 RGB (may be None when the source does not read it:
                ``TrueLabels``).
            true_labels: (H, W) uint8 class ids (sources with ``needs_truth``).
        """
        if image is None and self.source.needs_image:
            raise ValueError(f"edge source {self.mode!r} needs the image: pass an (H, W, 3) "
                             "uint8 RGB frame")
        if image is not None:
            check_rgb(image)
        if true_labels is not None:
            true_labels = np.asarray(true_labels)
            if true_labels.ndim != 2 or (image is not None
                                         and true_labels.shape != image.shape[:2]):
                raise ValueError(f"labels must be (H, W) class ids of the image "
                                 f"{None if image is None else image.shape[:2]}, got "
                                 f"{true_labels.shape}")
        t0 = time.perf_counter()
        labels = self.source.labels(image, true_labels)
        t1 = time.perf_counter()
        edge = self.extractor.edges(image, labels)
        t2 = time.perf_counter()
        return Frame(edge, labels, {"segmentation": (t1 - t0) * 1e3, "edges": (t2 - t1) * 1e3})
