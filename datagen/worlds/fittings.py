"""The meshes of a procedural floor's details that are not painted with its plan
(datagen/worlds/details.py): door leaves, architraves, window frames, round columns.

Each is made of closed boxes (a round column: the sides of a prism), apart from the grid's
faces by a few millimetres, so no vertex is shared with the grid's mesh: their edges are the
boxes' own creases, which the localizer's outlines turn into the right class pairs from every
view (a leaf's edge against the floor or the room behind it, an architrave against the wall).
Classes: a leaf (its glass pane too) and an architrave door, a window frame window, a column
wall. Looks: a leaf's broad faces the door's texture fitted to the leaf, its edges, the
architrave and a glazed leaf's stiles and rails the frame's; window frames the window frame's.
"""

from __future__ import annotations

import numpy as np

from core import classes as C
from datagen.mesh.building import Part
from datagen.worlds.details import Details, DoorFit, Leaf, RoundColumn, WindowFit
from datagen.worlds.floor_mesh import FRAME, GLASS_LOOK, WINDOW_FRAME

OVERHANG = 0.002  # m an architrave reaches past the opening's reveals (hides their edge)
NEAR = 0.002  # m between a window frame and the recess's faces
#: A box's six sides: (axis, 0 or 1 for the low or high side, its corners' (i, j, k) order).
_SIDES = [(0, 0, [(0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)]),
          (0, 1, [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)]),
          (1, 0, [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]),
          (1, 1, [(0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1)]),
          (2, 0, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]),
          (2, 1, [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])]


