"""Mode none's edges: Canny edges of an image, optionally its Hough line segments."""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from localize.frontend.edge_image import EdgeImage, check_rgb


def canny_edges(rgb: np.ndarray, low: float = 50.0, high: float = 150.0, blur: int = 3,
                hough: Mapping | None = None, colour: bool = False) -> EdgeImage:
    """Canny edges of an RGB image, optionally replaced by the Hough line segments they hold.

    Args:
        rgb: (H, W, 3) uint8.
        low, high: Canny hysteresis thresholds on the gradient magnitude.
        blur: Gaussian blur kernel size before Canny (odd; <= 1 disables it).
        hough: None or a mapping with ``threshold`` (votes), ``min_length`` and ``max_gap``
            (pixels) for ``cv2.HoughLinesP`` (``config.HoughConfig``); the found segments
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
