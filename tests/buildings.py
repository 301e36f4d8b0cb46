"""Synthetic buildings made of boxes (trimesh.creation.box) for occupancy and route tests."""

from __future__ import annotations

import functools

import numpy as np
import trimesh

from core import classes as C
from core.occupancy import OccupancyMap

HEIGHT = 2.8  # m, walls
THICK = 0.2  # m, walls and floor slab
BAND, MARGIN = (0.5, 2.2), 0.3  # m, the maps' flyable heights and margin


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo,
                                transform=trimesh.transformations.translation_matrix(
                                    (lo + hi) / 2))


def assemble(floors: list[tuple], solids: list[tuple]) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """One mesh of floor slabs (XY rectangles [x0, y0, x1, y1], top at z = 0, class floor)
    and solid blocks (XY rectangles, z 0..HEIGHT, class wall).

    Returns:
        vertices (V, 3), faces (F, 3), face_class (F,).
    """
    parts = [(_box((x0, y0, -THICK), (x1, y1, 0.0)), C.FLOOR) for x0, y0, x1, y1 in floors]
    parts += [(_box((x0, y0, 0.0), (x1, y1, HEIGHT)), C.WALL) for x0, y0, x1, y1 in solids]
    mesh = trimesh.util.concatenate([m for m, _ in parts])
    cls = np.concatenate([np.full(len(m.faces), c, np.uint8) for m, c in parts])
    return np.asarray(mesh.vertices), np.asarray(mesh.faces), cls


def ring(size_x: float = 10.0, size_y: float = 10.0, width: float = 2.0):
    """A square ring corridor ``width`` wide inside [0, size_x] x [0, size_y]: outer walls
    outside that rectangle, a solid inner block, one floor slab under everything."""
    X, Y, w, t = size_x, size_y, width, THICK
    walls = [(-t, -t, X + t, 0), (-t, Y, X + t, Y + t), (-t, 0, 0, Y), (X, 0, X + t, Y),
             (w, w, X - w, Y - w)]
    return assemble([(-t, -t, X + t, Y + t)], walls)


def ell(size_x: float = 10.0, size_y: float = 8.0, width: float = 2.0):
    """An L-shaped corridor: [0, size_x] x [0, width] and [0, width] x [0, size_y], walled,
    floor only under the L."""
    X, Y, w, t = size_x, size_y, width, THICK
    floors = [(-t, -t, X + t, w + t), (-t, -t, w + t, Y + t)]
    walls = [(-t, -t, X + t, 0), (-t, 0, 0, Y + t), (X, 0, X + t, w), (0, Y, w + t, Y + t),
             (w, w, X + t, w + t), (w, w + t, w + t, Y)]
    return assemble(floors, walls)


def ring_area(size_x: float, size_y: float, width: float, margin: float) -> float:
    """Free area of ``ring`` after the margin: the shrunk rectangle minus the grown inner block
    (its corners grown round)."""
    X, Y, w, m = size_x, size_y, width, margin
    return ((X - 2 * m) * (Y - 2 * m) - (X - 2 * w + 2 * m) * (Y - 2 * w + 2 * m)
            + 4 * (1 - np.pi / 4) * m**2)


def corridor_with_room(door: float = 0.9):
    """A 16 m x 2 m corridor along +X with a 4 m x 4 m room at its far end behind a door
    ``door`` wide (centred on the corridor)."""
    d0, d1 = 1.0 - door / 2, 1.0 + door / 2
    floors = [(-0.2, -0.2, 16.2, 2.2), (16.0, -1.2, 20.4, 3.2)]
    walls = [(-0.2, -0.2, 16.0, 0.0), (-0.2, 2.0, 16.0, 2.2), (-0.2, 0.0, 0.0, 2.0),
             (16.0, -1.2, 16.2, d0), (16.0, d1, 16.2, 3.2),
             (16.2, -1.2, 20.4, -1.0), (16.2, 3.0, 20.4, 3.2), (20.2, -1.0, 20.4, 3.0)]
    return assemble(floors, walls)


def with_ceiling(mesh, lo=(-1.0, -1.0), hi=(21.0, 21.0)):
    """A mesh plus a ceiling slab from z = HEIGHT up (class ceiling) over [lo, hi] in XY."""
    v, f, c = mesh
    cv, cf, _ = assemble([], [(*lo, *hi)])
    cv[:, 2] = np.where(cv[:, 2] > 0, HEIGHT + THICK, HEIGHT)
    return (np.concatenate([v, cv]), np.concatenate([f, cf + len(v)]),
            np.concatenate([c, np.full(len(cf), C.CEILING, np.uint8)]))


@functools.cache
def occupancy(name: str, cell: float = 0.05) -> OccupancyMap:
    """The map (BAND, MARGIN) of one of this module's buildings by name, built once: read it,
    do not change it."""
    builders = {"ring": ring, "ell": ell, "corridor_with_room": corridor_with_room}
    return OccupancyMap.from_mesh(*builders[name](), BAND, MARGIN, cell)
