"""The distractors' meshes, drawn per kind: furniture-like clutter (``CLUTTER_KINDS``; the
furnished-room kinds in ``furniture``) and people, in an object frame with z up, the origin at
the centre of the footprint on the floor (z = 0) and, for people, facing +x; and a mesh's
footprint (a circle about the origin, or its maker's chain of circles)."""

from __future__ import annotations

import numpy as np
import trimesh

from datagen.distractors.furniture import (
    SHELF_HEIGHT,
    _bed,
    _chair,
    _counter,
    _desk,
    _shelf,
    _shelf_rows,
)
from datagen.distractors.primitives import _box, _capsule, _ellipsoid, _frustum, _join, _rod

#: The furnished-room kinds (``furniture``): painted parts, footprints of many circles.
FURNISHED_KINDS: tuple[str, ...] = ("shelf", "shelf_rows", "desk", "counter", "bed")
CLUTTER_KINDS: tuple[str, ...] = ("box", "cabinet", "chair", "table", "plant", "trolley", "bin",
                                   "bench", "sofa", "whiteboard", *FURNISHED_KINDS)
MAX_HEIGHT = SHELF_HEIGHT[1]  # m, the tallest clutter object (shelving)
SMALL_HEIGHT = 1.8  # m, the tallest cabinet, plant or whiteboard
MAX_FACES = 16000  # the most faces of one object (parallel runs of shelving full of books)


def _cardboard(rng: np.random.Generator) -> trimesh.Trimesh:
    parts, z = [], 0.0
    size = rng.uniform([0.35, 0.3, 0.25], [0.7, 0.6, 0.55])
    for _ in range(rng.integers(1, 4)):
        parts.append(_box(tuple(size), (rng.normal(0, 0.03), rng.normal(0, 0.03),
                                        z + size[2] / 2), rng.normal(0, 0.15)))
        z += size[2]
        size = size * rng.uniform(0.6, 1.0, 3)
        if z + size[2] > 1.4:
            break
    return _join(parts)


def _cabinet(rng: np.random.Generator) -> trimesh.Trimesh:
    w, d = rng.uniform(0.45, 1.0), rng.uniform(0.35, 0.6)
    h = rng.uniform(0.7, SMALL_HEIGHT)
    parts = [_box((d, w, h), (0, 0, h / 2))]
    if rng.random() < 0.5:  # filing cabinet: drawers with handles on the front (+x)
        drawers = int(np.clip(round(h / 0.33), 2, 5))
        for i in range(drawers):
            zc = h * (i + 0.75) / drawers
            parts.append(_box((0.03, 0.15, 0.025), (d / 2 + 0.015, 0, zc)))
    else:  # two doors with vertical handles and a plinth
        for s in (-1, 1):
            parts.append(_box((0.03, 0.025, 0.15), (d / 2 + 0.015, s * 0.06, 0.55 * h)))
        parts.append(_box((d * 1.02, w * 1.02, 0.04), (0, 0, h + 0.02)))
    return _join(parts)


def _table(rng: np.random.Generator) -> trimesh.Trimesh:
    lx, ly = rng.uniform(0.5, 1.0), rng.uniform(0.45, 0.7)
    h, t = rng.uniform(0.7, 0.78), rng.uniform(0.025, 0.04)
    parts = [_box((lx, ly, t), (0, 0, h - t / 2))]
    r = rng.uniform(0.015, 0.03)
    for x in (-1, 1):
        for y in (-1, 1):
            p = np.array([x * (lx / 2 - 0.05), y * (ly / 2 - 0.05)])
            parts.append(_rod([*p, 0.0], [*p, h - t], r, 8))
    if rng.random() < 0.5:  # drawer block under the top, or items on it
        parts.append(_box((lx * 0.35, ly * 0.9, 0.15), (lx * 0.25, 0, h - t - 0.075)))
    if rng.random() < 0.6:
        for _ in range(rng.integers(1, 4)):
            e = rng.uniform([0.1, 0.1, 0.03], [0.35, 0.3, 0.3])
            parts.append(_box(tuple(e), (rng.uniform(-0.5, 0.5) * (lx - e[0]),
                                         rng.uniform(-0.5, 0.5) * (ly - e[1]), h + e[2] / 2),
                              rng.uniform(-np.pi, np.pi)))
    return _join(parts)


