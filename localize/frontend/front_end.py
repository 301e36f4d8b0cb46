"""The localizer's front end: a camera frame -> its labels -> its edge image -> score maps.

``FrontEnd(source, edges)`` takes an edge source (``localize.frontend.sources``: a mode name,
a labelling callable or an ``EdgeSource``) and the ``edges`` config;
``FrontEnd.frame(image, true_labels)`` runs the source and the edge extraction
(``localize.frontend.extractor``) once and returns an ``EdgeFrame``;
``EdgeFrame.observation(likelihood)`` makes a likelihood's score maps of it once and hands the
same maps to every later caller with the same map settings, so filters sharing an ``EdgeFrame``
share its segmentation, edge image and distance transforms.
"""

from __future__ import annotations

import functools
import os
import time
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import astuple, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from localize.config import MODES, EdgesConfig
from localize.frontend.edge_image import EdgeImage, check_rgb
from localize.frontend.extractor import EdgeExtractor, edge_settings
from localize.frontend.sources import edge_source

if TYPE_CHECKING:  # the filter reads the front end, never the other way round
    from localize.filter.likelihood import EdgeLikelihood, Observation


@dataclass
class EdgeFrame:
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


@functools.cache
def _cue_pool(pid: int) -> ThreadPoolExecutor:
    """One thread for the image cues, per process (a forked child makes its own)."""
    return ThreadPoolExecutor(1, thread_name_prefix="image-cues")


class FrontEnd:
    """Frames -> edge images with one edge source and the ``edges`` config.

    Args:
        source: an edge source, a mode name or a labelling callable (``edge_source``).
        edges: the ``edges`` settings (``localize.config.EdgesConfig``, or a partial mapping
            of them; None: the defaults).
        segmenter: the SegNet when ``source`` is ``"cnn"``.
    """

    def __init__(self, source, edges: EdgesConfig | Mapping | None = None, segmenter=None):
        edges = edge_settings(edges)
        self.source = edge_source(source, segmenter, edges.cnn)
        if self.source.mode not in MODES:
            raise ValueError(f"edge source mode {self.source.mode!r}: use one of {MODES}")
        self.extractor = EdgeExtractor(self.source.mode, edges)

    @property
    def mode(self) -> str:
        """The edge mode: ``none`` | ``cnn`` | ``oracle``."""
        return self.source.mode

    def frame(self, image: np.ndarray | None, true_labels: np.ndarray | None = None) -> EdgeFrame:
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
        cues = None
        if self.extractor.reads_image and image is not None:
            # the colour image's cues on a second core while the SegNet runs (onnxruntime
            # keeps one core busy with this small network: docs/notes/speed.md)
            cues = _cue_pool(os.getpid()).submit(self.extractor.image_cues, image)
        labels = self.source.labels(image, true_labels)
        t1 = time.perf_counter()
        edge = self.extractor.edges(image, labels, None if cues is None else cues.result())
        t2 = time.perf_counter()
        return EdgeFrame(edge, labels, {"segmentation": (t1 - t0) * 1e3, "edges": (t2 - t1) * 1e3})
