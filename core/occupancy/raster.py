"""Triangles onto a 2D grid of cells: footprints, band covers and lowest faces.

The rasterization behind ``OccupancyMap.from_mesh``. Triangles are (F, 3, 3)
world metres (Z up); a grid is ``(origin (2,) m, cell m, shape (H, W))`` with rows along +Y
and columns along +X, as the occupancy map's. Triangles are sampled densely enough that every
cell they cross gets a sample (``samples``); long ones are split first so that each chunk of
samples stays under ``MAX_POINTS``.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy import ndimage

MAX_POINTS = 1 << 19  # surface samples per chunk (memory bound of from_mesh)


def cells(xy: np.ndarray, origin: np.ndarray, cell: float,
           shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(2, N) row, column of the cell holding each of the (N, 2) m points ``xy`` (clipped to
    the grid) and (N,) whether it lies inside the grid."""
    cr = np.floor((xy - origin) / cell).astype(np.int64)
    inside = ((cr >= 0) & (cr < np.array([shape[1], shape[0]]))).all(1)
    rc = np.stack([np.clip(cr[:, 1], 0, shape[0] - 1), np.clip(cr[:, 0], 0, shape[1] - 1)])
    return rc, inside


def normal_z(tri: np.ndarray) -> np.ndarray:
    """(F,) z of the triangles' (unnormalised) normals, counter-clockwise winding."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n[:, 2]


def clip_z(tri: np.ndarray, parent: np.ndarray, level: float, above: bool,
            strict: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The parts of triangles (T, 3, 3) at z >= level (``above``) or z <= level, or strictly
    beyond it (``strict``), as triangles, each with its ``parent`` (T,) entry."""
    d = (tri[:, :, 2] - level) * (1 if above else -1)
    inside = d > 0 if strict else d >= 0
    n_in = inside.sum(1)
    out_tri, out_parent = [tri[n_in == 3]], [parent[n_in == 3]]
    for n, odd in ((1, inside), (2, ~inside)):  # roll the odd vertex out to position 0
        sel = n_in == n
        first = np.argmax(odd[sel], axis=1)
        idx = (first[:, None] + np.arange(3)) % 3
        t = np.take_along_axis(tri[sel], idx[:, :, None], axis=1)
        dd = np.take_along_axis(d[sel], idx, axis=1)
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        ab = a + (b - a) * (dd[:, :1] / (dd[:, :1] - dd[:, 1:2]))
        ac = a + (c - a) * (dd[:, :1] / (dd[:, :1] - dd[:, 2:3]))
        if n == 1:  # a inside: one triangle
            out_tri.append(np.stack([a, ab, ac], 1))
            out_parent.append(parent[sel])
        else:  # a outside: the quad ab, b, c, ac
            out_tri += [np.stack([ab, b, c], 1), np.stack([ab, c, ac], 1)]
            out_parent += [parent[sel], parent[sel]]
    return np.concatenate(out_tri), np.concatenate(out_parent)


def footprint(tri: np.ndarray, parent: np.ndarray, grid: tuple) -> np.ndarray:
    """(H, W) bool: the cells the triangles' XY footprints touch."""
    origin, cell, shape, spacing = grid
    mask = np.zeros(shape, bool)
    for pts, _ in samples(tri, spacing):
        rc, inside = cells(pts[:, :2], origin, cell, shape)
        mask[rc[0, inside], rc[1, inside]] = True
    return mask


def close(mask: np.ndarray, radius: float) -> np.ndarray:
    """(H, W) bool: the morphological closing of ``mask`` by a disc of ``radius`` cells (the
    mask padded first, so that nothing is lost at the grid's edge)."""
    r = int(np.ceil(radius - 1e-9))
    if r <= 0:
        return mask
    y, x = np.ogrid[-r:r + 1, -r:r + 1]
    disc = x * x + y * y <= radius * radius + 1e-9
    return ndimage.binary_closing(np.pad(mask, r), disc)[r:-r, r:-r] | mask


def fill_holes(mask: np.ndarray, max_cells: float) -> np.ndarray:
    """(H, W) bool: ``mask`` with its holes (regions of ~mask not reaching the grid's edge,
    4-connected) of at most ``max_cells`` cells filled."""
    if max_cells <= 0:
        return mask
    label, _ = ndimage.label(~mask)
    size = np.bincount(label.ravel())
    edge = np.unique(np.concatenate([label[0], label[-1], label[:, 0], label[:, -1]]))
    fill = size <= max_cells
    fill[0] = False
    fill[edge] = False
    return mask | fill[label]


def band_cover(tri: np.ndarray, grid: tuple, z_lo: float) -> np.ndarray:
    """(H, W) m of height covered in each cell by triangles (T, 3, 3) clipped to a band above
    ``z_lo``: the length of the union of the height ranges of the triangles whose XY
    footprints touch the cell (a triangle counts with its whole height range, so a long
    sloped one covers more than its part over the cell: obstacles err on the safe side)."""
    origin, cell, shape, spacing = grid
    n_cells = int(np.prod(shape))
    if len(tri) == 0:
        return np.zeros(shape)
    keys = []
    for pts, t in samples(tri, spacing):
        rc, inside = cells(pts[:, :2], origin, cell, shape)
        flat = np.ravel_multi_index((rc[0, inside], rc[1, inside]), shape)
        keys.append(np.unique(flat * len(tri) + t[inside]))
    c, t = np.divmod(np.unique(np.concatenate(keys)), len(tri))
    lo, hi = tri[t, :, 2].min(1) - z_lo, tri[t, :, 2].max(1) - z_lo
    # merge the ranges per cell: shift each cell's ranges past the previous cell's, order
    # by start, and a range starts a new run where it begins beyond all before it
    offset = c * (float(hi.max()) + 1.0)
    order = np.lexsort((lo, c))
    a, b, c = lo[order] + offset[order], hi[order] + offset[order], c[order]
    reach = np.maximum.accumulate(b)
    new = np.r_[True, a[1:] > reach[:-1]]
    first = np.flatnonzero(new)
    length = np.maximum.reduceat(b, first) - a[first]
    return np.bincount(c[first], weights=length, minlength=n_cells).reshape(shape)


