"""Placing distractors on a floor map (core.occupancy, margin 0: where things may stand): an
object's footprint is a circle of radius r about its origin, or a chain of circles (a long
counter, a run of shelving); it fits where the map's distance to the walls is at least each
circle's radius (plus a wall margin) at its centre, and must not overlap another object or a
keep-out circle (e.g. the camera)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import pose_from_xyzyaw, wrap_angle
from datagen.flights.map_cache import derived

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

    def in_sight(self, view: np.ndarray) -> np.ndarray:
        """(H * W,) bool: the cells seen from a point: view (5,) x, y (m), heading, half
        angle (rad) and reach (m); a cell is seen when its centre lies within the reach and
        the half angle of the heading and the floor is free along the ray to it (walls block,
        objects do not), on rays at most a cell apart at the reach."""
        x, y, heading, half, reach = np.asarray(view, np.float64).reshape(5)
        occ = self.occ
        n = int(np.ceil(2 * half * reach / occ.cell)) + 1
        angles = heading + np.linspace(-half, half, n)
        d = np.arange(1, int(np.ceil(reach / (occ.cell / 2))) + 1) * (occ.cell / 2)  # (K,)
        rays = np.stack([np.cos(angles), np.sin(angles)], 1)
        pts = np.array([x, y]) + d[None, :, None] * rays[:, None, :]  # (n, K, 2)
        free = occ.contains(pts.reshape(-1, 2)).reshape(n, len(d))
        first = np.where(free.all(1), len(d), np.argmin(free, axis=1))
        seen = np.concatenate([[0.0], d])[first]  # (n,) m of free floor along each ray
        centres = occ.centres(np.indices(occ.shape).reshape(2, -1))
        rel = centres - [x, y]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        off = wrap_angle(np.arctan2(rel[:, 1], rel[:, 0]) - heading)
        ray = np.clip(np.round((off + half) / max(2 * half, 1e-12) * (n - 1)), 0, n - 1)
        return (np.abs(off) <= half) & (dist <= np.minimum(reach, seen[ray.astype(int)]))

    def away(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) unit vectors away from the nearest wall at the points (N, 2) m."""
        rc, _ = self.occ.cell_of(xy)
        return self.gradient[rc[0], rc[1]]


