"""What each place of a floor sees: the distance to the floor's boundary along every azimuth.

The global search (``global_search``) compares a frame with every pose of the free space. Its
measurement is the line where the floor meets a wall, a door or a window: in the frame, the
floor pixels with one of those classes right above them; in the model, the world's edge
segments between the floor and one of those classes. The table holds, for every cell of a grid
over the free space and every one of R azimuths, the horizontal distance from the cell's
centre to the first such segment (``RayTable``). From a camera at height h above the floor a
boundary point at distance D is seen ``atan(h / D)`` below the horizon; a frame gives, per
azimuth relative to the camera's heading, that angle's tangent (``FloorBoundary``), so a pose
hypothesis is scored with one table look-up per azimuth (as F3Loc / UnLoc score a floor plan's
ray distances, with the label boundary in place of a learned depth).

Units: metres, radians; azimuths counter-clockwise from the world x axis, bin r covering
``[(r - 0.5), (r + 0.5)) * 2 pi / R``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from core import classes as C
from core.dataset import Camera, World
from core.occupancy import OccupancyMap

#: Classes whose boundary with the floor is measured (in the model and in the frame): the
#: structural surfaces that stand on the floor.
STANDING = (C.WALL, C.DOOR, C.WINDOW)


class SearchUnavailable(ValueError):
    """The global search cannot run on this building (or inside this start hint): its model
    holds nothing the search measures, or its grid no pose. The ``Localizer`` then starts
    with the uniform particle set (``global_search.start_search``)."""


def floor_boundary_segments(world: World) -> tuple[np.ndarray, np.ndarray]:
    """(M, 2, 2) xy (m) of the world's edge segments between the floor and a standing class
    (``STANDING``) and (M,) uint8 that class; ``SearchUnavailable`` naming the world when
    there are none (walls on a slab of their own, sharing no vertex with the floor)."""
    seg = np.asarray(world.segments, dtype=np.float64).reshape(-1, 2, 3)
    sc = np.asarray(world.segment_classes).reshape(-1, 2)
    floor = sc == C.FLOOR
    keep = (floor[:, 0] & np.isin(sc[:, 1], STANDING)) | (floor[:, 1] & np.isin(sc[:, 0],
                                                                                 STANDING))
    if not keep.any():
        raise SearchUnavailable(f"world {world.info.get('name', '?')!r} has no edge segment "
                                "between the floor and a wall, door or window "
                                "(world/edges.npz): the global search has nothing to match")
    other = np.where(floor[:, 0], sc[:, 1], sc[:, 0])
    return seg[keep][:, :, :2], other[keep].astype(np.uint8)


@dataclass
class RayTable:
    """Distances to the floor's boundary from the cells of a grid, along R azimuths.

    Attributes:
        dist: (Ny, Nx, R) float16 m, from each cell centre along azimuth bin r (``max_range``
            where nothing is hit; NaN for cells not in the table).
        kind: (Ny, Nx, R) uint8 the class standing where the ray meets the boundary (wall,
            door, window; 0 where nothing is hit or not in the table).
        valid: (Ny, Nx) bool, the cells the table holds (the free space, grown by ``grow``).
        origin: (2,) x, y (m) of cell [0, 0]'s lower-left corner.
        cell: m, cell size.
        max_range: m, the longest distance measured.
    """

    dist: np.ndarray
    kind: np.ndarray
    valid: np.ndarray
    origin: np.ndarray
    cell: float
    max_range: float

    @property
    def rays(self) -> int:
        """R, the azimuth bins."""
        return self.dist.shape[2]

    @classmethod
    def build(cls, world: World, cell: float = 0.25, rays: int = 180, max_range: float = 30.0,
              grow: float = 0.5, raster: float = 0.05) -> RayTable:
        """The table of ``world`` over its free space grown by ``grow`` m.

        Args:
            world: the model (``floor_boundary_segments``) and its free space.
            cell: m, the table's cell size.
            rays: R azimuth bins.
            max_range: m, rays stop there.
            grow: m, cells this far outside the free space are in the table too.
            raster: m, the boundary is drawn on a grid this fine and the rays marched by its
                distance transform (sphere tracing).
        """
        seg, seg_class = floor_boundary_segments(world)
        free: OccupancyMap = world.free
        lo = free.origin - grow - cell
        hi = free.origin + np.array(free.shape[::-1]) * free.cell + grow + cell
        nx, ny = (np.ceil((hi - lo) / cell)).astype(int)
        centres = lo + (np.stack(np.meshgrid(np.arange(nx), np.arange(ny)), -1) + 0.5) * cell
        valid = (free.outside_distance(centres.reshape(-1, 2)) <= grow).reshape(ny, nx)
        field, f_origin, nearest = _boundary_field(seg, seg_class, raster)
        pts = centres[valid]
        dist = np.full((ny, nx, rays), np.nan, dtype=np.float16)
        kind = np.zeros((ny, nx, rays), dtype=np.uint8)
        d = march(pts, rays, field, f_origin, raster, max_range)
        dist[valid] = d.astype(np.float16)
        ang = np.arange(rays) * (2 * np.pi / rays)
        hit = pts[:, None] + d[..., None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        ij = np.floor((hit - f_origin) / raster).astype(np.int64)
        ij[..., 0] = np.clip(ij[..., 0], 0, nearest.shape[1] - 1)
        ij[..., 1] = np.clip(ij[..., 1], 0, nearest.shape[0] - 1)
        kind[valid] = np.where(d < max_range, nearest[ij[..., 1], ij[..., 0]], 0)
        return cls(dist, kind, valid, lo, float(cell), float(max_range))

    def cells(self, xy: np.ndarray) -> np.ndarray:
        """(N,) int64 flat index of the cell of each point (N, 2); -1 outside the table."""
        ij = np.floor((np.asarray(xy) - self.origin) / self.cell).astype(np.int64)
        ny, nx = self.valid.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)
        flat = np.where(inside, ij[:, 1] * nx + ij[:, 0], 0)
        return np.where(inside & self.valid.ravel()[flat], flat, -1)

    def centres(self) -> np.ndarray:
        """(V, 2) centres of the valid cells, row-major."""
        iy, ix = np.nonzero(self.valid)
        return self.origin + (np.column_stack([ix, iy]) + 0.5) * self.cell


def _boundary_field(seg: np.ndarray, seg_class: np.ndarray, raster: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance field (m, (Hy, Hx) float32) to the boundary segments (M, 2, 2) drawn on a
    ``raster`` grid, its origin (2,) and (Hy, Hx) uint8 the class (``seg_class`` (M,)) of the
    segment nearest each pixel."""
    pts = seg.reshape(-1, 2)
    lo = pts.min(axis=0) - 2 * raster
    hi = pts.max(axis=0) + 2 * raster
    nx, ny = np.ceil((hi - lo) / raster).astype(int) + 1
    img = np.zeros((ny, nx), dtype=np.uint8)
    px = np.round((seg - lo) / raster).astype(np.int32)
    for (a, b), c in zip(px, seg_class, strict=True):  # one cv2 call per segment, at build
        cv2.line(img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), int(c), 1)
    dist, (iy, ix) = ndimage.distance_transform_edt(img == 0, return_indices=True)
    return dist.astype(np.float32) * raster, lo, img[iy, ix]


