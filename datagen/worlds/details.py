"""A procedural floor's details (``world.details``, ``DetailsConfig``): drawn onto a ``Plan``.

``draw_details`` adds to a drawn plan (datagen/worlds/procedural.py), in metres:

- **doors**: a doorway hung with a leaf (two for a double door, the doorway widened), closed
  in the opening or open into the room at an angle, some glazed (a glass pane in a frame of
  stiles and rails, all class door); architraves on both faces of the wall (class door);
- **windows**: recessed into the outer wall (``RECESS`` rectangles, free between sill and
  head: reveals, head and sill class window, the outdoor view fitted to the opening), some
  with a frame, mullions and transoms, some with a sill board (a ``SILL`` rectangle: the
  floor's cells under it free from the sill up); window walls glazing a space on an outer
  wall from (near) the floor to (near) the ceiling;
- **glass sheets**: a glass wall made a 2 cm sheet with mullions (``SHEET`` rectangles, class
  window) whose corridor face is drawn see-through, its room face left out of the render;
- **columns**: round (8-16 sides) column sets, free-standing columns in rooms, pillars
  engaged in corridor walls (square ones as ``COLUMN`` rectangles, in the grid; round ones
  as prisms, ``RoundColumn``).

The leaves, architraves, window frames and round columns are meshes of their own
(datagen/worlds/fittings.py); the rest is painted with the plan (datagen/worlds/floor_mesh.py).
Each feature draws from a stream of its own, ``SeedSequence([seed, DETAILS_STREAM, k])``, so
turning one on leaves the others as they were, and a floor with none is the seed's own.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from datagen.config import DetailsConfig, ProceduralWorldConfig
from datagen.worlds.floor_mesh import COLUMN, DOORWAY, RECESS, SHEET, SILL, SPACE, TRIM

DETAILS_STREAM = 1  # the details' streams: SeedSequence([seed, DETAILS_STREAM, feature])
GAP = 0.005  # m between a leaf and its opening (sides, head, floor); frames and reveals
HINGE_TUCK = 0.01  # m an open leaf's hinge lies behind its jamb (in front of the wall)
EMBED = 0.025  # m a closed leaf reaches into its jambs (its sides hidden in the wall)
LEAF_THICKNESS = (0.035, 0.05)  # m
DOUBLE_WIDTH = (1.4, 1.9)  # m, a double door's opening
STILE, BOTTOM_RAIL, TOP_RAIL = (0.08, 0.16), (0.12, 0.3), (0.08, 0.16)  # m, a glazed leaf's
ARCHITRAVE_WIDTH, ARCHITRAVE_DEPTH = (0.05, 0.12), (0.025, 0.04)  # m
RECESS_DEPTH = (0.08, 0.25)  # m, a window's reveal (at most the outer wall less 3 cm)
FRAME_WIDTH, FRAME_DEPTH = (0.04, 0.1), (0.03, 0.07)  # m, a window frame's bars
PANE_WIDTH = (0.6, 1.4)  # m between mullions
SILL_DEPTH, SILL_REACH = (0.03, 0.1), (0.0, 0.08)  # m into the room, past the reveals
WALL_MARGIN = (0.1, 0.4)  # m from a window wall to the space's ends
SHEET_THICKNESS, SHEET_MULLION, SHEET_SPACING = 0.02, (0.04, 0.07), (0.9, 1.5)  # m
ROOM_COLUMN = 3.6  # m, the least side of a room with a free-standing column
PILASTER_WIDTH, PILASTER_DEPTH, PILASTER_SPACING = (0.3, 0.6), (0.1, 0.25), (3.0, 6.0)  # m
FEATURES = ("columns", "glass", "doors", "room_columns", "pilasters", "windows")


@dataclass
class Leaf:
    """A door leaf: a box from ``hinge`` (3,) m (its corner on the hinge side, at the face
    towards the room, ``z0`` above the floor), ``width`` along ``w`` (3,), ``thickness``
    along ``t`` (3,), ``height`` up; ``angle`` deg open (0: closed); ``glazed``: (stile,
    bottom rail, top rail) m around a glass pane, or None."""

    hinge: np.ndarray
    w: np.ndarray
    t: np.ndarray
    width: float
    thickness: float
    height: float
    angle: float
    glazed: tuple[float, float, float] | None = None


@dataclass
class DoorFit:
    """A doorway's fittings: ``leaves``; ``architrave`` (width, depth) m or None; the
    doorway's ``along`` axis (0: x), its span ``a0``, ``a1`` m, the wall's faces ``faces``
    (2,) m across (corridor side first), its ``head`` m. ``framed``: the jambs and head take
    the frame's look."""

    leaves: list[Leaf]
    architrave: tuple[float, float] | None
    along: int
    a0: float
    a1: float
    faces: tuple[float, float]
    head: float

    @property
    def framed(self) -> bool:
        return bool(self.leaves) or self.architrave is not None