def place_objects(rng: np.random.Generator, footprints: np.ndarray | Sequence[np.ndarray],
                  floor: OccupancyMap | Sequence[OccupancyMap | None],
                  keepout: np.ndarray | None = None, max_tries: int = 256,
                  against_walls: float = 0.0, wall_margin: float = 0.0, aligned: float = 0.0,
                  view: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Place footprints (circles, or chains of circles) on the floor without overlaps.

    Objects are placed largest first; for each, max_tries candidates are drawn at once,
    uniform over the floor cells its origin may stand in, each with its yaw, and the first
    one whose every circle is clear of the walls (the distance to them at least its radius
    + wall_margin: ``floor.distance``, refined within the cell along the clearance's
    gradient), of the keep-outs and of the objects already placed is taken.

    Args:
        rng: random generator.
        footprints: (K,) radii in metres (a circle about each object's origin), or K arrays
            (C_k, 3) of circles x, y, r (m) in each object's frame (``footprint_circles``).
        floor: where things may stand (margin 0; its clearance is the distance to walls): one
            map for all, or one per object (e.g. one of more headroom for tall ones; None: the
            object is not placed).
        keepout: (Q, 3) x, y, radius circles no object may overlap (camera, flight path).
        max_tries: candidates per object.
        against_walls: probability that a candidate stands against a wall (its footprint's
            back, -x, ``wall_margin`` from it, within a cell) facing away from it (+x of the
            object along the clearance's gradient), leaving the middle free; the others have a
            uniform yaw.
        wall_margin: m kept between a footprint and a wall.
        aligned: probability that a candidate not against a wall turns square to the nearest
            wall (its yaw that of the wall's normal plus a multiple of 90 degrees: rows of
            desks and shelves); 0: none (no draw).
        view: (5,) x, y (m), heading, half angle (rad), reach (m): objects stand only where a
            camera there sees the floor (``_Floor.in_sight``); None: anywhere.

    Returns:
        xy_yaw: (K, 3) x, y (m) and yaw (rad) of each object; NaN where unplaced.
        placed: (K,) bool.
    """
    shapes = _footprints(footprints)
    K = len(shapes)
    floors = [floor] * K if isinstance(floor, OccupancyMap) else list(floor)
    if len(floors) != K:
        raise ValueError(f"place_objects: {len(floors)} floor maps for {K} objects")
    keep = (np.zeros((0, 3)) if keepout is None
            else np.asarray(keepout, dtype=np.float64).reshape(-1, 3))
    xy_yaw = np.full((K, 3), np.nan)
    placed = np.zeros(K, bool)
    obstacles = [keep]
    outer = np.array([np.max(np.hypot(c[:, 0], c[:, 1]) + c[:, 2]) for c in shapes])
    regions: dict[int, np.ndarray] = {}
    for k in np.argsort(-outer, kind="stable"):
        if floors[k] is None:
            continue
        where, c = _Floor.of(floors[k]), shapes[k]
        simple = len(c) == 1 and not c[0, :2].any()  # one circle about the origin
        # the origin's clearance is at least any circle's radius less its offset; against a
        # wall, the back's reach to -x
        need = float(np.max(c[:, 2] - np.hypot(c[:, 0], c[:, 1]))) + wall_margin
        back = float(np.max(c[:, 2] - c[:, 0])) + wall_margin
        inside = where.fitting(need - where.occ.cell)
        wall = where.fitting(back - where.occ.cell / 2, where.occ.cell)
        if view is not None:
            mask = regions.get(id(where))
            if mask is None:
                mask = regions[id(where)] = where.in_sight(view)
            inside, wall = inside[mask[inside]], wall[mask[wall]]
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
        g = where.away(cand)
        to_wall = np.arctan2(g[:, 1], g[:, 0])  # +x away from the nearest wall
        yaws = np.full(max_tries, yaw) if simple else rng.uniform(-np.pi, np.pi, max_tries)
        if aligned > 0:
            square = rng.random(max_tries) < aligned
            turn = rng.integers(4, size=max_tries) * (np.pi / 2)
            yaws = np.where(square, wrap_angle(to_wall + turn), yaws)
        yaws = np.where(snap, to_wall, yaws)
        centres = _world_xy(c, cand, yaws)  # (T, C, 2)
        clear = where.distance(centres.reshape(-1, 2)).reshape(centres.shape[:2])
        fits = np.flatnonzero(np.all(clear >= c[None, :, 2] + wall_margin, axis=1))
        i = _first_clear(centres, c[:, 2], fits, np.concatenate(obstacles))
        if i is not None:
            xy_yaw[k] = [cand[i, 0], cand[i, 1], yaws[i]]
            placed[k] = True
            obstacles.append(np.column_stack([centres[i], c[:, 2]]))
    return xy_yaw, placed


def _first_clear(centres: np.ndarray, radii: np.ndarray, tries: np.ndarray, obs: np.ndarray,
                 batch: int = 32) -> int | None:
    """The first of the candidates ``tries`` (ascending indices into centres (T, C, 2), of
    circles of radii (C,)) that overlaps none of the circles obs (Q, 3); None if all do
    (tested a batch at a time)."""
    for start in range(0, len(tries), batch):
        sel = tries[start:start + batch]
        d = np.linalg.norm(centres[sel, :, None, :] - obs[None, None, :, :2], axis=-1)
        ok = np.all(d >= obs[None, None, :, 2] + radii[None, :, None], axis=(1, 2))
        if ok.any():
            return int(sel[np.argmax(ok)])
    return None


def _footprints(footprints: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    """K (C_k, 3) circle sets from radii (K,) or circle sets; ValueError naming the bad one."""
    if isinstance(footprints, np.ndarray) and footprints.ndim == 1 or (
            len(footprints) and np.ndim(footprints[0]) == 0):
        r = np.asarray(footprints, dtype=np.float64).reshape(-1)
        shapes = [np.array([[0.0, 0.0, ri]]) for ri in r]
    else:
        shapes = [np.asarray(c, dtype=np.float64).reshape(-1, 3) for c in footprints]
    for k, c in enumerate(shapes):
        if not len(c) or np.any(c[:, 2] < 0) or not np.isfinite(c).all():
            raise ValueError(f"footprint {k}: radii must be non-negative and circles finite, "
                             f"got {c.tolist()}")
    return shapes


def _world_xy(circles: np.ndarray, xy: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(T, C, 2) m: the circles' (C, 3) centres for objects at xy (T, 2) turned by yaw (T,)."""
    cos, sin = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x, y = circles[None, :, 0], circles[None, :, 1]
    return np.stack([xy[:, :1] + cos * x - sin * y, xy[:, 1:] + sin * x + cos * y], axis=-1)


def placed_circles(footprints: Sequence[np.ndarray], xy_yaw: np.ndarray) -> np.ndarray:
    """(Q, 3) x, y, r (m) in the world of the placed objects' footprints (K of (C_k, 3), at
    xy_yaw (K, 3); NaN rows: not placed): the obstacles people walk around."""
    out = [np.column_stack([_world_xy(c, p[None, :2], p[2:3])[0], c[:, 2]])
           for c, p in zip(_footprints(footprints), np.asarray(xy_yaw, np.float64), strict=True)
           if not np.isnan(p[0])]
    return np.concatenate(out) if out else np.zeros((0, 3))


def object_poses(xy_yaw: np.ndarray) -> np.ndarray:
    """(K, 4, 4) world_from_object for floor placements (K, 3) x, y, yaw (z = 0)."""
    xy_yaw = np.asarray(xy_yaw, dtype=np.float64).reshape(-1, 3)
    state = np.stack([xy_yaw[:, 0], xy_yaw[:, 1], np.zeros(len(xy_yaw)), xy_yaw[:, 2]], 1)
    return pose_from_xyzyaw(state)
