"""Image edge maps for the three edge modes, each with a mask of where edges are known.

- ``none``: Canny on the grey image, optionally reduced to its Hough line segments (the paper's
  pipeline without segmentation). Every pixel is "known".
- ``cnn``: labels from the ONNX SegNet (``train.predict.OnnxSegmenter``), the structural ones
  with the training's class weights taken out (``structural_prior_labels``); edges are the
  boundaries between two *different structural* classes (floor, wall, ceiling, door, window);
  pixels of clutter, person, void or ignore, dilated by a few pixels, are *unknown*: an object
  that is not in the model may hide a model edge, so a model line falling there is neither
  confirmed nor contradicted (the likelihood scores such samples with the image's chance level).
  The boundaries are then snapped onto the image (``snap_to_image_edges``): the network places
  them at its quarter resolution, the image's gradient to a pixel.
- ``oracle``: the same from the true label images (not snapped), the upper bound of what
  segmentation gives.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

import cv2
import numpy as np

from core import classes as C
from core.config import reject_unknown_keys

log = logging.getLogger(__name__)

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


@dataclass
class EdgeImage:
    """Edge pixels and where edges are known.

    Attributes:
        edges: (H, W) bool, True on an edge.
        known: (H, W) bool, False where the image cannot tell whether a model edge is there
            (masked objects that are not in the model).
        pairs: None, or (H, W) uint8: at an edge pixel the ``pair_code`` of the two classes
            the boundary separates, 0 elsewhere (label modes; the likelihood's
            ``class_pairs`` matching reads it).
    """

    edges: np.ndarray
    known: np.ndarray
    pairs: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.edges.shape != self.known.shape or self.edges.ndim != 2:
            raise ValueError(f"edges {self.edges.shape} and known {self.known.shape} must be "
                             "the same (H, W)")
        if self.pairs is not None and self.pairs.shape != self.edges.shape:
            raise ValueError(f"pairs {self.pairs.shape} must match edges {self.edges.shape}")


def pair_code(a, b) -> np.ndarray:
    """Code of the unordered class pair {a, b}: ``16 * min + max`` as uint8 (class ids < 16;
    never 0 for two different classes).

    Args:
        a, b: class ids, scalars or arrays of one shape.
    """
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    if (np.maximum(a, b) >= 16).any():
        raise ValueError("class pair codes need class ids below 16")
    return (16 * np.minimum(a, b) + np.maximum(a, b)).astype(np.uint8)


def pair_classes(code):
    """The two class ids (lower, higher) of a ``pair_code``; scalars or arrays of one shape."""
    return code // 16, code % 16


def pair_name(code: int, names: Mapping[int, str]) -> str:
    """``"wall | door"`` for a ``pair_code``, from class names by id (an unnamed id as itself)."""
    a, b = pair_classes(int(code))
    return f"{names.get(a, a)} | {names.get(b, b)}"


def _check_rgb(rgb: np.ndarray) -> None:
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")


def canny_edges(rgb: np.ndarray, low: float = 50.0, high: float = 150.0, blur: int = 3,
                hough: dict | None = None, colour: bool = False) -> EdgeImage:
    """Canny edges of an RGB image, optionally replaced by the Hough line segments they hold.

    Args:
        rgb: (H, W, 3) uint8.
        low, high: Canny hysteresis thresholds on the gradient magnitude.
        blur: Gaussian blur kernel size before Canny (odd; <= 1 disables it).
        hough: None or a dict with ``threshold`` (votes), ``min_length`` and ``max_gap``
            (pixels) for ``cv2.HoughLinesP``; the found segments are drawn 1 px wide.
        colour: False: Canny on the grey image; True: on the RGB image (OpenCV takes, at each
            pixel, the gradient of the channel where it is strongest: a step between colours
            of equal brightness counts).

    Returns:
        The edge image; every pixel is known.
    """
    _check_rgb(rgb)
    img = np.ascontiguousarray(rgb) if colour else cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    if blur and blur > 1:
        img = cv2.GaussianBlur(img, (int(blur) | 1, int(blur) | 1), 0)
    edges = cv2.Canny(img, float(low), float(high), L2gradient=True)
    if hough:
        lines = cv2.HoughLinesP(edges, 1, np.pi / 180, int(hough.get("threshold", 30)),
                                minLineLength=float(hough.get("min_length", 20)),
                                maxLineGap=float(hough.get("max_gap", 3)))
        edges = np.zeros_like(edges)
        if lines is not None:
            for x0, y0, x1, y1 in lines.reshape(-1, 4):
                cv2.line(edges, (int(x0), int(y0)), (int(x1), int(y1)), 255, 1)
    return EdgeImage(edges > 0, np.ones(edges.shape, dtype=bool))


def edge_normal_angle(edges: np.ndarray, sigma: float = 1.0,
                      at: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Direction of the normal of a binary edge map (structure tensor), at every pixel or at
    the pixels ``at``.

    Args:
        edges: (H, W) bool.
        sigma: smoothing in pixels.
        at: None, or (ys, xs) int arrays of n pixels: the angle only there (the smoothing is
            the same; the arctangent, most of the cost, runs on n values, not H * W).

    Returns:
        (H, W) float32, or (n,) with ``at``: angle of the normal in [0, pi) (image x right,
        y down).
    """
    e = cv2.GaussianBlur(edges.astype(np.float32), (0, 0), sigma)
    gx = cv2.Sobel(e, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(e, cv2.CV_32F, 0, 1, ksize=3)
    jxx = cv2.GaussianBlur(gx * gx, (0, 0), 1.5 * sigma)
    jxy = cv2.GaussianBlur(gx * gy, (0, 0), 1.5 * sigma)
    jyy = cv2.GaussianBlur(gy * gy, (0, 0), 1.5 * sigma)
    if at is not None:
        jxx, jxy, jyy = jxx[at], jxy[at], jyy[at]
    theta = 0.5 * np.arctan2(2 * jxy, jxx - jyy)
    return np.mod(theta, np.pi).astype(np.float32)


def snap_to_image_edges(edge: EdgeImage, rgb: np.ndarray, radius: int,
                        min_gradient: float, band: bool = False,
                        stay: bool = False, colour: bool = False,
                        nearest: bool = False) -> EdgeImage:
    """Class boundaries moved onto the image's own edges: each edge pixel searches along its
    normal, up to ``radius`` pixels either way, for the strongest grey-level (or ``colour``)
    gradient across the boundary, and moves there if that gradient reaches ``min_gradient``;
    elsewhere (a door in a wall of the same paint) it stays. The paper's 1-D search along the
    normal, applied to the segmentation's boundaries: the SegNet says *which* boundary is
    there, at its quarter resolution, and the image says *where*, to a pixel.

    Args:
        edge: class boundaries (edges, known, pairs) of a frame, (H, W).
        rgb: (H, W, 3) uint8, the frame.
        radius: search distance, pixels; 0 returns ``edge`` unchanged.
        min_gradient: smallest |3x3 Sobel of the 3x3-blurred grey image| across the boundary
            (with ``colour``, the RMS of the three channels') that counts as an image edge (a
            step of h grey levels gives about 3 h).
        band: mark the two pixels on either side of the step instead of the one with the
            steepest gradient: the step's sub-pixel position along the normal is the vertex of
            the parabola through the gradient at the steepest pixel and its two neighbours, and
            the pixels at ``floor`` and ``floor + 1`` of it are marked. True label boundaries are
            drawn that way (``label_edges`` marks both sides), so a snapped boundary then lies
            where the true one would, not up to half a pixel to one side of it.
        stay: a boundary pixel that already lies on an image edge (a local maximum of the
            gradient along its normal that reaches ``min_gradient``) stays, even when a
            stronger edge lies within reach (a door leaf's edge a jamb's width inside a true
            door boundary); the others move as without it.
        colour: the gradient across the boundary is the root mean square over the R, G and B
            channels' instead of the grey image's (same scale for a grey step), so a step
            between two colours of equal brightness (a pink wall beside a grey jamb) counts.
        nearest: move to the nearest image edge within reach (a local maximum of the gradient
            along the normal that reaches ``min_gradient``) instead of the strongest, and stay
            where there is none. Edges rank by distance in pixels less 0.001 x gradient: of two
            as near, the stronger; a farther one wins only with a gradient ~1000 higher, about
            the largest a step can give. A boundary already on an edge stays (as ``stay``);
            one a pixel off goes to the edge beside it, not to a stronger texture edge two
            pixels away (the top of a skirting board above a floor | wall boundary).
            Overrides ``stay``.

    Returns:
        The edge image with moved edge pixels (several may land on one; pairs move along;
        none moves onto an unknown pixel).
    """
    if radius <= 0:
        return edge
    _check_rgb(rgb)
    if rgb.shape[:2] != edge.edges.shape:
        raise ValueError(f"image {rgb.shape[:2]} and edges {edge.edges.shape} differ in size")
    if not edge.edges.any():
        return edge
    H, W = edge.edges.shape
    img = rgb if colour else cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[..., None]
    img = cv2.GaussianBlur(img.astype(np.float32), (3, 3), 0).reshape(H, W, -1)  # (H, W, C)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3).reshape(H, W, -1)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3).reshape(H, W, -1)
    ys, xs = np.nonzero(edge.edges)
    theta = edge_normal_angle(edge.edges, at=(ys, xs))
    nx, ny = np.cos(theta)[:, None], np.sin(theta)[:, None]
    # (T,) steps along the normal; one more each side for the band's parabola
    t = np.arange(-radius - 1, radius + 2, dtype=np.float32)

    def along(step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel (y, x) of every edge pixel moved by ``step`` (n, T') along its normal."""
        return (np.clip(np.rint(ys[:, None] + step * ny), 0, H - 1).astype(np.intp),
                np.clip(np.rint(xs[:, None] + step * nx), 0, W - 1).astype(np.intp))

    py, px = along(t)  # (n, T)
    # (n, T, C) channel gradients along the normal -> their RMS (C = 1: the grey one's size)
    grad = np.sqrt(np.mean((gx[py, px] * nx[..., None] + gy[py, px] * ny[..., None]) ** 2,
                           axis=-1))
    across = grad[:, 1:-1] - 1e-3 * np.abs(t[1:-1])  # ties: stay
    across[~edge.known[py[:, 1:-1], px[:, 1:-1]]] = -1.0  # never onto a masked object
    i = np.arange(len(ys))
    inner = grad[:, 1:-1]
    # (n, 2 radius + 1) image edges along the normal: gradient peaks that count
    peak = (inner >= grad[:, :-2]) & (inner >= grad[:, 2:]) & (across >= min_gradient)
    if nearest:  # the nearest peak, ties to the stronger; none: stay
        best = np.where(peak, np.abs(t[1:-1]) - 1e-3 * inner, np.inf).argmin(1)
        move = peak.any(1)
        best = np.where(move, best, radius)
    else:
        best = across.argmax(1)
        move = across[i, best] >= min_gradient
        if stay:  # already on a peak: keep it
            best = np.where(peak[:, radius], radius, best)
            move |= peak[:, radius]
    if band:
        a, b, c = grad[i, best], grad[i, best + 1], grad[i, best + 2]
        curv = a - 2 * b + c
        with np.errstate(divide="ignore", invalid="ignore"):
            sub = np.where(curv < 0, 0.5 * (a - c) / curv, 0.0)
        lo = np.floor(t[best + 1] + np.clip(sub, -0.5, 0.5))[:, None] + np.float32([0, 1])
        by, bx = along(lo)  # (n, 2) the pixels either side of the step
        to_y = np.where(move[:, None], by, ys[:, None]).T.reshape(-1)  # (2n,) side-major
        to_x = np.where(move[:, None], bx, xs[:, None]).T.reshape(-1)
        src = np.tile(i, 2)
    else:
        to_y = np.where(move, py[i, best + 1], ys)
        to_x = np.where(move, px[i, best + 1], xs)
        src = i
    edges = np.zeros_like(edge.edges)
    edges[to_y, to_x] = True
    edges &= edge.known
    pairs = None
    if edge.pairs is not None:
        pairs = np.zeros_like(edge.pairs)
        pairs[to_y, to_x] = edge.pairs[ys[src], xs[src]]
        pairs[~edges] = 0
    return EdgeImage(edges, edge.known, pairs)


def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    """A bool mask (H, W) grown by a disk of ``radius`` pixels."""
    if radius <= 0 or not mask.any():
        return mask
    k = 2 * int(radius) + 1
    return cv2.dilate(mask.astype(np.uint8),
                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0


def structural_mask(labels: np.ndarray, structural: tuple[int, ...] = C.STRUCTURAL
                    ) -> np.ndarray:
    """(H, W) bool: the pixels of ``labels`` (uint8 class ids) whose class is structural."""
    lut = np.zeros(256, dtype=bool)
    lut[list(structural)] = True
    return lut[labels]


def class_changes(labels: np.ndarray, struct: np.ndarray
                  ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """The 4-neighbour pixel pairs p, q whose classes are two different structural classes.

    Args:
        labels: (H, W) class ids.
        struct: (H, W) bool, the structural pixels (``structural_mask``).

    Returns:
        For axis 0 (q below p) and axis 1 (q right of p): ``(diff, a, b)``, each (H - 1, W)
        or (H, W - 1): ``diff`` true at the p of each such pair, ``a`` and ``b`` the classes
        of p and q.
    """
    out = []
    for axis in (0, 1):
        a = np.take(labels, range(labels.shape[axis] - 1), axis=axis)
        b = np.take(labels, range(1, labels.shape[axis]), axis=axis)
        sa = np.take(struct, range(labels.shape[axis] - 1), axis=axis)
        sb = np.take(struct, range(1, labels.shape[axis]), axis=axis)
        out.append(((a != b) & sa & sb, a, b))
    return tuple(out)


def label_edges(labels: np.ndarray, structural: tuple[int, ...] = C.STRUCTURAL,
                dilate_px: int = 3, median: int = 0) -> EdgeImage:
    """Boundaries between different structural classes, and the mask of unknown pixels.

    A pixel is an edge pixel when a 4-neighbour holds a different structural class and it is
    structural itself (both sides of a boundary are marked, so the boundary lies midway).
    Non-structural pixels (clutter, person, void, 255) dilated by ``dilate_px`` are unknown.

    Args:
        labels: (H, W) uint8 class ids.
        structural: the class ids that are in the model.
        dilate_px: growth of the unknown mask, pixels (covers the objects' blurred borders).
        median: median filter size applied to the labels first (odd; 0 disables it), which
            removes speckle of a predicted segmentation.

    Returns:
        The edge image, with the class pair of each edge pixel (``pairs``; a pixel where two
        boundaries meet keeps one of their pairs).
    """
    if labels.ndim != 2:
        raise ValueError(f"expected an (H, W) label map, got {labels.shape}")
    labels = np.ascontiguousarray(labels, dtype=np.uint8)
    if median and median > 1:
        labels = cv2.medianBlur(labels, int(median) | 1)
    struct = structural_mask(labels, structural)
    edges = np.zeros(labels.shape, dtype=bool)
    pairs = np.zeros(labels.shape, dtype=np.uint8)
    for axis, (diff, a, b) in enumerate(class_changes(labels, struct)):
        # codes only at the boundaries (a few thousand pixels, not the whole image)
        ys, xs = np.nonzero(diff)  # between (ys, xs) and its next pixel along the axis
        code = pair_code(a[ys, xs], b[ys, xs])
        if axis == 0:
            edges[:-1] |= diff
            edges[1:] |= diff
            pairs[ys + 1, xs] = code
        else:
            edges[:, :-1] |= diff
            edges[:, 1:] |= diff
            pairs[ys, xs + 1] = code
        pairs[ys, xs] = code
    unknown = _dilate(~struct, int(dilate_px))
    edges &= ~unknown
    return EdgeImage(edges, ~unknown, np.where(edges, pairs, np.uint8(0)))


def check_classes(model_classes: list[dict], dataset_classes: list[dict], where: str) -> None:
    """Raise if the segmenter's classes differ from the dataset's (ids and names).

    Args:
        model_classes: the ONNX file's ``classes`` metadata.
        dataset_classes: ``dataset.json`` classes.
        where: the ONNX path, for the message.
    """
    def key(cs: list[dict]) -> list[tuple[int, str]]:
        return [(int(c["id"]), str(c["name"])) for c in cs]

    if key(model_classes) != key(dataset_classes):
        raise ValueError(
            f"{where}: the model's classes {key(model_classes)} do not match the dataset's "
            f"{key(dataset_classes)}; train the model on a dataset with the same class list "
            "(python -m train dataset=...) or localize with the dataset it was trained on.")


def load_segmenter(path: str | Path, dataset_classes: list[dict], threads: int = 2):
    """Open ``segnet.onnx`` with ``train.predict.OnnxSegmenter`` and check its class list.

    Raises:
        FileNotFoundError: the model file is missing (says how to make it).
        ValueError: it is not an ONNX model, or its classes do not match the dataset's.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"segmentation model not found: {path}. Train and export one with `python -m train` "
            "(or set localize's `onnx_model=` to an existing segnet.onnx, or drop `cnn` from "
            "modes).")
    from train.predict import OnnxSegmenter

    seg = OnnxSegmenter(str(path), threads=threads)
    classes = seg.classes
    if isinstance(classes, str):
        classes = json.loads(classes)
    check_classes(list(classes), dataset_classes, str(path))
    return seg


def _logits_and_labels(segmenter, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, H, W) logits and (H, W) argmax labels of a frame: from one run of the graph where the
    segmenter gives both (``OnnxSegmenter.logits_and_labels``), else the argmax of its logits."""
    both = getattr(segmenter, "logits_and_labels", None)
    if both is not None:
        z, labels = both(rgb)
        return np.asarray(z), np.asarray(labels)
    z = np.asarray(segmenter.logits(rgb))
    return z, z.argmax(0)


def structural_prior_labels(logits: np.ndarray, structural_ids: np.ndarray,
                            log_prior: np.ndarray, labels: np.ndarray | None = None
                            ) -> np.ndarray:
    """Class labels with the training's class-weight prior taken out of the structural choice.

    A network trained with class-weighted cross-entropy (weight w_c) learns softmax scores
    proportional to w_c p(c | x), not p(c | x): where the image is ambiguous it picks the
    higher-weight class. The demo's SegNet weighs wall 0.36 and floor, ceiling, door and window
    0.65-1.05, so those classes spread into the wall and their boundaries with it move (doors
    and windows over their wall-coloured jambs and reveals, for one). Subtracting log w_c from
    the logits gives back the decision by p(c | x); a fraction of it
    (``edges.cnn.prior_correction`` < 1) goes part of the way.

    Only the choice among structural classes is corrected: a pixel whose plain argmax is
    structural takes the structural class with the largest ``z_c - log w_c``; other pixels
    (clutter, person, void) keep their class, so the masks of unknown pixels do not change.

    Args:
        logits: (C, H, W) float class scores.
        structural_ids: (S,) int ids of the structural classes.
        log_prior: (C,) float log w_c (0 for a class without a weight), or a multiple of it.
        labels: (H, W) the plain argmax of ``logits`` if the caller has it (the graph's
            ``labels`` output); None computes it.

    Returns:
        (H, W) uint8 labels.
    """
    ids = np.asarray(structural_ids, dtype=np.int64)
    labels = logits.argmax(0) if labels is None else labels
    corrected = ids[(logits[ids] - np.asarray(log_prior)[ids, None, None]).argmax(0)]
    structural = np.zeros(logits.shape[0], dtype=bool)
    structural[ids] = True
    return np.where(structural[labels], corrected, labels).astype(np.uint8)


def class_log_prior(segmenter) -> np.ndarray | None:
    """log w_c (C,) of the class weights the segmenter was trained with (its ONNX metadata
    ``class_weights``, by class name); None, with a warning, for a model without them (trained
    before they were recorded, or without class weighting: nothing to correct). Classes with
    weight 0 (absent from the training labels) get 0."""
    if "class_weights" not in segmenter.metadata:
        log.warning("%s has no class_weights metadata (re-train with `python -m train` to "
                    "record them); edges.cnn.prior_correction is off", segmenter.path)
        return None
    weights = segmenter.metadata["class_weights"]
    if weights is None:  # trained without class weighting: no prior to take out
        return None
    missing = [c["name"] for c in segmenter.classes if c["name"] not in weights]
    if missing:
        raise ValueError(f"{segmenter.path}: metadata class_weights lacks the classes {missing}; "
                         "re-export the model with `python -m train`")
    w = np.array([float(weights[c["name"]]) for c in segmenter.classes])
    return np.log(np.where(w > 0, w, 1.0))


class EdgeExtractor:
    """Edge images of flight frames in one mode.

    Args:
        mode: ``none`` | ``cnn`` | ``oracle``.
        cfg: the ``edges`` config (canny, hough, labels settings).
        segmenter: an ``OnnxSegmenter`` (cnn mode only).
    """

    def __init__(self, mode: str, cfg: dict, segmenter=None):
        if mode not in MODES:
            raise ValueError(f"unknown edge mode {mode!r}; expected one of {MODES}")
        if mode == "cnn" and segmenter is None:
            raise ValueError("edge mode 'cnn' needs a segmenter (see load_segmenter)")
        self.mode, self.cfg, self.segmenter = mode, cfg, segmenter
        self.cnn = CnnSettings.from_cfg(cfg.get("cnn"))
        self.log_prior = None
        strength = self.cnn.prior_correction
        if mode == "cnn" and strength > 0:
            log_w = class_log_prior(segmenter)
            self.log_prior = None if log_w is None else strength * log_w

    @property
    def needs_labels(self) -> bool:
        """Whether the mode reads the true label image."""
        return self.mode == "oracle"

    def segment(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted labels (H, W) uint8 and their confidence (H, W) float32, the largest
        softmax probability, of an RGB frame (cnn mode). With ``cnn.prior_correction`` s > 0
        the structural labels come from ``structural_prior_labels`` with s * log w_c. The
        confidence is all ones when ``cnn.min_confidence`` is 0 (it is not used then, and the
        softmax is skipped)."""
        _check_rgb(rgb)
        need_conf = self.cnn.min_confidence > 0
        if self.log_prior is None and not need_conf:
            labels, conf = self.segmenter.labels(rgb), None  # argmax only: no softmax
        else:
            z, plain = _logits_and_labels(self.segmenter, rgb)
            labels = (plain if self.log_prior is None else structural_prior_labels(
                z, self.segmenter.structural_ids, self.log_prior, plain))
            # the largest softmax probability is 1 / sum_c exp(z_c - max z)
            conf = 1.0 / np.exp(z - z.max(0, keepdims=True)).sum(0) if need_conf else None
        labels = np.asarray(labels)
        if labels.shape != rgb.shape[:2]:
            raise ValueError(f"segmenter returned labels {labels.shape} for an image "
                             f"{rgb.shape[:2]}")
        conf = np.ones(labels.shape, np.float32) if conf is None else conf.astype(np.float32)
        return labels.astype(np.uint8, copy=False), conf

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
            known = known & ~_dilate(confidence < cc.min_confidence, int(lc["dilate_px"]))
        if cc.refine in ("none", "union"):
            edges = out.edges & known
            out = snap_to_image_edges(
                EdgeImage(edges, known, np.where(edges, out.pairs, np.uint8(0))), rgb,
                cc.snap_px, cc.snap_min_gradient, cc.snap_band, cc.snap_stay, cc.snap_colour,
                cc.snap_nearest)
            if cc.refine == "union":  # image edges beside the boundaries join them (no pair)
                near = _dilate(edges, cc.refine_px) & known
                out = EdgeImage(out.edges | (self._refine_canny(rgb) & near), known, out.pairs)
            return out
        if cc.refine == "canny":
            near = _dilate(out.edges & known, cc.refine_px)
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
