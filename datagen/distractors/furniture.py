"""Furnished-room kinds (class clutter): tall shelving (``shelf``: a run against a wall or
free-standing; ``shelf_rows``: parallel runs with aisles between, a bookstore's or library's
stacks), desks with screens and a chair, shop and reception counters (straight or L-shaped),
hospital beds, and the chair.

Each but the chair is a ``_painted`` mesh: its parts carry tones
(``datagen.appearance.materials.TONES``: a wood, laminate or metal carcass, books and boxes of
many colours, dark screens, a pale mattress) and its footprint is a chain of circles (a long
or L-shaped object fits where one circle about it would not). Object frame as
``datagen.distractors.meshes``: z up, standing on z = 0, the footprint centred on the origin;
a wall-standing object's back is at -x (it faces +x).
"""

from __future__ import annotations

import numpy as np
import trimesh

from datagen.appearance.materials import BODY, DARK, FRAME, ITEM, LIGHT, METAL
from datagen.distractors.primitives import _box, _boxes, _ellipsoid, _join, _painted, _rod

SHELF_HEIGHT = (1.8, 2.4)  # m, shelving units' height range


def _chair(rng: np.random.Generator) -> trimesh.Trimesh:
    """A four-legged or an office chair (a column on a five-star base), facing +x."""
    s, seat_z = rng.uniform(0.4, 0.5), rng.uniform(0.42, 0.48)
    t = rng.uniform(0.03, 0.06)
    back_h = rng.uniform(0.35, 0.5)
    parts = [_box((s, s, t), (0, 0, seat_z - t / 2)),
             _box((0.04, s, back_h), (-s / 2 + 0.02, 0, seat_z + back_h / 2 + 0.02))]
    if rng.random() < 0.5:  # four legs
        r = rng.uniform(0.012, 0.022)
        for x in (-1, 1):
            for y in (-1, 1):
                p = np.array([x * (s / 2 - 0.03), y * (s / 2 - 0.03)])
                parts.append(_rod([*p, 0.0], [*p, seat_z - t], r, 8))
    else:  # office chair: column on a five-star base with casters
        parts.append(_rod([0, 0, 0.08], [0, 0, seat_z - t], 0.025, 10))
        for k in range(5):
            a = 2 * np.pi * k / 5
            arm = 0.3
            parts.append(_box((arm, 0.04, 0.03), (np.cos(a) * arm / 2, np.sin(a) * arm / 2,
                                                  0.07), a))
            parts.append(_ellipsoid((np.cos(a) * arm, np.sin(a) * arm, 0.03), (0.03,) * 3, 0))
        if rng.random() < 0.6:  # armrests
            for y in (-1, 1):
                parts.append(_box((0.3, 0.05, 0.03), (0, y * (s / 2 + 0.02), seat_z + 0.2)))
                parts.append(_rod([0, y * (s / 2 + 0.02), seat_z], [0, y * (s / 2 + 0.02),
                                                                    seat_z + 0.2], 0.015, 8))
    return _join(parts)


