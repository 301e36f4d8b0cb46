"""Procedural office corridor: the structural model as a classed triangle mesh.

The corridor is the union of axis-aligned free-space boxes (the main corridor, side
openings, door and window recesses). Its model is the boundary of that union: every grid
face between a free and a solid cell becomes two triangles with the normal pointing into the
free space. Building on one global grid leaves no T-junctions, so edges are shared exactly and
`datagen.mesh.edges` can find creases from mesh adjacency.

Frame: world, Z up, metres; corridor x in [-width/2, width/2], y in [0, length] (long axis +Y),
floor at z = 0. "left" is -X (looking along +Y), "right" is +X.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from core import classes as C
from core.config import as_config, check_positive
from core.dataset import World
from core.occupancy import OccupancyMap
from datagen.config import WorldConfig
from datagen.mesh.edges import extract_edges

#: m, the cell of the corridor's occupancy map (its box bounds are multiples of it, so the
#: free cells' centres span the boxes exactly).
FREE_CELL = 0.05

# Kinds of free-space boxes.
MAIN, OPENING, DOOR_RECESS, WINDOW_RECESS = range(4)


@dataclass(frozen=True)
class Box:
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    kind: int
    inward: tuple[int, int, int] = (0, 0, 0)  # normal of the wall the recess is cut into


@dataclass
class CorridorModel:
    """A built corridor: the World the localizer uses plus what rendering needs.

    face_box: (F,) index into boxes of the free box each face bounds.
    frame: (F,) bool, the frame faces of door and window recesses (``recess_faces``).
    lights: (L, 4) ceiling light rectangles [cx, cy, size_x, size_y] at z = height - 0.01.
    free_boxes: (B, 4) m [xmin, ymin, xmax, ymax], the camera's free space as boxes (the
        world's occupancy map ``world.free`` is made from them).
    """

    world: World
    boxes: list[Box]
    face_box: np.ndarray
    frame: np.ndarray
    lights: np.ndarray
    height: float
    free_boxes: np.ndarray


def _side_geometry(side: str, width: float, length: float) -> tuple[int, float, int]:
    """(axis, wall coordinate, sign pointing out of the corridor) for a wall side."""
    table = {"left": (0, -width / 2, -1), "right": (0, width / 2, 1),
             "back": (1, 0.0, -1), "front": (1, length, 1)}
    if side not in table:
        raise ValueError(f"world: unknown wall side {side!r}; use one of {sorted(table)}")
    return table[side]


def _recess(side: str, centre: float, w: float, z0: float, z1: float, depth: float,
            kind: int, width: float, length: float) -> Box:
    axis, wall, sign = _side_geometry(side, width, length)
    other = 1 - axis
    lo, hi = [0.0, 0.0, z0], [0.0, 0.0, z1]
    lo[axis], hi[axis] = sorted((wall, wall + sign * depth))
    lo[other], hi[other] = centre - w / 2, centre + w / 2
    inward = [0, 0, 0]
    inward[axis] = -sign
    return Box(tuple(lo), tuple(hi), kind, tuple(inward))


def _or(value: float | None, default: float) -> float:
    """A door's or window's own size, else the world's (``world.door`` / ``world.window``)."""
    return default if value is None else value


def corridor_boxes(spec: WorldConfig) -> list[Box]:
    """Free-space boxes of a corridor config (``WorldConfig``)."""
    check_positive(spec, ("length", "width", "height"), "world")
    L, W, H = spec.length, spec.width, spec.height
    boxes = [Box((-W / 2, 0.0, 0.0), (W / 2, L, H), MAIN)]
    d, win_size = spec.door, spec.window
    for i, door in enumerate(spec.doors):
        dw, dh = _or(door.width, d.width), _or(door.height, d.height)
        if dh >= H:
            raise ValueError(f"world.doors[{i}]: height {dh} must be below the ceiling {H}")
        boxes.append(_recess(door.side, door.at, dw, 0.0, dh, d.depth, DOOR_RECESS, W, L))
    for i, win in enumerate(spec.windows):
        ww, wh = _or(win.width, win_size.width), _or(win.height, win_size.height)
        sill = _or(win.sill, win_size.sill)
        if sill + wh >= H:
            raise ValueError(f"world.windows[{i}]: sill + height exceeds the ceiling {H}")
        boxes.append(_recess(win.side, win.at, ww, sill, sill + wh, win_size.depth,
                             WINDOW_RECESS, W, L))
    for op in spec.openings:
        boxes.append(_recess(op.side, op.at, op.width, 0.0, H, op.depth, OPENING, W, L))
    _check_along_walls(boxes[1:], W, L)
    return boxes


