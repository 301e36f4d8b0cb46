"""Lens distortion in OpenCV's plumb_bob model: the fold check, the maps that render a pinhole
image through a distorted lens (datagen) and the maps that undistort a frame back to its
pinhole K (the localizer).

plumb_bob (OpenCV's ``D = (k1, k2, p1, p2, k3)``): a normalized image point (x, y) of the
pinhole camera, r^2 = x^2 + y^2, is seen at

    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

and at pixel K (x_d, y_d, 1). The distorted image and its pinhole version share K.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from core import classes as C

#: The plumb_bob coefficients, in OpenCV's order.
PLUMB_BOB = ("k1", "k2", "p1", "p2", "k3")
#: The largest undistorted radius (normalized, tan of the off-axis angle: 76 deg) the fold
#: check follows the radial map to.
MAX_RADIUS = 4.0
#: The pinhole render covering a distorted image may be at most this many times its size.
MAX_COVER = 3.0
#: Pixels a re-distorted ray may miss the pixel it came from (``distort_maps``).
ROUND_TRIP_PX = 1e-3


def coefficients(distortion) -> np.ndarray:
    """(5,) float64 plumb_bob coefficients of ``distortion`` ((k,) with k <= 5, padded with
    zeros; None or empty: zeros)."""
    d = np.zeros(5)
    if distortion is not None:
        given = np.asarray(distortion, dtype=np.float64).reshape(-1)
        if len(given) > 5:
            raise ValueError(f"plumb_bob has 5 coefficients {PLUMB_BOB}, got {len(given)}")
        d[:len(given)] = given
    return d


def is_distorted(distortion) -> bool:
    """Whether any coefficient is non-zero."""
    return bool(np.any(coefficients(distortion) != 0))


def corner_radius(K: np.ndarray, width: int, height: int) -> float:
    """The largest normalized radius of the image's corners (pixel edges, -0.5 and W - 0.5)."""
    K = np.asarray(K, dtype=np.float64)
    x = (np.array([-0.5, width - 0.5]) - K[0, 2]) / K[0, 0]
    y = (np.array([-0.5, height - 0.5]) - K[1, 2]) / K[1, 1]
    return float(np.sqrt(np.max(x**2) + np.max(y**2)))


def check_plumb_bob(distortion, K: np.ndarray, width: int, height: int,
                    where: str) -> np.ndarray:
    """The coefficients (5,) float64, checked: finite, and a radial map
    r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6) that keeps increasing until it reaches the image's
    corner radius (``corner_radius``), so every pixel sees one ray and no two rays meet.

    Raises:
        ValueError: naming ``where`` and the fix, when the map folds over the image.
    """
    d = coefficients(distortion)
    if not np.all(np.isfinite(d)):
        named = dict(zip(PLUMB_BOB, d.tolist(), strict=True))
        raise ValueError(f"{where}: the coefficients {named} must be finite numbers")
    k1, k2, _, _, k3 = d
    rd_max = corner_radius(K, width, height)
    r = np.linspace(0.0, MAX_RADIUS, 40001)[1:]
    r2 = r * r
    mapped = r * (1 + k1 * r2 + k2 * r2**2 + k3 * r2**3)
    slope = 1 + 3 * k1 * r2 + 5 * k2 * r2**2 + 7 * k3 * r2**3
    bad = np.flatnonzero(slope <= 0)
    reach = np.flatnonzero(mapped >= rd_max)
    end = reach[0] if len(reach) else len(r)
    if len(bad) and bad[0] <= end:
        i = bad[0]
        raise ValueError(
            f"{where}: k1 = {k1:g}, k2 = {k2:g}, k3 = {k3:g} fold the image: the radial map "
            f"r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6) stops increasing at r = {r[i]:.3f} (where "
            f"it reaches {mapped[i]:.3f}), before the image's corner radius {rd_max:.3f} (in "
            "normalized coordinates), so rays past it fold back onto the image and its corners "
            "see none; use a smaller |k1| "
            "or a k2 that holds the map up (a wide lens: k1 = -0.28, k2 = 0.07)")
    if not len(reach):
        raise ValueError(
            f"{where}: k1 = {k1:g}, k2 = {k2:g}, k3 = {k3:g} squeeze more than "
            f"{math.degrees(math.atan(MAX_RADIUS)):.0f} deg off axis into the image's corners "
            f"(radius {rd_max:.3f}): too wide for a pinhole lens model; use a smaller |k1|")
    return d


def _undistort_points(uv: np.ndarray, K: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N, 2) distorted pixels -> (N, 2) normalized pinhole coordinates (iterated to
    convergence)."""
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    pts = np.ascontiguousarray(uv, dtype=np.float64).reshape(-1, 1, 2)
    return cv2.undistortPoints(pts, K, d, criteria=crit)[:, 0]


def distort_points(xy: np.ndarray, K: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N, 2) normalized pinhole coordinates -> (N, 2) distorted pixels (cv2.projectPoints)."""
    pts = np.concatenate([xy, np.ones((len(xy), 1))], axis=1).reshape(-1, 1, 3)
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), np.asarray(K, np.float64), d)
    return uv[:, 0]


