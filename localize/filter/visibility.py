"""Occlusion of model edge samples, precomputed per camera cell as sparse lists.

Whether a 3D point is hidden behind other geometry depends on where the camera is, not on
where it looks. So visibility is ray-cast once per world from the centre of every cell of a
3D grid where a camera may be (the free space of an ``OccupancyMap``, grown by ``pad``, x the
heights of its band) to every edge sample within ``max_range`` metres, and stored per cell as
the ascending ids of the samples seen (CSR: ``indptr``, ``ids``). A particle looks up the cell
nearest to its camera centre; memory and build time grow with the free area x the samples in
range of a cell, not with the building's whole edge set. A sample counts as visible when
nothing is hit on the ray from the cell centre to within ``eps`` of the sample (the sample lies
on the surface itself). Each entry also holds the class pair seen along the sample from the
cell (``codes``): a crease seen with one face turned away is an outline of that face's class
against what lies behind it (``core.imaging.outline``), so the label modes keep only the
entries where a class boundary is seen. Positions outside the stored cells use the nearest
stored cell.

Rays go through Mitsuba's ``ray_test`` (llvm variant, millions of rays per second); with the
scalar fallback variant trimesh's ray intersector does it, slower. The lists are cached in an
``.npz`` keyed by a hash of the mesh, the samples, the free space and the settings.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from core.atomic import atomic_write
from core.dataset import World
from core.imaging.outline import seen_pairs
from core.imaging.rays import RayCaster
from core.occupancy import OccupancyMap
from localize.config import VisibilityConfig

log = logging.getLogger(__name__)

#: metres: side of the square tiles that order the stored cells (neighbours in space are
#: neighbours in row order, so particles sorted by row form compact groups).
TILE_M = 2.0
_ARRAYS = ("origin", "cell", "shape", "row_of", "flat", "indptr", "ids", "codes")


@dataclass(frozen=True)
class SparseVisibility:
    """The samples visible from each camera cell, within ``max_range``.

    Attributes:
        origin: (3,) centre of grid cell (0, 0, 0), metres.
        cell: (3,) cell size per axis, metres.
        shape: (3,) cells per axis (flat index in C order, x slowest).
        row_of: (G,) int32 row of each grid cell: its own when stored, else the nearest
            stored cell's.
        flat: (R,) int64 grid flat index of each stored row.
        indptr: (R + 1,) int64 CSR row pointers into ``ids``.
        ids: (nnz,) uint32 visible sample ids, ascending within a row.
        codes: (nnz,) uint8 the class pair (``core.classes.pair_code``) seen along each listed
            sample from the cell (``core.imaging.outline.seen_pairs``: a crease with one face
            turned away shows that face's class against what lies behind it); 0: one class.
        num_samples: P, the samples the ids index.
        max_range: metres; samples farther from a cell centre are not listed.
    """

    origin: np.ndarray
    cell: np.ndarray
    shape: np.ndarray
    row_of: np.ndarray
    flat: np.ndarray
    indptr: np.ndarray
    ids: np.ndarray
    codes: np.ndarray
    num_samples: int
    max_range: float

    @property
    def nbytes(self) -> int:
        """Bytes held by the arrays."""
        return sum(getattr(self, k).nbytes for k in _ARRAYS)

    def counts(self) -> np.ndarray:
        """(R,) int64 visible samples per stored row."""
        return np.diff(self.indptr)

    def centres(self) -> np.ndarray:
        """(R, 3) centres of the stored rows, metres."""
        return cell_centres(self.origin, self.cell, self.shape, self.flat)

    def rows(self, positions: np.ndarray) -> np.ndarray:
        """(N,) int64 row of the cell nearest to each position (N, 3), metres."""
        ijk = np.rint((np.asarray(positions) - self.origin) / self.cell).astype(np.int64)
        ijk = np.clip(ijk, 0, self.shape - 1)
        return self.row_of[np.ravel_multi_index(tuple(ijk.T), tuple(self.shape))].astype(
            np.int64)

    def gather(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ids of ``rows`` (m,) concatenated, and (total,) the position in ``rows`` of
        each."""
        start, n = self.indptr[rows], np.diff(self.indptr)[rows]
        which = np.repeat(np.arange(len(rows)), n)
        at = np.arange(len(which)) - np.repeat(np.cumsum(n) - n, n) + start[which]
        return self.ids[at].astype(np.int64), which

    def union(self, rows: np.ndarray) -> np.ndarray:
        """(P,) bool: the samples visible from any of ``rows``."""
        mark = np.zeros(self.num_samples, dtype=bool)
        mark[self.gather(np.unique(rows))[0]] = True
        return mark

    def visible_in(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """(N, C) bool: sample ``cols[c]`` visible from row ``rows[n]``; ``cols`` distinct."""
        urows, inv = np.unique(rows, return_inverse=True)
        ids, which = self.gather(urows)
        pos = np.full(self.num_samples, -1, dtype=np.int64)
        pos[cols] = np.arange(len(cols))
        at = pos[ids]
        hit = at >= 0
        out = np.zeros((len(urows), len(cols)), dtype=bool)
        out[which[hit], at[hit]] = True
        return out[inv.ravel()]

    def mask(self, positions: np.ndarray) -> np.ndarray:
        """(N, P) bool visibility of every sample from camera centres (N, 3); for few N."""
        rows = self.rows(positions)
        return self.visible_in(rows, np.arange(self.num_samples))

    def select(self, cols: np.ndarray, chunk: int = 1 << 22) -> SparseVisibility:
        """The lists for a subset of the samples: ``cols`` (ascending) become ids 0..C-1
        (``chunk`` ids at a time, bounding the temporaries)."""
        cols = np.asarray(cols, dtype=np.int64)
        new = np.full(self.num_samples, -1, dtype=np.int64)
        new[cols] = np.arange(len(cols))
        ids, indptr = [np.zeros(0, np.uint32)], np.zeros(len(self.indptr), np.int64)
        codes = [np.zeros(0, np.uint8)]
        done, lo = 0, 0  # ids kept so far; first row pointer not yet set
        for a in range(0, len(self.ids), chunk):
            mapped = new[self.ids[a:a + chunk]]
            keep = mapped >= 0
            ids.append(mapped[keep].astype(np.uint32))
            codes.append(self.codes[a:a + chunk][keep])
            before = np.cumsum(keep)  # kept up to and including each position
            hi = np.searchsorted(self.indptr, a + len(keep), side="right")
            p = self.indptr[lo:hi] - a  # row pointers in this chunk
            indptr[lo:hi] = done + np.where(p > 0, before[np.maximum(p - 1, 0)], 0)
            done, lo = done + int(before[-1]), hi
        indptr[lo:] = done
        return SparseVisibility(self.origin, self.cell, self.shape, self.row_of, self.flat,
                                indptr, np.concatenate(ids), np.concatenate(codes), len(cols),
                                self.max_range)

    def entries(self, keep: np.ndarray) -> SparseVisibility:
        """The lists with only the entries ``keep`` (nnz,) bool (e.g. those whose ``codes``
        are two classes: ``EdgeModel.class_change``)."""
        before = np.r_[0, np.cumsum(keep)]
        return SparseVisibility(self.origin, self.cell, self.shape, self.row_of, self.flat,
                                before[self.indptr], self.ids[keep], self.codes[keep],
                                self.num_samples, self.max_range)


def cell_centres(origin: np.ndarray, cell: np.ndarray, shape: np.ndarray, flat: np.ndarray
                 ) -> np.ndarray:
    """(R, 3) centres, metres, of the grid cells ``flat`` (R,) (``grid_layout``'s grid)."""
    ijk = np.stack(np.unravel_index(flat, tuple(shape)), axis=1)
    return origin + ijk * cell


def free_bounds(free: OccupancyMap) -> tuple[np.ndarray, np.ndarray]:
    """(3,) lowest and (3,) highest camera centre of a free-space map: its free cells'
    centres x its band, metres (rounded to 1e-6)."""
    if not free.free.any():
        raise ValueError("the free-space map has no free cell: no camera position to cast "
                         "visibility from")
    b = free.free_bounds
    # to the micrometre: cell centres are multiples of the cell size up to float rounding
    return (np.round(np.r_[b[:2], free.band[0]], 6), np.round(np.r_[b[2:], free.band[1]], 6))


def grid_layout(lo: np.ndarray, hi: np.ndarray, cell_xy: float, cell_z: float,
                pad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid over the box [lo, hi] (3,) metres, padded by ``pad`` metres.

    Returns:
        origin (3,), cell (3,), shape (3,) int64.
    """
    if cell_xy <= 0 or cell_z <= 0:
        raise ValueError(f"visibility cell sizes must be positive, got {cell_xy}, {cell_z}")
    lo, hi = np.asarray(lo, np.float64) - pad, np.asarray(hi, np.float64) + pad
    cell = np.array([cell_xy, cell_xy, cell_z], dtype=np.float64)
    shape = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1) + 1
    origin = (lo + hi) / 2 - cell * (shape - 1) / 2
    return origin, cell, shape


def stored_cells(free: OccupancyMap, origin: np.ndarray, cell: np.ndarray, shape: np.ndarray,
                 pad: float) -> tuple[np.ndarray, np.ndarray]:
    """The grid cells a camera may be in and the row of every grid cell.

    A column (x, y) is stored when its centre is within ``pad + cell_xy`` of a free map cell
    centre; all its heights are. Rows run tile by tile (``TILE_M``), then in flat order.

    Returns:
        flat (R,) int64 grid index of each row; row_of (G,) int32 (nearest stored cell for the
        others).
    """
    nx, ny, nz = (int(s) for s in shape)
    r, c = np.nonzero(free.free)
    xs = origin[0] + cell[0] * np.arange(nx)
    ys = origin[1] + cell[1] * np.arange(ny)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    reach, _ = cKDTree(free.centres(np.stack([r, c]))).query(
        np.stack([gx.ravel(), gy.ravel()], axis=1), distance_upper_bound=pad + 2 * cell[0])
    col = (reach <= pad + cell[0] + 1e-9).reshape(nx, ny)
    if not col.any():
        raise ValueError("no visibility cell lies near the free space; check the free map")
    stored = np.repeat(col[:, :, None], nz, axis=2)
    flat = np.flatnonzero(stored)
    i, j, _ = np.unravel_index(flat, (nx, ny, nz))
    t = max(1, int(round(TILE_M / cell[0])))
    flat = flat[np.lexsort((flat, j // t, i // t))]
    row = np.full(nx * ny * nz, -1, dtype=np.int64)
    row[flat] = np.arange(len(flat))
    _, near = ndimage.distance_transform_edt(~stored, sampling=cell, return_indices=True)
    nearest = np.ravel_multi_index(tuple(near.reshape(3, -1)), (nx, ny, nz))
    return flat, row[nearest].astype(np.int32)


def occluded(world: World, origins: np.ndarray, targets: np.ndarray, eps: float = 0.02,
             variant: str = "auto", chunk: int = 2_000_000) -> np.ndarray:
    """Whether the straight line from each origin to each target hits the mesh first.

    Args:
        world: the model (vertices, faces).
        origins: (G, 3) ray origins, metres.
        targets: (P, 3) points, metres.
        eps: hits within this distance of the target do not count (the target's own surface).
        variant: Mitsuba variant (``RayCaster``).
        chunk: rays per batch.

    Returns:
        (G, P) bool, True where the target is hidden from the origin.
    """
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    G, P = len(origins), len(targets)
    out = np.zeros((G, P), dtype=bool)
    if G == 0 or P == 0:
        return out
    caster = RayCaster(world.vertices, world.faces, variant)
    rows = max(1, chunk // P)
    for g0 in range(0, G, rows):
        o = np.repeat(origins[g0:g0 + rows], P, axis=0)
        t = np.tile(targets, (len(o) // P, 1))
        out[g0:g0 + rows] = caster.hidden(o, t, eps).reshape(-1, P)
    return out


def _batches(counts: np.ndarray, chunk: int) -> list[slice]:
    """Consecutive row slices whose ``counts`` sum to about ``chunk`` (at least one row)."""
    ends = np.searchsorted(np.cumsum(counts), np.arange(chunk, counts.sum() + chunk, chunk),
                           side="right")
    ends = np.unique(np.clip(np.r_[ends, len(counts)], 1, len(counts)))
    return [slice(a, b) for a, b in zip(np.r_[0, ends[:-1]], ends, strict=True)]


def build_visibility(world: World, points: np.ndarray, free: OccupancyMap | None = None,
                     settings: VisibilityConfig | None = None,
                     chunk: int = 2_000_000, classes: np.ndarray | None = None,
                     normals: np.ndarray | None = None) -> SparseVisibility:
    """Ray-cast the visibility of sample points from the stored cells' centres.

    Args:
        world: the model (mesh).
        points: (P, 3) edge samples, metres.
        free: where the camera may be (None: ``world.free``); the grid covers its free
            cells x band, padded by ``pad`` metres (``stored_cells``).
        settings: ``cell_xy``, ``cell_z``, ``pad``, ``eps`` (tolerance at the sample), metres;
            ``max_range`` (only samples this near a cell centre are cast and listed) and the
            Mitsuba ``variant`` (``RayCaster``); None: ``VisibilityConfig()``.
        chunk: rays per batch (memory: about 100 bytes a ray).
        classes: (P, 2) the classes of each point's edge, in the order of ``normals``; None:
            every ``codes`` entry 0.
        normals: (P, 2, 3) each point's crease normals (``datagen.mesh.edges.EdgeSet.normals``,
            NaN for no crease): the class pair seen from a cell is that of an outline where
            one face turns away (``core.imaging.outline.seen_pairs``); None: the edge's own.
    """
    v = VisibilityConfig() if settings is None else settings
    cell_xy, cell_z, pad, eps, max_range = v.cell_xy, v.cell_z, v.pad, v.eps, v.max_range
    variant = v.variant
    if max_range <= 0:
        raise ValueError(f"visibility.max_range must be positive, got {max_range}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if classes is not None and normals is None:
        normals = np.full((len(points), 2, 3), np.nan)
    free = world.free if free is None else free
    origin, cell, shape = grid_layout(*free_bounds(free), cell_xy, cell_z, pad)
    flat, row_of = stored_cells(free, origin, cell, shape, pad)
    centres = cell_centres(origin, cell, shape, flat)
    tree = cKDTree(points)
    near = tree.query_ball_point(centres, max_range, return_length=True)
    caster = RayCaster(world.vertices, world.faces, variant) if near.any() else None
    ids, codes, counts = [], [], np.zeros(len(flat), dtype=np.int64)
    for b in _batches(near, chunk) if near.any() else []:
        pairs = cKDTree(centres[b]).sparse_distance_matrix(tree, max_range,
                                                           output_type="ndarray")
        i, j = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
        seen = ~caster.hidden(centres[b][i], points[j], eps)
        i, j = i[seen], j[seen]
        order = np.lexsort((j, i))
        i, j = i[order], j[order]
        ids.append(j.astype(np.uint32))
        codes.append(np.zeros(len(j), np.uint8) if classes is None else seen_pairs(
            classes[j], normals[j], points[j], centres[b][i], caster, world.face_class))
        counts[b] = np.bincount(i, minlength=b.stop - b.start)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    ids = np.concatenate(ids) if ids else np.zeros(0, np.uint32)
    codes = np.concatenate(codes) if codes else np.zeros(0, np.uint8)
    return SparseVisibility(origin, cell, shape, row_of, flat, indptr, ids, codes, len(points),
                            float(max_range))


def cache_key(world: World, points: np.ndarray, free: OccupancyMap, settings: dict) -> str:
    """Hash (16 hex digits) of the mesh, the sample points, the free space and the settings."""
    h = hashlib.sha256()
    for a in (world.vertices, world.faces, points, free.free, free.origin, free.band,
              [free.cell]):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(repr(sorted(settings.items())).encode())
    return h.hexdigest()[:16]


def load_or_build(world: World, points: np.ndarray, free: OccupancyMap | None,
                  cache_dir: str | Path | None, settings: VisibilityConfig,
                  classes: np.ndarray | None = None, normals: np.ndarray | None = None
                  ) -> SparseVisibility:
    """The visibility lists from ``cache_dir/visibility_<key>.npz``, built and saved if
    missing (``free`` None: ``world.free``; ``settings``, ``classes`` and ``normals`` as
    ``build_visibility``'s)."""
    free = world.free if free is None else free
    key = {"cell_xy": settings.cell_xy, "cell_z": settings.cell_z, "pad": settings.pad,
           "eps": settings.eps, "max_range": settings.max_range, "layout": "sparse-codes"}
    path = None
    if cache_dir is not None:
        for name, a in (("classes", classes), ("normals", normals)):
            if a is not None:
                key[name] = hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]
        path = Path(cache_dir) / f"visibility_{cache_key(world, points, free, key)}.npz"
        if path.is_file():
            with np.load(path) as f:
                return SparseVisibility(*(f[k] for k in _ARRAYS), int(f["num_samples"]),
                                        float(f["max_range"]))
    vis = build_visibility(world, points, free, settings, classes=classes, normals=normals)
    if path is not None:
        atomic_write(path, lambda p: np.savez(
            p, **{k: getattr(vis, k) for k in _ARRAYS}, num_samples=vis.num_samples,
            max_range=vis.max_range))
    return vis