@dataclass
class WindowFit:
    """A recessed window: on the outer wall whose inner face is at ``line`` m across axis
    ``1 - along``, ``outward`` (+1/-1) the way into the wall; span ``a0``-``a1`` m along,
    ``sill``-``head`` m up, ``depth`` m deep; ``full``: the head is the space's ceiling;
    ``frame`` (bar width, depth) m or None; ``panes`` between mullions (equal widths; the
    view is fitted to each); ``transoms`` (k,) m heights."""

    along: int
    line: float
    outward: int
    a0: float
    a1: float
    sill: float
    head: float
    depth: float
    full: bool
    frame: tuple[float, float] | None = None
    panes: int = 1
    transoms: list[float] = field(default_factory=list)


@dataclass
class RoundColumn:
    """A column of ``sides`` faces around ``centre`` (2,) m, ``radius`` m (to the corners),
    from the floor to ``top`` m; ``engaged``: (2,) unit vector from the centre to the wall
    it is half sunk into (a half column), or None."""

    centre: np.ndarray
    radius: float
    sides: int
    top: float
    engaged: np.ndarray | None = None


@dataclass
class Details:
    """What ``draw_details`` added: fittings per doorway rectangle index, windows per
    ``RECESS`` rectangle index, the drawn side of each ``SHEET`` rectangle index (the sign
    along its across axis its drawn face's normal points to; 0: a mullion, all drawn),
    the doorway of each ``TRIM`` rectangle index, round columns, and counts (``info``)."""

    doors: dict[int, DoorFit] = field(default_factory=dict)
    trims: dict[int, int] = field(default_factory=dict)
    windows: dict[int, WindowFit] = field(default_factory=dict)
    sheets: dict[int, int] = field(default_factory=dict)
    columns: list[RoundColumn] = field(default_factory=list)
    info: dict = field(default_factory=dict)


def any_details(d: DetailsConfig) -> bool:
    """Whether any share of ``d`` is above 0."""
    return any(getattr(d, k) > 0 for k in _SHARES)


_SHARES = ("door_leaves", "double_doors", "glazed_doors", "architraves", "window_recess",
           "window_frames", "sills", "window_walls", "glass_sheets", "round_columns",
           "room_columns", "pilasters")


def check_details(d: DetailsConfig, where: str = "world.details") -> None:
    """Raise ValueError naming the key for a share outside [0, 1] or a bad door_angle."""
    for key in (*_SHARES, "door_open"):
        p = float(getattr(d, key))
        if not 0 <= p <= 1:
            raise ValueError(f"{where}.{key}: {p} must be a share in [0, 1]")
    a = np.asarray(d.door_angle, np.float64)
    if a.shape != (2,) or not (0 < a[0] <= a[1] <= 90):
        raise ValueError(f"{where}.door_angle: {a.tolist()} must be [min, max] deg with "
                         "0 < min <= max <= 90")


def _u(rng: np.random.Generator, r) -> float:
    return float(rng.uniform(r[0], r[1]))


def _along(axis: int, s0: float, s1: float, c0: float, c1: float) -> list[float]:
    """The rectangle [s0, s1] along ``axis`` (0: x) and [c0, c1] across it."""
    return [s0, c0, s1, c1] if axis == 0 else [c0, s0, c1, s1]


def _subtract(spans: list[tuple[float, float]], cut: tuple[float, float]
              ) -> list[tuple[float, float]]:
    """Intervals ``spans`` less the interval ``cut``."""
    out = []
    for a, b in spans:
        if cut[1] <= a or cut[0] >= b:
            out.append((a, b))
            continue
        if cut[0] > a:
            out.append((a, cut[0]))
        if cut[1] < b:
            out.append((cut[1], b))
    return out