def cover_camera(K: np.ndarray, distortion, width: int, height: int,
                 where: str = "lens") -> tuple[np.ndarray, int, int]:
    """The centred pinhole camera, of K's focal length (square pixels), whose image holds every
    ray a distorted (K, ``distortion``) image of width x height sees, with a pixel to spare
    for bilinear sampling.

    Returns:
        K_cover (3, 3), width_cover, height_cover (pixels).

    Raises:
        ValueError: the cover would be more than ``MAX_COVER`` times the image's size.
    """
    K = np.asarray(K, dtype=np.float64)
    d = coefficients(distortion)
    f = float(K[0, 0])
    if abs(K[1, 1] - f) > 1e-6 * f:
        raise ValueError(f"{where}: the render needs square pixels (fx = fy), got K {K.tolist()}")
    W, H = int(width), int(height)
    u = np.linspace(-0.5, W - 0.5, 4 * W + 1)
    v = np.linspace(-0.5, H - 0.5, 4 * H + 1)
    border = np.concatenate([np.stack([u, np.full_like(u, -0.5)], 1),
                             np.stack([u, np.full_like(u, H - 0.5)], 1),
                             np.stack([np.full_like(v, -0.5), v], 1),
                             np.stack([np.full_like(v, W - 0.5), v], 1)])
    xy = _undistort_points(border, K, d)
    wc = math.ceil(2 * f * np.max(np.abs(xy[:, 0])) + 3)
    hc = math.ceil(2 * f * np.max(np.abs(xy[:, 1])) + 3)
    if wc > MAX_COVER * W or hc > MAX_COVER * H:
        raise ValueError(f"{where}: the distorted image sees a field {wc}x{hc} pixels wide at "
                         f"its focal length, more than {MAX_COVER:g}x the image ({W}x{H}); "
                         "use smaller distortion coefficients")
    Kc = np.array([[f, 0.0, (wc - 1) / 2.0], [0.0, f, (hc - 1) / 2.0], [0.0, 0.0, 1.0]])
    return Kc, wc, hc


def distort_maps(K: np.ndarray, distortion, width: int, height: int, K_source: np.ndarray,
                 where: str = "lens") -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` that render a pinhole image of ``K_source`` through the lens:
    for each pixel (u, v) of the distorted width x height image of (K, ``distortion``), the
    pixel of the pinhole image its ray lands on.

    Returns:
        map_x, map_y: (height, width) float32 pixel coordinates in the source image.

    Raises:
        ValueError: a ray that does not map back onto its pixel (within ``ROUND_TRIP_PX``):
            coefficients the iterative inversion cannot follow.
    """
    K = np.asarray(K, dtype=np.float64)
    d = coefficients(distortion)
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    xy = _undistort_points(uv, K, d)
    miss = np.max(np.abs(distort_points(xy, K, d) - uv))
    if not miss <= ROUND_TRIP_PX:
        raise ValueError(f"{where}: the lens model cannot be inverted over the image (a pixel's "
                         f"ray maps back {miss:.3g} px away); use smaller coefficients")
    Ks = np.asarray(K_source, dtype=np.float64)
    mx = Ks[0, 0] * xy[:, 0] + Ks[0, 1] * xy[:, 1] + Ks[0, 2]
    my = Ks[1, 1] * xy[:, 1] + Ks[1, 2]
    return (mx.reshape(height, width).astype(np.float32),
            my.reshape(height, width).astype(np.float32))


@dataclass(frozen=True)
class Undistorter:
    """Undistorts frames of a (K, ``distortion``) camera back to the pinhole camera of the same
    K and size (``cv2.initUndistortRectifyMap``, computed once; ``cv2.remap`` per frame, about
    1 ms for 320 x 240).

    K: (3, 3); distortion: (5,) plumb_bob (fewer: padded with zeros), or OpenCV's rational
    model's (8,), (12,) or (14,); width, height: pixels.
    """

    K: np.ndarray
    distortion: np.ndarray
    width: int
    height: int

    @cached_property
    def _maps(self) -> tuple[np.ndarray, np.ndarray]:
        K = np.asarray(self.K, dtype=np.float64)
        d = np.asarray(self.distortion, dtype=np.float64).reshape(-1)
        d = d if len(d) > 5 else coefficients(d)
        return cv2.initUndistortRectifyMap(K, d, None, K,
                                           (int(self.width), int(self.height)), cv2.CV_32FC1)

    def _check(self, image: np.ndarray) -> None:
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f"a frame of {image.shape[1]}x{image.shape[0]} pixels given to the "
                             f"undistortion of a {self.width}x{self.height} camera")

    def image(self, image: np.ndarray) -> np.ndarray:
        """(H, W[, C]) image -> the same, undistorted (bilinear; pixels outside the lens's
        field repeat the nearest border pixel, so they add no edge)."""
        self._check(image)
        return cv2.remap(image, *self._maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    def labels(self, labels: np.ndarray, fill: int = C.IGNORE) -> np.ndarray:
        """(H, W) uint8 class ids -> the same, undistorted (nearest; ``fill`` outside the
        lens's field)."""
        self._check(labels)
        return cv2.remap(labels, *self._maps, cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=int(fill))
