"""What a user may know of where a global start begins: a region, a pose with covariance, a
heading range (``StartHint``).

A global start draws its poses only inside the hint: positions from the free cells inside
the region (a polygon, a rectangle, or a named space of the world), or from a Gaussian
around a pose (ROS's ``/initialpose``: a pose and its (6, 6) covariance), headings inside the
range. The free space stays a soft prior (``filter.outside_log_penalty_per_m``): a pose
drawn from a Gaussian may lie outside it and only loses weight. The hinted area (and heading
span) sets the particle count at the density of an unhinted start
(``FilterConfig.global_count``).

Settings: ``localize.config.HintConfig`` (``hint`` on the command line).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import wrap_angle, xyzyaw_from_pose

#: Indices of x, y, z, yaw in ROS's (6, 6) pose covariance (x, y, z, roll, pitch, yaw).
ROS_XYZYAW = (0, 1, 2, 5)
#: Redraws of the Gaussian's poses that fall outside the region or the heading range.
REDRAWS = 20
#: m a start pose given in the settings (``hint.pose``) may lie outside the free
#: space (its cells and its band of heights): a start measured by hand beside a wall, or a
#: drone on the floor below the band, lies within it (and is warned about); farther is an
#: error (a start in another frame or unit).
START_MAX_OUTSIDE_M = 1.0


def polygon_contains(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """(N,) bool: points (N, 2) inside a polygon (K, 2) (m; matplotlib's ``Path``)."""
    from matplotlib.path import Path  # the path module alone, not pyplot

    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return Path(np.asarray(polygon, dtype=np.float64)).contains_points(xy)


def polygon_area(polygon: np.ndarray) -> float:
    """Area of a simple polygon (K, 2), m2 (shoelace)."""
    x, y = np.asarray(polygon, dtype=np.float64).T
    return float(0.5 * abs(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def as_polygon(region: Sequence, where: str = "hint.region") -> np.ndarray:
    """(K, 2) polygon of a region: a rectangle [xmin, ymin, xmax, ymax] or corners
    [[x, y], ...] (K >= 3), metres; ValueError naming ``where``."""
    r = np.asarray(region, dtype=np.float64)
    if r.shape == (4,):
        x0, y0, x1, y1 = r
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"{where}: a rectangle is [xmin, ymin, xmax, ymax] with xmax > "
                             f"xmin and ymax > ymin, got {r.tolist()}")
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    if r.ndim != 2 or r.shape[1] != 2 or len(r) < 3 or not np.isfinite(r).all():
        raise ValueError(f"{where}: give a rectangle [xmin, ymin, xmax, ymax] or a polygon "
                         f"[[x, y], ...] of >= 3 corners (m), got shape {r.shape}")
    if polygon_area(r) <= 0:
        raise ValueError(f"{where}: the polygon {r.tolist()} has no area")
    return r


@dataclass(frozen=True)
class StartHint:
    """Where a global start begins: any of a region, a pose with covariance, a heading range.

    Attributes:
        region: (K, 2) polygon, metres (``as_polygon``); None: the whole free space.
        pose: (4,) x, y, z (m), yaw (rad) the start lies around; None: none.
        covariance: (4, 4) covariance of ``pose`` over x, y, z (m2), yaw (rad2).
        heading: (2,) radians: headings from ``heading[0]`` counter-clockwise to
            ``heading[1]``; None: every heading.
    """

    region: np.ndarray | None = None
    pose: np.ndarray | None = None
    covariance: np.ndarray | None = None
    heading: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.region is not None:
            object.__setattr__(self, "region", as_polygon(self.region))
        if (self.pose is None) != (self.covariance is None):
            raise ValueError("StartHint: a pose needs its covariance (and a covariance a pose)")
        if self.pose is not None:
            pose = np.asarray(self.pose, dtype=np.float64)
            cov = np.asarray(self.covariance, dtype=np.float64)
            if pose.shape != (4,) or cov.shape != (4, 4) or not np.isfinite(cov).all():
                raise ValueError(f"StartHint: pose must be (4,) x, y, z, yaw and covariance "
                                 f"(4, 4), got {pose.shape} and {cov.shape}")
            if np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() < -1e-9:
                raise ValueError("StartHint: the covariance is not positive semi-definite")
            object.__setattr__(self, "pose", pose)
            object.__setattr__(self, "covariance", 0.5 * (cov + cov.T))
        if self.heading is not None:
            lo, hi = (float(v) for v in self.heading)
            object.__setattr__(self, "heading", (lo, hi))

    @classmethod
    def from_initial_pose(cls, world_from_body: np.ndarray,
                          covariance: np.ndarray | Sequence[float]) -> StartHint:
        """The hint of a ROS ``/initialpose`` (geometry_msgs/PoseWithCovarianceStamped): its
        (4, 4) pose (``localize.ros2.convert.pose_of``) and its row-major (6, 6) covariance
        over x, y, z, roll, pitch, yaw (the x, y, z, yaw part is kept)."""
        cov6 = np.asarray(covariance, dtype=np.float64).reshape(6, 6)
        idx = np.array(ROS_XYZYAW)
        return cls(pose=xyzyaw_from_pose(np.asarray(world_from_body))[0],
                   covariance=cov6[np.ix_(idx, idx)])

    @classmethod
    def start_of_initial_pose(cls, world_from_body: np.ndarray,
                              covariance: np.ndarray | Sequence[float],
                              init_std: Sequence[float]) -> np.ndarray | StartHint:
        """What a ROS ``/initialpose`` starts: tracking from its pose ((4,) x, y, z, yaw)
        where its covariance is no wider than the tracking start's noise (``init_std``: x, y,
        z m, yaw deg; an all-zero covariance, as many publishers send, included), else a
        search inside its Gaussian (``from_initial_pose``; RViz's 2D Pose Estimate: 0.5 m,
        15 deg)."""
        return cls.from_initial_pose(world_from_body, covariance).start(init_std)

    def start(self, init_std: Sequence[float]) -> np.ndarray | StartHint:
        """What this hint starts: tracking from its pose ((4,) x, y, z, yaw) where it is a pose
        alone whose spread in x, y and yaw is no wider than the tracking start's noise
        (``init_std``: x, y, z m, yaw deg), else a search inside itself."""
        if self.pose is None or self.region is not None or self.heading is not None:
            return self
        std = np.array([init_std[0], init_std[1], np.deg2rad(init_std[3])], dtype=np.float64)
        var = np.diag(self.covariance)[[0, 1, 3]]
        return self.pose if bool((var <= std ** 2 + 1e-12).all()) else self

    @property
    def heading_span(self) -> float:
        """Radians of headings the hint allows, in (0, 2 pi]."""
        if self.heading is None:
            return 2 * np.pi
        span = float(np.mod(self.heading[1] - self.heading[0], 2 * np.pi))
        return span if span > 0 else 2 * np.pi

    def heading_ok(self, yaw: np.ndarray) -> np.ndarray:
        """(N,) bool: headings (N,) rad inside the range."""
        if self.heading is None:
            return np.ones(len(yaw), bool)
        return np.mod(yaw - self.heading[0], 2 * np.pi) <= self.heading_span + 1e-12

    def region_cells(self, free: OccupancyMap) -> np.ndarray:
        """Flat indices of the free cells whose centres lie inside the region (all free
        cells without one)."""
        idx = np.flatnonzero(free.free)
        if self.region is None:
            return idx
        rc = np.stack(np.unravel_index(idx, free.shape))
        return idx[polygon_contains(self.region, free.centres(rc))]

    def area(self, free: OccupancyMap) -> float:
        """m2 x heading share the hint covers: its free area (the polygon's own where it holds
        no free cell; a pose's 2-sigma ellipse) x ``heading_span`` / 2 pi; the particle count
        follows it (``FilterConfig.global_count``)."""
        if self.pose is not None:
            sx, sy = np.sqrt(np.maximum(np.diag(self.covariance)[:2], 1e-6))
            a = np.pi * 4 * sx * sy
            span = min(self.heading_span, 2 * np.sqrt(max(self.covariance[3, 3], 1e-6)) * 2)
        else:
            n = len(self.region_cells(free))
            a = n * free.cell ** 2 if n else polygon_area(self.region)
            span = self.heading_span
        return float(a * min(span, 2 * np.pi) / (2 * np.pi))

    def draw(self, rng: np.random.Generator, free: OccupancyMap, n: int) -> np.ndarray:
        """(n, 4) poses x, y, z (m), yaw (rad) inside the hint.

        A pose: the Gaussian of its covariance, redrawn (up to ``REDRAWS`` times) where a
        draw falls outside the region or the heading range. Else: uniform over the region's
        free cells (over the polygon itself when it holds none), heights over the free
        space's band, headings over the range.
        """
        n = int(n)
        if self.pose is not None:
            out = rng.multivariate_normal(self.pose, self.covariance, n, method="eigh")
            for _ in range(REDRAWS):
                bad = ~self._inside(out)
                if not bad.any():
                    break
                out[bad] = rng.multivariate_normal(self.pose, self.covariance,
                                                   int(bad.sum()), method="eigh")
            out[:, 3] = wrap_angle(out[:, 3])
            return out
        cells = self.region_cells(free)
        if len(cells):
            xy = self._in_cells(rng, free, cells, n)
        else:
            xy = self._uniform_in_region(rng, n)
        z = rng.uniform(free.band[0], free.band[1], n)
        if self.heading is None:
            yaw = rng.uniform(-np.pi, np.pi, n)
        else:
            yaw = wrap_angle(self.heading[0] + rng.uniform(0.0, self.heading_span, n))
        return np.column_stack([xy, z, yaw])

    def log_prior(self, states: np.ndarray) -> np.ndarray:
        """(N,) log prior of poses (N, 4) x, y, z (m), yaw (rad) under the hint, up to a
        constant: -inf outside the region or the heading range; a pose's Gaussian over x, y
        and yaw (height left to the search); the weights a global search starts from."""
        states = np.asarray(states, dtype=np.float64)
        out = np.where(self._inside(states), 0.0, -np.inf)
        if self.pose is not None:
            idx = np.array([0, 1, 3])
            d = states[:, idx] - self.pose[idx]
            d[:, 2] = wrap_angle(d[:, 2])
            cov = self.covariance[np.ix_(idx, idx)] + 1e-9 * np.eye(3)
            out = out - 0.5 * np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d)
        return out

    def _inside(self, poses: np.ndarray) -> np.ndarray:
        ok = self.heading_ok(poses[:, 3])
        if self.region is not None:
            ok &= polygon_contains(self.region, poses[:, :2])
        return ok

    def _in_cells(self, rng: np.random.Generator, free: OccupancyMap, cells: np.ndarray,
                  n: int) -> np.ndarray:
        """(n, 2) uniform over the cells (flat indices), inside the region: a point of a cell
        the polygon cuts is redrawn, up to ``REDRAWS`` times, then put at its cell's centre
        (inside: ``region_cells``)."""
        r, c = np.unravel_index(cells[rng.integers(len(cells), size=n)], free.shape)
        corner = free.origin + np.stack([c, r], 1) * free.cell
        xy = corner + rng.random((n, 2)) * free.cell
        if self.region is None:
            return xy
        for _ in range(REDRAWS):
            bad = ~polygon_contains(self.region, xy)
            if not bad.any():
                return xy
            xy[bad] = corner[bad] + rng.random((int(bad.sum()), 2)) * free.cell
        bad = ~polygon_contains(self.region, xy)
        xy[bad] = corner[bad] + 0.5 * free.cell
        return xy

    def _uniform_in_region(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 2) uniform in the polygon (rejection from its bounding box)."""
        lo, hi = self.region.min(axis=0), self.region.max(axis=0)
        out = np.empty((0, 2))
        while len(out) < n:
            xy = lo + rng.random((2 * n + 16, 2)) * (hi - lo)
            out = np.concatenate([out, xy[polygon_contains(self.region, xy)]])
        return out[:n]


def free_space_extent(free: OccupancyMap) -> str:
    """The free space's extent as messages give it: x, y (m) of its cells and its band of
    heights."""
    x0, y0, x1, y1 = free.free_bounds + np.array([-0.5, -0.5, 0.5, 0.5]) * free.cell
    return (f"x {x0:.2f} to {x1:.2f} m, y {y0:.2f} to {y1:.2f} m, heights {free.band[0]:.2f} "
            f"to {free.band[1]:.2f} m")


def region_overlaps(region: np.ndarray, free: OccupancyMap) -> bool:
    """Whether a polygon (K, 2), m, overlaps the free cells: a free cell's centre lies inside
    it, or a point of its outline (its corners and points along its edges, half a cell apart)
    lies in a free cell."""
    if len(StartHint(region=region).region_cells(free)):
        return True
    step = 0.5 * free.cell
    outline = [region]
    for a, b in zip(region, np.roll(region, -1, axis=0), strict=True):
        n = int(np.ceil(np.linalg.norm(b - a) / step)) + 1
        outline.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return bool(free.contains(np.concatenate(outline)).any())


def check_region(region: np.ndarray, free: OccupancyMap, where: str) -> None:
    """ValueError naming ``where`` (e.g. ``hint.region=[...]``) and the free space's extent
    when the polygon (K, 2) does not overlap the free space (``region_overlaps``)."""
    if not region_overlaps(region, free):
        raise ValueError(f"{where}: the region does not overlap the map's free space "
                         f"({free_space_extent(free)}; world/free.npz); give a region inside "
                         f"it, in the model's frame")


def check_start_position(xyz: Sequence[float], free: OccupancyMap, where: str) -> None:
    """ValueError naming ``where`` (e.g. ``start=[...]``) and the free space's extent when the
    position (3,) m lies more than ``START_MAX_OUTSIDE_M`` outside the free space."""
    d = float(free.outside_distance_xyz(np.asarray(xyz, dtype=np.float64)[None, :3])[0])
    if d > START_MAX_OUTSIDE_M:
        raise ValueError(f"{where}: the position lies {d:.2f} m outside the map's free space "
                         f"({free_space_extent(free)}; world/free.npz), more than the "
                         f"{START_MAX_OUTSIDE_M:g} m allowed; give a pose inside it, in the "
                         f"model's frame")


def named_space(world_info: Mapping, name: str) -> np.ndarray:
    """(K, 2) polygon of a space (room) the world names (world.json ``spaces``:
    ``{name: [[x, y], ...]}``); ValueError listing the names there are."""
    spaces = world_info.get("spaces") or {}
    for key, poly in spaces.items():
        if str(key).strip().lower() == str(name).strip().lower():
            return as_polygon(poly, f"world.json spaces.{key}")
    have = ", ".join(sorted(spaces)) or "none (world.json has no 'spaces')"
    raise ValueError(f"hint.space={name!r}: the world names no such space; its spaces: {have}; "
                     "give hint.region=[xmin,ymin,xmax,ymax] or a polygon instead")


def start_of_settings(hint, world_info: Mapping, free: OccupancyMap,
                      init_std: Sequence[float]) -> np.ndarray | StartHint | None:
    """What the ``hint`` settings (``localize.config.HintConfig``) start, for
    ``Localizer.reset``: (4,) x, y, z (m), yaw (rad) to track from where ``hint.pose`` is
    given alone with no ``pose_std`` or one no wider than the tracking start's noise
    (``init_std``: x, y, z m, yaw deg); a ``StartHint`` to search inside where anything else
    is set; None where nothing is. Raises as ``hint_from_settings``."""
    h = hint_from_settings(hint, world_info, free, init_std)
    return None if h is None else h.start(init_std)


def hint_from_settings(hint, world_info: Mapping, free: OccupancyMap,
                       init_std: Sequence[float]) -> StartHint | None:
    """The ``StartHint`` of the ``hint`` settings (``localize.config.HintConfig``), None
    when none is set; ``world_info`` (world.json) resolves ``hint.space``; a ``hint.pose``
    without ``pose_std`` has the tracking start's noise ``init_std`` (x, y, z m, yaw deg).

    Raises:
        ValueError: a setting malformed, a region (``hint.region``, ``hint.space``) that does
            not overlap the free space ``free`` (``check_region``), or a ``hint.pose`` more
            than ``START_MAX_OUTSIDE_M`` outside it, naming the key and the free space's
            extent.
    """
    if hint is None:
        return None
    region = pose = cov = heading = None
    if hint.region is not None and hint.space is not None:
        raise ValueError("hint.region and hint.space both set: give one")
    if hint.region is not None:
        region = as_polygon(hint.region)
        check_region(region, free, f"hint.region={list(hint.region)}")
    elif hint.space is not None:
        region = named_space(world_info, hint.space)
        check_region(region, free, f"hint.space={hint.space!r} (world.json spaces)")
    if hint.pose is not None:
        p = np.asarray(list(hint.pose), dtype=np.float64)
        s = np.asarray(list(init_std if hint.pose_std is None else hint.pose_std),
                       dtype=np.float64)
        if p.shape != (4,) or s.shape != (4,) or (s < 0).any() or not np.isfinite(p).all():
            raise ValueError(f"hint.pose is [x, y, z, yaw_deg] in the model's frame and "
                             f"hint.pose_std [sx, sy, sz, syaw_deg] >= 0 or null, got "
                             f"{list(hint.pose)}, {hint.pose_std}")
        check_start_position(p[:3], free, f"hint.pose={list(hint.pose)}")
        pose = np.array([p[0], p[1], p[2], np.deg2rad(p[3])])
        cov = np.diag(np.array([s[0], s[1], s[2], np.deg2rad(s[3])]) ** 2)
    if hint.heading_deg is not None:
        h = list(hint.heading_deg)
        if len(h) != 2:
            raise ValueError(f"hint.heading_deg is [from, to] degrees (counter-clockwise), got "
                             f"{h}")
        heading = (float(np.deg2rad(h[0])), float(np.deg2rad(h[1])))
    if region is None and pose is None and heading is None:
        return None
    return StartHint(region, pose, cov, heading)