class _Editor:
    """The plan's rectangles while details are added: rectangles, kinds, tops, bottoms,
    roles as lists (indices stay: rectangles are only added, or emptied)."""

    def __init__(self, plan) -> None:
        self.rects = [list(map(float, r)) for r in plan.rects]
        self.kinds, self.roles = list(plan.kinds), list(plan.roles)
        self.tops, self.bots = list(map(float, plan.tops)), list(map(float, plan.bots))

    def add(self, r, kind: str, top: float, role: str, bot: float = 0.0) -> int:
        self.rects.append([float(v) for v in r])
        self.kinds.append(kind)
        self.tops.append(float(top))
        self.bots.append(float(bot))
        self.roles.append(role)
        return len(self.rects) - 1

    def hits(self, r, gap: float, kinds: tuple[str, ...], skip: tuple[int, ...] = ()) -> bool:
        """Whether r comes within ``gap`` m of a rectangle of ``kinds`` (but ``skip``)."""
        a = np.asarray(self.rects)
        sel = np.isin(np.asarray(self.kinds), kinds)
        sel[list(skip)] = False
        hit = ((a[:, 0] < r[2] + gap - 1e-9) & (r[0] < a[:, 2] + gap - 1e-9)
               & (a[:, 1] < r[3] + gap - 1e-9) & (r[1] < a[:, 3] + gap - 1e-9))
        return bool((hit & sel).any())

    def top_at(self, xy) -> float:
        """The ceiling's height at point ``xy`` (m): the highest top of the spaces there."""
        a = np.asarray(self.rects)
        inside = ((a[:, 0] < xy[0]) & (xy[0] < a[:, 2]) & (a[:, 1] < xy[1]) & (xy[1] < a[:, 3])
                  & np.isin(np.asarray(self.kinds), (SPACE, DOORWAY)))
        return float(np.max(np.asarray(self.tops)[inside], initial=0.0))

    def containing(self, xy, kinds: tuple[str, ...] = (SPACE,)) -> int:
        """Index of the first rectangle of ``kinds`` holding point ``xy``, -1 if none."""
        a = np.asarray(self.rects)
        inside = ((a[:, 0] < xy[0]) & (xy[0] < a[:, 2]) & (a[:, 1] < xy[1]) & (xy[1] < a[:, 3])
                  & np.isin(np.asarray(self.kinds), kinds))
        idx = np.flatnonzero(inside)
        return int(idx[0]) if len(idx) else -1


def draw_details(plan, s: ProceduralWorldConfig) -> tuple[object, Details]:
    """The plan with ``s.details`` added, and what was added (see the module docstring).

    Args:
        plan: a ``datagen.worlds.procedural.Plan`` (not changed).
        s: the floor's settings (``seed``, ``details``, ``outer_wall``, ``column_size``).

    Returns:
        (the new Plan, Details).
    """
    from dataclasses import replace

    d = s.details
    check_details(d)
    ed, out = _Editor(plan), Details()

    def rng(feature: str) -> np.random.Generator:
        return np.random.default_rng([s.seed, DETAILS_STREAM, FEATURES.index(feature)])

    if d.round_columns > 0:
        _round_sets(ed, out, plan, d, rng("columns"))
    if d.glass_sheets > 0:
        _glass_sheets(ed, out, plan, d, rng("glass"))
    if d.door_leaves > 0 or d.architraves > 0:
        _doors(ed, out, plan, d, rng("doors"))
    if d.room_columns > 0:
        _room_columns(ed, out, plan, s, rng("room_columns"))
    if d.pilasters > 0:
        _pilasters(ed, out, plan, d, rng("pilasters"))
    windows = dict(plan.windows)
    if d.window_recess > 0 or d.window_walls > 0:
        windows = _windows(ed, out, plan, s, rng("windows"))
    leaves = [leaf for f in out.doors.values() for leaf in f.leaves]
    out.info = {
        "leaves": len(leaves), "open_leaves": sum(leaf.angle > 0 for leaf in leaves),
        "glazed_leaves": sum(leaf.glazed is not None for leaf in leaves),
        "double_doors": sum(len(f.leaves) == 2 for f in out.doors.values()),
        "architraves": sum(f.architrave is not None for f in out.doors.values()),
        "recessed_windows": len(out.windows),
        "window_walls": sum(w.sill < 0.3 for w in out.windows.values()),
        "framed_windows": sum(w.frame is not None for w in out.windows.values()),
        "sill_boards": ed.roles.count("sill"), "glass_sheets": ed.roles.count("sheet"),
        "round_columns": len(out.columns), "room_columns": ed.roles.count("room_column"),
        "pilasters": ed.roles.count("pilaster"),
    }
    keep = np.array([k != "" for k in ed.kinds])
    new = replace(plan, rects=np.asarray(ed.rects)[keep], kinds=np.asarray(ed.kinds)[keep],
                  tops=np.asarray(ed.tops)[keep], bots=np.asarray(ed.bots)[keep],
                  roles=np.asarray(ed.roles)[keep], windows=windows,
                  info={**plan.info, "details": out.info})
    index = np.cumsum(keep) - 1  # old index -> new index (emptied rectangles are dropped)
    out.doors = {int(index[i]): f for i, f in out.doors.items()}
    out.windows = {int(index[i]): w for i, w in out.windows.items()}
    out.sheets = {int(index[i]): v for i, v in out.sheets.items()}
    out.trims = {int(index[j]): int(index[i]) for j, i in out.trims.items()}
    return new, out


