"""Edge images: edge pixels, where edges are known, and the class pair of each boundary.

``EdgeImage`` is what every edge mode makes (``localize.frontend.extractor``); beside it the
structure-tensor normal of an edge map (``edge_normal_angle``) and the RGB frame check
(``check_rgb``). The class-pair code of a boundary is ``core.classes.pair_code``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


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


def check_rgb(rgb: np.ndarray) -> None:
    """Raise ValueError, naming the shape and dtype received, unless ``rgb`` is (H, W, 3)
    uint8."""
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")


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