def _check_along_walls(features: list[Box], width: float, length: float) -> None:
    for i, b in enumerate(features):
        axis = 1 if b.inward[0] != 0 else 0  # the coordinate along the wall
        extent = length if axis == 1 else width
        span = (-width / 2, width / 2) if axis == 0 else (0.0, extent)
        if b.lo[axis] < span[0] - 1e-9 or b.hi[axis] > span[1] + 1e-9:
            raise ValueError(
                f"world: feature {i} (doors/windows/openings) spans "
                f"{b.lo[axis]:.2f}..{b.hi[axis]:.2f} along its wall, outside the wall "
                f"{span[0]:.2f}..{span[1]:.2f}; move its `at`")


def boundary_mesh(boxes: list[Box]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Triangulated boundary of a union of axis-aligned boxes, normals into free space.

    Returns:
        vertices (V, 3) metres; faces (F, 3) int64; face_cell_box (F,) box index of the free
        cell each face bounds; face_normal_axis (F, 2) [axis, sign] of the inward normal.
    """
    cuts = [np.unique(np.concatenate([[b.lo[a], b.hi[a]] for b in boxes]).round(9))
            for a in range(3)]
    centres = [(c[:-1] + c[1:]) / 2 for c in cuts]
    X, Y, Z = np.meshgrid(*centres, indexing="ij")
    owner = np.full(X.shape, -1, dtype=np.int64)
    for i in reversed(range(len(boxes))):  # lowest index wins
        b = boxes[i]
        inside = ((X > b.lo[0]) & (X < b.hi[0]) & (Y > b.lo[1]) & (Y < b.hi[1])
                  & (Z > b.lo[2]) & (Z < b.hi[2]))
        owner[inside] = i
    free = np.pad(owner >= 0, 1)  # solid outside the grid
    own = np.pad(owner, 1, constant_values=-1)
    shape = np.array([len(c) for c in cuts])  # grid points per axis
    faces_list, box_list, normal_list = [], [], []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        a = np.moveaxis(free, axis, 0)
        o = np.moveaxis(own, axis, 0)
        for sign in (+1, -1):
            # A face with inward normal +axis: solid at index i, free at i + 1 (sign +1).
            if sign > 0:
                mask = ~a[:-1] & a[1:]
                cell_box = o[1:][mask]
            else:
                mask = a[:-1] & ~a[1:]
                cell_box = o[:-1][mask]
            # Padded coords: the plane index (a grid cut), then the other two axes (in
            # increasing axis order) as cell index + 1.
            idx = np.argwhere(mask)
            others = [ax for ax in range(3) if ax != axis]
            cell = {axis: idx[:, 0], others[0]: idx[:, 1] - 1, others[1]: idx[:, 2] - 1}
            quad = []
            for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                g = {axis: cell[axis], u: cell[u] + du, v: cell[v] + dv}
                quad.append(np.ravel_multi_index((g[0], g[1], g[2]), shape))
            quad = np.stack(quad, axis=1)  # counter-clockwise around +axis in (u, v)
            if sign < 0:
                quad = quad[:, ::-1]
            faces_list.append(np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]))
            box_list.append(np.concatenate([cell_box, cell_box]))
            normal_list.append(np.tile([axis, sign], (2 * len(quad), 1)))
    faces = np.concatenate(faces_list)
    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    gi = np.stack(np.unravel_index(used, shape), axis=1)
    vertices = np.stack([cuts[a][gi[:, a]] for a in range(3)], axis=1)
    return vertices, faces, np.concatenate(box_list), np.concatenate(normal_list)


def recess_faces(boxes: list[Box], face_box: np.ndarray,
                 normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The faces of door and window recesses, by part.

    Args:
        face_box: (F,) box index; normal: (F, 2) [axis, sign] of the inward normal.

    Returns:
        back (F,) bool: the recess's back (the door leaf, the glass);
        frame (F,) bool: its jambs, head and, for a window, its sill (a door recess's floor is
        floor, not frame).
    """
    kind = np.array([b.kind for b in boxes])[face_box]
    inward = np.array([b.inward for b in boxes])[face_box]  # (F, 3)
    axis, sign = normal[:, 0], normal[:, 1]
    recess = (kind == DOOR_RECESS) | (kind == WINDOW_RECESS)
    back = recess & (inward[np.arange(len(axis)), axis] == sign)
    door_floor = (kind == DOOR_RECESS) & (axis == 2) & (sign > 0)
    return back, recess & ~back & ~door_floor


def classify_faces(boxes: list[Box], face_box: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Semantic class of each boundary face from its box kind and inward normal.

    A recess's frame faces (``recess_faces``: jambs, head, sill) take the door's or window's
    class, so the opening's class boundary is the recess's outer edge, a crease seen from
    every side (docs/datagen.md).

    Args:
        face_box: (F,) box index; normal: (F, 2) [axis, sign] of the inward normal.

    Returns:
        (F,) uint8 class ids (floor, wall, ceiling, door, window).
    """
    kind = np.array([b.kind for b in boxes])[face_box]
    axis, sign = normal[:, 0], normal[:, 1]
    cls = np.full(len(face_box), C.WALL, dtype=np.uint8)
    up, down = (axis == 2) & (sign > 0), (axis == 2) & (sign < 0)
    recess = (kind == DOOR_RECESS) | (kind == WINDOW_RECESS)
    cls[up & ~(kind == WINDOW_RECESS)] = C.FLOOR
    cls[down & ~recess] = C.CEILING
    back, frame = recess_faces(boxes, face_box, normal)
    opening = back | frame
    for k, c in ((DOOR_RECESS, C.DOOR), (WINDOW_RECESS, C.WINDOW)):
        cls[(kind == k) & opening] = c
    return cls


def free_space(spec: WorldConfig, boxes: list[Box]) -> tuple[np.ndarray, np.ndarray]:
    """XY boxes where a camera may fly (main corridor and openings shrunk by the margin).

    Returns:
        boxes (B, 4) [xmin, ymin, xmax, ymax]; z_range (2,).
    """
    m = spec.camera_margin
    out = []
    for b in boxes:
        if b.kind in (MAIN, OPENING):
            lo = [b.lo[0] + m, b.lo[1] + m]
            hi = [b.hi[0] - m, b.hi[1] - m]
            if b.kind == OPENING:  # joins the corridor: no margin on the open side
                axis = int(np.flatnonzero(b.inward)[0])
                if b.inward[axis] > 0:
                    hi[axis] = b.hi[axis] + m
                else:
                    lo[axis] = b.lo[axis] - m
            if hi[0] > lo[0] and hi[1] > lo[1]:
                out.append([lo[0], lo[1], hi[0], hi[1]])
    z = np.array(spec.z_range, dtype=np.float64)
    H = spec.height
    if not (0 <= z[0] < z[1] <= H):
        raise ValueError(f"world.z_range {z.tolist()} must satisfy 0 <= lo < hi <= height {H}")
    if not out:
        raise ValueError(f"world.camera_margin {m} leaves no free space; make it smaller")
    return np.array(out), z


def light_rects(spec: WorldConfig) -> np.ndarray:
    """(L, 4) ceiling light panels [cx, cy, size_x, size_y], evenly spaced along the corridor."""
    n = spec.lights.count
    L = spec.length
    ys = (np.arange(n) + 0.5) * L / max(n, 1)
    sx, sy = spec.lights.size
    return np.array([[0.0, y, float(sx), float(sy)] for y in ys]).reshape(-1, 4)


def build_world(spec: WorldConfig | Mapping | None = None) -> CorridorModel:
    """Build the corridor model from a world config (``WorldConfig``, or a mapping of the
    keys that differ from its defaults; None: the defaults)."""
    spec = as_config(WorldConfig, spec, "world")
    boxes = corridor_boxes(spec)
    vertices, faces, face_box, normal = boundary_mesh(boxes)
    face_class = classify_faces(boxes, face_box, normal)
    segments, seg_classes, crease, normals = extract_edges(vertices, faces, face_class,
                                                           spec.crease_deg)
    fboxes, z_range = free_space(spec, boxes)
    free = OccupancyMap.from_boxes(fboxes, z_range, FREE_CELL, spec.camera_margin)
    lights = light_rects(spec)
    info = {
        "name": spec.name, "length": float(spec.length), "width": float(spec.width),
        "height": float(spec.height),
        "free_space": {"boxes": fboxes.tolist(), "z_range": z_range.tolist(),
                       "cell": FREE_CELL, "margin": float(spec.camera_margin),
                       "area_m2": round(free.area, 3)},
        "lights": lights.tolist(),
        "num_faces": int(len(faces)), "num_edges": int(len(segments)),
    }
    world = World(vertices=vertices, faces=faces, face_class=face_class, segments=segments,
                  segment_classes=seg_classes, crease_deg=crease, free=free, info=info,
                  normals=normals)
    frame = recess_faces(boxes, face_box, normal)[1]
    return CorridorModel(world, boxes, face_box, frame, lights, spec.height, fboxes)