def _round_sets(ed: _Editor, out: Details, plan, d: DetailsConfig,
                rng: np.random.Generator) -> None:
    """Make each set of columns (a lobby's, a corridor's) round with ``d.round_columns``."""
    cols = [i for i, k in enumerate(ed.kinds) if k == COLUMN]
    sets: dict[int, list[int]] = {}
    for i in cols:
        r = ed.rects[i]
        sets.setdefault(ed.containing(((r[0] + r[2]) / 2, (r[1] + r[3]) / 2)), []).append(i)
    for members in sets.values():
        if rng.random() >= d.round_columns:
            continue
        for i in members:
            r = np.asarray(ed.rects[i])
            half = (r[2] - r[0]) / 2
            radius = half * float(np.sqrt(4 / np.pi))  # the square's area
            centre = (r[:2] + r[2:]) / 2
            out.columns.append(RoundColumn(centre, radius, _sides(radius), ed.top_at(centre)))
            ed.kinds[i] = ""  # emptied: dropped from the plan


def _sides(radius: float) -> int:
    """Faces of a round column of ``radius``: the most of 16, 12, 10, 8 whose neighbouring
    faces meet at more than 20 deg with their centres > 3 cm off each other's planes (the
    edges' planar regions keep them apart: every vertical corner a model edge)."""
    for n in (16, 12, 10, 8):
        if radius * np.cos(np.pi / n) * (1 - np.cos(2 * np.pi / n)) > 0.03:
            return n
    return 8


def _glass_sheets(ed: _Editor, out: Details, plan, d: DetailsConfig,
                  rng: np.random.Generator) -> None:
    """Make glass walls (role glass) 2 cm sheets with mullions, ``d.glass_sheets`` of them."""
    for i in [i for i, role in enumerate(ed.roles) if role == "glass"]:
        if rng.random() >= d.glass_sheets:
            continue
        r = ed.rects[i]
        along = 0 if r[2] - r[0] > r[3] - r[1] else 1
        room = _room_of(ed, i)
        q = ed.rects[room]
        c0, c1 = r[1 - along], r[3 - along]
        mid = (c0 + c1) / 2
        room_mid = (q[1 - along] + q[3 - along]) / 2
        corridor = -1 if room_mid > mid else 1  # the corridor's side, along the across axis
        ed.kinds[i], ed.tops[i], ed.roles[i] = SPACE, plan.height, "glass_strip"
        out.sheets[ed.add(_along(along, r[along], r[along + 2], mid - SHEET_THICKNESS / 2,
                                 mid + SHEET_THICKNESS / 2), SHEET, 0.0, "sheet")] = corridor
        m = _u(rng, SHEET_MULLION)
        step = _u(rng, SHEET_SPACING)
        n = max(1, int(round((r[along + 2] - r[along]) / step)))
        for p in np.linspace(r[along], r[along + 2], n + 1)[1:-1]:
            out.sheets[ed.add(_along(along, p - m / 2, p + m / 2, mid - m / 2, mid + m / 2),
                              SHEET, 0.0, "mullion")] = 0


def _room_of(ed: _Editor, i: int) -> int:
    """The room a glass wall or doorway rectangle ``i`` belongs to (the last one before it)."""
    return max(j for j in range(i) if ed.roles[j] == "room")