def _plant(rng: np.random.Generator) -> trimesh.Trimesh:
    r_top, pot_h = rng.uniform(0.12, 0.22), rng.uniform(0.2, 0.4)
    parts = [_frustum(r_top * rng.uniform(0.65, 0.85), r_top, pot_h)]
    total = rng.uniform(0.5, 1.6)
    stem_top = max(pot_h + 0.1, total - 0.25)
    parts.append(_rod([0, 0, pot_h], [0, 0, stem_top], 0.015, 6))
    spread = rng.uniform(0.15, 0.35)
    for _ in range(rng.integers(4, 9)):
        rad = rng.uniform(0.08, 0.18)
        z_lo = max(pot_h + rad, stem_top - 0.4)
        c = (rng.uniform(-1, 1) * spread, rng.uniform(-1, 1) * spread,
             rng.uniform(z_lo, max(z_lo, stem_top)))
        parts.append(_ellipsoid(c, (rad, rad, rad * rng.uniform(0.7, 1.2)), 1))
    mesh = _join(parts)
    lo, hi = mesh.bounds
    if hi[2] > SMALL_HEIGHT:
        mesh.apply_scale([1.0, 1.0, SMALL_HEIGHT / hi[2]])
    return mesh


def _trolley(rng: np.random.Generator) -> trimesh.Trimesh:
    """A service cart: 2-3 shelves on four corner posts, casters, a push handle (at -x)."""
    lx, ly = rng.uniform(0.55, 0.9), rng.uniform(0.4, 0.55)
    h = rng.uniform(0.8, 1.0)
    shelves = int(rng.integers(2, 4))
    parts = []
    for i in range(shelves):
        z = 0.15 + (h - 0.15) * i / (shelves - 1)
        parts.append(_box((lx, ly, 0.03), (0, 0, z)))
        if rng.random() < 0.4:  # a load on the shelf
            e = rng.uniform([0.15, 0.15, 0.05], [0.4, 0.35, 0.2])
            if i < shelves - 1:
                e[2] = min(e[2], (h - 0.15) / (shelves - 1) - 0.05)
            parts.append(_box(tuple(e), (rng.uniform(-0.2, 0.2) * lx, 0, z + 0.015 + e[2] / 2)))
    for x in (-1, 1):
        for y in (-1, 1):
            p = np.array([x * (lx / 2 - 0.02), y * (ly / 2 - 0.02)])
            parts.append(_rod([*p, 0.1], [*p, h], 0.012, 6))
            parts.append(_ellipsoid((*p, 0.05), (0.05, 0.02, 0.05), 0))  # caster
    for y in (-1, 1):  # the push handle
        parts.append(_rod([-lx / 2, y * (ly / 2 - 0.05), h], [-lx / 2 - 0.1, y * (ly / 2 - 0.05),
                                                                h + 0.1], 0.012, 6))
    parts.append(_rod([-lx / 2 - 0.1, -(ly / 2 - 0.05), h + 0.1],
                      [-lx / 2 - 0.1, ly / 2 - 0.05, h + 0.1], 0.015, 6))
    return _join(parts)


def _bin(rng: np.random.Generator) -> trimesh.Trimesh:
    """A waste bin (a tapered round bin, sometimes with a lid) or a wheelie bin."""
    if rng.random() < 0.6:
        r, h = rng.uniform(0.14, 0.25), rng.uniform(0.3, 0.75)
        parts = [_frustum(r * rng.uniform(0.75, 0.95), r, h)]
        if rng.random() < 0.5:  # a domed or flat lid
            parts.append(_ellipsoid((0, 0, h), (r * 1.02, r * 1.02, rng.uniform(0.02, 0.12)), 1))
        return _join(parts)
    w, d, h = rng.uniform(0.45, 0.6), rng.uniform(0.5, 0.7), rng.uniform(0.9, 1.1)
    parts = [_box((d, w, h - 0.1), (0, 0, 0.05 + (h - 0.1) / 2)),
             _box((d + 0.06, w + 0.02, 0.05), (0.03, 0, h - 0.025)),  # the lid
             _box((0.05, w * 0.8, 0.04), (-d / 2 - 0.03, 0, h - 0.12))]  # the handle
    for y in (-1, 1):
        parts.append(_rod([-d / 2 + 0.08, y * (w / 2 - 0.03), 0.1],
                          [-d / 2 + 0.08, y * (w / 2 + 0.02), 0.1], 0.1, 10))
    return _join(parts)