def _row_of_items(rng: np.random.Generator, y0: float, y1: float, front: float, side: int,
                  depth: float, z: float, room: float) -> tuple[np.ndarray, np.ndarray]:
    """What stands on one shelf between y0 and y1 (m): books side by side (their heights and
    depths varying about a series' own, now and then a gap), a few boxes, or nothing; their
    fronts at x = ``front`` facing ``side`` (+1: +x), at most ``depth`` deep and ``room``
    tall, standing on z.

    Returns:
        centres, extents: (N, 3) m.
    """
    style = rng.random()
    if style < 0.06 or room < 0.12 or y1 - y0 < 0.1:
        return np.zeros((0, 3)), np.zeros((0, 3))
    if style < 0.2:  # boxes, binders, stock
        n = int(rng.integers(1, 4))
        w = rng.uniform(0.2, 0.4, n)
        thick = w * min(1.0, (y1 - y0) / w.sum())
    else:  # books; sparse shelves keep a part of the row
        n = int((y1 - y0) / 0.018) + 2
        thick = rng.uniform(0.018, 0.06, n)
    h = np.clip(rng.uniform(0.55, 0.92) * room * rng.uniform(0.85, 1.12, n), 0.1, room - 0.01)
    d = np.clip(rng.uniform(0.6, 0.95) * depth * rng.uniform(0.9, 1.06, n), 0.08, depth)
    step = thick + 0.002
    if rng.random() < 0.35:  # a gap after a random book
        step[rng.integers(n)] += rng.uniform(0.05, 0.25)
    width = (y1 - y0) * (rng.uniform(0.3, 0.7) if style < 0.3 else 1.0)
    start = y0 + (0.0 if rng.random() < 0.5 else (y1 - y0) - width)
    ends = start + np.cumsum(step)
    keep = ends <= start + width - 0.003
    thick, h, d, ends = thick[keep], h[keep], d[keep], ends[keep]
    y = ends - thick / 2 - 0.001
    x = front - side * d / 2
    centres = np.column_stack([x, y, z + h / 2])
    return centres, np.column_stack([d, thick, h])


def _shelf_run(rng: np.random.Generator, units: int, width: float, depth: float,
               height: float, double: bool, tone: int, x0: float = 0.0
               ) -> list[tuple[int, trimesh.Trimesh]]:
    """A run of ``units`` shelving units of ``width`` (m) side by side along y, ``depth``
    along x about x0, ``height`` tall, their shelves full of books and boxes: single-sided
    open to +x with a back panel, or double-sided (a gondola) with a divider.

    Returns:
        (tone, mesh) pieces: the carcass (of ``tone``) and the items (tone item).
    """
    L = units * width
    t = rng.uniform(0.018, 0.03)  # board thickness
    plinth = rng.uniform(0.06, 0.12)
    levels = max(4, round((height - plinth) / rng.uniform(0.3, 0.4)))
    boards = plinth + (height - t - plinth) * np.arange(1, levels + 1) / levels  # undersides
    sides_y = -L / 2 + t / 2 + np.arange(units + 1) * (L - t) / units
    centres = [[x0, y, height / 2] for y in sides_y] + [[x0, 0, z + t / 2] for z in boards]
    extents = [[depth, t, height]] * (units + 1) + [[depth, L, t]] * levels
    centres.append([x0, 0, plinth / 2])
    extents.append([depth - 0.04, L - t, plinth])
    panel = 0.012 if not double else 0.016
    back = x0 if double else x0 - depth / 2 + panel / 2
    centres.append([back, 0, (plinth + height) / 2])
    extents.append([panel, L - t, height - plinth])
    pieces = [(tone, _boxes(np.array(centres), np.array(extents)))]
    floors = np.concatenate([[plinth], boards[:-1] + t])
    for side in ((1, -1) if double else (1,)):
        front = x0 + side * (depth / 2 - rng.uniform(0.0, 0.02))
        reach = (depth / 2 - panel / 2) if double else depth - panel
        rows = [_row_of_items(rng, sides_y[k] + t / 2 + 0.003, sides_y[k + 1] - t / 2, front,
                              side, reach - 0.02, z, top - z)
                for k in range(units) for z, top in zip(floors, boards, strict=True)]
        c, e = np.concatenate([r[0] for r in rows]), np.concatenate([r[1] for r in rows])
        if len(c):  # no bottoms or backs: a third fewer triangles to rebuild per image
            pieces.append((ITEM, _boxes(c, e, hidden=((2, -1), (0, -side)))))
    return pieces


def _carcass(rng: np.random.Generator) -> int:
    """The tone of a shelving carcass: wood or laminate, or (a quarter) metal."""
    return FRAME if rng.random() < 0.75 else METAL


