"""``world=procedural``: an office floor drawn from a seed, as a classed ``Building``.

The plan (``draw_plan``) is a set of axis-aligned rectangles in metres on the floor's outline
[0, size_x] x [0, size_y]: corridors along the lines of a coarse grid (a random spanning tree
of the grid's nodes, so L and T junctions, plus extra grid edges that close loops), a lobby
(a wider, higher hall) at one node, rooms along the corridors behind door openings in the
corridor wall, recesses in the corridor walls, columns in the lobby and wide corridors, glass
walls (class window) between some rooms and their corridor, and windows along the outer
walls. ``world.details`` (datagen/worlds/details.py) add door leaves, architraves, recessed
and framed windows, window walls, glass sheets and more columns, from a stream of their own.
``build_floor`` paints the rectangles onto the grid of all their edges' coordinates and emits
the surfaces between free and solid cells (datagen/worlds/floor_mesh.py: floor, ceiling,
walls, the reveals and head of each door opening in class door, the lintel above it in class
wall), each piece of wall split at every height in use, so the mesh is conforming (no
T-junctions); the details' leaves, frames and round columns are meshes of their own
(datagen/worlds/fittings.py). The result goes through the same path to a
``datagen.worlds.site.Site`` as an imported building.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core import classes as C
from datagen.config import ProceduralWorldConfig
from datagen.importers.classify import class_shares
from datagen.mesh.building import Building, assemble
from datagen.worlds.details import any_details, check_details, draw_details
from datagen.worlds.fittings import fitting_parts
from datagen.worlds.floor_mesh import COLUMN, DOORWAY, GLASS, SPACE, surfaces

_RANGES = ("grid_spacing", "corridor_width", "height", "lobby_size", "room_depth",
           "door_spacing", "door_width", "door_height", "window_spacing", "window_width",
           "window_sill", "window_height", "recess_width", "recess_depth", "column_size")
_PROBS = ("loops", "columns", "recesses", "glass")


@dataclass
class Plan:
    """A drawn floor plan (metres; rectangles [x0, y0, x1, y1]).

    rects (N, 4), kinds (N,) str (``floor_mesh.KINDS``: SPACE, GLASS, DOORWAY, COLUMN; the
    details add SHEET, RECESS, SILL), tops (N,) m ceiling height of free rectangles (0 for
    solid ones), bots (N,) m the free height's bottom (0 but a window's sill), roles (N,)
    str: corridor, junction, lobby, room, recess, door, glass, column (and the details');
    corridor_widths (E,) m; nodes (M, 2) m grid nodes; edges (E, 2) node indices of the
    corridors; loops: corridors beyond the spanning tree; height,
    lobby_height m; windows: axis -> (W, 2) m intervals along the outer walls of that axis
    (x: the walls at y = const); window_z (2,) m sill and head; size (2,) m; outer m;
    details: what ``datagen.worlds.details.draw_details`` added (its ``Details``), or None.
    """

    rects: np.ndarray
    kinds: np.ndarray
    tops: np.ndarray
    bots: np.ndarray
    roles: np.ndarray
    corridor_widths: np.ndarray
    nodes: np.ndarray
    edges: np.ndarray
    loops: int
    height: float
    lobby_height: float
    windows: dict[str, np.ndarray]
    window_z: np.ndarray
    size: np.ndarray
    outer: float
    info: dict = field(default_factory=dict)
    details: object = None


def check_settings(s: ProceduralWorldConfig, where: str = "world") -> None:
    """Raise ValueError naming the key for a range that is not [min, max] with
    0 < min <= max, a probability outside [0, 1], or a bad size."""
    for key in _RANGES:
        r = np.asarray(getattr(s, key), np.float64)
        if r.shape != (2,) or not (0 < r[0] <= r[1]) or not np.isfinite(r).all():
            raise ValueError(f"{where}.{key}: {r.tolist()} must be [min, max] m with "
                             "0 < min <= max")
    for key in _PROBS:
        p = float(getattr(s, key))
        if not 0 <= p <= 1:
            raise ValueError(f"{where}.{key}: {p} must be a probability in [0, 1]")
    size = np.asarray(s.size, np.float64)
    if size.shape != (2,) or not (size > 0).all():
        raise ValueError(f"{where}.size: {size.tolist()} must be [x, y] m, both > 0")
    for key in ("wall_thickness", "outer_wall"):
        if not getattr(s, key) > 0:
            raise ValueError(f"{where}.{key}: {getattr(s, key)} must be > 0 m")
    if s.door_height[1] >= s.height[0]:
        raise ValueError(f"{where}.door_height: {list(s.door_height)} must stay below "
                         f"{where}.height's min {s.height[0]} m")
    if s.window_sill[1] + s.window_height[1] >= s.height[0]:
        raise ValueError(f"{where}.window_sill + {where}.window_height: the windows' heads "
                         f"({s.window_sill[1] + s.window_height[1]} m) must stay below "
                         f"{where}.height's min {s.height[0]} m")
    check_details(s.details, f"{where}.details")
    if (s.details.window_recess > 0 or s.details.window_walls > 0) and s.outer_wall < 0.1:
        raise ValueError(f"{where}.outer_wall: {s.outer_wall} m is too thin for recessed "
                         f"windows ({where}.details.window_recess, window_walls); make it "
                         ">= 0.1 m or set both to 0")
    need = 2 * (s.outer_wall + s.room_depth[0] + s.wall_thickness) + s.corridor_width[1]
    if size.min() < need:
        raise ValueError(f"{where}.size: {size.tolist()} is too small for a corridor with "
                         f"rooms on both sides; make both >= {need:.1f} m")


def _uniform(rng: np.random.Generator, r) -> float:
    return float(rng.uniform(r[0], r[1]))


def _spanning_tree(rng: np.random.Generator, n: int, edges: np.ndarray) -> np.ndarray:
    """(E,) bool: the edges of a random spanning tree of nodes 0..n-1 (randomized Kruskal)."""
    parent = np.arange(n)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    tree = np.zeros(len(edges), bool)
    for e in rng.permutation(len(edges)):
        a, b = root(edges[e, 0]), root(edges[e, 1])
        if a != b:
            parent[a] = b
            tree[e] = True
    return tree


class _Rects:
    """A growing list of plan rectangles."""

    def __init__(self) -> None:
        self.rects: list[list[float]] = []
        self.kinds: list[str] = []
        self.tops: list[float] = []
        self.roles: list[str] = []

    def add(self, r, kind: str, top: float, role: str) -> None:
        self.rects.append([float(v) for v in r])
        self.kinds.append(kind)
        self.tops.append(top)
        self.roles.append(role)

    def clear_of(self, r, gap: float, skip: tuple[int, ...] = ()) -> bool:
        """Whether r keeps ``gap`` m from every free rectangle but those in ``skip``."""
        if not self.rects:
            return True
        a = np.asarray(self.rects)
        free = np.array([k in (SPACE, DOORWAY) for k in self.kinds])
        free[list(skip)] = False
        hit = ((a[:, 0] < r[2] + gap - 1e-9) & (r[0] < a[:, 2] + gap - 1e-9)
               & (a[:, 1] < r[3] + gap - 1e-9) & (r[1] < a[:, 3] + gap - 1e-9))
        return not (hit & free).any()


def _along(axis: int, s0: float, s1: float, c0: float, c1: float) -> list[float]:
    """The rectangle [s0, s1] along ``axis`` (0: x) and [c0, c1] across it."""
    return [s0, c0, s1, c1] if axis == 0 else [c0, s0, c1, s1]


def draw_plan(s: ProceduralWorldConfig, rng: np.random.Generator) -> Plan:
    """Draw a floor plan from ``s``'s ranges with ``rng`` (see the module docstring)."""
    check_settings(s)
    size = np.asarray(s.size, np.float64)
    t, outer = float(s.wall_thickness), float(s.outer_wall)
    h = _uniform(rng, s.height)
    h_lobby = _uniform(rng, [h, s.height[1]])
    w_max = float(s.corridor_width[1])
    # grid nodes, inset so perimeter rooms of a drawn depth fit between corridor and outer wall
    inset = np.full(2, outer + _uniform(rng, s.room_depth) + t + w_max / 2)
    spacing = _uniform(rng, s.grid_spacing)
    counts = np.maximum(1, np.floor((size - 2 * inset) / spacing + 1e-9).astype(int) + 1)
    size = np.where(counts > 1, size, 2 * inset)  # too short for two lines: one, centred
    gx, gy = (np.linspace(inset[a], size[a] - inset[a], counts[a]) for a in (0, 1))
    ii, jj = np.meshgrid(np.arange(counts[0]), np.arange(counts[1]), indexing="ij")
    nodes = np.column_stack([gx[ii.ravel()], gy[jj.ravel()]])
    index = np.arange(len(nodes)).reshape(counts)
    edges = np.concatenate([
        np.column_stack([index[:-1].ravel(), index[1:].ravel()]),
        np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()])]).reshape(-1, 2)
    if len(edges) == 0:
        raise ValueError(f"world.size: {size.tolist()} leaves room for one grid node only; "
                         "make it larger or world.grid_spacing smaller")
    keep = _spanning_tree(rng, len(nodes), edges)
    extra = ~keep & (rng.random(len(edges)) < s.loops)
    if not extra.any() and (~keep).any() and min(counts) >= 2:
        extra[rng.choice(np.flatnonzero(~keep))] = True  # at least one loop
    keep |= extra
    edges = edges[keep]
    widths = rng.uniform(s.corridor_width[0], s.corridor_width[1], len(edges))
    half = np.zeros(len(nodes))
    np.maximum.at(half, edges.ravel(), np.repeat(widths / 2, 2))
    used = np.flatnonzero(half > 0)
    out = _Rects()
    inner = [outer, outer, size[0] - outer, size[1] - outer]
    edge_rect = []
    door_h = _uniform(rng, s.door_height)
    for (a, b), w in zip(edges, widths, strict=True):
        axis = 0 if nodes[a, 1] == nodes[b, 1] else 1
        c = nodes[a, 1 - axis]
        edge_rect.append(len(out.rects))
        out.add(_along(axis, nodes[a, axis], nodes[b, axis], c - w / 2, c + w / 2), SPACE, h,
                "corridor")
    for n in used:
        x, y, r = nodes[n, 0], nodes[n, 1], half[n]
        out.add([x - r, y - r, x + r, y + r], SPACE, h, "junction")
    lobby_node = int(rng.choice(used))
    lx, ly = rng.uniform(s.lobby_size[0], s.lobby_size[1], 2) / 2
    x, y = nodes[lobby_node]
    lobby = [max(x - lx, inner[0]), max(y - ly, inner[1]), min(x + lx, inner[2]),
             min(y + ly, inner[3])]
    out.add(lobby, SPACE, h_lobby, "lobby")
    columns = []
    if rng.random() < s.columns:  # a lattice of columns 1.5 m in from the lobby's walls
        c = _uniform(rng, s.column_size) / 2
        for cx in np.linspace(lobby[0] + 1.5, lobby[2] - 1.5, max(1, int((lobby[2] - lobby[0]
                                                                          - 3) // 3) + 1)):
            for cy in np.linspace(lobby[1] + 1.5, lobby[3] - 1.5,
                                  max(1, int((lobby[3] - lobby[1] - 3) // 3) + 1)):
                if lobby[2] - lobby[0] > 3 and lobby[3] - lobby[1] > 3:
                    columns.append([cx - c, cy - c, cx + c, cy + c])
    # rooms, then recesses, along each corridor side between its junctions
    sides = []
    for e, ((a, b), w) in enumerate(zip(edges, widths, strict=True)):
        axis = 0 if nodes[a, 1] == nodes[b, 1] else 1
        lo, hi = sorted((a, b), key=lambda n: nodes[n, axis])
        s0, s1 = nodes[lo, axis] + half[lo] + t, nodes[hi, axis] - half[hi] - t
        c = nodes[a, 1 - axis]
        if w >= 2.8 and rng.random() < s.columns:  # columns along a wide corridor's middle
            cs = _uniform(rng, s.column_size) / 2
            for p in np.arange(s0 + 1.0, s1 - 1.0, _uniform(rng, [3.0, 5.0])):
                columns.append(_along(axis, p - cs, p + cs, c - cs, c + cs))
        for side in (-1, 1):
            sides.append((e, axis, s0, s1, c, w, side))
    for _, axis, s0, s1, c, w, side in sides:
        wall = c + side * w / 2
        far = inner[3 - axis] if side > 0 else inner[1 - axis]  # the outer wall that side
        to_outer = abs(far - wall) - t
        depth = to_outer if to_outer <= s.room_depth[1] + t + w_max else _uniform(
            rng, s.room_depth)
        p = s0
        while p < s1 - s.door_spacing[0] * 0.7:
            rw = min(_uniform(rng, s.door_spacing), s1 - p)
            for d in (depth, (depth + s.room_depth[0]) / 2, s.room_depth[0]):
                near = wall + side * t
                r = _along(axis, p, p + rw, *sorted((near, near + side * d)))
                if d > 0 and out.clear_of(r, t - 1e-6):
                    out.add(r, SPACE, h, "room")
                    dw = min(_uniform(rng, s.door_width), rw - 0.4)
                    dc = rng.uniform(p + 0.2 + dw / 2, p + rw - 0.2 - dw / 2)
                    if rng.random() < s.glass:
                        out.add(_along(axis, p, p + rw, *sorted((wall, near))), GLASS, 0.0,
                                "glass")
                    out.add(_along(axis, dc - dw / 2, dc + dw / 2, *sorted((wall, near))),
                            DOORWAY, door_h, "door")
                    break
            else:  # no room fits here: try a metre further on
                p += 1.0
                continue
            p += rw + t
    for e, axis, s0, s1, c, w, side in sides:
        if rng.random() >= s.recesses:
            continue
        rw, rd = _uniform(rng, s.recess_width), _uniform(rng, s.recess_depth)
        if s1 - s0 < rw:
            continue
        p = rng.uniform(s0, s1 - rw)
        wall = c + side * w / 2
        r = _along(axis, p, p + rw, *sorted((wall, wall + side * rd)))
        if out.clear_of(r, t, skip=(edge_rect[e],)):
            out.add(r, SPACE, h, "recess")
    for r in columns:
        out.add(r, COLUMN, 0.0, "column")
    # windows along the outer walls: one per window_spacing, centred in each bay
    ws, ww = _uniform(rng, s.window_spacing), _uniform(rng, s.window_width)
    sill = _uniform(rng, s.window_sill)
    head = min(sill + _uniform(rng, s.window_height), h - 0.2)
    windows = {}
    for axis, name in ((0, "x"), (1, "y")):
        centres = np.arange(outer + ws / 2, size[axis] - outer - ws / 2 + 1e-9, ws)
        windows[name] = np.column_stack([centres - ww / 2, centres + ww / 2])
    info = {"nodes": int(len(used)), "corridors": int(len(edges)), "loops": int(extra.sum()),
            "rooms": out.roles.count("room"), "doors": out.roles.count("door"),
            "glass_walls": out.roles.count("glass"), "recesses": out.roles.count("recess"),
            "columns": out.roles.count("column"), "lobby": [round(float(v), 3) for v in lobby],
            "height": round(h, 3), "lobby_height": round(h_lobby, 3),
            "corridor_widths": [round(float(w), 3) for w in widths],
            "door_height": round(door_h, 3), "size": size.round(3).tolist(),
            "window_spacing": round(ws, 3), "window_width": round(ww, 3)}
    return Plan(np.asarray(out.rects), np.asarray(out.kinds), np.asarray(out.tops),
                np.zeros(len(out.rects)), np.asarray(out.roles), widths, nodes[used], edges,
                int(extra.sum()), h, h_lobby, windows, np.array([sill, head]), size, outer, info)


def build_floor(s: ProceduralWorldConfig) -> tuple[Building, Plan]:
    """The floor of ``s`` (``seed``): its classed mesh (floor at z = 0, metres) and plan,
    with ``s.details`` (datagen/worlds/details.py: leaves, frames, ...) where any is on.

    Returns:
        the Building (``info`` as ``load_building``'s: counts, class shares, floor_z,
        wall_top_z, bounds, and ``plan``: the plan's figures, with ``details`` counted) and
        the Plan (the details' rectangles in it).
    """
    plan = draw_plan(s, np.random.default_rng(s.seed))
    details = None
    if any_details(s.details):
        plan, details = draw_details(plan, s)
        plan.details = details
    parts = surfaces(plan, details)
    if details is not None:
        parts += fitting_parts(details)
    b = assemble(parts)
    counts = np.bincount(b.face_class, minlength=C.NUM_CLASSES)
    lo, hi = b.vertices.min(axis=0), b.vertices.max(axis=0)
    b.info = {
        "source": f"procedural seed {s.seed}", "format": "procedural",
        "vertices": int(len(b.vertices)), "faces": int(len(b.faces)),
        "faces_per_class": {C.NAMES[i]: int(counts[i]) for i in range(C.NUM_CLASSES)
                            if counts[i]},
        "class_shares": class_shares(b), "floor_z": 0.0,
        "wall_top_z": round(float(hi[2]), 4), "ceiling_added": 0,
        "bounds": [lo.round(4).tolist(), hi.round(4).tolist()], "plan": plan.info,
    }
    return b, plan