def march(points: np.ndarray, rays: int, field: np.ndarray, f_origin: np.ndarray,
          raster: float, max_range: float, max_steps: int = 200) -> np.ndarray:
    """(P, R) float32 m from each point (P, 2) along R azimuths to the boundary of the distance
    ``field``: sphere tracing, each ray advancing by the field's value until within one raster
    cell of the boundary; rays leaving the field or passing ``max_range`` read ``max_range``."""
    ang = np.arange(rays) * (2 * np.pi / rays)
    d = np.stack([np.cos(ang), np.sin(ang)], -1)  # (R, 2)
    P = len(points)
    t = np.zeros(P * rays, dtype=np.float32)
    o = np.repeat(points, rays, axis=0).astype(np.float32)
    dd = np.tile(d, (P, 1)).astype(np.float32)
    live = np.arange(P * rays)
    ny, nx = field.shape
    for _ in range(max_steps):
        if not len(live):
            break
        q = (o[live] + dd[live] * t[live, None] - f_origin.astype(np.float32)) / raster
        ix, iy = np.floor(q[:, 0]).astype(np.int64), np.floor(q[:, 1]).astype(np.int64)
        out = (ix < 0) | (ix >= nx) | (iy < 0) | (iy >= ny)
        step = field[np.clip(iy, 0, ny - 1), np.clip(ix, 0, nx - 1)]
        hit = ~out & (step <= raster)
        t[live[out]] = max_range
        t[live[~out & ~hit]] += np.maximum(step[~out & ~hit] - 0.5 * raster, 0.5 * raster)
        far = t[live] >= max_range
        t[live[far]] = max_range
        live = live[~(out | hit | far)]
    return np.minimum(t, max_range).reshape(P, rays)