def box(origin: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box from corner ``origin`` (3,) m along the three orthogonal ``edges`` (3, 3) m.

    Returns:
        vertices (24, 3) m (4 per side), faces (12, 3) wound outwards, side (12,) of each
        face: 2 * axis + (0: the side at origin, 1: the far one), axis the edge's row.
    """
    o, e = np.asarray(origin, np.float64), np.asarray(edges, np.float64)
    centre = o + e.sum(axis=0) / 2
    verts, faces, side = [], [], []
    for axis, far, corners in _SIDES:
        q = np.array([o + np.array(c, np.float64) @ e for c in corners])
        n = np.cross(q[1] - q[0], q[2] - q[0])
        if n @ (q.mean(axis=0) - centre) < 0:
            q = q[::-1]
        base = len(verts) * 4
        verts.append(q)
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
        side += [2 * axis + far] * 2
    return np.concatenate(verts), np.asarray(faces), np.asarray(side)


def _parts_of(boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray]], cls: int, name: str,
              look: str, broad: dict[int, str] | None = None, uv_of=None) -> list[Part]:
    """Parts of boxes (vertices, faces, side) of one class: faces of the sides in ``broad``
    (side -> look) take that look and ``uv_of(corners (T, 3, 3), box index)`` -> (T, 3, 2);
    the others ``look``, box-projected."""
    groups: dict[str, list] = {}
    for b, (v, f, side) in enumerate(boxes):
        for s in np.unique(side):
            key = (broad or {}).get(int(s), look)
            tri = v[f[side == s]]
            uv = uv_of(tri, b) if broad and int(s) in broad else None
            groups.setdefault(key, []).append((tri, uv))
    out = []
    for key, items in groups.items():
        tri = np.concatenate([t for t, _ in items])
        uv = (np.concatenate([u for _, u in items]) if all(u is not None for _, u in items)
              else None)
        out.append(Part(tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3),
                        f"{name}/{key}", face_class=cls, uv=uv, look=key))
    return out


def leaf_parts(leaf: Leaf, name: str) -> list[Part]:
    """A leaf: one box, or stiles and rails around a glass pane; its broad faces the door
    texture (u across the leaf from the hinge, v up), the rest the frame's."""
    z = np.array([0.0, 0.0, 1.0])
    w, t, h = leaf.w, leaf.t, leaf.height

    def piece(u0: float, u1: float, v0: float, v1: float):
        return box(leaf.hinge + u0 * w + v0 * z, np.array([(u1 - u0) * w, leaf.thickness * t,
                                                           (v1 - v0) * z]))

    if leaf.glazed is None:
        boxes = [piece(0.0, leaf.width, 0.0, h)]
    else:
        stile, bottom, top = leaf.glazed
        u1 = leaf.width - stile
        boxes = [piece(0.0, stile, 0.0, h), piece(u1, leaf.width, 0.0, h),
                 piece(stile + 0.001, u1 - 0.001, 0.0, bottom),
                 piece(stile + 0.001, u1 - 0.001, h - top, h)]

    def uv_of(tri: np.ndarray, _: int) -> np.ndarray:
        d = tri - leaf.hinge
        return np.stack([d @ w / leaf.width, (d @ z) / h], axis=-1)

    parts = _parts_of(boxes, C.DOOR, name, FRAME, {2: "door", 3: "door"}, uv_of)
    if leaf.glazed is not None:
        stile, bottom, top = leaf.glazed
        mid = leaf.hinge + leaf.thickness / 2 * t
        p = np.array([mid + (stile - 0.005) * w + (bottom - 0.005) * z,
                      mid + (leaf.width - stile + 0.005) * w + (bottom - 0.005) * z,
                      mid + (leaf.width - stile + 0.005) * w + (h - top + 0.005) * z,
                      mid + (stile - 0.005) * w + (h - top + 0.005) * z])
        parts.append(Part(p, np.array([[0, 1, 2], [0, 2, 3]]), f"{name}/pane",
                          face_class=C.DOOR, look=GLASS_LOOK))
    return parts


def architrave_parts(door: DoorFit, name: str) -> list[Part]:
    """The architrave on both faces of a doorway's wall: two posts and a head, ``OVERHANG``
    over the opening, standing on the floor; class door, the frame's look."""
    width, depth = door.architrave
    boxes = []
    e_along = np.zeros(3)
    e_along[door.along] = 1.0
    z = np.array([0.0, 0.0, 1.0])
    a0, a1, head = door.a0 + OVERHANG, door.a1 - OVERHANG, door.head - OVERHANG
    for face, out in ((door.faces[0], np.sign(door.faces[0] - door.faces[1])),
                      (door.faces[1], np.sign(door.faces[1] - door.faces[0]))):
        e_out = np.zeros(3)
        e_out[1 - door.along] = out
        at = np.zeros(3)
        at[1 - door.along] = face
        top = door.head + width
        for s0, s1 in ((a0 - width, a0), (a1, a1 + width)):
            boxes.append(box(at + s0 * e_along, np.array([(s1 - s0) * e_along, depth * e_out,
                                                          top * z])))
        boxes.append(box(at + (a0 + 0.001) * e_along + head * z,
                         np.array([(a1 - a0 - 0.002) * e_along, depth * e_out,
                                   (top - head - 0.001) * z])))
    return _parts_of(boxes, C.DOOR, name, FRAME)


def frame_parts(win: WindowFit, name: str) -> list[Part]:
    """A recessed window's frame: border bars, mullions between equal panes, transoms split
    at the mullions, ``NEAR`` off the recess's faces; class window."""
    fw, fd = win.frame
    e_along, e_in = np.zeros(3), np.zeros(3)
    e_along[win.along], e_in[1 - win.along] = 1.0, -win.outward
    z = np.array([0.0, 0.0, 1.0])
    back = np.zeros(3)
    back[1 - win.along] = win.line + win.outward * (win.depth - NEAR)
    a0, a1, z0, z1 = win.a0 + NEAR, win.a1 - NEAR, win.sill + NEAR, win.head - NEAR

    def bar(s0: float, s1: float, v0: float, v1: float):
        return box(back + s0 * e_along + v0 * z,
                   np.array([(s1 - s0) * e_along, (fd - NEAR) * e_in, (v1 - v0) * z]))

    pane = (win.a1 - win.a0) / win.panes
    mullions = [win.a0 + k * pane for k in range(1, win.panes)]
    boxes = [bar(a0, a0 + fw, z0, z1), bar(a1 - fw, a1, z0, z1),
             bar(a0 + fw + 0.001, a1 - fw - 0.001, z0, z0 + fw),
             bar(a0 + fw + 0.001, a1 - fw - 0.001, z1 - fw, z1)]
    boxes += [bar(p - fw / 2, p + fw / 2, z0 + fw + 0.001, z1 - fw - 0.001) for p in mullions]
    cuts = [a0 + fw, *[c for p in mullions for c in (p - fw / 2, p + fw / 2)], a1 - fw]
    for t in win.transoms:
        for s0, s1 in zip(cuts[::2], cuts[1::2], strict=True):
            boxes.append(bar(s0 + 0.001, s1 - 0.001, t - fw / 2, t + fw / 2))
    return _parts_of(boxes, C.WINDOW, name, WINDOW_FRAME)


def column_part(col: RoundColumn, name: str) -> Part:
    """The sides of a round column's prism (a half column's: the half off its wall), from the
    floor to its top; class wall."""
    n = col.sides
    if col.engaged is None:
        phi = np.linspace(0.0, 2 * np.pi, n + 1)
    else:
        away = np.arctan2(-col.engaged[1], -col.engaged[0])
        phi = away + np.linspace(-np.pi / 2, np.pi / 2, n // 2 + 1)
    ring = col.centre + col.radius * np.column_stack([np.cos(phi), np.sin(phi)])
    lo = np.column_stack([ring, np.zeros(len(ring))])
    hi = np.column_stack([ring, np.full(len(ring), col.top)])
    k = len(ring) - 1
    v = np.concatenate([lo, hi])
    i = np.arange(k)
    faces = np.concatenate([np.column_stack([i, i + 1, k + 2 + i]),
                            np.column_stack([i, k + 2 + i, k + 1 + i])])  # outwards (CCW)
    return Part(v, faces, name, face_class=C.WALL)


def fitting_parts(details: Details) -> list[Part]:
    """Every detail's mesh as parts (named ``procedural/<detail><n>/...``)."""
    parts = []
    for n, door in enumerate(details.doors.values()):
        for k, leaf in enumerate(door.leaves):
            parts += leaf_parts(leaf, f"procedural/leaf{n}_{k}")
        if door.architrave is not None:
            parts += architrave_parts(door, f"procedural/architrave{n}")
    for n, win in enumerate(details.windows.values()):
        if win.frame is not None:
            parts += frame_parts(win, f"procedural/window_frame{n}")
    parts += [column_part(c, f"procedural/column{n}") for n, c in enumerate(details.columns)]
    return parts

