"""Class boundaries moved onto the image's own edges (the paper's search along the normal)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from localize.edges import EdgeImage, check_rgb, edge_normal_angle


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
    check_rgb(rgb)
    if rgb.shape[:2] != edge.edges.shape:
        raise ValueError(f"image {rgb.shape[:2]} and edges {edge.edges.shape} differ in size")
    if not edge.edges.any():
        return edge
    ys, xs = np.nonzero(edge.edges)
    prof = _normal_profiles(edge, rgb, ys, xs, radius, colour)
    best, move = _choose_steps(prof, edge.known, radius, min_gradient, stay, nearest)
    i = np.arange(len(ys))
    if band:
        to_y, to_x = _band_targets(prof, best, move, ys, xs)
        src = np.tile(i, 2)
    else:
        to_y = np.where(move, prof.py[i, best + 1], ys)
        to_x = np.where(move, prof.px[i, best + 1], xs)
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


@dataclass(frozen=True)
class _Profiles:
    """The image gradient along each edge pixel's normal.

    Attributes:
        t: (T,) float32 steps along the normal, -radius - 1 .. radius + 1 pixels (one more
            each side than the search, for the band's parabola).
        py, px: (n, T) intp pixel at each step of each of the n edge pixels.
        grad: (n, T) float32 gradient across the boundary there (RMS over the channels).
        ny, nx: (n, 1) float32 unit normal of each edge pixel (image y down, x right).
        shape: (H, W) of the image.
    """

    t: np.ndarray
    py: np.ndarray
    px: np.ndarray
    grad: np.ndarray
    ny: np.ndarray
    nx: np.ndarray
    shape: tuple[int, int]

    def along(self, ys: np.ndarray, xs: np.ndarray,
              step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """See ``_step_pixels``."""
        return _step_pixels(ys, xs, step, self.ny, self.nx, self.shape)


def _step_pixels(ys: np.ndarray, xs: np.ndarray, step: np.ndarray, ny: np.ndarray,
                 nx: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (y, x), each (n, T') intp, of every edge pixel (ys, xs) moved by ``step`` (n, T')
    or (T',) pixels along its unit normal (ny, nx) (n, 1), clipped to the image ``shape``."""
    H, W = shape
    return (np.clip(np.rint(ys[:, None] + step * ny), 0, H - 1).astype(np.intp),
            np.clip(np.rint(xs[:, None] + step * nx), 0, W - 1).astype(np.intp))


def _normal_profiles(edge: EdgeImage, rgb: np.ndarray, ys: np.ndarray, xs: np.ndarray,
                     radius: int, colour: bool) -> _Profiles:
    """The gradient profiles (``_Profiles``) of the edge pixels (ys, xs) of ``edge``."""
    H, W = edge.edges.shape
    img = rgb if colour else cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[..., None]
    img = cv2.GaussianBlur(img.astype(np.float32), (3, 3), 0).reshape(H, W, -1)  # (H, W, C)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3).reshape(H, W, -1)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3).reshape(H, W, -1)
    theta = edge_normal_angle(edge.edges, at=(ys, xs))
    nx, ny = np.cos(theta)[:, None], np.sin(theta)[:, None]
    t = np.arange(-radius - 1, radius + 2, dtype=np.float32)
    py, px = _step_pixels(ys, xs, t, ny, nx, (H, W))  # (n, T)
    # (n, T, C) channel gradients along the normal -> their RMS (C = 1: the grey one's size)
    grad = np.sqrt(np.mean((gx[py, px] * nx[..., None] + gy[py, px] * ny[..., None]) ** 2,
                           axis=-1))
    return _Profiles(t, py, px, grad, ny, nx, (H, W))


def _choose_steps(prof: _Profiles, known: np.ndarray, radius: int, min_gradient: float,
                  stay: bool, nearest: bool) -> tuple[np.ndarray, np.ndarray]:
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
    if stay:  # already on a peak: keep it
        best = np.where(peak[:, radius], radius, best)
        move |= peak[:, radius]
    return best, move


def _band_targets(prof: _Profiles, best: np.ndarray, move: np.ndarray, ys: np.ndarray,
                  xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(2n,) y and x of the two pixels either side of each step's sub-pixel position (the
    vertex of the parabola through the gradient at the chosen step and its neighbours),
    side-major; pixels that do not move stay."""
    grad, i = prof.grad, np.arange(len(best))
    a, b, c = grad[i, best], grad[i, best + 1], grad[i, best + 2]
    curv = a - 2 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        sub = np.where(curv < 0, 0.5 * (a - c) / curv, 0.0)
    lo = np.floor(prof.t[best + 1] + np.clip(sub, -0.5, 0.5))[:, None] + np.float32([0, 1])
    by, bx = prof.along(ys, xs, lo)  # (n, 2) the pixels either side of the step
    to_y = np.where(move[:, None], by, ys[:, None]).T.reshape(-1)
    to_x = np.where(move[:, None], bx, xs[:, None]).T.reshape(-1)
    return to_y, to_x
