"""Distractors: furniture-like clutter and walking people, which are not in the 3D model.

Meshes are built from trimesh primitives in an object frame with z up, the origin at the
centre of the footprint on the floor (z = 0) and, for people, facing +x. Placement works on
floor circles on a floor map (core.occupancy, margin 0: where things may stand): an object
of footprint radius r at (x, y) fits where the map's distance to the walls is at least r
(plus a wall margin), and must not overlap another object or a keep-out circle (e.g. the
camera).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

from core.config import as_config
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyzyaw, wrap_angle
from datagen.config import DistractorPreset
from datagen.map_cache import derived
from datagen.routes import first_blocked

CLUTTER_KINDS: tuple[str, ...] = ("box", "cabinet", "chair", "table", "plant", "trolley", "bin",
                                   "bench", "sofa", "whiteboard")
MAX_HEIGHT = 1.8  # m, tallest clutter object


# --------------------------------------------------------------------------- primitives


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float],
         yaw: float = 0.0) -> trimesh.Trimesh:
    """Axis box of the given extents (m) centred at centre, rotated by yaw about z."""
    T = trimesh.transformations.rotation_matrix(yaw, (0, 0, 1))
    T[:3, 3] = centre
    return trimesh.creation.box(extents=extents, transform=T)


def _rod(p0: np.ndarray, p1: np.ndarray, radius: float, sections: int = 10) -> trimesh.Trimesh:
    """Closed cylinder between two points."""
    return trimesh.creation.cylinder(radius=radius, segment=np.array([p0, p1], float),
                                     sections=sections)


def _capsule(p0: np.ndarray, p1: np.ndarray, radius: float) -> trimesh.Trimesh:
    """Capsule whose axis runs from p0 to p1 (the caps extend radius beyond them)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    mesh = trimesh.creation.capsule(height=max(length, 1e-3), radius=radius, count=[8, 8])
    T = trimesh.geometry.align_vectors([0, 0, 1], axis / max(length, 1e-9))
    T[:3, 3] = (p0 + p1) / 2
    mesh.apply_transform(T)
    return mesh


def _ellipsoid(centre: tuple[float, float, float], radii: tuple[float, float, float],
               subdivisions: int = 1) -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.apply_scale(radii)
    mesh.apply_translation(centre)
    return mesh


def _frustum(r_bottom: float, r_top: float, height: float, sections: int = 14) -> trimesh.Trimesh:
    """Closed truncated cone standing on z = 0 (a pot)."""
    mesh = trimesh.creation.cylinder(radius=1.0, height=height, sections=sections)
    v = mesh.vertices.copy()
    top = v[:, 2] > 0
    v[:, :2] *= np.where(top, r_top, r_bottom)[:, None]
    v[:, 2] += height / 2
    return trimesh.Trimesh(v, mesh.faces, process=False)


def _join(parts: list[trimesh.Trimesh], yaw: float = 0.0) -> trimesh.Trimesh:
    """Concatenate parts, rotate by yaw and re-centre the footprint on the origin."""
    mesh = trimesh.util.concatenate(parts)
    if yaw:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, (0, 0, 1)))
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return mesh


# --------------------------------------------------------------------------- clutter


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
    h = rng.uniform(0.7, MAX_HEIGHT)
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


def _chair(rng: np.random.Generator) -> trimesh.Trimesh:
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
    if hi[2] > MAX_HEIGHT:
        mesh.apply_scale([1.0, 1.0, MAX_HEIGHT / hi[2]])
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
    top = rng.uniform(1.5, MAX_HEIGHT)
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
           "whiteboard": _whiteboard}