def _bench(rng: np.random.Generator) -> trimesh.Trimesh:
    """A waiting-area bench: a seat (one slab or slats) on legs or two end frames, sometimes
    a backrest."""
    lx, ly = rng.uniform(0.9, 1.3), rng.uniform(0.35, 0.45)
    seat_z = rng.uniform(0.42, 0.47)
    parts = []
    if rng.random() < 0.5:
        parts.append(_box((lx, ly, 0.05), (0, 0, seat_z - 0.025)))
    else:  # slats along the bench
        slats = int(rng.integers(3, 6))
        for i in range(slats):
            y = (i + 0.5) / slats * ly - ly / 2
            parts.append(_box((lx, ly / slats * 0.75, 0.035), (0, y, seat_z - 0.0175)))
    for x in (-1, 1):
        xl = x * (lx / 2 - 0.08)
        if rng.random() < 0.5:
            parts.append(_box((0.05, ly, seat_z - 0.05), (xl, 0, (seat_z - 0.05) / 2)))
        else:
            for y in (-1, 1):
                parts.append(_rod([xl, y * (ly / 2 - 0.04), 0.0],
                                  [xl, y * (ly / 2 - 0.04), seat_z - 0.05], 0.02, 8))
    if rng.random() < 0.5:  # backrest at -y
        back_h = rng.uniform(0.3, 0.45)
        parts.append(_box((lx, 0.04, back_h), (0, -ly / 2 + 0.02, seat_z + 0.05 + back_h / 2)))
        for x in (-1, 1):
            parts.append(_box((0.04, 0.04, 0.06), (x * (lx / 2 - 0.08), -ly / 2 + 0.02,
                                                   seat_z + 0.025)))
    return _join(parts, yaw=np.pi / 2)


def _sofa(rng: np.random.Generator) -> trimesh.Trimesh:
    """An armchair or a small sofa: a base, seat cushions, a backrest and arms."""
    lx, ly = rng.uniform(0.75, 1.2), rng.uniform(0.7, 0.8)
    seat_z, arm_w = rng.uniform(0.4, 0.46), rng.uniform(0.1, 0.18)
    back_d, top = rng.uniform(0.15, 0.22), rng.uniform(0.75, 0.9)
    inner = lx - 2 * arm_w
    parts = [_box((inner, ly - back_d, seat_z - 0.12), (0, back_d / 2, 0.06 + (seat_z - 0.12) / 2)),
             _box((lx, back_d, top - 0.06), (0, -ly / 2 + back_d / 2, 0.06 + (top - 0.06) / 2))]
    seats = 1 if inner < 0.8 else 2
    for i in range(seats):
        x = (i + 0.5) / seats * inner - inner / 2
        parts.append(_box((inner / seats - 0.01, ly - back_d - 0.02, 0.12),
                          (x, back_d / 2, seat_z - 0.06)))
    arm_z = rng.uniform(0.55, 0.65)
    for x in (-1, 1):
        parts.append(_box((arm_w, ly, arm_z - 0.06), (x * (lx - arm_w) / 2, 0,
                                                      0.06 + (arm_z - 0.06) / 2)))
        for y in (-1, 1):  # feet
            parts.append(_box((0.05, 0.05, 0.06), (x * (lx / 2 - 0.05), y * (ly / 2 - 0.05), 0.03)))
    return _join(parts, yaw=np.pi / 2)


def _whiteboard(rng: np.random.Generator) -> trimesh.Trimesh:
    """A mobile whiteboard or flip chart: a thin board on two legs with splayed feet."""
    w, bh = rng.uniform(0.7, 1.2), rng.uniform(0.6, 0.9)
    top = rng.uniform(1.5, SMALL_HEIGHT)
    parts = [_box((0.03, w, bh), (0, 0, top - bh / 2)),
             _box((0.08, w, 0.03), (0.04, 0, top - bh - 0.015))]  # the pen tray
    foot = rng.uniform(0.4, 0.55)
    for y in (-1, 1):
        yl = y * (w / 2 + 0.02)
        parts.append(_rod([0, yl, 0.06], [0, yl, top], 0.016, 8))
        parts.append(_box((foot, 0.04, 0.03), (0, yl, 0.045)))
        for x in (-1, 1):
            parts.append(_ellipsoid((x * (foot / 2 - 0.03), yl, 0.03), (0.03,) * 3, 0))
    return _join(parts)


_MAKERS = {"box": _cardboard, "cabinet": _cabinet, "chair": _chair, "table": _table,
           "plant": _plant, "trolley": _trolley, "bin": _bin, "bench": _bench, "sofa": _sofa,
           "whiteboard": _whiteboard, "shelf": _shelf, "shelf_rows": _shelf_rows, "desk": _desk,
           "counter": _counter, "bed": _bed}


