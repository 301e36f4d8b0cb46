"""Edge images: edge pixels, where edges are known, and the class pair of each boundary.

The building blocks of the edge modes (``localize.frontend.extractor``): Canny edges of an image
(``canny_edges``, optionally its Hough segments), boundaries between structural classes of a
label map (``label_edges``) with the mask of unknown pixels (objects that are not in the
model), the class-pair code of a boundary (``pair_code``) and the structure-tensor normal of an
edge map (``edge_normal_angle``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from core import classes as C


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


def check_rgb(rgb: np.ndarray) -> None:
    """Raise ValueError, naming the shape and dtype received, unless ``rgb`` is (H, W, 3)
    uint8."""
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")


def canny_edges(rgb: np.ndarray, low: float = 50.0, high: float = 150.0, blur: int = 3,
                hough: Mapping | None = None, colour: bool = False) -> EdgeImage:
    """Canny edges of an RGB image, optionally replaced by the Hough line segments they hold.

    Args:
        rgb: (H, W, 3) uint8.
        low, high: Canny hysteresis thresholds on the gradient magnitude.
        blur: Gaussian blur kernel size before Canny (odd; <= 1 disables it).
        hough: None or a mapping with ``threshold`` (votes), ``min_length`` and ``max_gap``
            (pixels) for ``cv2.HoughLinesP`` (``config.HoughSettings``); the found segments
            are drawn 1 px wide.
        colour: False: Canny on the grey image; True: on the RGB image (OpenCV takes, at each
            pixel, the gradient of the channel where it is strongest: a step between colours
            of equal brightness counts).

    Returns:
        The edge image; every pixel is known.
    """
    check_rgb(rgb)
    img = np.ascontiguousarray(rgb) if colour else cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    if blur and blur > 1:
        img = cv2.GaussianBlur(img, (int(blur) | 1, int(blur) | 1), 0)
    edges = cv2.Canny(img, float(low), float(high), L2gradient=True)
    if hough:
        lines = cv2.HoughLinesP(edges, 1, np.pi / 180, int(hough["threshold"]),
                                minLineLength=float(hough["min_length"]),
                                maxLineGap=float(hough["max_gap"]))
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



def dilate(mask: np.ndarray, radius: int) -> np.ndarray:
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
    unknown = dilate(~struct, int(dilate_px))
    edges &= ~unknown
    return EdgeImage(edges, ~unknown, np.where(edges, pairs, np.uint8(0)))