def _doors(ed: _Editor, out: Details, plan, d: DetailsConfig,
           rng: np.random.Generator) -> None:
    """Leaves, double doors and architraves on the doorways (role door)."""
    glass_rooms = {_room_of(ed, i) for i, role in enumerate(ed.roles)
                   if role in ("glass", "glass_strip")}
    heads = [ed.tops[i] for i, role in enumerate(ed.roles) if role == "door"]
    above = plan.height - max(heads, default=0.0) - 0.02  # the architrave stays below ceilings
    profile = (min(_u(rng, ARCHITRAVE_WIDTH), above), _u(rng, ARCHITRAVE_DEPTH))  # per floor
    for i in [i for i, role in enumerate(ed.roles) if role == "door"]:
        r = ed.rects[i]
        along = 0 if r[2] - r[0] > r[3] - r[1] else 1
        room = _room_of(ed, i)
        q = ed.rects[room]
        c0, c1 = r[1 - along], r[3 - along]
        into = 1 if (q[1 - along] + q[3 - along]) / 2 > (c0 + c1) / 2 else -1  # to the room
        faces = (c0, c1) if into > 0 else (c1, c0)  # corridor side first
        a0, a1 = r[along], r[along + 2]
        hung = rng.random() < d.door_leaves
        double = hung and rng.random() < d.double_doors
        if double:
            width = min(_u(rng, DOUBLE_WIDTH), q[along + 2] - q[along] - 0.4)
            if width > a1 - a0 + 0.2:
                centre = float(np.clip((a0 + a1) / 2, q[along] + 0.2 + width / 2,
                                       q[along + 2] - 0.2 - width / 2))
                a0, a1 = centre - width / 2, centre + width / 2
                r[along], r[along + 2] = a0, a1
            else:
                double = False
        arch = None
        if rng.random() < d.architraves and room not in glass_rooms and profile[0] >= 0.03:
            arch = profile
            for s0, s1 in ((a0 - arch[0], a0), (a1, a1 + arch[0])):
                out.trims[ed.add(_along(along, s0, s1, c0, c1), TRIM, 0.0, "trim")] = i
        leaves = []
        if hung:
            hinges = [(a0, 1), (a1, -1)] if double else [[(a0, 1), (a1, -1)][rng.integers(2)]]
            span = (a1 - a0) / 2 if double else a1 - a0
            thick = _u(rng, LEAF_THICKNESS)
            front = (arch[1] if arch else 0.0) + 0.003  # an open leaf stands off the wall
            for jamb, sign in hinges:
                angle = _u(rng, d.door_angle) if rng.random() < d.door_open else 0.0
                glazed = ((_u(rng, STILE), _u(rng, BOTTOM_RAIL), _u(rng, TOP_RAIL))
                          if rng.random() < d.glazed_doors else None)
                leaves.append(_leaf(along, jamb, sign, faces[1], into, span, not double,
                                    thick, ed.tops[i], angle, glazed, front))
        if leaves or arch:
            out.doors[i] = DoorFit(leaves, arch, along, a0, a1, faces, ed.tops[i])


def _leaf(along: int, jamb: float, sign: int, room_face: float, into: int, span: float,
          single: bool, thick: float, head: float, angle: float,
          glazed: tuple[float, float, float] | None, front: float) -> Leaf:
    """A leaf hinged at the ``jamb``, closing ``span`` m of the opening towards ``sign``
    along (all of it ``single``, else half). Closed: ``GAP`` inside the wall's room face, its
    sides ``EMBED`` into the jambs (a double door's leaves meet in the middle). Open
    ``angle`` deg into the room (``into``): hinged ``front`` m in front of the room face and
    ``HINGE_TUCK`` behind the jamb, ``GAP`` short of the span. Either way no slit is left
    that a render shows at a pixel's scale and the model's outlines would see through."""
    e_along, e_across = np.zeros(3), np.zeros(3)
    e_along[along], e_across[1 - along] = sign, into
    a = np.radians(angle)
    w = np.cos(a) * e_along + np.sin(a) * e_across
    t = -np.cos(a) * e_across + np.sin(a) * e_along
    hinge = np.zeros(3)
    if angle > 0:
        hinge[along], hinge[1 - along] = jamb - sign * HINGE_TUCK, room_face + into * front
        width = span + HINGE_TUCK - GAP
    else:
        hinge[along], hinge[1 - along] = jamb - sign * EMBED, room_face - into * GAP
        width = span + EMBED * (2 if single else 1)
    hinge[2] = GAP
    return Leaf(hinge, w, t, width, thick, head - 2 * GAP, angle, glazed)


