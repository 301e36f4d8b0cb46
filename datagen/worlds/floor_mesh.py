"""The classed surfaces of a procedural floor's plan (datagen/worlds/procedural.py).

The plan's rectangles are painted onto the grid of all their edges' coordinates (``paint``):
each cell is solid or free between a bottom and a top height (0 and the ceiling for a room;
a window's recess from its sill to its head; a sill board's cells from the sill up). The
surfaces lie between free and solid cells, and between free cells where one's height range
ends inside the other's (``surfaces``): floors and ceilings of the free cells, the walls
between, each piece of wall split at every height in use, so the mesh is conforming (no
T-junctions). Classes: a doorway's reveals and head door, the lintel above it wall; a glass
wall's faces window; a window's recess (reveals, head, sill, the view at its back) window;
flat windows (``Plan.windows``) are the outer walls' faces between sill and head.

A face may carry a look (``Part.look``): the frame's texture on a hung doorway's reveals, the
window frame's on a recess's, the outdoor view fitted to each pane at a recess's back, a
glass sheet's see-through face and its hidden far face (datagen/worlds/scene.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core import classes as C
from datagen.mesh.building import Part

#: Rectangle kinds of a plan, painted in this order (later ones win): free space, a glass
#: wall, a thin glass sheet or its mullion (solid, class window), a doorway, a window's
#: recess in the outer wall, a sill board, the wall under an architrave beside a doorway
#: (its faces class door up to the architrave's top), a column.
SPACE, GLASS, SHEET, DOORWAY, RECESS, SILL, TRIM, COLUMN = (
    "space", "glass", "sheet", "doorway", "recess", "sill", "trim", "column")
KINDS = (SPACE, GLASS, SHEET, DOORWAY, RECESS, SILL, TRIM, COLUMN)
#: Looks a face of the grid may take (``Part.look``; "" its class's texture).
WINDOW_VIEW, WINDOW_FRAME, FRAME, GLASS_LOOK, HIDDEN = (
    "window", "window_frame", "frame", "glass", "hidden")
LOOKS = (WINDOW_VIEW, WINDOW_FRAME, FRAME, GLASS_LOOK, HIDDEN)


@dataclass
class Grid:
    """A plan painted: xs (nx+1,), ys (ny+1,) m cell edges; per cell (nx, ny): free, bot and
    top (m, the free height range), door (the doorway rectangle's index, -1), glass (a glass
    wall's solid cell), sheet (the ``SHEET`` rectangle's index, -1), recess (the ``RECESS``
    rectangle's index, -1), sill (a sill board's cell), trim (the ``TRIM`` rectangle's
    index, -1)."""

    xs: np.ndarray
    ys: np.ndarray
    free: np.ndarray
    bot: np.ndarray
    top: np.ndarray
    door: np.ndarray
    glass: np.ndarray
    sheet: np.ndarray
    recess: np.ndarray
    sill: np.ndarray
    trim: np.ndarray


def paint(plan) -> Grid:
    """The plan painted onto the grid of its coordinates (``Grid``)."""
    r = plan.rects
    xs = np.unique(np.concatenate([[0.0, plan.size[0]], r[:, [0, 2]].ravel(),
                                   plan.windows["x"].ravel()]).round(6))
    ys = np.unique(np.concatenate([[0.0, plan.size[1]], r[:, [1, 3]].ravel(),
                                   plan.windows["y"].ravel()]).round(6))
    cx, cy = (xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2
    inside = ((cx[None, :, None] > r[:, 0, None, None]) & (cx[None, :, None] < r[:, 2, None, None])
              & (cy[None, None, :] > r[:, 1, None, None])
              & (cy[None, None, :] < r[:, 3, None, None]))  # (N, nx, ny)
    shape = (len(cx), len(cy))
    g = Grid(xs, ys, np.zeros(shape, bool), np.zeros(shape), np.zeros(shape),
             np.full(shape, -1), np.zeros(shape, bool), np.full(shape, -1), np.full(shape, -1),
             np.zeros(shape, bool), np.full(shape, -1))
    bots = plan.bots
    for kind in KINDS:
        for i in np.flatnonzero(plan.kinds == kind):
            m = inside[i]
            if kind == SPACE:
                g.free[m], g.top[m] = True, np.maximum(g.top[m], plan.tops[i])
            elif kind == GLASS:
                g.glass[m & ~g.free] = True
            elif kind == SHEET:
                g.free[m], g.top[m], g.glass[m], g.sheet[m] = False, 0.0, False, i
            elif kind == DOORWAY:
                g.free[m], g.top[m], g.door[m], g.glass[m], g.sheet[m] = (
                    True, plan.tops[i], i, False, -1)
            elif kind == RECESS:
                m = m & ~g.free
                g.free[m], g.bot[m], g.top[m], g.recess[m] = True, bots[i], plan.tops[i], i
            elif kind == SILL:
                m = m & g.free
                g.bot[m], g.sill[m] = bots[i], True
            elif kind == TRIM:
                g.trim[m & ~g.free] = i
            else:
                g.free[m], g.top[m], g.door[m], g.glass[m] = False, 0.0, -1, False
                g.sheet[m], g.recess[m], g.bot[m], g.sill[m] = -1, -1, 0.0, False
    return g


def _quads(corners: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners (Q, 4, 3) of quads (in order around) reversed where needed, so each faces its
    (Q, 3) normal, and the faces (2Q, 3) of their vertices (4Q, 3)."""
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    flip = (n * normal).sum(axis=1) < 0
    corners = np.where(flip[:, None, None], corners[:, ::-1], corners)
    base = 4 * np.arange(len(corners))[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    return corners, faces


class _Faces:
    """Quads being collected: corners (4, 3) m, normal, class, look (index into LOOKS, -1:
    the class's texture), owner (the recess's rectangle index for a window's view, -1)."""

    def __init__(self) -> None:
        self.corners, self.normals, self.classes, self.looks, self.owners = [], [], [], [], []

    def add(self, corners, normals, classes, looks=None, owners=None) -> None:
        n = len(corners)
        self.corners.append(corners)
        self.normals.append(normals)
        self.classes.append(classes)
        self.looks.append(np.full(n, -1) if looks is None else looks)
        self.owners.append(np.full(n, -1) if owners is None else owners)


def _wall_quads(axis: int, c, s0, s1, za, zb) -> np.ndarray:
    """(Q, 4, 3) quads in the plane ``axis`` = c (Q,), from s0 to s1 across and za to zb up."""
    zz0, zz1 = np.full(len(c), za), np.full(len(c), zb)
    if axis == 0:
        pts = [np.column_stack([c, s0, zz0]), np.column_stack([c, s1, zz0]),
               np.column_stack([c, s1, zz1]), np.column_stack([c, s0, zz1])]
    else:
        pts = [np.column_stack([s0, c, zz0]), np.column_stack([s1, c, zz0]),
               np.column_stack([s1, c, zz1]), np.column_stack([s0, c, zz1])]
    return np.stack(pts, axis=1)


def surfaces(plan, details=None) -> list[Part]:
    """The grid's surfaces of ``plan`` as classed parts (one per class and look), with the
    looks of ``details`` (a ``datagen.worlds.details.Details``, None: none).

    Returns:
        Parts named ``procedural/<class>`` (``procedural/<class>/<look>`` with a look),
        vertices in m (floor at z = 0), faces wound to face the free cells.
    """
    g = paint(plan)
    n_rects = len(plan.rects)
    framed, full = np.zeros(n_rects + 1, bool), np.zeros(n_rects + 1, bool)  # [-1]: none
    w_across, w_back = np.full(n_rects + 1, -1), np.zeros(n_rects + 1)
    s_side, s_across = np.zeros(n_rects + 1, int), np.full(n_rects + 1, -1)
    trim_top = np.zeros(n_rects + 1)  # a doorway's or trim's architrave top, m (0: none)
    if details is not None:
        for i, f in details.doors.items():
            framed[i] = f.framed
            if f.architrave is not None:
                trim_top[i] = f.head + f.architrave[0]
        for j, i in details.trims.items():
            trim_top[j] = trim_top[i]
        for i, w in details.windows.items():
            full[i], w_across[i] = w.full, 1 - w.along
            w_back[i] = w.line + w.outward * w.depth
        for i, side in details.sheets.items():
            r = plan.rects[i]
            s_side[i], s_across[i] = side, 1 if r[2] - r[0] > r[3] - r[1] else 0
    out = _Faces()
    xs, ys, free, top, bot = g.xs, g.ys, g.free, g.top.round(6), g.bot.round(6)
    # floor and ceilings of the free cells
    i, j = np.nonzero(free)
    x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
    raised = bot[i, j] > 0  # a recess's sill, a sill board
    lintel = (g.recess[i, j] >= 0) & ~full[g.recess[i, j]]  # a recess's head
    door_frame = framed[g.door[i, j]] & (g.door[i, j] >= 0)
    for z, up, cls, look in (
            (bot[i, j], 1.0, np.where(raised, C.WINDOW, C.FLOOR),
             np.where(raised, LOOKS.index(WINDOW_FRAME), -1)),
            (top[i, j], -1.0, np.where(g.door[i, j] >= 0, C.DOOR,
                                       np.where(lintel, C.WINDOW, C.CEILING)),
             np.where(door_frame, LOOKS.index(FRAME),
                      np.where(lintel, LOOKS.index(WINDOW_FRAME), -1)))):
        out.add(np.stack([np.column_stack([x0, y0, z]), np.column_stack([x1, y0, z]),
                          np.column_stack([x1, y1, z]), np.column_stack([x0, y1, z])], axis=1),
                np.tile([0.0, 0.0, up], (len(i), 1)), cls, look)
    # walls between neighbouring cells, split at every height in use
    sill, head = plan.window_z.round(6)
    levels = np.unique(np.concatenate([[0.0, sill, head], top[free], bot[free],
                                       trim_top[trim_top > 0]]).round(6))
    for axis in (0, 1):

        def grid(a, fill, axis=axis):
            return np.pad(a if axis == 0 else a.T, [(1, 1), (0, 0)], constant_values=fill)

        fr, bt, tp = grid(free, False), grid(bot, 0.0), grid(top, 0.0)
        dr, gl, sh, rc, tr = (grid(g.door, -1), grid(g.glass, False), grid(g.sheet, -1),
                              grid(g.recess, -1), grid(g.trim, -1))
        line = xs if axis == 0 else ys
        cross = ys if axis == 0 else xs
        sl, sr = slice(None, -1), slice(1, None)
        for a_sl, b_sl, sign in ((sl, sr, 1.0), (sr, sl, -1.0)):  # a: the cell faced
            fa, ba, ta, da, ra = fr[a_sl], bt[a_sl], tp[a_sl], dr[a_sl], rc[a_sl]
            fb, bb, tb, gb, sb = fr[b_sl], bt[b_sl], tp[b_sl], gl[b_sl], sh[b_sl]
            # under an architrave: a trim cell's face, or a lintel's over a doorway
            under = np.where(fb, np.where(da < 0, trim_top[dr[b_sl]], 0.0),
                             trim_top[tr[b_sl]])
            parts = [(np.where(fb, np.maximum(tb, ba), ba), ta),  # above b's range, or all
                     (ba, np.where(fb, np.minimum(ta, bb), ba))]  # below b's range
            for lower, (z_lo, z_hi) in enumerate(parts):
                k, m = np.nonzero(fa & (z_hi > z_lo + 1e-9))
                if lower and not len(k):
                    continue
                c, s0, s1 = line[k], cross[m], cross[m + 1]
                solid = ~fb[k, m]
                door, rec, sheet = da[k, m], ra[k, m], sb[k, m]
                base = np.where(~solid, C.WALL, np.where(
                    door >= 0, C.DOOR, np.where(gb[k, m] | (sheet >= 0), C.WINDOW, C.WALL)))
                base = np.where(rec >= 0, C.WINDOW, base)
                look = _wall_looks(axis, sign, c, solid, door, rec, sheet, framed, w_across,
                                   w_back, s_side, s_across)
                windowed = np.zeros(len(k), bool)
                if not lower:  # flat windows: the outer walls' faces in a window's span
                    beyond = c + sign * 1e-3  # just past the face, in cell b
                    outer_b = solid & ((beyond < plan.outer)
                                       | (beyond > plan.size[axis] - plan.outer))
                    mid = (s0 + s1) / 2
                    wins = plan.windows["y" if axis == 0 else "x"]
                    in_win = ((mid[:, None] > wins[None, :, 0])
                              & (mid[:, None] < wins[None, :, 1])).any(axis=1)
                    windowed = outer_b & in_win & (door < 0) & (base == C.WALL)
                lo_k, hi_k = z_lo[k, m], z_hi[k, m]
                for q in range(len(levels) - 1):
                    za, zb = levels[q], levels[q + 1]
                    use = (lo_k <= za + 1e-9) & (hi_k >= zb - 1e-9)
                    if not use.any():
                        continue
                    cls = np.where(windowed[use] & (za >= sill - 1e-9) & (zb <= head + 1e-9),
                                   C.WINDOW, base[use])
                    trimmed = zb <= under[k, m][use] + 1e-9
                    cls = np.where(trimmed, C.DOOR, cls)
                    normal = np.zeros((int(use.sum()), 3))
                    normal[:, axis] = -sign  # towards cell a
                    out.add(_wall_quads(axis, c[use], s0[use], s1[use], za, zb), normal, cls,
                            np.where(trimmed, LOOKS.index(FRAME), look[use]),
                            np.where(look[use] == LOOKS.index(WINDOW_VIEW), rec[use], -1))
    return _parts(out, details)


def _wall_looks(axis: int, sign: float, c, solid, door, rec, sheet, framed, w_across,
                w_back, s_side, s_across) -> np.ndarray:
    """(Q,) look indices of wall faces (normal along ``axis``, -sign; at line c (Q,))."""
    look = np.full(len(c), -1)
    look[solid & (door >= 0) & framed[door]] = LOOKS.index(FRAME)
    on_sheet = solid & (sheet >= 0) & (door < 0)
    across = on_sheet & (s_across[sheet] == axis) & (s_side[sheet] != 0)
    look[on_sheet] = LOOKS.index(WINDOW_FRAME)  # mullions, a sheet's ends
    look[across & (s_side[sheet] == -sign)] = LOOKS.index(GLASS_LOOK)
    look[across & (s_side[sheet] != -sign)] = LOOKS.index(HIDDEN)
    in_recess = rec >= 0
    look[in_recess] = LOOKS.index(WINDOW_FRAME)
    back = in_recess & solid & (w_across[rec] == axis) & (np.abs(c - w_back[rec]) < 1e-6)
    look[back] = LOOKS.index(WINDOW_VIEW)
    return look


def _view_uv(corners: np.ndarray, normal: np.ndarray, window) -> np.ndarray:
    """(Q, 4, 2) texture coordinates of the view at a window's back: u in panes from the
    window's left end seen from the room, v from its sill (0) to its head (1)."""
    right = np.cross(-normal, [0.0, 0.0, 1.0])  # seen from the front, u runs right
    ends = np.zeros((2, 3))
    ends[:, window.along] = window.a0, window.a1
    start = (ends @ right.T).min(axis=0)  # (Q,)
    pane = (window.a1 - window.a0) / window.panes
    u = (np.einsum("qkc,qc->qk", corners, right) - start[:, None]) / pane
    v = (corners[:, :, 2] - window.sill) / (window.head - window.sill)
    return np.stack([u, v], axis=-1)


def _parts(out: _Faces, details) -> list[Part]:
    """The collected quads as parts, one per class and look."""
    corners, faces = _quads(np.concatenate(out.corners), np.concatenate(out.normals))
    normal = np.concatenate(out.normals)
    cls = np.concatenate(out.classes).astype(np.uint8)
    look = np.concatenate(out.looks).astype(int)
    owner = np.concatenate(out.owners).astype(int)
    uv = np.full((len(corners), 4, 2), np.nan)
    for r in np.unique(owner[owner >= 0]):
        sel = owner == r
        uv[sel] = _view_uv(corners[sel], normal[sel], details.windows[int(r)])
    tri_uv = np.concatenate([uv[:, [0, 1, 2]], uv[:, [0, 2, 3]]])
    q_of = np.concatenate([np.arange(len(corners))] * 2)  # quad of each face
    vertices = corners.reshape(-1, 3)
    parts = []
    for c in np.unique(cls):
        for k in np.unique(look[cls == c]):
            f = faces[(cls[q_of] == c) & (look[q_of] == k)]
            sel = (cls[q_of] == c) & (look[q_of] == k)
            used, inv = np.unique(f, return_inverse=True)
            name = f"procedural/{C.NAMES[c]}" + ("" if k < 0 else f"/{LOOKS[k]}")
            parts.append(Part(vertices[used], inv.reshape(-1, 3), name, face_class=int(c),
                              uv=tri_uv[sel] if k >= 0 else None,
                              look="" if k < 0 else LOOKS[k]))
    return parts
