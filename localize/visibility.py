"""Occlusion of model edge samples, precomputed on a 3D grid of camera positions.

Whether a 3D point is hidden behind other geometry depends on where the camera is, not on
where it looks. So visibility is ray-cast once per world from the centre of every cell of a
regular grid over the flyable space to every edge sample, and a particle looks up the row of
the grid cell nearest to its camera centre: an (N, P) boolean gather, no rendering per particle.
A sample counts as visible when nothing is hit on the ray from the cell centre to within
``eps`` of the sample (the sample lies on the surface itself).

Rays go through Mitsuba's ``ray_test`` (llvm variant, millions of rays per second); with the
scalar fallback variant trimesh's ray intersector does it, slower. The grid is cached in an
``.npz`` keyed by a hash of the mesh, the samples and the grid settings.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.atomic import atomic_write
from core.dataset import World

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class VisibilityGrid:
    """Visibility of P samples from the cells of a regular 3D grid.

    Attributes:
        origin: (3,) centre of cell (0, 0, 0), metres.
        cell: (3,) cell size per axis, metres.
        shape: (3,) cells per axis.
        visible: (G, P) bool, G = prod(shape), C order (x slowest).
    """

    origin: np.ndarray
    cell: np.ndarray
    shape: np.ndarray
    visible: np.ndarray

    def cell_index(self, positions: np.ndarray) -> np.ndarray:
        """Flat index (N,) of the cell nearest to each position (N, 3), clamped to the grid."""
        ijk = np.rint((np.asarray(positions) - self.origin) / self.cell).astype(np.int64)
        ijk = np.clip(ijk, 0, self.shape - 1)
        return np.ravel_multi_index(tuple(ijk.T), tuple(self.shape))

    def lookup(self, positions: np.ndarray) -> np.ndarray:
        """Visibility (N, P) bool of every sample from camera centres (N, 3), metres."""
        return self.visible[self.cell_index(positions)]

    def select(self, cols: np.ndarray) -> VisibilityGrid:
        """The grid for a subset of the samples (columns ``cols``)."""
        return VisibilityGrid(self.origin, self.cell, self.shape,
                              np.ascontiguousarray(self.visible[:, cols]))

    def centres(self) -> np.ndarray:
        """(G, 3) cell centres in flat-index order."""
        axes = [self.origin[a] + self.cell[a] * np.arange(self.shape[a]) for a in range(3)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def grid_layout(world: World, cell_xy: float, cell_z: float,
                pad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid over the bounding box of the free cells' centres, padded by ``pad`` metres.

    Returns:
        origin (3,), cell (3,), shape (3,) int64.
    """
    if cell_xy <= 0 or cell_z <= 0:
        raise ValueError(f"visibility cell sizes must be positive, got {cell_xy}, {cell_z}")
    b, z = world.free.free_bounds, world.z_range
    lo = np.array([b[0] - pad, b[1] - pad, z[0] - pad])
    hi = np.array([b[2] + pad, b[3] + pad, z[1] + pad])
    cell = np.array([cell_xy, cell_xy, cell_z], dtype=np.float64)
    shape = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1) + 1
    origin = (lo + hi) / 2 - cell * (shape - 1) / 2
    return origin, cell, shape


def _mitsuba_scene(world: World):
    import mitsuba as mi

    mesh = mi.Mesh("model", len(world.vertices), len(world.faces), has_vertex_normals=False,
                   has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.ascontiguousarray(
        world.vertices, dtype=np.float32).ravel())
    params["faces"] = mi.UInt32(np.ascontiguousarray(world.faces, dtype=np.uint32).ravel())
    params.update()
    return mi, mi.load_dict({"type": "scene", "model": mesh})


