"""Built-in objects the map lacks (``realism.map.builtins``): cabinets and pillars, boxes
standing on the floor against a wall, off every flight's camera path.

The flights' renders show them and the map (``datagen.realism.map_error.make_map``) does not;
``with_builtins`` adds them to the truth written to ``world_truth/``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core import classes as C
from core.dataset import World
from core.imaging.realism import MapErrorConfig
from core.occupancy import OccupancyMap
from datagen.mesh.edges import extract_edges
from datagen.realism.map_error import OPENING_KINDS, TRIES
from datagen.worlds.scene import TEXTURE_EXTENT, Surface, box_uv, ceiling_above


@dataclass(frozen=True)
class Builtin:
    """An unmodelled built-in object: a box standing on the floor against a wall.

    kind: cabinet or pillar; centre (2,) m of its footprint; yaw rad of its +x axis (pointing
    out of the wall); size (3,) m along x (out of the wall), y (along it), z; base z m.
    """

    kind: str
    centre: tuple[float, float]
    yaw: float
    size: tuple[float, float, float]
    base: float

    def corners(self, behind: float = 0.0, inset: float = 0.0) -> np.ndarray:
        """(4, 2) m footprint corners, counter-clockwise seen from above (its back moved
        ``behind`` m further back, its sides ``inset`` m in)."""
        hx, hy = self.size[0] / 2, self.size[1] / 2 - inset
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array([[-hx - behind, -hy], [hx, -hy], [hx, hy], [-hx - behind, hy]])
        return local @ np.array([[c, s], [-s, c]]) + np.asarray(self.centre)

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """Closed box: (8, 3) vertices m, (12, 3) faces wound outwards."""
        xy = self.corners()
        z0, z1 = self.base, self.base + self.size[2]
        v = np.concatenate([np.c_[xy, np.full(4, z0)], np.c_[xy, np.full(4, z1)]])
        f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7],  # bottom, top
                      [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                      [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
        return v, f

    def footprint_circle(self) -> np.ndarray:
        """(3,) x, y, radius m of the circle around its footprint (a keep-out for
        distractors)."""
        return np.array([*self.centre, math.hypot(self.size[0], self.size[1]) / 2])

    def as_json(self) -> dict:
        return {"kind": self.kind, "centre": [round(float(x), 4) for x in self.centre],
                "yaw_deg": round(math.degrees(self.yaw), 3),
                "size_m": [round(float(x), 4) for x in self.size],
                "base_z": round(float(self.base), 4)}


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(P,) m from each 2D point to the nearest of the segments a[k]-b[k] ((K, 2) each)."""
    d = b - a
    t = np.clip(np.einsum("pkj,kj->pk", points[:, None] - a, d)
                / np.maximum(np.einsum("kj,kj->k", d, d), 1e-18), 0, 1)
    near = a + t[..., None] * d
    return np.linalg.norm(points[:, None] - near, axis=-1).min(axis=1)