def make_clutter_mesh(kind: str, rng: np.random.Generator) -> trimesh.Trimesh:
    """A random furniture-like object.

    Args:
        kind: one of CLUTTER_KINDS.
        rng: random generator.

    Returns:
        Mesh in metres, z up, footprint centred on the origin, standing on z = 0,
        at most MAX_HEIGHT tall and under 2000 faces.
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


# --------------------------------------------------------------------------- placement

_TOL = 1e-6  # m, slack of the clearance tests


@dataclass
class _Floor:
    """A floor map's cells sorted by clearance, for drawing the cells a circle fits in, and
    the distance to the walls within a cell.

    cells: (C,) flat indices of the floor cells, by increasing clearance (m, (C,)).
    gradient: (H, W, 2) unit vectors x, y along which the clearance grows (away from walls;
    0 where it is flat).
    """

    occ: OccupancyMap
    cells: np.ndarray
    clearance: np.ndarray
    gradient: np.ndarray

    @classmethod
    def of(cls, occ: OccupancyMap) -> _Floor:
        """The floor of a map, built once per map (cached while the map lives: treat it as
        read-only)."""
        if not isinstance(occ, OccupancyMap):
            raise TypeError(f"floor must be an OccupancyMap (where things stand), got "
                            f"{type(occ).__name__}")
        return derived(occ, "floor", cls._build)

    @classmethod
    def _build(cls, occ: OccupancyMap) -> _Floor:
        idx = np.flatnonzero(occ.free)
        clear = occ.clearance.ravel()[idx]
        order = np.argsort(clear, kind="stable")
        gy, gx = np.gradient(occ.clearance.astype(np.float64))
        g = np.stack([gx, gy], -1)
        g /= np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)
        return cls(occ, idx[order], clear[order], g)

    def fitting(self, need: float, band: float | None = None) -> np.ndarray:
        """Flat indices of the cells of clearance >= need (and < need + band)."""
        lo = np.searchsorted(self.clearance, need - _TOL)
        hi = len(self.cells) if band is None else np.searchsorted(self.clearance,
                                                                  need + band - _TOL)
        return self.cells[lo:hi]

    def points(self, rng: np.random.Generator, cells: np.ndarray) -> np.ndarray:
        """(N, 2) m uniform points in the cells (N,) flat indices."""
        r, c = np.unravel_index(cells, self.occ.shape)
        u = rng.random((len(cells), 2))
        return self.occ.origin + (np.stack([c, r], 1) + u) * self.occ.cell

    def distance(self, xy: np.ndarray) -> np.ndarray:
        """(N,) m from the points (N, 2) to the nearest wall: their cell's clearance moved
        along its gradient to the point (exact beside a straight wall); -inf off the floor."""
        rc, inside = self.occ.cell_of(xy)
        g = self.gradient[rc[0], rc[1]]
        d = self.occ.clearance[rc[0], rc[1]] + np.einsum("nc,nc->n", g,
                                                         xy - self.occ.centres(rc))
        return np.where(inside & self.occ.free[rc[0], rc[1]], d, -np.inf)

    def away(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) unit vectors away from the nearest wall at the points (N, 2) m."""
        rc, _ = self.occ.cell_of(xy)
        return self.gradient[rc[0], rc[1]]