def _shelf(rng: np.random.Generator) -> trimesh.Trimesh:
    """Tall shelving: a run of 1-3 units (0.8-1 m each, 1.8-2.4 m tall) along y, open to +x
    (0.3-0.42 m deep, its back against a wall) or both ways (0.5-0.7 m, free-standing)."""
    double = rng.random() < 0.4
    units, width = int(rng.integers(1, 4)), rng.uniform(0.8, 1.0)
    depth = rng.uniform(0.5, 0.7) if double else rng.uniform(0.3, 0.42)
    return _painted(_shelf_run(rng, units, width, depth, rng.uniform(*SHELF_HEIGHT), double,
                               _carcass(rng)))


def _shelf_rows(rng: np.random.Generator) -> trimesh.Trimesh:
    """2-3 parallel double-sided runs of 1-3 units along y with aisles of 0.9-1.5 m between
    them: the stacks of a bookstore or a library (the aisles are free floor: the footprint
    covers the runs only)."""
    runs, units = int(rng.integers(2, 4)), int(rng.integers(1, 4))
    width, depth = rng.uniform(0.8, 1.0), rng.uniform(0.5, 0.7)
    height, aisle = rng.uniform(*SHELF_HEIGHT), rng.uniform(0.9, 1.5)
    xs = (np.arange(runs) - (runs - 1) / 2) * (depth + aisle)
    pieces, rects, tone = [], [], _carcass(rng)
    for x in xs:
        pieces += _shelf_run(rng, units, width, depth, height, True, tone, float(x))
        rects.append([x - depth / 2, -units * width / 2, x + depth / 2, units * width / 2])
    return _painted(pieces, np.array(rects))


def _desk(rng: np.random.Generator) -> trimesh.Trimesh:
    """An office desk (1.2-1.8 m wide, 0.6-0.8 m deep) on legs or panel ends, maybe a drawer
    pedestal, with one or two screens on stands at the back (-x), a keyboard and mouse,
    papers and a chair in front (+x)."""
    lx, ly = rng.uniform(0.6, 0.8), rng.uniform(1.2, 1.8)
    h, t = rng.uniform(0.72, 0.76), rng.uniform(0.025, 0.04)
    frame = [[0, 0, h - t / 2]], [[lx, ly, t]]
    metal: tuple[list, list] = ([], [])
    if rng.random() < 0.5:  # four square legs
        leg = rng.uniform(0.04, 0.06)
        for x in (-1, 1):
            for y in (-1, 1):
                metal[0].append([x * (lx / 2 - 0.05), y * (ly / 2 - 0.05), (h - t) / 2])
                metal[1].append([leg, leg, h - t])
    else:  # panel ends and a modesty panel
        for y in (-1, 1):
            frame[0].append([0, y * (ly / 2 - 0.03), (h - t) / 2])
            frame[1].append([lx - 0.06, 0.025, h - t])
        frame[0].append([-lx / 2 + 0.08, 0, h - t - 0.2])
        frame[1].append([0.02, ly - 0.1, 0.35])
    pedestal = rng.random() < 0.5
    if pedestal:  # a drawer pedestal with three handles
        y = rng.choice([-1, 1]) * (ly / 2 - 0.3)
        ph = h - t - 0.03
        frame[0].append([0.0, y, 0.02 + ph / 2])
        frame[1].append([lx * 0.75, 0.4, ph])
        for k in range(3):
            metal[0].append([lx * 0.375 + 0.01, y, 0.02 + ph * (k + 0.75) / 3])
            metal[1].append([0.02, 0.12, 0.02])
    dark: tuple[list, list] = ([], [])
    screens = 1 if rng.random() < 0.6 else 2
    mw, mh = rng.uniform(0.48, 0.62), rng.uniform(0.28, 0.38)
    lift, mx = rng.uniform(0.08, 0.15), -lx / 2 + rng.uniform(0.12, 0.22)
    shift = rng.uniform(-0.1, 0.1)
    for k in range(screens):
        y = (k - (screens - 1) / 2) * (mw + 0.02) + shift
        dark[0].extend([[mx, y, h + lift + mh / 2], [mx - 0.04, y, h + lift / 2 + 0.01],
                        [mx - 0.02, y, h + 0.0075]])
        dark[1].extend([[0.03, mw, mh], [0.03, 0.06, lift], [0.18, 0.22, 0.015]])
    kx = min(mx + rng.uniform(0.22, 0.32), lx / 2 - 0.08)
    ky = rng.uniform(-0.1, 0.1)
    dark[0].extend([[kx, ky, h + 0.01], [kx, ky + 0.3, h + 0.015]])
    dark[1].extend([[0.14, 0.44, 0.02], [0.1, 0.06, 0.03]])
    pieces = [(FRAME, _boxes(*map(np.array, frame))), (DARK, _boxes(*map(np.array, dark)))]
    if metal[0]:
        pieces.append((METAL, _boxes(*map(np.array, metal))))
    if rng.random() < 0.5:  # papers
        n = int(rng.integers(1, 4))
        c = np.column_stack([rng.uniform(-0.1, lx / 2 - 0.15, n),
                             rng.choice([-1, 1], n) * rng.uniform(0.3, ly / 2 - 0.15, n),
                             np.full(n, h + 0.005)])
        pieces.append((LIGHT, _boxes(c, np.tile([0.3, 0.21, 0.01], (n, 1)))))
    if rng.random() < 0.6:  # the chair facing the desk, pushed in (its base clear of a
        # pedestal) or pulled out
        chair = _chair(rng)
        chair.apply_transform(trimesh.transformations.rotation_matrix(np.pi, (0, 0, 1)))
        out = rng.uniform(0.25, 0.4) if pedestal else rng.uniform(0.0, 0.35)
        chair.apply_translation([lx / 2 + out, rng.uniform(-0.2, 0.2), 0])
        pieces.append((BODY, chair))
    return _painted(pieces)