def lowest_faces_up(tri: np.ndarray, up: np.ndarray, grid: tuple) -> np.ndarray:
    """(H, W) bool: the lowest of the triangles over a cell faces up (``up`` (T,); at equal
    heights, to 0.1 mm, up wins)."""
    origin, cell, shape, spacing = grid
    z0 = tri[:, :, 2].min() if len(tri) else 0.0
    lowest = np.full(int(np.prod(shape)), np.iinfo(np.int64).max)  # 2 * height + (not up)
    for pts, t in samples(tri, spacing):
        rc, inside = cells(pts[:, :2], origin, cell, shape)
        key = 2 * np.round((pts[inside, 2] - z0) * 1e4).astype(np.int64) + ~up[t[inside]]
        np.minimum.at(lowest, np.ravel_multi_index((rc[0, inside], rc[1, inside]), shape), key)
    return ((lowest % 2 == 0) & (lowest < np.iinfo(np.int64).max)).reshape(shape)


def split_long(tri: np.ndarray, parent: np.ndarray,
                max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Halve triangles (T, 3, 3) across their longest XY edge until every XY edge is <=
    max_edge.

    Returns:
        the pieces (P, 3, 3) and (P,) the ``parent`` entry of each.
    """
    done_tri, done_parent = [tri[:0]], [parent[:0]]
    while len(tri):
        edge = np.linalg.norm(tri[:, [1, 2, 0], :2] - tri[:, :, :2], axis=2)  # i -> i + 1
        ok = edge.max(1) <= max_edge
        done_tri.append(tri[ok])
        done_parent.append(parent[ok])
        tri, parent, longest = tri[~ok], parent[~ok], edge[~ok].argmax(1)
        # roll so the longest edge is vertex 0 -> 1, then split it at its midpoint
        idx = (longest[:, None] + np.arange(3)) % 3
        t = np.take_along_axis(tri, idx[:, :, None], axis=1)
        mid = (t[:, 0] + t[:, 1]) / 2
        tri = np.concatenate([np.stack([t[:, 0], mid, t[:, 2]], 1),
                              np.stack([mid, t[:, 1], t[:, 2]], 1)])
        parent = np.concatenate([parent, parent])
    return np.concatenate(done_tri), np.concatenate(done_parent)


def samples(tri: np.ndarray, spacing: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Points on triangles (T, 3, 3) whose XY lattice steps are at most ``spacing``.

    Each triangle gets the lattice A + i/ku (B - A) + j/kv (C - A), i/ku + j/kv <= 1, with A
    the corner opposite its longest XY edge and ku, kv the XY lengths of AB, AC over the
    spacing: every point of the triangle's XY footprint is within ``spacing`` of a sample.
    Triangles are split first so that one has at most ~2000 points, and a chunk at most
    ``MAX_POINTS``.

    Yields:
        points (P, 3) and (P,) the index of each point's triangle in ``tri``.
    """
    tri, parent = split_long(tri, np.arange(len(tri)), 64 * spacing)
    edge = np.linalg.norm(tri[:, [1, 2, 0], :2] - tri[:, :, :2], axis=2)
    a = (edge.argmax(1) + 2) % 3  # the corner opposite the longest edge
    idx = (a[:, None] + np.arange(3)) % 3
    t = np.take_along_axis(tri, idx[:, :, None], axis=1)
    ab, ac = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    ku = np.maximum(np.ceil(np.linalg.norm(ab[:, :2], axis=1) / spacing), 1).astype(np.int64)
    kv = np.maximum(np.ceil(np.linalg.norm(ac[:, :2], axis=1) / spacing), 1).astype(np.int64)
    bound = np.cumsum((ku + 1) * (kv + 1))  # points per triangle are at most this
    start = 0
    while start < len(t):
        base = bound[start - 1] if start else 0
        stop = max(int(np.searchsorted(bound, base + MAX_POINTS, side="right")), start + 1)
        # rows i of every triangle, then the points j of every row
        rows = ku[start:stop] + 1
        row_tri = np.repeat(np.arange(start, stop), rows)
        i = np.arange(rows.sum()) - np.repeat(np.cumsum(rows) - rows, rows)
        u = i / ku[row_tri]
        per_row = np.floor(kv[row_tri] * (1 - u) + 1e-9).astype(np.int64) + 1
        which = np.repeat(row_tri, per_row)
        j = np.arange(per_row.sum()) - np.repeat(np.cumsum(per_row) - per_row, per_row)
        u, v = np.repeat(u, per_row), j / kv[which]
        pts = t[which, 0] + u[:, None] * ab[which] + v[:, None] * ac[which]
        yield pts, parent[which]
        start = stop