def _room_columns(ed: _Editor, out: Details, plan, s: ProceduralWorldConfig,
                  rng: np.random.Generator) -> None:
    """A free-standing column in rooms >= ``ROOM_COLUMN`` each way, 1.2 m from the walls and
    clear of the door and its leaf."""
    d = s.details
    doors = {_room_of(ed, i): i for i, role in enumerate(ed.roles) if role == "door"}
    for j in [j for j, role in enumerate(ed.roles) if role == "room"]:
        q = np.asarray(ed.rects[j])
        if min(q[2] - q[0], q[3] - q[1]) < ROOM_COLUMN or rng.random() >= d.room_columns:
            continue
        half = _u(rng, s.column_size) / 2
        rd = np.asarray(ed.rects[doors[j]]) if j in doors else None
        for _ in range(10):
            c = rng.uniform(q[:2] + 1.2, q[2:] - 1.2)
            if rd is None or np.linalg.norm(c - (rd[:2] + rd[2:]) / 2) > (
                    np.max(rd[2:] - rd[:2]) + 0.9):
                break
        else:
            continue
        if rng.random() < d.round_columns:
            radius = half * float(np.sqrt(4 / np.pi))
            out.columns.append(RoundColumn(c, radius, _sides(radius), ed.top_at(c)))
        else:
            ed.add([c[0] - half, c[1] - half, c[0] + half, c[1] + half], COLUMN, 0.0,
                   "room_column")


def _pilasters(ed: _Editor, out: Details, plan, d: DetailsConfig,
               rng: np.random.Generator) -> None:
    """Pillars engaged in corridor walls where the wall behind is solid, 0.3 m clear of
    doorways, recesses and other spaces; square, or round (half columns) with
    ``d.round_columns``."""
    nodes, edges, widths = plan.nodes, plan.edges, plan.corridor_widths
    half = np.zeros(int(edges.max()) + 1)
    np.maximum.at(half, edges.ravel(), np.repeat(widths / 2, 2))
    free = (SPACE, DOORWAY)
    for e, ((a, b), w) in enumerate(zip(edges, widths, strict=True)):
        axis = 0 if nodes[a, 1] == nodes[b, 1] else 1
        lo, hi = sorted((a, b), key=lambda n: nodes[n, axis])
        s0, s1 = nodes[lo, axis] + half[lo], nodes[hi, axis] - half[hi]
        c = nodes[a, 1 - axis]
        for side in (-1, 1):
            if rng.random() >= d.pilasters:
                continue
            wall = c + side * w / 2
            step, pw = _u(rng, PILASTER_SPACING), _u(rng, PILASTER_WIDTH)
            pd = min(_u(rng, PILASTER_DEPTH), w / 5)
            is_round = rng.random() < d.round_columns
            if is_round:
                pd = pw / 2
            for p in np.arange(s0 + _u(rng, [0.5, step]), s1 - 0.5, step):
                r = _along(axis, p - pw / 2, p + pw / 2, *sorted((wall, wall - side * pd)))
                behind = _along(axis, p - pw / 2 - 0.3, p + pw / 2 + 0.3,
                                *sorted((wall, wall + side * 0.05)))
                if (ed.hits(behind, 0.0, free) or ed.hits(r, 0.3, free, skip=(e,))
                        or ed.hits(r, 0.3, (COLUMN, SHEET))):
                    continue
                if is_round:
                    centre = np.zeros(2)
                    centre[axis], centre[1 - axis] = p, wall
                    toward = np.zeros(2)
                    toward[1 - axis] = side
                    inside = centre - 0.01 * toward
                    out.columns.append(RoundColumn(centre, pw / 2, _sides(pw / 2),
                                                   ed.top_at(inside), toward))
                    ed.add(r, "", 0.0, "pilaster")  # counted, not painted
                else:
                    ed.add(r, COLUMN, 0.0, "pilaster")


