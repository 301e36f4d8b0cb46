"""Class boundaries of a label map, and their move onto the image's own edges.

``label_edges`` marks the boundaries between two different structural classes (with the mask
of unknown pixels: objects that are not in the model); ``snap_to_image_edges`` moves them
onto the image's gradient (the paper's search along the normal).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from core import classes as C
from core.classes import class_changes, pair_code, structural_mask
from localize.frontend.edge_image import EdgeImage, check_rgb, edge_normal_angle


def dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    """A bool mask (H, W) grown by a disk of ``radius`` pixels."""
    if radius <= 0 or not mask.any():
        return mask
    k = 2 * int(radius) + 1
    return cv2.dilate(mask.astype(np.uint8),
                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0


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



def image_gradients(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The colour gradient tensor ``snap_to_image_edges`` reads: of the 3x3 Sobel x and y
    (gx, gy, each (H, W, 3)) of the 3x3-blurred image, the channel means of gx^2, gx gy and
    gy^2, each (H, W) float32. The RMS over the channels of the gradient along a unit normal
    (nx, ny) is ``sqrt(nx^2 gxx + 2 nx ny gxy + ny^2 gyy)``. Of the image alone: they can be
    made while the SegNet runs."""
    check_rgb(rgb)
    img = cv2.GaussianBlur(rgb.astype(np.float32), (3, 3), 0)  # (H, W, 3)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    mean = np.full((1, 3), 1.0 / 3.0)  # the channel mean, by OpenCV's per-pixel transform
    return tuple(cv2.transform(cv2.multiply(a, b), mean) for a, b in ((gx, gx), (gx, gy), (gy, gy)))


def snap_to_image_edges(edge: EdgeImage, rgb: np.ndarray, radius: int,
                        min_gradient: float, nearest: bool = False,
                        gradients: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                        ) -> EdgeImage:
    """Class boundaries moved onto the image's own edges: each edge pixel searches along its
    normal, up to ``radius`` pixels either way, for the strongest colour gradient across the
    boundary, and moves there if that gradient reaches ``min_gradient``; elsewhere (a door in
    a wall of the same paint) it stays. The paper's 1-D search along the normal, applied to the
    segmentation's boundaries: the SegNet says *which* boundary is there, at its quarter
    resolution, and the image says *where*, to a pixel.

    A boundary pixel that already lies on an image edge (a local maximum of the gradient along
    its normal that reaches ``min_gradient``) stays, even when a stronger edge lies within
    reach (a door leaf's edge a jamb's width inside a true door boundary).

    Args:
        edge: class boundaries (edges, known, pairs) of a frame, (H, W).
        rgb: (H, W, 3) uint8, the frame.
        radius: search distance, pixels; 0 returns ``edge`` unchanged.
        min_gradient: smallest gradient across the boundary that counts as an image edge: the
            root mean square over the R, G and B channels of the 3x3 Sobel of the 3x3-blurred
            image (a grey step of h levels gives about 3 h; a step between two colours of equal
            brightness counts too).
        nearest: move to the nearest image edge within reach (a local maximum of the gradient
            along the normal that reaches ``min_gradient``) instead of the strongest, and stay
            where there is none. Edges rank by distance in pixels less 0.001 x gradient: of two
            as near, the stronger; a farther one wins only with a gradient ~1000 higher, about
            the largest a step can give. A boundary already on an edge stays; one a pixel off
            goes to the edge beside it, not to a stronger texture edge two pixels away (the top
            of a skirting board above a floor | wall boundary).
        gradients: ``image_gradients(rgb)`` if the caller has them (None: made here).

    Returns:
        The edge image with moved edge pixels (several may land on one; pairs move along;
        none moves onto an unknown pixel).
    """
    if radius <= 0:
        return edge
    check_rgb(rgb)
    if rgb.shape[:2] != edge.edges.shape:
        raise ValueError(f"image {rgb.shape[:2]} and edges {edge.edges.shape} differ in size")
    if not edge.edges.any():
        return edge
    ys, xs = np.nonzero(edge.edges)
    prof = _normal_profiles(edge, gradients or image_gradients(rgb), ys, xs, radius)
    best, move = _choose_steps(prof, edge.known, radius, min_gradient, nearest)
    i = np.arange(len(ys))
    to_y = np.where(move, prof.py[i, best + 1], ys)
    to_x = np.where(move, prof.px[i, best + 1], xs)
    edges = np.zeros_like(edge.edges)
    edges[to_y, to_x] = True
    edges &= edge.known
    pairs = None
    if edge.pairs is not None:
        pairs = np.zeros_like(edge.pairs)
        pairs[to_y, to_x] = edge.pairs[ys, xs]
        pairs[~edges] = 0
    return EdgeImage(edges, edge.known, pairs)