def place_objects(rng: np.random.Generator, radii: np.ndarray, floor: OccupancyMap,
                  keepout: np.ndarray | None = None, max_tries: int = 256,
                  against_walls: float = 0.0, wall_margin: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Place circular footprints on the floor without overlaps.

    Objects are placed largest first; for each, max_tries candidates are drawn at once,
    uniform over the floor cells it fits in (the distance to the walls at least radius +
    wall_margin: ``floor.distance``, refined within the cell along the clearance's
    gradient), and the first one clear of the keep-outs and of the objects already placed is
    taken.

    Args:
        rng: random generator.
        radii: (K,) footprint radii in metres.
        floor: where things may stand (margin 0; its clearance is the distance to walls).
        keepout: (Q, 3) x, y, radius circles no object may overlap (camera, flight path).
        max_tries: candidates per object.
        against_walls: probability that a candidate stands against a wall (its footprint
            ``wall_margin`` from it, within a cell) facing away from it (+x of the object
            along the clearance's gradient), leaving the middle free; the others have a
            uniform yaw.
        wall_margin: m kept between a footprint and a wall.

    Returns:
        xy_yaw: (K, 3) x, y (m) and yaw (rad) of each object; NaN where unplaced.
        placed: (K,) bool.
    """
    radii = np.asarray(radii, dtype=np.float64).reshape(-1)
    if np.any(radii < 0):
        raise ValueError(f"radii must be non-negative, got {radii.tolist()}")
    where = _Floor.of(floor)
    keep = (np.zeros((0, 3)) if keepout is None
            else np.asarray(keepout, dtype=np.float64).reshape(-1, 3))
    K = len(radii)
    xy_yaw = np.full((K, 3), np.nan)
    placed = np.zeros(K, bool)
    obstacles = [keep]
    for k in np.argsort(-radii, kind="stable"):
        need = radii[k] + wall_margin
        inside = where.fitting(need - floor.cell)
        wall = where.fitting(need - floor.cell / 2, floor.cell)
        yaw = rng.uniform(-np.pi, np.pi)
        if not len(inside):
            continue
        snap = rng.random(max_tries) < against_walls
        pick = inside[rng.integers(len(inside), size=max_tries)]
        if len(wall):
            pick = np.where(snap, wall[rng.integers(len(wall), size=max_tries)], pick)
        else:
            snap[:] = False
        cand = where.points(rng, pick)
        obs = np.concatenate(obstacles)
        d = np.linalg.norm(cand[:, None, :] - obs[None, :, :2], axis=-1)  # (T, Q)
        ok = np.all(d >= obs[None, :, 2] + radii[k], axis=1) & (where.distance(cand) >= need)
        if ok.any():
            i = int(np.argmax(ok))
            if snap[i]:
                g = where.away(cand[i : i + 1])[0]
                yaw = float(np.arctan2(g[1], g[0]))
            xy_yaw[k] = [cand[i, 0], cand[i, 1], yaw]
            placed[k] = True
            obstacles.append(np.array([[cand[i, 0], cand[i, 1], radii[k]]]))
    return xy_yaw, placed


def object_poses(xy_yaw: np.ndarray) -> np.ndarray:
    """(K, 4, 4) world_from_object for floor placements (K, 3) x, y, yaw (z = 0)."""
    xy_yaw = np.asarray(xy_yaw, dtype=np.float64).reshape(-1, 3)
    state = np.stack([xy_yaw[:, 0], xy_yaw[:, 1], np.zeros(len(xy_yaw)), xy_yaw[:, 2]], 1)
    return pose_from_xyzyaw(state)


# --------------------------------------------------------------------------- people

GOAL_CANDIDATES = 32  # goals drawn per new goal, among those in sight a far one is taken
FAR_SHARE = 0.7  # a goal is far at >= this share of the farthest candidate's distance
ARRIVED_M = 0.3  # m from its goal a walker picks a new one
GOAL_ROOM = 0.1  # m a goal keeps from the walls beyond a person's radius


@dataclass
class _Crowd:
    """The walkers of ``person_tracks``: P people on a floor map.

    floor: where people stand; walk_map: the cells a person's centre may occupy (clearance
    >= radius; the lines of sight to goals); goals: flat indices of the cells goals are drawn
    from; speed: (P,) m/s; pos, goal: (P, 2) m; heading: (P,) rad; blocked: (P,) frames a
    person has been blocked for.
    """

    rng: np.random.Generator
    radius: float
    floor: _Floor
    walk_map: OccupancyMap
    goals: np.ndarray
    speed: np.ndarray
    pos: np.ndarray
    goal: np.ndarray
    heading: np.ndarray
    blocked: np.ndarray

    @classmethod
    def start(cls, rng: np.random.Generator, n: int, floor: OccupancyMap, radius: float,
              speed: tuple[float, float], keepout: np.ndarray) -> _Crowd:
        """n people placed like objects (clear of the keep-outs and each other), each
        walking towards a goal in sight."""
        where = _Floor.of(floor)
        walkable = where.fitting(radius)
        if not len(walkable):
            raise ValueError(f"no floor is {radius} m from the walls: people of radius "
                             f"{radius} m cannot stand anywhere; lower person_radius")
        start, ok = place_objects(rng, np.full(n, radius), floor, keepout)
        if not ok.all():
            start[~ok, :2] = where.points(rng, walkable[rng.integers(len(walkable),
                                                                     size=int((~ok).sum()))])
        roomy = where.fitting(radius + GOAL_ROOM)
        crowd = cls(rng, radius, where, floor.eroded(max(radius - floor.margin, 0.0)),
                    roomy if len(roomy) else walkable, rng.uniform(speed[0], speed[1], n),
                    start[:, :2].copy(), np.zeros((n, 2)), np.zeros(n), np.zeros(n, int))
        crowd.new_goals(np.ones(n, bool))
        crowd.heading = np.arctan2(*(crowd.goal - crowd.pos)[:, ::-1].T)
        return crowd

    def new_goals(self, mask: np.ndarray, back: np.ndarray | None = None) -> None:
        """New goals for the people of ``mask`` (P,): of ``GOAL_CANDIDATES`` random floor
        cells, the farthest one in a straight line of walkable cells (any one if none is);
        for those of ``back`` (P,), behind them if there is one."""
        idx = np.flatnonzero(mask)
        if not len(idx):
            return
        k = GOAL_CANDIDATES
        cand = self.floor.points(self.rng, self.goals[self.rng.integers(len(self.goals),
                                                                        size=len(idx) * k)])
        origin = np.repeat(self.pos[idx], k, axis=0)
        seen = ~np.isfinite(first_blocked(self.walk_map, origin, cand))
        score = np.linalg.norm(cand - origin, axis=1) * np.where(seen, 1.0, 1e-6)
        if back is not None:
            heading = np.repeat(self.heading[idx], k)
            rel = cand - origin
            ahead = rel[:, 0] * np.cos(heading) + rel[:, 1] * np.sin(heading) > 0
            score *= np.where(np.repeat(back[idx], k) & ahead, 1e-3, 1.0)
        score = score.reshape(len(idx), k)
        far = score >= FAR_SHARE * score.max(axis=1, keepdims=True)  # the far ones: any
        pick = np.argmax(far * self.rng.random(far.shape), axis=1)
        self.goal[idx] = cand.reshape(len(idx), k, 2)[np.arange(len(idx)), pick]

    def turn_around(self, stuck: np.ndarray) -> None:
        """Who arrived at their goal picks a new goal, who is ``stuck`` (P,) one behind."""
        arrived = np.linalg.norm(self.goal - self.pos, axis=1) < ARRIVED_M
        turn = arrived | stuck
        if turn.any():
            self.new_goals(turn, back=stuck)
            self.blocked[turn] = 0

    def clearance(self, p: np.ndarray, circles: np.ndarray) -> np.ndarray:
        """(P, O) free distance from each person placed at p (P, 2) to each of the (O, 3)
        circles, the first P of which are the people themselves (inf to oneself)."""
        n = len(self.pos)
        dist = np.linalg.norm(p[:, None, :] - circles[None, :, :2], axis=-1)
        clear = dist - self.radius - circles[None, :, 2]
        clear[:, :n][np.eye(n, dtype=bool)] = np.inf
        return clear

    def steer(self, circles: np.ndarray, clear: np.ndarray) -> np.ndarray:
        """(P, 2) wanted walking directions: towards the goal, pushed away from the circles
        ahead (a sidestep away from each thing, to the right of each person; to the other
        side where a wall leaves no room), and off the walls (the clearance's gradient)."""
        pos = self.pos
        want = self.goal - pos
        want /= np.linalg.norm(want, axis=1, keepdims=True) + 1e-9
        diff = pos[:, None, :] - circles[None, :, :2]  # (P, O, 2) from the others to each
        away = diff / (np.linalg.norm(diff, axis=-1, keepdims=True) + 1e-9)
        fwd = np.stack([np.cos(self.heading), np.sin(self.heading)], 1)
        ahead = np.einsum("poc,pc->po", -away, fwd) > -0.2
        weight = np.exp(-np.clip(clear, 0, None) / 0.4) * ahead * np.isfinite(clear)
        perp = np.stack([-want[:, 1], want[:, 0]], 1)  # left of the wanted direction
        side = np.sign(np.einsum("poc,pc->po", away, perp) + 1e-6)  # sidestep away
        side[:, : len(pos)] = -1.0  # people keep right of each other
        occ = self.floor.occ
        reach = occ.cell  # a sidestep with no room for one cell goes the other way
        room = [occ.distance(pos + sign * reach * perp) >= self.radius for sign in (1, -1)]
        side = np.where((side > 0) & ~room[0][:, None] & room[1][:, None], -1.0, side)
        side = np.where((side < 0) & ~room[1][:, None] & room[0][:, None], 1.0, side)  # not
        # into a wall: to the side with room
        push = away + side[..., None] * perp[:, None, :]
        steer = want + 1.5 * np.sum(weight[..., None] * push, axis=1)
        gap = self.floor.occ.distance(pos) - self.radius
        return steer + 0.5 * np.exp(-np.clip(gap, 0, None) / 0.2)[:, None] * self.floor.away(pos)

    def walk(self, circles: np.ndarray, dt: float, max_turn: float) -> None:
        """One frame: turn (at most max_turn rad) towards ``steer``'s direction and step;
        a step into a wall slides along it, and a step that comes nearer a wall than the
        radius or overlaps a circle (or another's step) more than now is not taken."""
        clear = self.clearance(self.pos, circles)
        steer = self.steer(circles, clear)
        target = np.arctan2(steer[:, 1], steer[:, 0])
        turn = np.clip(wrap_angle(target - self.heading), -max_turn, max_turn)
        self.heading = wrap_angle(self.heading + turn)
        step = self.speed[:, None] * dt * np.stack([np.cos(self.heading),
                                                    np.sin(self.heading)], 1)
        new = self.pos + step
        off = self.floor.distance(new) < self.radius
        if off.any():  # slide: drop the part of the step towards the wall
            g = self.floor.away(self.pos[off])
            into = np.minimum(np.einsum("pc,pc->p", step[off], g), 0.0)
            new[off] = self.pos[off] + step[off] - into[:, None] * g
        new_clear = self.clearance(new, circles)
        bad = (np.any((new_clear < 0) & (new_clear < clear), axis=1)
               | (self.floor.distance(new) < self.radius))
        # people step at once: who would overlap another's step more stays too
        n = len(self.pos)
        moved = np.where(bad[:, None], self.pos, new)
        both = self.clearance(moved, np.column_stack([moved, np.full(n, self.radius)]))
        bad |= np.any((both < 0) & (both < clear[:, :n]), axis=1)
        self.pos = np.where(bad[:, None], self.pos, new)
        self.blocked = np.where(bad, self.blocked + 1, 0)


def person_tracks(rng: np.random.Generator, num_people: int, num_frames: int, fps: float,
                  floor: OccupancyMap,
                  speed: tuple[float, float] = tuple(DistractorPreset().person_speed),
                  radius: float = DistractorPreset.person_radius,
                  obstacles: np.ndarray | None = None,
                  avoid: np.ndarray | None = None,
                  avoid_radius: float = DistractorPreset.person_camera_keepout,
                  max_turn_deg_s: float = DistractorPreset.person_max_turn_deg_s,
                  patience_s: float = DistractorPreset.person_patience_s) -> np.ndarray:
    """Trajectories of people walking about the floor.

    Each person walks towards a goal: of a few random floor cells, the farthest one in
    sight (in a corridor: towards its far end); on arrival, or when blocked for patience_s,
    it picks a new one. The heading turns at a bounded rate towards the goal, steered around
    other people, static obstacles and the avoid track (a small social-force model: a push
    away from what is ahead plus a sidestep) and off the walls (the clearance's gradient). A
    step that would overlap someone or something more is not taken; a step into a wall
    slides along it. People never stand nearer a wall than ``radius`` (within the map's
    cell); they rarely overlap each other.

    Args:
        rng: random generator.
        num_people, num_frames: counts.
        fps: frame rate (Hz).
        floor: where people may walk (margin 0; its clearance is the distance to walls).
        speed: (min, max) walking speed in m/s, drawn per person.
        radius: body radius (m) kept from the walls and used for avoidance.
        obstacles: (Q, 3) x, y, radius static circles to walk around (e.g. clutter).
        avoid: (num_frames, 2) x, y of something to keep clear of at each frame (the camera).
        avoid_radius: radius (m) of that keep-out.
        max_turn_deg_s: largest heading change rate.
        patience_s: how long a blocked person waits before choosing a new goal.

    Returns:
        (num_people, num_frames, 3) x, y (m), yaw (rad, walking direction).
    """
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    P, N, dt = int(num_people), int(num_frames), 1.0 / float(fps)
    out = np.zeros((P, N, 3))
    if P == 0 or N == 0:
        return out
    obs = (np.zeros((0, 3)) if obstacles is None
           else np.asarray(obstacles, dtype=np.float64).reshape(-1, 3))
    avoid_xy = None if avoid is None else np.asarray(avoid, dtype=np.float64).reshape(N, 2)
    keep = obs if avoid_xy is None else np.vstack([obs, [*avoid_xy[0], avoid_radius]])
    crowd = _Crowd.start(rng, P, floor, radius, speed, keep)
    max_turn = np.deg2rad(max_turn_deg_s) * dt
    for t in range(N):
        out[:, t, :2] = crowd.pos
        out[:, t, 2] = crowd.heading
        crowd.turn_around(crowd.blocked > patience_s * fps)
        circles = [np.column_stack([crowd.pos, np.full(P, radius)]), obs]
        if avoid_xy is not None:
            circles.append(np.array([[*avoid_xy[t], avoid_radius]]))
        crowd.walk(np.concatenate(circles), dt, max_turn)
    return out


# --------------------------------------------------------------------------- presets


def check_preset(preset: DistractorPreset, where: str = "distractors preset") -> None:
    """Raise ValueError, naming ``where`` (e.g. ``distractor_presets.paper``), if a preset's
    counts are not 0 <= min <= max or its kinds are not a non-empty subset of CLUTTER_KINDS."""
    for key in ("clutter", "people"):
        lo, hi = getattr(preset, key).min, getattr(preset, key).max
        if not 0 <= lo <= hi:
            raise ValueError(f"{where}: need 0 <= {key}.min <= {key}.max, got {lo}, {hi}")
    if not preset.kinds or set(preset.kinds) - set(CLUTTER_KINDS):
        raise ValueError(f"{where}: kinds must be a non-empty subset of {list(CLUTTER_KINDS)}, "
                         f"got {list(preset.kinds)}")


def preset_counts(rng: np.random.Generator, preset: DistractorPreset | Mapping[str, Any]
                  ) -> tuple[int, int]:
    """Number of clutter objects and people for one image or flight.

    Args:
        preset: a distractors preset (``DistractorPreset``, or a mapping of the keys that
            differ from its defaults).

    Returns:
        (num_clutter, num_people), uniform in the preset's [min, max] ranges.
    """
    preset = as_config(DistractorPreset, preset, "distractors preset")
    check_preset(preset)
    return (int(rng.integers(preset.clutter.min, preset.clutter.max + 1)),
            int(rng.integers(preset.people.min, preset.people.max + 1)))


def sample_kinds(rng: np.random.Generator, n: int,
                 preset: DistractorPreset | Mapping[str, Any]) -> list[str]:
    """n clutter kinds drawn from the preset's ``kinds`` list (uniformly)."""
    preset = as_config(DistractorPreset, preset, "distractors preset")
    check_preset(preset)
    kinds = list(preset.kinds)
    return [kinds[i] for i in rng.integers(0, len(kinds), n)]