def _wall_spans(ed: _Editor, along: int, line: float, outward: int
                ) -> list[tuple[float, float]]:
    """The free stretches (a0, a1) m along an outer wall's inner face: where a space
    (``SPACE`` rectangle) reaches the face and no column stands."""
    spans = []
    for r, k in zip(ed.rects, ed.kinds, strict=True):
        inner = r[3 - along] if outward < 0 else r[1 - along]  # its side towards the room
        face = r[1 - along] if outward < 0 else r[3 - along]  # its side at the wall
        if k == SPACE and abs(face - line) < 1e-6 and (inner - line) * outward < 0:
            spans.append((r[along], r[along + 2]))
    cuts = [(r[along] - 0.05, r[along + 2] + 0.05) for r, k in zip(ed.rects, ed.kinds,
                                                                   strict=True)
            if k == COLUMN and r[1 - along] - 0.05 < line < r[3 - along] + 0.05]
    out = []
    for a0, a1 in spans:
        pieces = [(a0, a1)]
        for cut in cuts:
            pieces = _subtract(pieces, cut)
        out += [(p0, p1) for p0, p1 in pieces if p1 - p0 > 0.3]
    return out


def _windows(ed: _Editor, out: Details, plan, s: ProceduralWorldConfig,
             rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Window walls and recessed windows on the outer walls; returns the flat windows left
    (``Plan.windows``)."""
    d = s.details
    size, outer = plan.size, plan.outer
    # one window wall's sill and head per floor (each height in use splits every wall)
    wall_sill = 0.0 if rng.random() < 0.5 else _u(rng, [0.02, 0.1])
    wall_gap = 0.0 if rng.random() < 0.5 else _u(rng, [0.2, 0.5])
    depth_max = s.outer_wall - 0.03
    flat = {}
    sill0, head0 = (float(v) for v in plan.window_z)
    for along, name in ((0, "x"), (1, "y")):
        kept = [tuple(w) for w in plan.windows[name]]
        for line, outward in ((outer, -1), (size[1 - along] - outer, 1)):
            for a0, a1 in _wall_spans(ed, along, line, outward):
                runs = [(max(a0, w0), min(a1, w1)) for w0, w1 in kept
                        if min(a1, w1) - max(a0, w0) > 0.3]
                at = np.zeros(2)
                at[along], at[1 - along] = (a0 + a1) / 2, line - outward * 0.01
                top = ed.top_at(at)
                if a1 - a0 >= 1.5 and rng.random() < d.window_walls:
                    m0, m1 = _u(rng, WALL_MARGIN), _u(rng, WALL_MARGIN)
                    sill, head = wall_sill, top - wall_gap
                    runs = [(a0 + m0, a1 - m1)]
                elif rng.random() < d.window_recess:
                    sill, head = sill0, head0
                else:
                    continue
                kept = [p for k in kept for p in _subtract([k], (a0, a1))]  # no flat ones
                for w0, w1 in runs:
                    _window(ed, out, d, rng, along, line, outward, (w0, w1), (a0, a1),
                            sill, head, top, min(_u(rng, RECESS_DEPTH), depth_max))
        flat[name] = np.asarray(kept, np.float64).reshape(-1, 2)
    return flat


def _window(ed: _Editor, out: Details, d: DetailsConfig, rng: np.random.Generator,
            along: int, line: float, outward: int, span: tuple[float, float],
            room: tuple[float, float], sill: float, head: float, top: float,
            depth: float) -> None:
    """One recessed window (``RECESS``), its frame and its sill board (``SILL``)."""
    a0, a1 = span
    full = head >= top - 1e-9
    w = WindowFit(along, line, outward, a0, a1, sill, head, depth, full)
    if rng.random() < d.window_frames:
        fw, fd = _u(rng, FRAME_WIDTH), min(_u(rng, FRAME_DEPTH), depth - 0.02)
        w.frame = (fw, fd)
        w.panes = max(1, int(round((a1 - a0) / _u(rng, PANE_WIDTH))))
        tall = head - sill
        if tall > 1.6 and rng.random() < 0.6:
            w.transoms = [sill + (min(2.1 - sill, 0.75 * tall) if sill < 0.5
                                  else _u(rng, [0.55, 0.75]) * tall)]
    else:
        w.panes = max(1, int(round((a1 - a0) / 1.2)))
    i = ed.add(_along(along, a0, a1, *sorted((line, line + outward * depth))), RECESS, head,
               "window", bot=sill)
    out.windows[i] = w
    if sill >= 0.3 and rng.random() < d.sills:
        reach, sd = _u(rng, SILL_REACH), _u(rng, SILL_DEPTH)
        s0, s1 = max(room[0], a0 - reach), min(room[1], a1 + reach)
        ed.add(_along(along, s0, s1, *sorted((line, line - outward * sd))), SILL, top,
               "sill", bot=sill)
