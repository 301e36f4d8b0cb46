"""The local axis of the free space: the direction of the longest free chord through a cell.

In a corridor that is the corridor's long axis wherever one stands in it (even at its ends,
where the end wall is nearer than the side walls), in a room its long side; training poses
look along it as a copter flying there would (``training_views.sample_training_poses``).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage

from core.occupancy import OccupancyMap
from datagen.flights.map_cache import derived

DIRECTIONS = 12  # chord directions tried, evenly over 180 deg (15 deg apart)

def chord_lengths(free: np.ndarray, angle: float, cell: float) -> np.ndarray:
    """(H, W) float32 m: the length of the run of free cells along direction ``angle`` (rad,
    from +X towards +Y) through each cell; 0 in blocked cells (and within a cell of them, where
    the rotated grid's nearest sample misses).

    The mask is resampled (nearest) onto a grid rotated by ``angle``, whose rows then run along
    the direction, run lengths are counted per row, and the result is sampled back.
    """
    h, w = free.shape
    size = int(np.ceil(np.hypot(h, w))) + 2
    c, s = np.cos(angle), np.sin(angle)
    # canvas pixel (u, v) -> source (col, row): the canvas centre on the source centre,
    # canvas +u along the direction, +v across it (cols are +X, rows +Y)
    centre_src, centre_dst = np.array([(w - 1) / 2, (h - 1) / 2]), (size - 1) / 2
    rot = np.array([[c, -s], [s, c]])
    m = np.hstack([rot, (centre_src - rot @ [centre_dst, centre_dst])[:, None]])
    canvas = cv2.warpAffine(free.astype(np.uint8), m, (size, size),
                            flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderValue=0) > 0
    flat = canvas.ravel()
    starts = flat & ~np.pad(canvas, ((0, 0), (1, 0)))[:, :-1].ravel()
    run = np.cumsum(starts) * flat
    lengths = (np.bincount(run)[run] * flat).astype(np.float32).reshape(canvas.shape) * cell
    lengths = ndimage.maximum_filter(lengths, size=3)  # the back-sampling's nearest misses
    back = cv2.warpAffine(lengths, m, (w, h), flags=cv2.INTER_NEAREST, borderValue=0)
    return np.where(free, back, 0.0).astype(np.float32)


def free_axes(occ: OccupancyMap) -> np.ndarray:
    """(H, W) float32 rad in [0, pi): per free cell, the direction of the longest free chord
    through it (``DIRECTIONS`` directions tried); 0 in blocked cells. Computed once per map
    (datagen.flights.map_cache): treat the map as read-only."""
    return derived(occ, "free_axes", _longest_chords)


def _longest_chords(occ: OccupancyMap) -> np.ndarray:
    angles = np.arange(DIRECTIONS) * np.pi / DIRECTIONS
    best = np.zeros(occ.shape, np.float32)
    axis = np.zeros(occ.shape, np.float32)
    for a in angles:
        length = chord_lengths(occ.free, a, occ.cell)
        longer = length > best
        best = np.where(longer, length, best)
        axis = np.where(longer, np.float32(a), axis)
    return axis


def axis_at(occ: OccupancyMap, xy: np.ndarray) -> np.ndarray:
    """(N,) rad in [0, pi): the free space's axis (``free_axes``) at the points (N, 2) m."""
    rc, _ = occ.cell_of(xy)
    return free_axes(occ)[rc[0], rc[1]].astype(np.float64)