def place_builtins(c: MapErrorConfig, floor: OccupancyMap, paths: list[np.ndarray],
                   vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                   floor_z: float, rng: np.random.Generator) -> list[Builtin]:
    """``c.builtins`` boxes against walls: a floor cell next to a wall drawn, the box's back
    put on the wall (along ``floor``'s clearance gradient), kept where its front is on the
    floor and a wall is behind the whole of its back (5 cm behind it is off the floor: not
    across a corner or an opening), no door or window within 0.15 m behind it or over it
    (below its top), clear of the boxes placed and ``c.builtin_clearance_m`` from every camera
    path.

    Args:
        floor: where things may stand (no margin; Site.floor).
        paths: (N, 2) m camera xy of each flight.
        vertices, faces, face_class: the true mesh (a pillar reaches its ceiling).
        floor_z: m, the floor's height.

    Returns:
        The placed objects (fewer than asked where none fit in ``TRIES``).
    """
    paths = [np.asarray(p, np.float64).reshape(-1, 2) for p in paths]
    path = np.concatenate(paths) if paths else np.zeros((0, 2))
    seg_a = np.concatenate([p[:-1] if len(p) > 1 else p for p in paths]) if paths else path
    seg_b = np.concatenate([p[1:] if len(p) > 1 else p for p in paths]) if paths else path
    rows, cols = np.nonzero(floor.free)
    xy_cells = floor.centres(np.stack([rows, cols]))
    near_wall = floor.clearance[rows, cols] <= 1.5 * floor.cell
    cells = xy_cells[near_wall]
    grad_r, grad_c = np.gradient(floor.clearance.astype(np.float64))
    opening = np.isin(face_class, list(OPENING_KINDS.values()))
    tri = vertices[faces[opening]]
    openings = np.concatenate([tri.reshape(-1, 3), tri.mean(axis=1)])  # corners and centres
    out: list[Builtin] = []
    for _ in range(c.builtins):
        kind = str(c.builtin_kinds[rng.integers(len(c.builtin_kinds))])
        for _try in range(TRIES):
            if not len(cells):
                break
            at = cells[rng.integers(len(cells))]
            rc, _ = floor.cell_of(at[None])
            r, k = int(rc[0, 0]), int(rc[1, 0])
            away = np.array([grad_c[r, k], grad_r[r, k]])
            if np.linalg.norm(away) < 1e-9:
                continue
            away /= np.linalg.norm(away)
            # the wall: where the clearance runs out behind the cell
            wall = at - (float(floor.clearance[r, k]) + floor.cell / 2) * away
            yaw = math.atan2(away[1], away[0])
            if kind == "cabinet":
                along, out_of, height = c.builtin_cabinet_m
            else:
                along, out_of = c.builtin_pillar_m
                top = ceiling_above(vertices, faces, np.array([[*wall + 0.5 * out_of * away,
                                                                floor_z + 0.1]]))[0]
                if not np.isfinite(top):
                    continue
                height = float(top - floor_z)
            b = Builtin(kind, tuple(wall + away * out_of / 2), yaw, (out_of, along, height),
                        floor_z)
            xy = b.corners()
            front = np.array([xy[1], xy[2], (xy[1] + xy[2]) / 2])
            behind = np.array([xy[0], xy[3], (xy[0] + xy[3]) / 2]) - 0.05 * away
            if not floor.contains(front).all() or floor.contains(behind).any():
                continue  # its front on the floor, a wall behind the whole of its back
            low = openings[openings[:, 2] < b.base + b.size[2], :2]
            if len(low) and _inside(low, b.corners(behind=0.15, inset=0.01)).any():
                continue  # not in front of a door or window
            edge = np.concatenate([xy, (xy + np.roll(xy, -1, 0)) / 2])
            if len(path) and _segment_distance(edge, seg_a, seg_b).min() < c.builtin_clearance_m:
                continue
            if len(path) and _inside(path, xy).any():
                continue
            if any(_overlap(xy, o.corners()) for o in out):
                continue
            out.append(b)
            break
    return out


def _inside(points: np.ndarray, quad: np.ndarray) -> np.ndarray:
    """(P,) bool: points inside a convex counter-clockwise (4, 2) polygon."""
    e = np.roll(quad, -1, 0) - quad
    d = points[:, None] - quad
    return np.all(e[None, :, 0] * d[..., 1] - e[None, :, 1] * d[..., 0] >= 0, axis=1)


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex quads overlap (separating axes)."""
    for quad in (a, b):
        e = np.roll(quad, -1, 0) - quad
        normals = np.stack([e[:, 1], -e[:, 0]], 1)
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(0) < pb.min(0)) | (pb.max(0) < pa.min(0))):
            return False
    return True


def builtin_surfaces(builtins: list[Builtin]) -> list[Surface]:
    """The built-in objects as scene surfaces: class wall, the wall's texture
    (``scene.box_uv``, v from the object's base)."""
    out = []
    for i, b in enumerate(builtins):
        v, f = b.mesh()
        tri = v[f]
        uv = box_uv(tri, TEXTURE_EXTENT["wall"], b.base)
        out.append(Surface(f"builtin{i}", C.WALL, "wall", tri.reshape(-1, 3), uv.reshape(-1, 2)))
    return out


def with_builtins(world: World, builtins: list[Builtin], crease_deg: float) -> World:
    """The world with the built-in boxes added to its mesh (class wall) and their edges
    (``extract_edges`` of each box alone) to its model edges."""
    if not builtins:
        return world
    V, F, K = [world.vertices], [world.faces], [world.face_class]
    S, SC, CR = [world.segments], [world.segment_classes], [world.crease_deg]
    n = len(world.vertices)
    for b in builtins:
        v, f = b.mesh()
        V.append(v)
        F.append(f + n)
        K.append(np.full(len(f), C.WALL, dtype=world.face_class.dtype))
        n += len(v)
        s, sc, cr = extract_edges(v, f, np.full(len(f), C.WALL, np.uint8), crease_deg)[:3]
        S.append(s)
        SC.append(sc.astype(world.segment_classes.dtype))
        CR.append(cr)
    info = {**world.info, "builtins": [b.as_json() for b in builtins]}
    S = np.concatenate(S)
    normals = None
    if world.normals is not None:
        normals = np.full((len(S), 2, 3), np.nan)
        normals[:len(world.normals)] = world.normals
    return World(np.concatenate(V), np.concatenate(F), np.concatenate(K), S,
                 np.concatenate(SC), np.concatenate(CR), world.free, info, normals)
