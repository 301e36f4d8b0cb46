"""Free space as a 2D occupancy map: where a camera may fly, for one band of heights.

The grid covers world x, y (metres, Z up). Cell centres lie at integer multiples of ``cell``,
so maps of one cell size line up whatever they were built from. ``free[r, c]`` is the cell
whose lower-left corner is ``origin + (c, r) * cell``: rows run along +Y, columns along +X.

A cell is free when its column has floor below the band, no surface of the model within the
band [z_lo, z_hi], is not inside a solid, and its centre is at least ``margin`` from every
cell that fails those tests (a Euclidean distance transform). ``OccupancyMap.from_mesh``
builds that from a classed triangle mesh, and for meshes others made (scans with holes and
noise, furnished rooms) more tolerantly where asked: the ceiling's footprint counts as floor,
the footprint is closed morphologically and its small holes filled, and a column is an
obstacle only where its surfaces cover a share of the band's height (a wall, not a stray
triangle or a table top); ``OccupancyMap.from_boxes`` from the procedural
corridor's free boxes (already shrunk by the margin), so both give one structure.

Distances are those between cell centres: exact for a wall through cell centres, otherwise
within half a cell; a point of a free cell may be up to half a cell nearer an obstacle than
the margin.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from core import classes as C
from core.atomic import atomic_write
from core.occupancy import raster

_TOL = 1e-6  # m, slack of the margin test (distances are sums of cell multiples)
MAX_POINTS = 1 << 19  # surface samples per chunk (memory bound of from_mesh)
_KEYS = ("free", "clearance", "origin", "cell", "band", "margin")
#: The most cells a map may have: 0.5 km^2 of 0.1 m cells (a 700 m square; building it from a
#: mesh takes a few GB and minutes). A model read in the wrong units is far larger.
MAX_CELLS = 50_000_000

#: plot colours (RGB): free, within the margin of an obstacle, obstacle / outside.
FREE_RGB, MARGIN_RGB, BLOCKED_RGB = (255, 255, 255), (200, 200, 200), (60, 60, 60)
#: plot colours of the paths, in turn.
PATH_RGB = ((220, 20, 60), (30, 110, 220), (0, 160, 70), (230, 140, 0))


@dataclass
class OccupancyMap:
    """A 2D occupancy map of the flyable heights.

    free: (H, W) bool, cells a camera centre may occupy.
    clearance: (H, W) float32 m, distance from a cell centre to the nearest obstacle (from
        ``from_boxes``: the margin plus the distance to the free region's edge); 0 where
        the cell is an obstacle or outside the building.
    origin: (2,) float64 m, x, y of the lower-left corner of cell [0, 0].
    cell: m, cell size.
    band: (z_lo, z_hi) m, the flyable heights the map is for.
    margin: m, the clearance a free cell keeps from obstacles.
    """

    free: np.ndarray
    clearance: np.ndarray
    origin: np.ndarray
    cell: float
    band: tuple[float, float]
    margin: float

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_mesh(cls, vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                  band: Sequence[float], margin: float, cell: float,
                  floor_classes: Sequence[int] = (C.FLOOR,), samples_per_cell: float = 2.0,
                  exclude_solids: bool = True, ceiling_classes: Sequence[int] = (),
                  close: float = 0.0, max_hole: float = 0.0,
                  obstacle_span: float = 0.0) -> OccupancyMap:
        """Rasterise a classed triangle mesh.

        The triangles are clipped to the band (obstacles), below it (floor faces) and above
        it (for ``exclude_solids``), and each piece is sampled on a lattice of its own whose
        steps are at most ``cell / samples_per_cell`` in XY, so every cell a piece's XY
        footprint covers gets a sample (a vertical wall: an unbroken line of cells).

        Args:
            vertices: (V, 3) m, world frame, Z up.
            faces: (F, 3) vertex indices.
            face_class: (F,) class ids (core.classes).
            band: (z_lo, z_hi) m, the flyable heights.
            margin: m kept from obstacles (the camera's margin).
            cell: m, cell size.
            floor_classes: the classes that are floor.
            samples_per_cell: lattice steps per cell length (>= 2).
            exclude_solids: a column whose lowest surface above the band faces up (the top
                of a closed block seen from inside it; at equal heights up wins) is inside a
                solid, not free; with ``obstacle_span``, above the band's top
                ``obstacle_span`` share instead (a door's head, in the band at its top only,
                leaves the opening free), and only where 3 x 3 cells are (a stray
                triangle of a scan is no solid). Needs outward-facing normals
                (counter-clockwise winding seen from outside); False for meshes whose
                winding is not reliable.
            ceiling_classes: faces of these classes above the band also mark a column as
                inside the building (a scan sees the ceiling where furniture hides the
                floor; a stairwell, a canopy over the entrance count too); (): the floor
                alone.
            close: m, radius of the morphological closing of that support (the floor's
                footprint, with the ceiling's): gaps and holes narrower than about twice this
                (scan noise, unseen floor) are filled; 0: none.
            max_hole: m^2, holes of the closed support (regions enclosed by it) up to this
                area are filled too (a hole of the scan under a table); 0: none.
            obstacle_span: share of the band's height [0, 1] that a column's surfaces in the
                band must cover (the union of the heights of the pieces touching the cell)
                for the cell to be an obstacle: a wall or a cabinet covers the band, a stray
                triangle, a table top or a door's head do not; 0: any surface.

        Returns:
            The map; its grid covers the mesh's XY bounds plus one cell.

        Raises:
            ValueError: bad arguments, vertices that are NaN or infinite, a grid of more than
                ``MAX_CELLS`` cells (a model in the wrong units), no floor below the band or
                no free space left.
        """
        v, f, cls_ = _check_mesh(vertices, faces, face_class)
        z_lo, z_hi = _check_band(band)
        cell, margin = _positive(cell, "cell"), float(margin)
        if samples_per_cell < 2:
            raise ValueError(f"samples_per_cell must be >= 2, got {samples_per_cell}")
        origin, shape = _grid(v[:, :2].min(0), v[:, :2].max(0), cell)
        grid = (origin, cell, shape, cell / samples_per_cell)
        if not 0.0 <= obstacle_span <= 1.0 or close < 0 or max_hole < 0:
            raise ValueError(f"obstacle_span must be in [0, 1] and close, max_hole >= 0, got "
                             f"{obstacle_span}, {close}, {max_hole}")
        tri, index = v[f], np.arange(len(f))
        in_band = raster.clip_z(*raster.clip_z(tri, index, z_lo, above=True), z_hi, above=False)
        if obstacle_span > 0:
            span = obstacle_span * (z_hi - z_lo)
            blocked = raster.band_cover(in_band[0], grid, z_lo) >= span - _TOL
        else:
            blocked = raster.footprint(*in_band, grid)
        is_floor = np.isin(cls_, np.asarray(floor_classes))
        floor = raster.footprint(*raster.clip_z(tri[is_floor], index[is_floor], z_lo,
                                                above=False, strict=True), grid)
        if not floor.any():
            raise ValueError(f"mesh: no floor below the band {[z_lo, z_hi]} (faces of classes "
                             f"{list(floor_classes)} below z = {z_lo}); check the face classes "
                             "and the band")
        is_ceiling = np.isin(cls_, np.asarray(ceiling_classes, dtype=cls_.dtype))
        if is_ceiling.any():
            ceiling = raster.footprint(*raster.clip_z(tri[is_ceiling], index[is_ceiling], z_hi,
                                                      above=True, strict=True), grid)
            floor |= ceiling
        floor = raster.fill_holes(raster.close(floor, close / cell), max_hole / cell**2)
        top_up = np.zeros(shape, bool)
        if exclude_solids:  # inside a solid over the top ``obstacle_span`` of the band
            level = z_hi - obstacle_span * (z_hi - z_lo)
            above, parent = raster.clip_z(tri, index, level, above=True, strict=True)
            top_up = raster.lowest_faces_up(above, raster.normal_z(tri)[parent] > 0, grid)
            if obstacle_span > 0:  # a solid is wider than a stray triangle: 3 x 3 cells
                top_up = ndimage.binary_opening(top_up, np.ones((3, 3), bool))
        raw = floor & ~blocked & ~top_up
        clearance = ndimage.distance_transform_edt(raw, sampling=cell).astype(np.float32)
        free = raw & (clearance >= margin - _TOL)
        occ = cls(free, clearance, origin, cell, (z_lo, z_hi), margin)
        occ._check_not_empty("mesh")
        return occ

    @classmethod
    def from_boxes(cls, free_boxes: np.ndarray, band: Sequence[float], cell: float,
                   margin: float = 0.0) -> OccupancyMap:
        """Rasterise free-space boxes (the procedural corridor's ``World.free_boxes``).

        Args:
            free_boxes: (B, 4) m [xmin, ymin, xmax, ymax], already shrunk by the margin; a
                cell is free when its centre lies in one of them (edges included).
            band: (z_lo, z_hi) m.
            cell: m, cell size.
            margin: m, the margin the boxes were shrunk by (for ``clearance``).
        """
        boxes = np.asarray(free_boxes, dtype=np.float64).reshape(-1, 4)
        if len(boxes) == 0 or np.any(boxes[:, 2:] <= boxes[:, :2]):
            raise ValueError(f"free_boxes must be (B, 4) [xmin, ymin, xmax, ymax] with "
                             f"max > min, got {boxes.tolist()}")
        z_lo, z_hi = _check_band(band)
        cell = _positive(cell, "cell")
        origin, shape = _grid(boxes[:, :2].min(0), boxes[:, 2:].max(0), cell)
        # first / one-past-last cell whose centre is in each box, per axis
        first = np.ceil((boxes[:, :2] - origin) / cell - 0.5 - 1e-9).astype(np.int64)
        last = np.floor((boxes[:, 2:] - origin) / cell - 0.5 + 1e-9).astype(np.int64) + 1
        diff = np.zeros((shape[0] + 1, shape[1] + 1), np.int64)  # summed-area corners
        np.add.at(diff, (first[:, 1], first[:, 0]), 1)
        np.add.at(diff, (first[:, 1], last[:, 0]), -1)
        np.add.at(diff, (last[:, 1], first[:, 0]), -1)
        np.add.at(diff, (last[:, 1], last[:, 0]), 1)
        free = diff.cumsum(0).cumsum(1)[:-1, :-1] > 0
        edge = ndimage.distance_transform_edt(free, sampling=cell)
        clearance = np.where(free, margin + edge - cell, 0.0).astype(np.float32)
        occ = cls(free, clearance, origin, cell, (z_lo, z_hi), float(margin))
        occ._check_not_empty("free_boxes")
        return occ

    # ------------------------------------------------------------------ queries

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) cells: rows along +Y, columns along +X."""
        return self.free.shape

    @property
    def area(self) -> float:
        """Free area, m^2."""
        return float(self.free.sum()) * self.cell**2

    @property
    def extent(self) -> np.ndarray:
        """(4,) m [xmin, ymin, xmax, ymax] of the grid."""
        h, w = self.shape
        return np.concatenate([self.origin, self.origin + np.array([w, h]) * self.cell])

    def cell_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cells of points: (2, N) int64 [row, col] (clipped) and (N,) bool inside the grid."""
        return raster.cells(np.asarray(xy, dtype=np.float64).reshape(-1, 2), self.origin,
                      self.cell, self.shape)

    def centres(self, rc: np.ndarray) -> np.ndarray:
        """(N, 2) m centres of the cells (2, N) [row, col]."""
        rc = np.asarray(rc)
        return self.origin + (np.stack([rc[1], rc[0]], 1) + 0.5) * self.cell

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(N,) bool: the points (N, 2) m lie in free cells."""
        rc, inside = self.cell_of(xy)
        return inside & self.free[rc[0], rc[1]]

    def distance(self, xy: np.ndarray) -> np.ndarray:
        """(N,) m from the points (N, 2) to the nearest obstacle, to within a cell (the
        clearance of their cells; 0 outside the grid)."""
        rc, inside = self.cell_of(xy)
        return np.where(inside, self.clearance[rc[0], rc[1]], 0.0)

    def outside_distance_xyz(self, xyz: np.ndarray) -> np.ndarray:
        """(N,) m from positions (N, 3) to the free space: the larger of the horizontal
        distance to the free cells (``outside_distance``) and the vertical one to the band;
        0 inside."""
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        z = xyz[:, 2]
        d_z = np.maximum(np.maximum(self.band[0] - z, z - self.band[1]), 0.0)
        return np.maximum(self.outside_distance(xyz[:, :2]), d_z)

    @property
    def free_bounds(self) -> np.ndarray:
        """(4,) m [xmin, ymin, xmax, ymax] of the free cells' centres."""
        r, c = np.nonzero(self.free)
        if len(r) == 0:
            raise ValueError("the map has no free cells")
        lo = self.centres(np.stack([[r.min()], [c.min()]]))[0]
        hi = self.centres(np.stack([[r.max()], [c.max()]]))[0]
        return np.concatenate([lo, hi])

    @functools.cached_property
    def _outside(self) -> np.ndarray:
        """(H, W) float64 m, distance from a cell centre to the nearest free cell centre."""
        return ndimage.distance_transform_edt(~self.free, sampling=self.cell)

    def outside_distance(self, xy: np.ndarray) -> np.ndarray:
        """(N,) m from the points (N, 2) to the free space: 0 in a free cell, else the
        distance between cell centres to the nearest free cell plus, for a point beyond the
        grid, its distance to the grid."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        rc, _ = self.cell_of(xy)
        ext = self.extent
        beyond = np.hypot(*np.maximum(np.maximum(ext[:2] - xy, xy - ext[2:]), 0.0).T)
        return np.where(self.free[rc[0], rc[1]], 0.0, self._outside[rc[0], rc[1]] + beyond)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 2) m points uniform over the free cells (a free cell, then uniform in it)."""
        idx = np.flatnonzero(self.free)
        if len(idx) == 0:
            raise ValueError(f"no free cells to sample (margin {self.margin} m)")
        pick = idx[rng.integers(len(idx), size=int(n))]
        r, c = np.unravel_index(pick, self.shape)
        return self.origin + (np.stack([c, r], 1) + rng.random((int(n), 2))) * self.cell

    def eroded(self, extra: float) -> OccupancyMap:
        """The map with ``extra`` m more margin (free where clearance >= margin + extra)."""
        if extra < 0:
            raise ValueError(f"extra margin must be >= 0, got {extra}")
        margin = self.margin + float(extra)
        free = self.free & (self.clearance >= margin - _TOL)
        return OccupancyMap(free, self.clearance, self.origin, self.cell, self.band, margin)

    # ------------------------------------------------------------------ files and images

    def save(self, path: str | Path) -> None:
        """Write an .npz file atomically (``load`` reads it)."""
        arrays = {"free": self.free, "clearance": self.clearance.astype(np.float32),
                  "origin": np.asarray(self.origin, np.float64), "cell": np.float64(self.cell),
                  "band": np.asarray(self.band, np.float64), "margin": np.float64(self.margin)}

        def write(tmp: Path) -> None:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **arrays)

        atomic_write(path, write)

    @classmethod
    def load(cls, path: str | Path) -> OccupancyMap:
        """Read a map written by ``save``."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"occupancy map {path} not found")
        with np.load(path) as z:
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise ValueError(f"{path}: not an occupancy map (missing {missing}); write one "
                                 "with OccupancyMap.save")
            d = {k: z[k] for k in _KEYS}
        if d["free"].shape != d["clearance"].shape or d["free"].ndim != 2:
            raise ValueError(f"{path}: free {d['free'].shape} and clearance "
                             f"{d['clearance'].shape} must be the same (H, W)")
        return cls(d["free"].astype(bool), d["clearance"].astype(np.float32),
                   d["origin"].astype(np.float64), float(d["cell"]),
                   (float(d["band"][0]), float(d["band"][1])), float(d["margin"]))

    def to_pixels(self, xy: np.ndarray, scale: int = 1) -> np.ndarray:
        """(N, 2) float pixel (u, v) of world points (N, 2) m in ``plot``'s image."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        uv = (xy - self.origin) / self.cell * scale - 0.5
        return np.stack([uv[:, 0], self.shape[0] * scale - 1 - uv[:, 1]], 1)

    def plot(self, paths: Sequence[np.ndarray] = (), scale: int = 1) -> np.ndarray:
        """Top-down image of the map, +Y up: free white, within the margin light grey,
        obstacles and outside dark; ``paths`` ((K, 2) m each) drawn in colours in turn.

        Returns:
            (H * scale, W * scale, 3) uint8 RGB.
        """
        img = np.empty((*self.shape, 3), np.uint8)
        img[:] = BLOCKED_RGB
        img[self.clearance > 0] = MARGIN_RGB
        img[self.free] = FREE_RGB
        img = np.ascontiguousarray(np.repeat(np.repeat(img[::-1], scale, 0), scale, 1))
        for i, path in enumerate(paths):
            uv = np.round(self.to_pixels(path, scale)).astype(np.int32)
            cv2.polylines(img, [uv.reshape(-1, 1, 2)], False, PATH_RGB[i % len(PATH_RGB)],
                          max(1, scale // 2), cv2.LINE_AA)
        return img

    def _check_not_empty(self, source: str) -> None:
        if not self.free.any():
            raise ValueError(f"{source}: no free space left (band {list(self.band)}, margin "
                             f"{self.margin} m, cell {self.cell} m); lower the margin or "
                             "check the band against the floor and ceiling heights")


# ---------------------------------------------------------------------- helpers


def lowest_above(vertices: np.ndarray, faces: np.ndarray, occ: OccupancyMap,
                 level: float) -> np.ndarray:
    """(H, W) m: over each cell of ``occ``'s grid, the height of the lowest near-horizontal
    surface (normal within 60 degrees of vertical) above ``level``, the faces clipped there;
    inf where there is none. Above a map's band: its ceilings and the heads of its doors."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flat = np.abs(n[:, 2]) >= 0.5 * np.linalg.norm(n, axis=1)
    tri = raster.clip_z(tri[flat], np.flatnonzero(flat), level, above=True, strict=True)[0]
    lowest = np.full(int(np.prod(occ.shape)), np.inf)
    for pts, _ in raster.samples(tri, occ.cell / 2):
        rc, inside = occ.cell_of(pts[:, :2])
        np.minimum.at(lowest, np.ravel_multi_index((rc[0, inside], rc[1, inside]), occ.shape),
                      pts[inside, 2])
    return lowest.reshape(occ.shape)


def _positive(value: float, key: str) -> float:
    value = float(value)
    if not value > 0:
        raise ValueError(f"{key} must be positive, got {value}")
    return value


def _check_band(band: Sequence[float]) -> tuple[float, float]:
    b = np.asarray(band, dtype=np.float64).reshape(-1)
    if b.shape != (2,) or not b[0] < b[1]:
        raise ValueError(f"band must be [z_lo, z_hi] with z_lo < z_hi, got {b.tolist()}")
    return float(b[0]), float(b[1])


def _check_mesh(vertices: np.ndarray, faces: np.ndarray,
                face_class: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    cls_ = np.asarray(face_class).reshape(-1)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"vertices must be (V, 3), got {v.shape}")
    bad = int((~np.isfinite(v).all(axis=1)).sum())
    if bad:
        raise ValueError(f"vertices: {bad} of {len(v)} are not finite (NaN or infinite)")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be (F, 3) integer vertex indices, got {f.shape} {f.dtype}")
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces index vertices {f.min()}..{f.max()}, but there are {len(v)}")
    if len(cls_) != len(f):
        raise ValueError(f"face_class has {len(cls_)} entries for {len(f)} faces")
    return v, f.astype(np.int64), cls_


def _grid(lo: np.ndarray, hi: np.ndarray, cell: float) -> tuple[np.ndarray, tuple[int, int]]:
    """Origin and (H, W) of the lattice grid covering [lo, hi] plus one cell on each side;
    ValueError for more than ``MAX_CELLS`` cells."""
    k0 = np.floor(lo / cell + 0.5) - 1  # lattice index of the first centre
    k1 = np.floor(hi / cell + 0.5) + 1
    cells = float(np.prod(k1 - k0 + 1))
    if cells > MAX_CELLS:
        size = np.asarray(hi, np.float64) - lo
        raise ValueError(f"the grid over {size[0]:.1f} x {size[1]:.1f} m at {cell} m cells "
                         f"would have {cells:,.0f} cells, more than {MAX_CELLS:,} (memory and "
                         f"time grow with them): is the model in metres? (one drawn in mm and "
                         f"read as metres is 1000 x too wide); else use a larger cell")
    origin = (k0 - 0.5) * cell
    return origin, (int(k1[1] - k0[1] + 1), int(k1[0] - k0[0] + 1))