def _counter_leg(x0: float, x1: float, y0: float, y1: float, h: float, front: int,
                 ledge: float, kick: float, top_t: float) -> tuple[list, list, list, list]:
    """One straight stretch of a counter over [x0, x1] x [y0, y1] (m), ``h`` tall, its
    customer side at +x (``front`` 0) or +y (1): the body on a recessed plinth (``kick``
    deep) and its worktop, and where ``ledge`` > 0 a front panel rising to h + ledge under a
    transaction top.

    Returns:
        centres and extents (lists of (3,) m) of the body (tone body) and of the tops
        (tone frame).
    """
    lo, hi = np.array([x0, y0]), np.array([x1, y1])
    a = front  # the axis of the customer side
    body_lo, body_hi = lo.copy(), hi.copy()
    body_hi[a] -= kick

    def box(lo_xy, hi_xy, z0, z1):
        return [*(np.add(lo_xy, hi_xy) / 2), (z0 + z1) / 2], [*(np.subtract(hi_xy, lo_xy)),
                                                               z1 - z0]

    body = [box(body_lo, body_hi, 0.0, 0.1), box(lo, hi, 0.1, h - top_t)]
    over = hi.copy()
    over[a] += 0.03 if ledge == 0 else -0.04  # over the front, or up to the front panel
    tops = [box(lo, over, h - top_t, h)]
    if ledge > 0:
        p_lo = hi.copy()
        p_lo[1 - a] = lo[1 - a]
        p_lo[a] = hi[a] - 0.04
        body.append(box(p_lo, hi, 0.0, h + ledge - top_t))
        t_lo, t_hi = lo.copy(), hi.copy()
        t_lo[a], t_hi[a] = hi[a] - 0.3, hi[a] + 0.06
        tops.append(box(t_lo, t_hi, h + ledge - top_t, h + ledge))
    return ([c for c, _ in body], [e for _, e in body], [c for c, _ in tops],
            [e for _, e in tops])