def make_clutter_mesh(kind: str, rng: np.random.Generator) -> trimesh.Trimesh:
    """A random furniture-like object.

    Args:
        kind: one of CLUTTER_KINDS.
        rng: random generator.

    Returns:
        Mesh in metres, z up, footprint centred on the origin, standing on z = 0, at most
        MAX_HEIGHT tall; under 2000 faces for the first ten kinds (at most SMALL_HEIGHT
        tall), up to ``MAX_FACES`` for shelving full of books. The furnished kinds
        (``furniture``) carry ``metadata``: ``parts`` (V,) and ``tones`` (P,) (their parts'
        colours, ``datagen.appearance.materials.part_colours``) and ``footprint`` (C, 3).
    """
    if kind not in _MAKERS:
        raise ValueError(f"unknown clutter kind {kind!r}; use one of {list(CLUTTER_KINDS)}")
    return _MAKERS[kind](rng)


def make_person_mesh(rng: np.random.Generator) -> trimesh.Trimesh:
    """A person-like figure in mid-stride: legs, feet, torso, arms, neck and head.

    Returns:
        Mesh 1.5-1.95 m tall, z up, origin on the floor between the feet, facing +x.
    """
    H = rng.uniform(1.5, 1.95)
    s = H / 1.75  # proportions of a 1.75 m adult
    stride = np.deg2rad(rng.uniform(0.0, 20.0))
    swing = np.deg2rad(rng.uniform(0.0, 25.0))
    hip_z, shoulder_z = 0.52 * H, 0.815 * H
    hip_y, shoulder_y = 0.09 * s, rng.uniform(0.19, 0.23) * s
    leg_r, arm_r = 0.062 * s, 0.042 * s
    head = np.array([0.1, 0.082, 0.115]) * s
    parts = []
    for side, sign in ((1, 1), (-1, -1)):  # left leg forward, right arm forward
        angle = sign * stride
        ankle = np.array([np.sin(angle) * (hip_z - 0.07 * s), side * hip_y,
                          hip_z - np.cos(angle) * (hip_z - 0.07 * s)])
        parts.append(_capsule([0, side * hip_y, hip_z - 0.02 * s], ankle, leg_r))
        foot = 0.26 * s
        parts.append(_box((foot, 0.095 * s, 0.07 * s),
                          (ankle[0] + 0.3 * foot, side * hip_y, 0.035 * s)))
        a = -sign * swing  # arms swing against the legs
        hand_len = 0.34 * H
        shoulder = np.array([0.0, side * shoulder_y, shoulder_z - arm_r])
        hand = shoulder + hand_len * np.array([np.sin(a), 0.08 * side, -np.cos(a)])
        parts.append(_capsule(shoulder, hand, arm_r))
    torso_h = shoulder_z - hip_z
    torso = trimesh.creation.cylinder(radius=1.0, height=torso_h, sections=14)
    torso.apply_scale([0.12 * s, shoulder_y + 0.01 * s, 1.0])
    torso.apply_translation([0, 0, hip_z + torso_h / 2])
    parts.append(torso)
    parts.append(_ellipsoid((0, 0, shoulder_z), (0.12 * s, shoulder_y + 0.02 * s, 0.05 * s), 1))
    neck_top = H - 2 * head[2] + 0.02 * s
    parts.append(_rod([0, 0, shoulder_z], [0, 0, neck_top + 0.02 * s], 0.05 * s, 10))
    parts.append(_ellipsoid((0.01 * s, 0, H - head[2]), tuple(head), 2))
    parts.append(_ellipsoid((0.1 * s, 0, H - 1.1 * head[2]), (0.02 * s,) * 3, 0))  # nose
    mesh = trimesh.util.concatenate(parts)
    lo, hi = mesh.bounds
    mesh.apply_translation([0.0, 0.0, -lo[2]])  # ankles straddle x = 0
    mesh.apply_scale([1.0, 1.0, H / (hi[2] - lo[2])])
    return mesh


def footprint_radius(mesh: trimesh.Trimesh) -> float:
    """Radius (m) of the smallest origin-centred circle holding the mesh's XY footprint."""
    return float(np.max(np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])))


def footprint_circles(mesh: trimesh.Trimesh) -> np.ndarray:
    """(C, 3) circles x, y, r (m, in the object frame) covering the mesh's XY footprint: its
    maker's (``metadata["footprint"]``: a chain along a long object, each run of shelving
    apart) or the one circle of ``footprint_radius`` about the origin."""
    circles = mesh.metadata.get("footprint")
    if circles is not None:
        return np.asarray(circles, np.float64).reshape(-1, 3)
    return np.array([[0.0, 0.0, footprint_radius(mesh)]])