@dataclass
class FloorBoundary:
    """Where a frame sees the floor meet a standing surface, per azimuth bin.

    Attributes:
        offsets: (J,) float64 radians, azimuth of each observed bin relative to the camera's
            heading (the body's yaw), counter-clockwise.
        tan: (J,) float64 tangent of the boundary's angle below the horizon (> 0) in that bin
            (the largest of the bin's pixels: the nearest boundary).
        kind: (J,) uint8 the class above the floor at that pixel (``STANDING``).
        camera: (3,) the camera centre relative to the body in its heading frame (x forward,
            y left, z up), m.
    """

    offsets: np.ndarray
    tan: np.ndarray
    kind: np.ndarray
    camera: np.ndarray

    def __len__(self) -> int:
        return len(self.tan)

    def take(self, keep: np.ndarray) -> FloorBoundary:
        """The bins ``keep`` (indices or a mask)."""
        return FloorBoundary(self.offsets[keep], self.tan[keep], self.kind[keep], self.camera)


def floor_boundary(labels: np.ndarray, camera: Camera, tilt: np.ndarray | None, rays: int,
                   stride: int = 1) -> FloorBoundary:
    """The floor boundary of a label image (``FloorBoundary``).

    A pixel is on it when it is floor and the pixel right above it (``stride`` rows up, image
    columns every ``stride``) is a standing class (``STANDING``); its ray, turned by the IMU's
    roll and pitch (``tilt``, (3, 3) or None: level) and the camera mount, gives the azimuth and
    the tangent below the horizon; pixels are binned by azimuth into the table's R bins.

    Args:
        labels: (H, W) uint8 class ids (``core.classes``).
        camera: K, size, body_from_cam.
        tilt: (3, 3) roll/pitch rotation of the body (``projection.tilt_from_pose``).
        rays: R, the azimuth bins (``RayTable.rays``).
        stride: pixel step of the search.
    """
    lab = np.asarray(labels)[::stride, ::stride]
    floor = lab[1:] == C.FLOOR
    above = np.isin(lab[:-1], STANDING)
    vs, us = np.nonzero(floor & above)
    R_hb = (np.eye(3) if tilt is None else np.asarray(tilt, dtype=np.float64)) \
        @ np.asarray(camera.body_from_cam, dtype=np.float64)[:3, :3]
    cam = (np.eye(3) if tilt is None else np.asarray(tilt, dtype=np.float64)) \
        @ np.asarray(camera.body_from_cam, dtype=np.float64)[:3, 3]
    if not len(vs):
        return FloorBoundary(np.zeros(0), np.zeros(0), np.zeros(0, np.uint8), cam)
    uv1 = np.column_stack([us * stride, (vs + 1) * stride, np.ones(len(us))]).astype(np.float64)
    d = uv1 @ np.linalg.inv(camera.K).T @ R_hb.T  # (n, 3) rays in the heading frame
    horiz = np.hypot(d[:, 0], d[:, 1])
    tan = -d[:, 2] / np.maximum(horiz, 1e-9)
    down = tan > 1e-3
    width = 2 * np.pi / rays
    b = np.rint(np.arctan2(d[down, 1], d[down, 0]) / width).astype(np.int64)
    tan, kind = tan[down], lab[:-1][vs[down], us[down]]
    if not len(tan):  # floor meets a wall only above the horizon (a SegNet's stray labels)
        return FloorBoundary(np.zeros(0), np.zeros(0), np.zeros(0, np.uint8), cam)
    order = np.lexsort((tan, b))  # by bin, then tan: each bin's last is its nearest boundary
    b, tan, kind = b[order], tan[order], kind[order]
    last = np.flatnonzero(np.r_[b[1:] != b[:-1], True])
    return FloorBoundary(b[last] * width, tan[last], kind[last].astype(np.uint8), cam)