def _counter(rng: np.random.Generator) -> trimesh.Trimesh:
    """A shop or reception counter: 1.6-3.5 m long (along y), 0.55-0.75 m deep, 0.9-1.05 m
    tall, its customer side at +x; maybe L-shaped (a 1-2 m return along x at one end, its
    customer side at +y), maybe with a raised transaction ledge, a screen and things on it."""
    L, D, h = rng.uniform(1.6, 3.5), rng.uniform(0.55, 0.75), rng.uniform(0.9, 1.05)
    top_t, kick = rng.uniform(0.03, 0.05), rng.uniform(0.05, 0.09)
    ledge = rng.uniform(0.15, 0.3) if rng.random() < 0.5 else 0.0
    legs = [(0.0, D, 0.0, L, 0)]
    if rng.random() < 0.4:
        L2 = rng.uniform(1.0, 2.0)
        legs.append((D - L2, D, L - D, L, 1))
    body_c, body_e, top_c, top_e = [], [], [], []
    for x0, x1, y0, y1, front in legs:
        bc, be, tc, te = _counter_leg(x0, x1, y0, y1, h, front, ledge, kick, top_t)
        body_c += bc
        body_e += be
        top_c += tc
        top_e += te
    pieces = [(BODY, _boxes(np.array(body_c), np.array(body_e))),
              (FRAME, _boxes(np.array(top_c), np.array(top_e)))]
    sy = rng.uniform(0.3, L - 0.6)
    if rng.random() < 0.7:  # a screen on a stand, facing the staff (-x)
        pieces.append((DARK, _boxes(np.array([[0.2, sy, h + 0.3], [0.23, sy, h + 0.07]]),
                                    np.array([[0.03, 0.5, 0.32], [0.04, 0.06, 0.14]]))))
    n = int(rng.integers(0, 4))  # things on the top (not on a ledge): a till, boxes, leaflets
    if n:
        room = D - (0.3 if ledge else 0.0) - 0.04  # m of the top's depth in front of a ledge
        e = rng.uniform([0.1, 0.1, 0.03], [min(0.35, room), 0.35, 0.3], (n, 3))
        far = L - 0.2 - (D if len(legs) > 1 else 0.0)  # short of an L's return
        c = np.column_stack([0.02 + e[:, 0] / 2 + rng.random(n) * (room - e[:, 0]),
                             rng.uniform(0.2, far, n), h + e[:, 2] / 2])
        pieces.append((ITEM, _boxes(c, e)))
    rects = [[x0, y0, x1 + (0.06 if f == 0 else 0), y1 + (0.06 if f == 1 else 0)]
             for x0, x1, y0, y1, f in legs]
    return _painted(pieces, np.array(rects))


def _pitched(extents: tuple[float, float, float], hinge: tuple[float, float],
             angle: float) -> trimesh.Trimesh:
    """A box lying on z = hinge z with its +x end at the hinge (x, z) (m), raised by
    ``angle`` (rad) about the hinge's y axis: a bed's raised head section."""
    box = _box(extents, (hinge[0] - extents[0] / 2, 0, hinge[1] + extents[2] / 2))
    T = trimesh.transformations.rotation_matrix(angle, (0, 1, 0), (hinge[0], 0, hinge[1]))
    box.apply_transform(T)
    return box