@dataclass(frozen=True)
class _Profiles:
    """The image gradient along each edge pixel's normal.

    Attributes:
        t: (T,) float32 steps along the normal, -radius - 1 .. radius + 1 pixels (one more
            each side than the search, for the peak test at its ends).
        py, px: (n, T) intp pixel at each step of each of the n edge pixels.
        grad: (n, T) float32 gradient across the boundary there (RMS over the channels).
    """

    t: np.ndarray
    py: np.ndarray
    px: np.ndarray
    grad: np.ndarray


def _step_pixels(ys: np.ndarray, xs: np.ndarray, step: np.ndarray, ny: np.ndarray,
                 nx: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (y, x), each (n, T') intp, of every edge pixel (ys, xs) moved by ``step`` (n, T')
    or (T',) pixels along its unit normal (ny, nx) (n, 1), clipped to the image ``shape``."""
    H, W = shape
    return (np.clip(np.rint(ys[:, None] + step * ny), 0, H - 1).astype(np.intp),
            np.clip(np.rint(xs[:, None] + step * nx), 0, W - 1).astype(np.intp))


def _normal_profiles(edge: EdgeImage, gradients: tuple[np.ndarray, np.ndarray, np.ndarray],
                     ys: np.ndarray, xs: np.ndarray, radius: int) -> _Profiles:
    """The gradient profiles (``_Profiles``) of the edge pixels (ys, xs) of ``edge``, from
    the image's gradient tensor (``image_gradients``)."""
    H, W = edge.edges.shape
    gxx, gxy, gyy = gradients
    theta = edge_normal_angle(edge.edges, at=(ys, xs))
    nx, ny = np.cos(theta)[:, None], np.sin(theta)[:, None]
    t = np.arange(-radius - 1, radius + 2, dtype=np.float32)
    py, px = _step_pixels(ys, xs, t, ny, nx, (H, W))  # (n, T)
    # (n, T) RMS over the channels of the gradient along the normal
    sq = nx * nx * gxx[py, px] + 2.0 * nx * ny * gxy[py, px] + ny * ny * gyy[py, px]
    grad = np.sqrt(np.maximum(sq, 0.0)).astype(np.float32)
    return _Profiles(t, py, px, grad)


def _choose_steps(prof: _Profiles, known: np.ndarray, radius: int, min_gradient: float,
                  nearest: bool) -> tuple[np.ndarray, np.ndarray]:
    """Where each edge pixel goes: (n,) int index into the 2 radius + 1 search steps, and
    (n,) bool whether it moves (see ``snap_to_image_edges`` for the rules)."""
    grad, t = prof.grad, prof.t
    across = grad[:, 1:-1] - 1e-3 * np.abs(t[1:-1])  # ties: stay
    across[~known[prof.py[:, 1:-1], prof.px[:, 1:-1]]] = -1.0  # never onto a masked object
    i = np.arange(len(grad))
    inner = grad[:, 1:-1]
    # (n, 2 radius + 1) image edges along the normal: gradient peaks that count
    peak = (inner >= grad[:, :-2]) & (inner >= grad[:, 2:]) & (across >= min_gradient)
    if nearest:  # the nearest peak, ties to the stronger; none: stay
        best = np.where(peak, np.abs(t[1:-1]) - 1e-3 * inner, np.inf).argmin(1)
        move = peak.any(1)
        return np.where(move, best, radius), move
    best = across.argmax(1)
    move = across[i, best] >= min_gradient
    best = np.where(peak[:, radius], radius, best)  # already on a peak: keep it
    move |= peak[:, radius]
    return best, move

