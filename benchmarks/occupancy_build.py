"""Build time and memory of an occupancy map for a hospital-sized floor, and route planning.

Usage::

    python benchmarks/occupancy_build.py                  # 0.05 and 0.1 m cells
    python benchmarks/occupancy_build.py --cells 0.1 --plot /tmp/floor.png

The floor is synthetic (``floor_plan``): 25 m x 57 m, a ring corridor 2.4 m wide around a
solid core, rooms between the ring and the outer walls with a door each onto the corridor, a
bed and a cabinet in every room, floor and ceiling slabs; its boxes are subdivided to about
``--triangles`` triangles, as an exported model is finely triangulated. For every cell size:
``OccupancyMap.from_mesh`` time (best of ``--repeat``) and its peak of traced memory
(tracemalloc: the numpy arrays it allocates), the grid and the free area; then
``plan_route`` time for a default route and for one of >= 40 m with >= 2 turns of >= 60 deg
(the issue's hospital flights), with their lengths and turns.
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import classes as C  # noqa: E402
from core.atomic import write_png  # noqa: E402
from core.occupancy import OccupancyMap  # noqa: E402
from datagen.flights.routes import find_turns, plan_route, route_length  # noqa: E402

SIZE = (25.0, 57.0)  # m, x, y
RING = (5.0, 2.4)  # m, rooms' depth between the outer wall and the corridor; corridor width
ROOM = 3.6  # m, room width along the corridor
DOOR = 1.0  # m
HEIGHT, WALL = 2.8, 0.15  # m
BAND, MARGIN = (0.5, 2.2), 0.3


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations
                                .translation_matrix((lo + hi) / 2))


def _room_side(x0: float, x1: float, y_lo: float, y_hi: float, wall_x: float,
               axis: int) -> tuple[list, list]:
    """Walls and furniture of a row of rooms between two wall lines (coordinates in the
    frame where the row runs along ``axis``); the corridor-side wall at ``wall_x`` gets a
    door per room."""
    walls, furniture = [], []
    edges = np.arange(y_lo, y_hi + 1e-9, ROOM)
    edges[-1] = y_hi
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        mid = (a + b) / 2
        walls += [(wall_x - WALL / 2, a, wall_x + WALL / 2, mid - DOOR / 2),
                  (wall_x - WALL / 2, mid + DOOR / 2, wall_x + WALL / 2, b),
                  (x0, b - WALL / 2, x1, b + WALL / 2)]
        inner = x0 + 0.3 if wall_x > x0 + 1 else x1 - 2.3
        furniture += [((inner, a + 0.4, 0.0), (inner + 2.0, a + 1.3, 0.6)),
                      ((inner, b - 0.8, 0.0), (inner + 0.5, b - 0.3, 1.8))]
    if axis == 0:  # swap x and y
        walls = [(y0, x0_, y1, x1_) for x0_, y0, x1_, y1 in walls]
        furniture = [((lo[1], lo[0], lo[2]), (hi[1], hi[0], hi[2])) for lo, hi in furniture]
    return walls, furniture


def floor_plan(triangles: int = 50_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The synthetic floor: vertices (V, 3) m, faces (F, 3), face_class (F,)."""
    X, Y = SIZE
    d, w = RING
    t = 0.2
    parts = [(_box((-t, -t, -t), (X + t, Y + t, 0.0)), C.FLOOR),
             (_box((-t, -t, HEIGHT), (X + t, Y + t, HEIGHT + t)), C.CEILING)]
    walls = [(-t, -t, X + t, 0.0), (-t, Y, X + t, Y + t), (-t, 0.0, 0.0, Y), (X, 0.0, X + t, Y),
             (d + w, d + w, X - d - w, Y - d - w)]  # outer walls, the solid core
    furniture = []
    for x0, x1, wall_x in ((0.0, d, d), (X - d, X, X - d)):  # west and east rows
        ws, fs = _room_side(x0, x1, d, Y - d, wall_x, 1)
        walls, furniture = walls + ws, furniture + fs
    for y0, y1, wall_y in ((0.0, d, d), (Y - d, Y, Y - d)):  # south and north rows
        ws, fs = _room_side(y0, y1, 0.0, X, wall_y, 0)
        walls, furniture = walls + ws, furniture + fs
    parts += [(_box((x0, y0, 0.0), (x1, y1, HEIGHT)), C.WALL) for x0, y0, x1, y1 in walls]
    parts += [(_box(lo, hi), C.CLUTTER) for lo, hi in furniture]
    mesh = trimesh.util.concatenate([m for m, _ in parts])
    face_class = np.concatenate([np.full(len(m.faces), c, np.uint8) for m, c in parts])
    # subdivide to about the asked number of triangles: the finest even level below it, then
    # the largest faces once more (each adds 3)
    v, f, cls = mesh.vertices, mesh.faces, face_class
    for max_edge in (8.0, 4.0, 2.0, 1.0, 0.5, 0.25, 0.125):
        v2, f2, idx = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge,
                                                       return_index=True)
        if len(f2) > triangles:
            break
        v, f, cls = v2, f2, face_class[idx]
    extra = min(max(triangles - len(f), 0) // 3, len(f))
    if extra:
        split = np.zeros(len(f), bool)
        split[np.argsort(trimesh.triangles.area(np.asarray(v)[f]))[::-1][:extra]] = True
        v, f = trimesh.remesh.subdivide(v, f, np.flatnonzero(split))
        cls = np.concatenate([cls[~split], np.repeat(cls[split], 4)])  # trimesh's order
    return np.asarray(v), np.asarray(f), cls


def measure(vertices, faces, face_class, cell: float, repeat: int) -> tuple[OccupancyMap,
                                                                              float, float]:
    """The map, its best build time (s) and the peak traced memory of one build (MB)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        occ = OccupancyMap.from_mesh(vertices, faces, face_class, BAND, MARGIN, cell)
        best = min(best, time.perf_counter() - t0)
    tracemalloc.start()
    OccupancyMap.from_mesh(vertices, faces, face_class, BAND, MARGIN, cell)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return occ, best, peak


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=float, nargs="+", default=[0.05, 0.1])
    ap.add_argument("--triangles", type=int, default=50_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plot", type=Path, help="write the last map with its routes here (PNG)")
    args = ap.parse_args()
    v, f, cls = floor_plan(args.triangles)
    print(f"floor {SIZE[0]} x {SIZE[1]} m: {len(f)} triangles, {len(v)} vertices")
    for cell in args.cells:
        occ, secs, peak = measure(v, f, cls, cell, args.repeat)
        print(f"cell {cell} m: grid {occ.shape[1]} x {occ.shape[0]}, free {occ.area:.1f} m^2; "
              f"from_mesh {secs:.2f} s, peak traced memory {peak:.0f} MB")
        routes = []
        for label, settings in (("default", {}),
                                ("min 40 m, 2 turns", {"min_length": 40.0, "min_turns": 2})):
            t0 = time.perf_counter()
            route = plan_route(occ, np.random.default_rng(args.seed), settings)
            secs = time.perf_counter() - t0
            turns = find_turns(route)
            print(f"  plan_route ({label}): {secs:.2f} s, {route_length(route):.1f} m, turns "
                  f"{np.round(turns[:, 1]).astype(int).tolist()} deg")
            routes.append(route)
        if args.plot:
            write_png(args.plot, occ.plot(routes, scale=2))


if __name__ == "__main__":
    main()
