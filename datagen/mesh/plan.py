"""A top-down plan image of a building's classes (orthographic, numpy rasterisation).

As an architect's plan: the building is cut at a height (default 1.5 m above the floor) and
each pixel shows the class of the highest surface below the cut. Triangles with an area in
plan are filled with their interpolated height; vertical ones (walls, door frames, window
reveals) are drawn as their outline (3 px wide) at their top height (at most the cut), so they
show over the floor, and door openings show as gaps in the walls. The free space and paths
(flights, routes) may be drawn over it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from core import classes as C
from core.atomic import write_png
from core.occupancy import PATH_RGB, OccupancyMap
from datagen.mesh.building import Building

BACKGROUND = (255, 255, 255)
FREE_TINT = (120, 200, 255)  # RGB blended into the free space's pixels


def _fill(tri: np.ndarray, cls: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """Pixels covered by triangles in plan (pixel coordinates, z in metres): (pixel index,
    height, class)."""
    lo = np.clip(np.floor(tri[:, :, :2].min(axis=1)).astype(np.int64), 0, None)
    hi = np.minimum(np.ceil(tri[:, :, :2].max(axis=1)).astype(np.int64),
                    [shape[1] - 1, shape[0] - 1])
    size = np.maximum(hi - lo + 1, 0)
    n = size[:, 0] * size[:, 1]
    t = np.repeat(np.arange(len(tri)), n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    px = lo[t, 0] + k % size[t, 0]
    py = lo[t, 1] + k // size[t, 0]
    a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
    x, y = px + 0.5, py + 0.5
    den = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    w0 = ((b[:, 1] - c[:, 1]) * (x - c[:, 0]) + (c[:, 0] - b[:, 0]) * (y - c[:, 1])) / den
    w1 = ((c[:, 1] - a[:, 1]) * (x - c[:, 0]) + (a[:, 0] - c[:, 0]) * (y - c[:, 1])) / den
    w2 = 1 - w0 - w1
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
    z = w0 * a[:, 2] + w1 * b[:, 2] + w2 * c[:, 2]
    return (py * shape[1] + px)[inside], z[inside], cls[t][inside]


def _chunks(cost: np.ndarray, budget: int = 500_000) -> list[slice]:
    """Consecutive slices whose ``cost`` (samples per triangle) adds up to about ``budget``."""
    cum = np.cumsum(cost)
    cuts = np.searchsorted(cum, np.arange(budget, cum[-1] if len(cum) else 0, budget))
    edges = np.unique(np.r_[0, cuts, len(cost)])
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _zbuffer(z_buf: np.ndarray, label: np.ndarray, pix: np.ndarray, z: np.ndarray,
             cls: np.ndarray) -> None:
    """Keep per pixel the class of the highest sample (in place)."""
    order = np.lexsort((z, pix))
    last = np.r_[pix[order][1:] != pix[order][:-1], True]
    pix, z, cls = pix[order][last], z[order][last], cls[order][last]
    higher = z > z_buf[pix]
    z_buf[pix[higher]] = z[higher]
    label[pix[higher]] = cls[higher]


def _outline(tri: np.ndarray, cls: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """Pixels along the plan outline of triangles (3 px wide), at each triangle's top
    height."""
    p0 = tri[:, [0, 1, 2], :2].reshape(-1, 2)
    p1 = tri[:, [1, 2, 0], :2].reshape(-1, 2)
    n = np.ceil(np.linalg.norm(p1 - p0, axis=1)).astype(np.int64) + 1
    e = np.repeat(np.arange(len(p0)), n)
    s = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.maximum(n[e] - 1, 1)
    pts = (p0[e] + (p1[e] - p0[e]) * s[:, None]).astype(np.int64)
    step = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    pts = (pts[:, None, :] + step).reshape(-1, 2)
    px = np.clip(pts[:, 0], 0, shape[1] - 1)
    py = np.clip(pts[:, 1], 0, shape[0] - 1)
    f = np.repeat(e // 3, len(step))
    return py * shape[1] + px, tri[f, :, 2].max(axis=1), cls[f]


def plan_labels(b: Building, metres_per_px: float | None = None, cut: float | None = None
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """Class per pixel seen from above (+Y up in the image).

    Args:
        b: the building. metres_per_px: pixel size (None: the longer side ~1200 px, at least
            0.02 m). cut: the height (m) of the cut (None: ``info["floor_z"]`` + 1.5 m);
            ceiling faces are left out in any case.

    Returns:
        labels (H, W) uint8 (255 where nothing is), origin (2,) the world XY of pixel (0, H-1)'s
        corner, metres_per_px.
    """
    lo, hi = b.vertices[:, :2].min(axis=0) - 0.5, b.vertices[:, :2].max(axis=0) + 0.5
    res = metres_per_px or max(0.02, float((hi - lo).max()) / 1200)
    shape = (int(np.ceil((hi[1] - lo[1]) / res)), int(np.ceil((hi[0] - lo[0]) / res)))
    top = b.info.get("floor_z", 0.0) + 1.5 if cut is None else cut
    tri = b.vertices[b.faces]
    keep = (b.face_class != C.CEILING) & (tri[:, :, 2].min(axis=1) < top)
    tri = np.concatenate([(tri[keep, :, :2] - lo) / res, tri[keep, :, 2:]], axis=2)
    tri[:, :, 2] = np.minimum(tri[:, :, 2], top)
    cls = b.face_class[keep]
    d1, d2 = tri[:, 1, :2] - tri[:, 0, :2], tri[:, 2, :2] - tri[:, 0, :2]
    flat = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / 2 >= 0.25
    labels = np.full(shape[0] * shape[1], 255, np.uint8)
    z_buf = np.full(shape[0] * shape[1], -np.inf)
    filled, fc = tri[flat], cls[flat]
    size = np.ceil(filled[:, :, :2].max(axis=1) - filled[:, :, :2].min(axis=1)) + 2
    for part in _chunks(size[:, 0] * size[:, 1]):
        _zbuffer(z_buf, labels, *_fill(filled[part], fc[part], shape))
    upright, uc = tri[~flat], cls[~flat]
    perimeter = np.linalg.norm(upright[:, [1, 2, 0], :2] - upright[:, :, :2], axis=2).sum(axis=1)
    for part in _chunks(9 * (perimeter + 6)):
        _zbuffer(z_buf, labels, *_outline(upright[part], uc[part], shape))
    return labels.reshape(shape)[::-1], lo, res


def plan_image(b: Building, metres_per_px: float | None = None, cut: float | None = None,
               free: OccupancyMap | None = None, paths: Sequence[np.ndarray] = ()) -> np.ndarray:
    """(H, W + legend, 3) uint8 RGB plan of the classes with a legend (class, area share) and
    a scale bar (at most 200 px); ``free`` tints the free space's cells, and ``paths`` ((K, 2)
    m each, e.g. the flights) are drawn over it in the colours of ``OccupancyMap.plot``."""
    labels, lo, res = plan_labels(b, metres_per_px, cut)
    rgb = C.palette()[labels]
    rgb[labels == 255] = BACKGROUND
    h, w = labels.shape
    if free is not None:
        u, v = np.meshgrid(np.arange(w), np.arange(h))
        xy = lo + np.stack([u.ravel() + 0.5, h - 0.5 - v.ravel()], 1) * res
        inside = free.contains(xy).reshape(h, w)
        rgb[inside] = (0.55 * rgb[inside] + 0.45 * np.array(FREE_TINT)).astype(np.uint8)
    for i, path in enumerate(paths):
        p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
        uv = np.stack([(p[:, 0] - lo[0]) / res, h - (p[:, 1] - lo[1]) / res], 1)
        cv2.polylines(rgb, [np.round(uv).astype(np.int32).reshape(-1, 1, 2)], False,
                      PATH_RGB[i % len(PATH_RGB)], 2, cv2.LINE_AA)
    panel = np.full((max(h, 260), 230, 3), 255, np.uint8)
    shares = b.info.get("class_shares", {})
    for row, name in enumerate(n for n in C.NAMES if n in shares):
        y = 20 + 26 * row
        cv2.rectangle(panel, (10, y - 12), (30, y + 4), C.CLASSES[C.ID[name]][2], -1)
        cv2.putText(panel, f"{name} {100 * shares[name]:.1f}%", (38, y), cv2.FONT_HERSHEY_SIMPLEX,
                    0.5, (0, 0, 0), 1, cv2.LINE_AA)
    metres = max([m for m in (0.5, 1, 2, 5, 10, 20, 50) if m / res <= 200] or [0.5])
    y = 20 + 26 * (len(shares) + 1)
    cv2.line(panel, (10, y), (10 + round(metres / res), y), (0, 0, 0), 2)
    cv2.putText(panel, f"{metres:g} m", (10, y + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                (0, 0, 0), 1, cv2.LINE_AA)
    out = np.full((max(h, panel.shape[0]), w + panel.shape[1], 3), 255, np.uint8)
    out[:h, :w] = rgb
    out[: panel.shape[0], w:] = panel
    return out


def write_plan(b: Building, path: str | Path, metres_per_px: float | None = None,
               cut: float | None = None, free: OccupancyMap | None = None,
               paths: Sequence[np.ndarray] = ()) -> Path:
    """Write ``plan_image`` as a PNG (atomically); returns the path."""
    path = Path(path)
    write_png(path, plan_image(b, metres_per_px, cut, free, paths))
    return path
