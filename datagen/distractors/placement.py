"""Placing distractors on a floor map (core.occupancy, margin 0: where things may stand): an
object of footprint radius r at (x, y) fits where the map's distance to the walls is at least
r (plus a wall margin), and must not overlap another object or a keep-out circle (e.g. the
camera)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import pose_from_xyzyaw
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
