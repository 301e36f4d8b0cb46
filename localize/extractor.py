"""Image edge maps for the three edge modes, each with a mask of where edges are known.

- ``none``: Canny on the grey image, optionally reduced to its Hough line segments (the paper's
  pipeline without segmentation). Every pixel is "known".
- ``cnn``: labels from the ONNX SegNet (``train.predict.OnnxSegmenter``), the structural ones
  with the training's class weights taken out (``segmenter.structural_prior_labels``); edges
  are the boundaries between two *different structural* classes (floor, wall, ceiling, door,
  window); pixels of clutter, person, void or ignore, dilated by a few pixels, are *unknown*:
  an object that is not in the model may hide a model edge, so a model line falling there is
  neither confirmed nor contradicted (the likelihood scores such samples with the image's
  chance level). The boundaries are then snapped onto the image (``snap.snap_to_image_edges``):
  the network places them at its quarter resolution, the image's gradient to a pixel.
- ``oracle``: the same from the true label images (not snapped), the upper bound of what
  segmentation gives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from core import classes as C
from core.config import reject_unknown_keys
from localize.edges import EdgeImage, canny_edges, dilate, label_edges
from localize.segmenter import LabelPredictor
from localize.snap import snap_to_image_edges

MODES = ("none", "cnn", "oracle")
REFINES = ("none", "canny", "mask", "union")


@dataclass(frozen=True)
class CnnSettings:
    """``edges.cnn``: how the cnn mode makes edges of the SegNet's output.

    The defaults are conf/edges/default.yaml's (a test keeps them equal), where each choice is
    explained with its measurements; a partial config gets the same behaviour as the full one.

    Attributes:
        prior_correction: strength s of ``structural_prior_labels`` (0: plain argmax).
        min_confidence: pixels whose largest softmax probability is below it are unknown (0:
            off).
        snap_px: search reach of ``snap_to_image_edges``, pixels (0: no snap).
        snap_min_gradient, snap_band, snap_stay, snap_colour, snap_nearest: its other
            settings.
        refine: ``none`` (the snapped class boundaries), ``union`` (those and the Canny edges
            within ``refine_px`` of them), ``canny`` (those Canny edges only) or ``mask`` (mode
            none's edges, objects masked).
        refine_px: pixels, for ``refine: union`` and ``canny``.
        refine_low, refine_high: their Canny hysteresis thresholds (mode none has its own,
            ``edges.canny``).
        refine_colour: their Canny runs on the colour image, not the grey one.
    """

    prior_correction: float = 0.75
    min_confidence: float = 0.0
    snap_px: int = 2
    snap_min_gradient: float = 8.0
    snap_band: bool = False
    snap_stay: bool = True
    snap_colour: bool = True
    snap_nearest: bool = False
    refine: str = "union"
    refine_px: int = 6
    refine_low: float = 25.0
    refine_high: float = 75.0
    refine_colour: bool = True

    def __post_init__(self) -> None:
        if self.refine not in REFINES:
            raise ValueError(f"edges.cnn.refine={self.refine!r}: use one of {REFINES}")
        for key in ("prior_correction", "min_confidence", "snap_px", "snap_min_gradient",
                    "refine_px", "refine_low", "refine_high"):
            if getattr(self, key) < 0:
                raise ValueError(f"edges.cnn.{key} must be >= 0, got {getattr(self, key)}")

    @classmethod
    def from_cfg(cls, cfg: Mapping | None) -> CnnSettings:
        """From the ``edges.cnn`` mapping (None or missing keys: the defaults); an unknown key
        raises ValueError listing the known ones."""
        cfg = dict(cfg or {})
        reject_unknown_keys(cfg, (f.name for f in fields(cls)), "edges.cnn settings")
        types = {f.name: type(f.default) for f in fields(cls)}
        for k, v in cfg.items():
            if not _fits(types[k], v):
                raise ValueError(f"edges.cnn.{k}={v!r}: expected a {types[k].__name__} (e.g. "
                                 f"{getattr(cls, k)!r})")
        return cls(**{k: types[k](v) for k, v in cfg.items()})


def _fits(kind: type, value) -> bool:
    """Whether a config value can stand for a setting of type ``kind`` (bool, str, int or
    float) without changing meaning: a number for a number (a whole one for an int), never a
    bool for a number or a string for either."""
    if kind in (bool, str):
        return isinstance(value, kind)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return kind is float or float(value).is_integer()




class EdgeExtractor:
    """Edge images of frames in one mode.

    Args:
        mode: ``none`` | ``cnn`` | ``oracle``.
        cfg: the ``edges`` config (canny, hough, labels, cnn settings; conf/edges/default.yaml).
        segmenter: an ``OnnxSegmenter`` for ``segment`` (cnn mode; ``edges`` takes the labels
            from the caller and needs none).
    """

    def __init__(self, mode: str, cfg: dict, segmenter=None):
        if mode not in MODES:
            raise ValueError(f"unknown edge mode {mode!r}; expected one of {MODES}")
        self.mode, self.cfg = mode, cfg
        self.cnn = CnnSettings.from_cfg(cfg.get("cnn"))
        missing = [k for k in self.needs_keys if k not in cfg]
        if missing:
            raise ValueError(f"the edges config lacks {missing} (edge mode {mode}); pass "
                             "conf/edges/default.yaml (the `edges` node of the composed "
                             "localize config)")
        self.predictor = None
        if mode == "cnn" and segmenter is not None:
            self.predictor = LabelPredictor(segmenter, self.cnn.prior_correction,
                                            self.cnn.min_confidence)

    @property
    def needs_keys(self) -> tuple[str, ...]:
        """The ``edges`` config keys this mode's edges read."""
        if self.mode == "none":
            return ("canny", "hough")
        if self.mode == "oracle":
            return ("labels",)
        return {"none": ("labels",), "mask": ("labels", "canny", "hough")}.get(
            self.cnn.refine, ("labels", "canny"))

    @property
    def segmenter(self):
        """The segmenter of ``segment`` (None without one)."""
        return None if self.predictor is None else self.predictor.segmenter

    @property
    def log_prior(self) -> np.ndarray | None:
        """(C,) s * log w_c the structural labels are corrected by (None: plain argmax)."""
        return None if self.predictor is None else self.predictor.log_prior

    def segment(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted labels (H, W) uint8 and confidence (H, W) float32 of an RGB frame (cnn
        mode; ``segmenter.LabelPredictor``)."""
        if self.predictor is None:
            raise ValueError("edge mode 'cnn' needs a segmenter to segment a frame (see "
                             "localize.segmenter.load_segmenter)")
        return self.predictor(rgb)

    def edges(self, rgb: np.ndarray, labels: np.ndarray | None = None,
              confidence: np.ndarray | None = None) -> EdgeImage:
        """Edge image of a frame.

        Args:
            rgb: (H, W, 3) uint8 (used by mode none, and by cnn with ``cnn.snap_px`` > 0 or
                ``cnn.refine`` union or canny).
            labels: (H, W) uint8 class ids (true labels for oracle, predicted for cnn).
            confidence: (H, W) float32 largest softmax probability (cnn only; pixels below
                ``cnn.min_confidence`` become unknown).
        """
        if self.mode == "none":
            return EdgeImage(self._canny(rgb, hough=True), np.ones(rgb.shape[:2], dtype=bool))
        if labels is None:
            raise ValueError(f"edge mode {self.mode!r} needs a label map")
        lc = self.cfg["labels"]
        if self.mode == "oracle":
            return label_edges(labels, C.STRUCTURAL, int(lc["dilate_px"]), 0)
        cc = self.cnn
        out = label_edges(labels, C.STRUCTURAL, int(lc["dilate_px"]), int(lc["median"]))
        known = out.known
        if confidence is not None and cc.min_confidence > 0:
            known = known & ~dilate(confidence < cc.min_confidence, int(lc["dilate_px"]))
        if cc.refine in ("none", "union"):
            edges = out.edges & known
            out = snap_to_image_edges(
                EdgeImage(edges, known, np.where(edges, out.pairs, np.uint8(0))), rgb,
                cc.snap_px, cc.snap_min_gradient, cc.snap_band, cc.snap_stay, cc.snap_colour,
                cc.snap_nearest)
            if cc.refine == "union":  # image edges beside the boundaries join them (no pair)
                near = dilate(edges, cc.refine_px) & known
                out = EdgeImage(out.edges | (self._refine_canny(rgb) & near), known, out.pairs)
            return out
        if cc.refine == "canny":
            near = dilate(out.edges & known, cc.refine_px)
            return EdgeImage(self._refine_canny(rgb) & near & known, known)
        return EdgeImage(self._canny(rgb, hough=True) & known, known)  # refine: mask

    @property
    def class_boundaries_only(self) -> bool:
        """See ``class_boundaries_only``."""
        return class_boundaries_only(self.mode, self.cfg)

    def _canny(self, rgb: np.ndarray, hough: bool) -> np.ndarray:
        """Canny edges (H, W) bool of a frame, reduced to Hough segments if ``hough`` and
        ``hough.enabled``."""
        c, h = self.cfg["canny"], self.cfg["hough"]
        lines = dict(h) if hough and h.get("enabled", False) else None
        return canny_edges(rgb, c["low"], c["high"], c["blur"], lines).edges

    def _refine_canny(self, rgb: np.ndarray) -> np.ndarray:
        """Canny edges (H, W) bool of a frame at ``cnn.refine_low`` / ``refine_high`` (of its
        colour with ``cnn.refine_colour``), for ``cnn.refine`` union and canny."""
        cc = self.cnn
        return canny_edges(rgb, cc.refine_low, cc.refine_high, self.cfg["canny"]["blur"],
                           colour=cc.refine_colour).edges


def class_boundaries_only(mode: str, cfg: dict) -> bool:
    """Whether a mode's edges show only class boundaries, so that only the model segments whose
    two sides differ in class can match them.

    Args:
        mode: ``none`` | ``cnn`` | ``oracle``.
        cfg: the ``edges`` config (``cnn.refine: mask`` keeps every Canny edge).
    """
    if mode == "none":
        return False
    if mode == "cnn":
        return CnnSettings.from_cfg(cfg.get("cnn")).refine != "mask"
    return True