def occluded(world: World, origins: np.ndarray, targets: np.ndarray, eps: float = 0.02,
             variant: str = "auto", chunk: int = 2_000_000) -> np.ndarray:
    """Whether the straight line from each origin to each target hits the mesh first.

    Args:
        world: the model (vertices, faces).
        origins: (G, 3) ray origins, metres.
        targets: (P, 3) points, metres.
        eps: hits within this distance of the target do not count (the target's own surface).
        variant: Mitsuba variant (``auto``: llvm if it works, else the scalar fallback, for
            which trimesh casts the rays).
        chunk: rays per batch.

    Returns:
        (G, P) bool, True where the target is hidden from the origin.
    """
    from core.variant import choose_variant

    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    targets = np.asarray(targets, dtype=np.float64).reshape(-1, 3)
    G, P = len(origins), len(targets)
    out = np.zeros((G, P), dtype=bool)
    if G == 0 or P == 0:
        return out
    use_mitsuba = choose_variant(variant) != "scalar_rgb"
    if use_mitsuba:
        mi, scene = _mitsuba_scene(world)
    else:
        import trimesh

        log.warning("visibility: casting rays with trimesh (no llvm Mitsuba variant); slow")
        tm = trimesh.Trimesh(world.vertices, world.faces, process=False)
    rows = max(1, chunk // P)
    for g0 in range(0, G, rows):
        o = np.repeat(origins[g0:g0 + rows], P, axis=0)
        d = np.tile(targets, (len(o) // P, 1)) - o
        dist = np.linalg.norm(d, axis=1)
        d = d / np.maximum(dist, 1e-12)[:, None]
        maxt = np.maximum(dist - eps, 0.0)
        if use_mitsuba:
            ray = mi.Ray3f(mi.Point3f(*[np.ascontiguousarray(o[:, i], dtype=np.float32)
                                        for i in range(3)]),
                           mi.Vector3f(*[np.ascontiguousarray(d[:, i], dtype=np.float32)
                                         for i in range(3)]))
            ray.maxt = mi.Float(maxt.astype(np.float32))
            hit = np.asarray(scene.ray_test(ray), dtype=bool)
        else:
            loc, idx_ray, _ = tm.ray.intersects_location(o, d, multiple_hits=True)
            hit = np.zeros(len(o), dtype=bool)
            if len(idx_ray):
                t = np.einsum("ij,ij->i", loc - o[idx_ray], d[idx_ray])
                hit[idx_ray[(t > 1e-6) & (t < maxt[idx_ray])]] = True
        out[g0:g0 + rows] = (hit & (dist > eps)).reshape(-1, P)
    return out


def build_visibility_grid(world: World, points: np.ndarray, cell_xy: float = 0.2,
                          cell_z: float = 0.25, pad: float = 0.3, eps: float = 0.02,
                          variant: str = "auto") -> VisibilityGrid:
    """Ray-cast the visibility of sample points from every grid cell centre.

    Args:
        world: the model; the grid covers its free cells x z_range, padded by ``pad`` metres.
        points: (P, 3) edge samples, metres.
        cell_xy, cell_z: cell sizes, metres.
        eps: tolerance at the sample (metres).
        variant: Mitsuba variant, see ``occluded``.
    """
    origin, cell, shape = grid_layout(world, cell_xy, cell_z, pad)
    grid = VisibilityGrid(origin, cell, shape, np.zeros((0, len(points)), dtype=bool))
    hidden = occluded(world, grid.centres(), points, eps=eps, variant=variant)
    return VisibilityGrid(origin, cell, shape, ~hidden)


def cache_key(world: World, points: np.ndarray, settings: dict) -> str:
    """Hash (16 hex digits) of the mesh, the sample points and the grid settings."""
    h = hashlib.sha256()
    for a in (world.vertices, world.faces, world.free.free_bounds, world.z_range, points):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(repr(sorted(settings.items())).encode())
    return h.hexdigest()[:16]


def load_or_build(world: World, points: np.ndarray, cache_dir: str | Path | None,
                  cell_xy: float = 0.2, cell_z: float = 0.25, pad: float = 0.3,
                  eps: float = 0.02, variant: str = "auto") -> VisibilityGrid:
    """The visibility grid from ``cache_dir/visibility_<key>.npz``, built and saved if missing."""
    settings = {"cell_xy": cell_xy, "cell_z": cell_z, "pad": pad, "eps": eps}
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"visibility_{cache_key(world, points, settings)}.npz"
        if path.is_file():
            with np.load(path) as f:
                P = len(points)
                vis = np.unpackbits(f["packed"], axis=1, count=P).astype(bool)
                return VisibilityGrid(f["origin"], f["cell"], f["shape"], vis)
    grid = build_visibility_grid(world, points, cell_xy, cell_z, pad, eps, variant)
    if path is not None:
        atomic_write(path, lambda p: np.savez_compressed(
            p, origin=grid.origin, cell=grid.cell, shape=grid.shape,
            packed=np.packbits(grid.visible, axis=1)))
    return grid
