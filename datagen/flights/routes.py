"""Routes through the free space of an occupancy map, and motion along them.

A route is an (K, 2) polyline in metres (world x, y), its points ``spacing`` apart, every
point in free space. ``plan_route`` finds a long one between two far-apart cells (where the
space has none as long as asked, laps of a loop around it: ``loops``);
``route_from_waypoints`` checks and smooths a user's. ``route_at`` turns an arc length into
a position and the direction of travel, the frame a flight's sway (along the left normal)
and yaw swings (about the tangent) are added in; ``route_to_trajectory`` flies a route at a
speed. ``find_turns`` reports the route's turns.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from core.config import as_config
from core.occupancy import OccupancyMap
from datagen.config import RouteConfig
from datagen.flights.loops import extent_text, perimeter_loop

log = logging.getLogger(__name__)

_BEZIER_POINTS = 16  # samples of a rounded corner before resampling
_HALVINGS = 6  # times a corner's radius is halved before it is left sharp
LOOP_INSETS = (1.0, 0.5, 0.25)  # m a fitted loop may keep inside the route's free space
# (the first whose lap is long enough; less where narrower)
MIN_ROUTE_M = 2.0  # m, the shortest route (a loop's lap) a flight is fitted to


# ---------------------------------------------------------------------- planning


def route_graph(occ: OccupancyMap, wall_cost: float) -> tuple[sparse.csr_matrix, np.ndarray]:
    """The free cells as an 8-connected graph (a diagonal step needs both cells beside it free).

    A step costs its length (m) x (1 + wall_cost / clearance), clearance averaged over its two
    cells, so cheap paths keep away from walls.

    Returns:
        (N, N) upper-triangular sparse costs, undirected; (N,) flat cell index of each node.
    """
    free = occ.free
    h, w = free.shape
    node = np.full(free.shape, -1, np.int64)
    cells = np.flatnonzero(free)
    node.flat[cells] = np.arange(len(cells))
    inv = 1.0 / np.maximum(occ.clearance.astype(np.float64), occ.cell / 2)
    rows, cols, costs = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = (slice(0, h - dr), slice(max(0, -dc), w - max(0, dc)))
        b = (slice(dr, h), slice(max(0, dc), w - max(0, -dc)))
        ok = free[a] & free[b]
        if dr and dc:  # no corner cutting
            ok &= free[b[0], a[1]] & free[a[0], b[1]]
        rows.append(node[a][ok])
        cols.append(node[b][ok])
        step = occ.cell * np.hypot(dr, dc)
        costs.append(step * (1 + wall_cost * 0.5 * (inv[a][ok] + inv[b][ok])))
    graph = sparse.coo_matrix((np.concatenate(costs), (np.concatenate(rows),
                                                       np.concatenate(cols))),
                              shape=(len(cells), len(cells))).tocsr()
    return graph, cells


def plan_route(occ: OccupancyMap, rng: np.random.Generator,
               settings: RouteConfig | Mapping | None = None, fit: bool = True) -> np.ndarray:
    """A long route through the largest connected free region, ``extra_margin`` farther from
    obstacles than the map's margin.

    Both ends lie on the ridge of the free space (cells whose clearance no neighbour
    exceeds: the middle of corridors and rooms). From a random free cell, the ridge cell
    costliest to reach is one end, A; the other, B, is drawn among the ridge cells at >=
    ``far_fraction`` of the costliest route from A. The cheapest A -> B path
    (``route_graph``) is simplified and its corners rounded (``smooth_route``). A route
    shorter than ``min_length`` (at least ``MIN_ROUTE_M``) or with fewer than ``min_turns``
    turns is drawn again, up to ``tries`` times.

    Where none of the draws holds, ``fit`` fits the route to the free space (``_fitted``,
    with a warning naming what was relaxed): the drawn route of ``min_length`` with the most
    turns, else laps of a loop around the region (``loops.perimeter_loop``) as long as
    ``min_length``.

    Args:
        occ: the free space.
        rng: random generator (the start cell and B).
        settings: ``RouteConfig`` (or a mapping of the keys that differ; None: defaults).
        fit: fit the route to the free space where no draw holds; False: raise.

    Returns:
        (K, 2) m route points, ``settings.spacing`` apart.

    Raises:
        ValueError: bad settings; no free space; without ``fit``, no draw holding; with it,
            a free space without room for a route of ``MIN_ROUTE_M``.
    """
    c = as_config(RouteConfig, settings, "route")
    if not 0 < c.far_fraction <= 1:
        raise ValueError(f"route.far_fraction must be in (0, 1], got {c.far_fraction}")
    if c.wall_cost < 0 or c.tries < 1:
        raise ValueError(f"route.wall_cost must be >= 0 and route.tries >= 1, got "
                         f"{c.wall_cost}, {c.tries}")
    if c.extra_margin < 0:
        raise ValueError(f"route.extra_margin must be >= 0, got {c.extra_margin}")
    given, occ = occ, occ.eroded(c.extra_margin)
    if not occ.free.any():
        raise ValueError(f"route: no free space is {occ.margin} m from obstacles (the map's "
                         f"margin plus route.extra_margin {c.extra_margin}; the free space is "
                         f"{extent_text(given.free, given.cell)}); lower route.extra_margin")
    graph, cells = route_graph(occ, c.wall_cost)
    _, label = csgraph.connected_components(graph, directed=False)
    region = label == np.bincount(label).argmax()
    if region.sum() < 2 and not fit:
        raise ValueError("route: the free space is a single cell; lower the margin or the "
                         "cell size")
    clear = occ.clearance.astype(np.float64) * occ.free
    ridge = (clear >= ndimage.maximum_filter(clear, size=3) - 1e-6).flat[cells] & region
    need = max(c.min_length, MIN_ROUTE_M)
    best, drawn = (-1, -1.0), []
    for _ in range(c.tries if region.sum() >= 2 else 0):
        route = _far_route(occ, graph, cells, np.flatnonzero(region), ridge, rng, c)
        length = route_length(route)  # 0 where both ends fell in one cell (a tiny space)
        found = (count_turns(route, c.turn_deg) if length > 0 else 0, length)
        if found[1] >= need and found[0] >= c.min_turns:
            return route
        best = max(best, found)
        drawn.append((found, route))
    asked = (f"no route of >= {need:.1f} m with >= {c.min_turns} turns of >= "
             f"{c.turn_deg} deg in {c.tries} tries (best: {best[1]:.1f} m, {best[0]} turns)")
    if not fit:
        raise ValueError(f"route: {asked}; lower route.min_length / min_turns or give "
                         "waypoints")
    region_cells = np.zeros(occ.shape, bool)
    region_cells.flat[cells[region]] = True
    return _fitted(occ, given, region_cells, drawn, asked, replace(c, min_length=need), rng)


def _fitted(occ: OccupancyMap, given: OccupancyMap, region: np.ndarray,
            drawn: list[tuple[tuple[int, float], np.ndarray]], asked: str, c: RouteConfig,
            rng: np.random.Generator) -> np.ndarray:
    """``plan_route``'s route where no draw held: the draw of ``min_length`` with the most
    turns, else laps of a loop (``_loop_laps``), else the longest draw; a warning names what
    was relaxed.

    Args:
        occ: the map ``given`` eroded by ``c.extra_margin``.
        given: the map ``plan_route`` was given (for the error).
        region: (H, W) bool, the largest connected region of ``occ``.
        drawn: ((turns, length m), (K, 2) m route) of each draw.
        asked: what no draw held, for messages.
        rng: random generator (where a loop starts, and which way round).

    Raises:
        ValueError: no loop or draw of ``MIN_ROUTE_M``, naming the free space's size.
    """
    long = [d for d in drawn if d[0][1] >= c.min_length]
    if long:
        (turns, length), route = max(long, key=lambda d: d[0])
        log.warning("route: %s; flying a %.1f m route with %d turns (min_turns relaxed)",
                    asked, length, turns)
        return route
    route, one = _loop_laps(occ, region, c, rng)
    if route is not None:
        log.warning("route: %s; flying %d lap(s) of a %.1f m loop around the free space "
                    "instead of a route between far-apart places (%.1f m, %d turns)", asked,
                    round(route_length(route) / one), one, route_length(route),
                    count_turns(route, c.turn_deg))
        return route
    (_, length), route = max(drawn, key=lambda d: d[0][1], default=((0, 0.0), None))
    if length >= MIN_ROUTE_M:
        log.warning("route: %s; flying the longest, %.1f m (min_length relaxed: the flight "
                    "is flown slower)", asked, length)
        return route
    raise ValueError(f"route: the free space is too small for a flight: "
                     f"{extent_text(given.free, given.cell)} ({given.margin} m from obstacles), "
                     f"its largest region {extent_text(region, occ.cell)} once "
                     f"route.extra_margin {c.extra_margin} m farther: room for a route of "
                     f"{max(length, one):.1f} m, under {MIN_ROUTE_M} m; lower "
                     "route.extra_margin or the world's camera_margin, or fly a larger space")


def _loop_laps(occ: OccupancyMap, region: np.ndarray, c: RouteConfig,
               rng: np.random.Generator) -> tuple[np.ndarray | None, float]:
    """Laps of a loop around a region (H, W) bool (``loops.perimeter_loop``), as many as
    ``c.min_length`` takes.

    The loop keeps the first of ``LOOP_INSETS`` whose lap reaches ``c.min_length`` (else the
    longest lap: a lower inset gets through narrower gaps), is simplified (within half its
    inset at most, so a corridor's loop keeps two lanes) and rounded as ``smooth_route``
    does. It starts at the middle of a side drawn by its length, either way round.

    Returns:
        (K, 2) m route (None where one lap is under ``MIN_ROUTE_M``) and one lap's length (m;
        0 without a loop).
    """
    lap, one = None, 0.0
    for inset in LOOP_INSETS:
        loop, kept = perimeter_loop(occ, region, inset)
        if loop is None:
            continue
        simple = _simplify(occ, loop, min(c.simplify_m, max(kept, occ.cell) / 2))
        length = route_length(_round_corners(occ, simple, c.turn_radius, c.spacing))
        if length > one or length >= c.min_length:
            lap, one = simple, length
        if length >= c.min_length:
            break
    if lap is None or one < MIN_ROUTE_M:
        return None, one
    lap = _from_a_side(lap[::-1] if rng.random() < 0.5 else lap, rng)
    laps = max(int(np.ceil(c.min_length / one)), 1)
    while True:  # at most twice: resampled chords make laps a hair short
        route = _round_corners(occ, np.concatenate([lap] + [lap[1:]] * (laps - 1)),
                               c.turn_radius, c.spacing)
        if route_length(route) >= c.min_length:
            return route, one
        laps += 1


def _from_a_side(loop: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A closed polygon (V + 1, 2) m (last = first) started at the middle of a side drawn by
    its length: (V + 2, 2) m, so laps join on a straight piece."""
    side = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    i = int(rng.choice(len(side), p=side / side.sum()))
    mid = (loop[i] + loop[i + 1]) / 2
    return np.concatenate([mid[None], loop[i + 1:], loop[1 : i + 1], mid[None]])


