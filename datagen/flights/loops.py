"""A loop around a free region: what a flight falls back to where the free space has no route
as long as the flight (a single room, a short corridor).

``perimeter_loop`` follows the region's outer edge some way inside it (around furniture near
the walls, down one side of a corridor and back up the other); ``routes.plan_route`` smooths
it and flies it as many times as the flight needs.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage

from core.occupancy import OccupancyMap

_NEIGHBOURS = np.ones((3, 3), bool)


def perimeter_loop(occ: OccupancyMap, region: np.ndarray,
                   inset: float) -> tuple[np.ndarray | None, float]:
    """The outer boundary of the part of ``region`` at least ``inset`` m beyond the map's
    margin (at most half the region's deepest such distance, so a narrow region keeps a loop).

    The loop runs through the centres of boundary cells whose 8 neighbours are all free, so
    every straight piece between consecutive points stays in free cells. Where the part falls
    apart (a door narrower than twice the inset), the longest boundary is taken.

    Args:
        occ: the free space (its ``clearance`` and ``margin``).
        region: (H, W) bool, free cells of one connected region.
        inset: m.

    Returns:
        (P + 1, 2) m closed loop (last point = first), or None where no cell qualifies; the
        inset it keeps (m; half the width of a corridor's loop).
    """
    depth = np.where(region, occ.clearance - occ.margin, 0.0)  # m beyond the margin
    level = min(max(inset, 0.0), 0.5 * float(depth.max()))
    inner = region & (depth >= level) & ndimage.binary_erosion(occ.free, _NEIGHBOURS)
    if not inner.any():
        return None, level
    contours, _ = cv2.findContours(inner.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    cols_rows = max(contours, key=lambda c: cv2.arcLength(c, True))[:, 0]  # (P, 2) [col, row]
    loop = occ.centres(np.stack([cols_rows[:, 1], cols_rows[:, 0]]))
    return np.concatenate([loop, loop[:1]]), level


def extent_text(mask: np.ndarray, cell: float) -> str:
    """'W x H m, A m2': the span of the centres of the True cells of a (H, W) mask of ``cell``
    m cells, and their area."""
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        return "empty"
    return (f"{np.ptp(cols) * cell:.1f} x {np.ptp(rows) * cell:.1f} m, "
            f"{mask.sum() * cell**2:.1f} m2")