def _bed(rng: np.random.Generator) -> trimesh.Trimesh:
    """A hospital bed (2-2.2 m along x, 0.9-1.05 m wide): a metal frame on lift columns and
    casters, a pale mattress whose head section may be raised, a blanket, a pillow, a head
    board at -x (against the wall), a foot board, maybe side rails and a drip stand."""
    L, W = rng.uniform(2.0, 2.2), rng.uniform(0.9, 1.05)
    zm, mt = rng.uniform(0.5, 0.72), rng.uniform(0.12, 0.18)  # mattress top, thickness
    zf = zm - mt  # the deck under the mattress
    frame_tone = METAL if rng.random() < 0.6 else LIGHT
    fc = [[0, 0, zf - 0.03], [0, W / 2 - 0.02, zf - 0.05], [0, -W / 2 + 0.02, zf - 0.05]]
    fe = [[L - 0.06, W - 0.02, 0.06], [L - 0.06, 0.04, 0.1], [L - 0.06, 0.04, 0.1]]
    metal_c = [[x * (L / 2 - 0.45), 0, (zf - 0.06 + 0.22) / 2] for x in (-1, 1)]
    metal_e = [[0.12, 0.12, zf - 0.06 - 0.22]] * 2
    dark_c = [[0, 0, 0.17]] + [[x * (L / 2 - 0.25), y * (W / 2 - 0.2), 0.06]
                               for x in (-1, 1) for y in (-1, 1)]
    dark_e = [[L - 0.4, W - 0.35, 0.1]] + [[0.1, 0.05, 0.12]] * 4
    pieces = [(frame_tone, _boxes(np.array(fc), np.array(fe))),
              (METAL, _boxes(np.array(metal_c), np.array(metal_e))),
              (DARK, _boxes(np.array(dark_c), np.array(dark_e)))]
    head_len = rng.uniform(0.7, 0.85)
    joint = -L / 2 + 0.05 + head_len  # where a raised head section hinges
    angle = rng.uniform(np.deg2rad(15), np.deg2rad(45)) if rng.random() < 0.4 else 0.0
    mattress = [_box((L / 2 - 0.05 - joint, W - 0.04, mt), ((L / 2 - 0.05 + joint) / 2, 0,
                                                             zf + mt / 2)),
                _pitched((head_len, W - 0.04, mt), (joint, zf), angle)]
    pillow_at = np.array([joint - head_len + 0.25, zf + mt + 0.05])
    c, s = np.cos(angle), np.sin(angle)
    rel = pillow_at - [joint, zf]
    pillow_at = np.array([joint, zf]) + [c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1]]
    pieces.append((LIGHT, trimesh.util.concatenate(
        mattress + [_ellipsoid((pillow_at[0], 0, pillow_at[1]), (0.18, W * 0.32, 0.07), 1)])))
    board_tone = FRAME if rng.random() < 0.5 else BODY
    head_top, foot_top = zm + rng.uniform(0.35, 0.55), zm + rng.uniform(0.08, 0.2)
    boards = [_box((0.05, W + 0.04, head_top - zf + 0.2), (-L / 2 + 0.025, 0,
                                                           (head_top + zf - 0.2) / 2)),
              _box((0.05, W + 0.04, foot_top - zf + 0.2), (L / 2 - 0.025, 0,
                                                           (foot_top + zf - 0.2) / 2))]
    pieces.append((board_tone, trimesh.util.concatenate(boards)))
    if rng.random() < 0.7:  # a blanket over the foot end, hanging over the sides
        bl = rng.uniform(0.5, 0.65) * L
        bx = L / 2 - 0.06 - bl / 2
        pieces.append((BODY, _boxes(
            np.array([[bx, 0, zm + 0.015], [bx, W / 2 + 0.01, zm - 0.06],
                      [bx, -W / 2 - 0.01, zm - 0.06]]),
            np.array([[bl, W + 0.04, 0.03], [bl, 0.02, 0.18], [bl, 0.02, 0.18]]))))
    if rng.random() < 0.6:  # side rails along the head half
        rl = rng.uniform(0.6, 0.9)
        rx = -L / 2 + 0.1 + rl / 2
        pieces.append((frame_tone, _boxes(
            np.array([[rx, y * (W / 2 + 0.04), zm + 0.12] for y in (-1, 1)]),
            np.array([[rl, 0.03, 0.24]] * 2))))
    if rng.random() < 0.25:  # a drip stand by the head
        y = rng.choice([-1, 1]) * (W / 2 + 0.12)
        top = rng.uniform(1.8, 2.0)
        pieces.append((METAL, trimesh.util.concatenate([
            _rod([-L / 2 + 0.2, y, 0.05], [-L / 2 + 0.2, y, top], 0.012, 8),
            _box((0.4, 0.04, 0.03), (-L / 2 + 0.2, y, 0.03)),
            _box((0.04, 0.4, 0.03), (-L / 2 + 0.2, y, 0.03)),
            _box((0.25, 0.02, 0.02), (-L / 2 + 0.2, y, top - 0.03))])))
    return _painted(pieces)