def _far_route(occ: OccupancyMap, graph: sparse.csr_matrix, cells: np.ndarray,
               region: np.ndarray, ridge: np.ndarray, rng: np.random.Generator,
               c: RouteConfig) -> np.ndarray:
    """One draw of ``plan_route``'s route (region: node ids; ridge: (N,) bool)."""
    start = region[rng.integers(len(region))]
    dist = csgraph.dijkstra(graph, directed=False, indices=start)
    a = int(np.argmax(np.where(ridge, dist, -1)))
    dist, pred = csgraph.dijkstra(graph, directed=False, indices=a, return_predecessors=True)
    far_ok = ridge & np.isfinite(dist)
    far = np.flatnonzero(far_ok & (dist >= c.far_fraction * dist[far_ok].max()))
    b = int(far[rng.integers(len(far))])
    path = [b]
    while path[-1] != a:  # O(path length), once per route
        path.append(int(pred[path[-1]]))
    rc = np.unravel_index(cells[np.array(path[::-1])], occ.shape)
    return smooth_route(occ, occ.centres(np.stack(rc)), c)


def smooth_route(occ: OccupancyMap, points: np.ndarray,
                 settings: RouteConfig | Mapping | None = None) -> np.ndarray:
    """A cell path (P, 2) m simplified within ``simplify_m`` (keeping every straight piece in
    free space), its corners rounded and the result resampled: (K, 2) m."""
    c = as_config(RouteConfig, settings, "route")
    vertices = _simplify(occ, np.asarray(points, np.float64), c.simplify_m)
    return _round_corners(occ, vertices, c.turn_radius, c.spacing)


def route_from_waypoints(occ: OccupancyMap, waypoints: Sequence[Sequence[float]] | np.ndarray,
                         settings: RouteConfig | Mapping | None = None) -> np.ndarray:
    """A user's route: waypoints (K, 2) m checked against the free space, corners rounded.

    Raises:
        ValueError: a waypoint outside the free space, or a segment through an obstacle
            (naming the segment and where it is blocked).
    """
    c = as_config(RouteConfig, settings, "route")
    wp = np.asarray(waypoints, dtype=np.float64)
    if wp.ndim != 2 or wp.shape[1] != 2 or len(wp) < 2 or not np.isfinite(wp).all():
        raise ValueError(f"route: waypoints must be [[x, y], ...] (at least two, metres), got "
                         f"{np.asarray(waypoints).tolist()}")
    inside = occ.contains(wp)
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        d = float(occ.distance(wp[i : i + 1])[0])
        raise ValueError(f"route: waypoint {i} ({wp[i, 0]:.2f}, {wp[i, 1]:.2f}) is not in the "
                         f"free space ({d:.2f} m from the nearest obstacle, margin "
                         f"{occ.margin} m); move it")
    blocked = first_blocked(occ, wp[:-1], wp[1:])
    if np.isfinite(blocked).any():
        i = int(np.flatnonzero(np.isfinite(blocked))[0])
        at = wp[i] + (wp[i + 1] - wp[i]) * blocked[i] / np.linalg.norm(wp[i + 1] - wp[i])
        raise ValueError(f"route: segment {i} -> {i + 1} ({wp[i, 0]:.2f}, {wp[i, 1]:.2f}) -> "
                         f"({wp[i + 1, 0]:.2f}, {wp[i + 1, 1]:.2f}) is blocked at "
                         f"({at[0]:.2f}, {at[1]:.2f}), {blocked[i]:.2f} m after waypoint {i}; "
                         "add a waypoint around the obstacle")
    return _round_corners(occ, wp, c.turn_radius, c.spacing)


def first_blocked(occ: OccupancyMap, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(S,) m along each segment a -> b ((S, 2) m each) to its first point outside the free
    space (sampled every quarter cell), inf where the segment is clear."""
    a, b = np.atleast_2d(a).astype(np.float64), np.atleast_2d(b).astype(np.float64)
    length = np.linalg.norm(b - a, axis=1)
    n = np.ceil(length / (occ.cell / 4)).astype(np.int64) + 1
    seg = np.repeat(np.arange(len(a)), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.maximum(n - 1, 1)[seg]
    pts = a[seg] + frac[:, None] * (b - a)[seg]
    dist = np.where(occ.contains(pts), np.inf, frac * length[seg])
    out = np.full(len(a), np.inf)
    np.minimum.at(out, seg, dist)
    return out


def _simplify(occ: OccupancyMap, pts: np.ndarray, tol: float) -> np.ndarray:
    """Ramer-Douglas-Peucker within ``tol`` m whose kept segments stay in free space."""
    keep = np.zeros(len(pts), bool)
    keep[[0, -1]] = True
    stack = [(0, len(pts) - 1)]
    while stack:  # one pass per kept vertex
        i, j = stack.pop()
        if j <= i + 1:
            continue
        d = _point_line_distance(pts[i + 1 : j], pts[i], pts[j])
        if d.max() > tol or np.isfinite(first_blocked(occ, pts[i], pts[j])[0]):
            k = i + 1 + int(np.argmax(d))
            keep[k] = True
            stack += [(i, k), (k, j)]
    return pts[keep]


def _point_line_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip((p - a) @ ab / max(float(ab @ ab), 1e-18), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def _round_corners(occ: OccupancyMap, vertices: np.ndarray, radius: float,
                   spacing: float) -> np.ndarray:
    """Replace each inner vertex of a polyline by a quadratic Bezier from ``radius`` before it
    to ``radius`` after it (at most half of each side), halving a corner's radius while its
    curve leaves the free space; then resample every ``spacing`` m."""
    if spacing <= 0:
        raise ValueError(f"route.spacing must be positive, got {spacing}")
    r = np.full(max(len(vertices) - 2, 0), max(float(radius), 0.0))
    for attempt in range(_HALVINGS + 2):
        curve, s, span = _rounded(vertices, r, spacing)
        bad = s[~occ.contains(curve)]
        k = np.searchsorted(span[:, 0], bad, side="right") - 1  # the corner arc before
        corners = np.unique(k[(k >= 0) & (bad <= span[np.maximum(k, 0), 1] + spacing)])
        if not len(corners):
            break
        r[corners] = r[corners] / 2 if attempt < _HALVINGS else 0.0
    return curve


def _rounded(vertices: np.ndarray, r: np.ndarray,
             spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rounded polyline resampled: points (K, 2), their arc lengths (K,), and (C, 2) the
    arc-length span of each corner's curve."""
    p = vertices
    if len(p) > 2:
        d = np.diff(p, axis=0)
        seg = np.linalg.norm(d, axis=1)
        u = d / np.maximum(seg, 1e-12)[:, None]
        rr = np.minimum(r, 0.5 * np.minimum(seg[:-1], seg[1:]))[:, None]
        q0, q1, q2 = p[1:-1] - rr * u[:-1], p[1:-1], p[1:-1] + rr * u[1:]
        t = np.linspace(0, 1, _BEZIER_POINTS)[None, :, None]
        arcs = (1 - t) ** 2 * q0[:, None] + 2 * t * (1 - t) * q1[:, None] + t**2 * q2[:, None]
        p = np.concatenate([p[:1], arcs.reshape(-1, 2), p[-1:]])
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    keep = np.r_[True, step > 1e-9]
    p, s = p[keep], np.concatenate([[0.0], np.cumsum(step[step > 1e-9])])
    if len(vertices) > 2:  # arc-length span of every corner's curve (before dropping points)
        all_s = np.concatenate([[0.0], np.cumsum(step)])
        ends = all_s[1:-1].reshape(-1, _BEZIER_POINTS)
        corner_s = ends[:, [0, -1]]
    else:
        corner_s = np.zeros((0, 2))
    n = max(int(np.ceil(s[-1] / spacing)), 1) + 1
    s_new = np.linspace(0.0, s[-1], n)
    curve = np.stack([np.interp(s_new, s, p[:, i]) for i in range(2)], 1)
    return curve, s_new, corner_s


# ---------------------------------------------------------------------- motion along a route


def route_length(route: np.ndarray) -> float:
    """Length (m) of a route (K, 2)."""
    return float(np.linalg.norm(np.diff(np.asarray(route, np.float64), axis=0), axis=1).sum())


def _segments(route: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A route's points without repeats (K, 2) and their arc lengths (K,)."""
    p = np.asarray(route, np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
        raise ValueError(f"route must be (K >= 2, 2), got {p.shape}")
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    p = p[np.r_[True, step > 1e-12]]
    if len(p) < 2:
        raise ValueError("route has zero length")
    return p, np.concatenate([[0.0], np.cumsum(step[step > 1e-12])])


def route_at(route: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and direction of travel at arc lengths along a route.

    The direction is the segments' directions interpolated between their midpoints, so on a
    route of ``plan_route`` (points a few cm apart) it turns smoothly through a corner.

    Args:
        route: (K, 2) m.
        s: (N,) m from the route's start, clipped to [0, length].

    Returns:
        xy (N, 2) m; tangent (N, 2) unit vectors (the left normal is (-ty, tx)).
    """
    p, cum = _segments(route)
    d = np.diff(p, axis=0) / np.diff(cum)[:, None]
    mid = (cum[1:] + cum[:-1]) / 2
    s = np.clip(np.asarray(s, np.float64).reshape(-1), 0, cum[-1])
    xy = np.stack([np.interp(s, cum, p[:, i]) for i in range(2)], 1)
    t = np.stack([np.interp(s, mid, d[:, i]) for i in range(2)], 1)
    return xy, t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)


def route_to_trajectory(route: np.ndarray, speed: float, fps: float,
                        num_frames: int | None = None, ramp_s: float = 2.0
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fly a route at a speed: a smooth speed-up over ``ramp_s``, cruise, slow-down.

    Args:
        route: (K, 2) m.
        speed: m/s cruise speed.
        fps: frames per second.
        num_frames: N; None: as many as the whole route takes. A route shorter than the
            flight is flown slower, ending at its end.
        ramp_s: s of speed-up and of slow-down (smoothstep; at most half the flight).

    Returns:
        xy (N, 2) m; heading (N,) rad, the direction of travel (world yaw, from +X towards
        +Y); s (N,) m along the route.
    """
    if speed <= 0 or fps <= 0:
        raise ValueError(f"need speed > 0 and fps > 0, got {speed}, {fps}")
    length = route_length(route)
    whole = num_frames is None
    if whole:
        num_frames = int(np.ceil((length / speed + ramp_s) * fps)) + 1
    if num_frames < 2:
        raise ValueError(f"need num_frames >= 2, got {num_frames}")
    t = np.arange(int(num_frames)) / float(fps)
    ramp = max(min(ramp_s, t[-1] / 2), 1e-9)
    rise, fall = np.clip(t / ramp, 0, 1), np.clip((t[-1] - t) / ramp, 0, 1)
    v = speed * (3 * rise**2 - 2 * rise**3) * (3 * fall**2 - 2 * fall**3)
    s = np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 / fps)])
    if s[-1] > length or whole:
        s *= length / s[-1]
    xy, tangent = route_at(route, s)
    return xy, np.arctan2(tangent[:, 1], tangent[:, 0]), s


# ---------------------------------------------------------------------- turns


def find_turns(route: np.ndarray, min_angle_deg: float = 60.0,
               window_m: float = 3.0) -> np.ndarray:
    """The turns of a route: where the direction of travel changes by at least
    ``min_angle_deg`` over ``window_m`` of route (a rounded corner spans about twice the
    turn radius).

    Returns:
        (T, 2) [arc length (m) at the turn's middle, signed angle (deg, left positive): the
        largest change over the window].
    """
    p, cum = _segments(route)
    d = np.diff(p, axis=0)
    seg_heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    s = np.arange(0.0, cum[-1], 0.05)
    heading = seg_heading[np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(d) - 1)]
    half = window_m / 2
    turn = np.rad2deg(np.interp(s + half, s, heading) - np.interp(s - half, s, heading))
    out = []
    for sign in (1, -1):
        labels, n = ndimage.label(sign * turn >= min_angle_deg)
        if n:
            idx = np.arange(1, n + 1)
            middle = np.array(ndimage.center_of_mass(sign * turn, labels, idx))[:, 0]
            angle = sign * np.asarray(ndimage.maximum(sign * turn, labels, idx))
            out.append(np.stack([np.interp(middle, np.arange(len(s)), s), angle], 1))
    turns = np.concatenate(out) if out else np.zeros((0, 2))
    return turns[np.argsort(turns[:, 0])]


def count_turns(route: np.ndarray, min_angle_deg: float = 60.0, window_m: float = 3.0) -> int:
    """How many turns of at least ``min_angle_deg`` a route has (``find_turns``)."""
    return len(find_turns(route, min_angle_deg, window_m))
