"""Camera body poses in flight: smooth hand-flown flights, views along them, noisy odometry.

All poses are (N, 4, 4) world_from_body (body x forward, y left, z up; world Z up). Positions
come from an occupancy map of the free space (core.occupancy); flights fly routes through it
(datagen.flights.routes). Flight and odometry parameters come from a flight preset
(``FlightConfig``: its ``route``, ``trajectory`` and ``odometry``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial.transform import Rotation

from core.config import as_config
from core.imaging.realism import HarderFlightConfig
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyz_rpy, wrap_angle
from datagen.config import FlightConfig, OdometryConfig, TrajectoryConfig
from datagen.flights.routes import (
    find_turns,
    first_blocked,
    plan_route,
    route_at,
    route_from_waypoints,
    route_length,
)
from datagen.flights.training_views import check_z

log = logging.getLogger(__name__)

GRAVITY = 9.81  # m/s^2
END_MARGIN = 0.5  # m a flight stops short of its route's far end (at most 5 % of the route)
ROOM_STEP = 0.1  # m between the route points where the sway room is measured
DRIFT = 0.5  # m beyond the sway amplitude a flight's centre line may drift off its route


def _pair(cfg: Any, key: str, where: str) -> tuple[float, float]:
    """The [min, max] pair ``cfg.<key>`` (a number: both), checked."""
    value = getattr(cfg, key)
    try:
        lo, hi = (float(v) for v in (value if hasattr(value, "__len__") else (value, value)))
    except (TypeError, ValueError) as err:
        raise ValueError(f"{where}.{key} must be a number or [min, max], got {value!r}") from err
    if hi < lo:
        raise ValueError(f"{where}.{key} = [{lo}, {hi}] has max < min; swap them")
    return lo, hi


def sample_flight_views(rng: np.random.Generator, n: int, free: OccupancyMap,
                        z_range: np.ndarray, presets: Sequence[FlightConfig | Mapping],
                        routes: Sequence[np.ndarray]) -> np.ndarray:
    """Camera body poses as the flights fly, for training images.

    Each pose is a random frame of its own flight (``flight_trajectory``) of a random preset
    along that preset's route, forwards or backwards with equal chance, over a random stretch
    of it as long as the flight needs: heights, sway, yaw swings and tilts as flown.

    Args:
        rng: random generator.
        n: number of poses.
        free: where a camera may be.
        z_range: (2,) allowed heights (m).
        presets: flight presets (``FlightConfig``, or mappings of the keys that differ from
            its defaults).
        routes: (K, 2) m, the route of each preset (``flight_route``, resolved once by the
            caller: planning is costly).

    Returns:
        (n, 4, 4) world_from_body.
    """
    if not presets:
        raise ValueError("training.flight_views needs at least one preset under `flights`")
    if len(routes) != len(presets):
        raise ValueError(f"sample_flight_views: {len(routes)} routes for {len(presets)} presets")
    out = np.empty((n, 4, 4))
    for i in range(n):
        k = int(rng.integers(len(presets)))
        preset = as_config(FlightConfig, presets[k], "flights")
        trajectory = replace(preset.trajectory, reverse=bool(rng.random() < 0.5))
        need = _route_needed(preset)
        route, length = routes[k], route_length(routes[k])
        if length > need:
            route = route_window(route, rng.uniform(0.0, length - need), need)
        poses = flight_trajectory(rng, preset.num_frames, preset.fps, route, free, z_range,
                                  trajectory)
        out[i] = poses[rng.integers(len(poses))]
    return out


def smooth_noise(rng: np.random.Generator, t: np.ndarray, freq_hz: tuple[float, float],
                 terms: int = 4) -> np.ndarray:
    """Smooth random signal: a sum of sinusoids with random frequencies and phases.

    Args:
        rng: random generator.
        t: (N,) times in seconds.
        freq_hz: (min, max) frequency range of the components.
        terms: number of sinusoids.

    Returns:
        (N,) signal scaled to peak exactly 1 in absolute value over t (0 if N == 0).
    """
    t = np.asarray(t, dtype=np.float64)
    f = rng.uniform(freq_hz[0], freq_hz[1], terms)
    phase = rng.uniform(0, 2 * np.pi, terms)
    amp = rng.uniform(0.5, 1.0, terms) / np.maximum(f, 1e-3)  # 1/f: slower is larger
    amp /= amp.sum()
    s = np.sin(2 * np.pi * f[None, :] * t[:, None] + phase) @ amp
    peak = np.max(np.abs(s)) if len(s) else 0.0
    return s / peak if peak > 1e-12 else s


# ---------------------------------------------------------------------- routes of flights


def _route_needed(preset: FlightConfig, fastest: bool = True) -> float:
    """m of route a flight of the preset may need: its fastest (or slowest) speed x duration,
    its largest start offset and the end margin."""
    where = "flights.trajectory"
    duration = max(preset.num_frames - 1, 1) / float(preset.fps)
    speed = _pair(preset.trajectory, "speed", where)[1 if fastest else 0]
    return (speed * duration + _pair(preset.trajectory, "start_offset", where)[1]
            + 2 * END_MARGIN)


def route_window(route: np.ndarray, start: float, length: float) -> np.ndarray:
    """The stretch [start, start + length] m of a route (K, 2), resampled every 5 cm."""
    total = route_length(route)
    a = float(np.clip(start, 0.0, total))
    b = float(np.clip(start + length, a, total))
    s = np.linspace(a, b, max(int(np.ceil((b - a) / 0.05)), 1) + 1)
    return route_at(route, s)[0]


def _stretch_with_turns(route: np.ndarray, preset: FlightConfig) -> np.ndarray:
    """A planned route cut to the length the flight needs, where its part surely flown (the
    slowest speed x duration after the largest start offset, from the end when reversed)
    holds the most turns of ``route_settings.turn_deg``."""
    need, total = _route_needed(preset), route_length(route)
    if total <= need + 0.5:
        return route
    c, where = preset.trajectory, "flights.trajectory"
    duration = max(preset.num_frames - 1, 1) / float(preset.fps)
    start_hi = _pair(c, "start_offset", where)[1]
    sure = _pair(c, "speed", where)[0] * duration
    turns = find_turns(route, preset.route_settings.turn_deg)[:, 0]
    a = np.arange(0.0, total - need, 0.25)[:, None]
    lo = a + (need - start_hi - sure if c.reverse else start_hi)
    count = ((turns[None] > lo) & (turns[None] < lo + sure)).sum(1)
    return route_window(route, float(a[int(np.argmax(count)), 0]), need)


def flight_route(preset: FlightConfig | Mapping, free: OccupancyMap,
                 own_route: np.ndarray | None, rng: np.random.Generator,
                 where: str = "flights") -> np.ndarray:
    """The route a flight preset flies (its ``route``).

    ``auto``: the world's own route if it has one (the corridor's centre line along +Y), else
    one planned through ``free`` (``routes.plan_route`` with the preset's
    ``route_settings``, at least the length the fastest flight needs; where there is none,
    the slowest one's; where there is none either, one fitted to the free space: the
    fastest flight's length with fewer turns, or laps of a loop around a room or down and up
    a short corridor; each with a warning) and cut to the fastest flight's length where the
    part every flight flies turns most. A list of waypoints [[x, y], ...] m:
    ``routes.route_from_waypoints``.

    Args:
        preset: a flight preset (``FlightConfig`` or a mapping of the keys that differ).
        free: the free space of the camera.
        own_route: (K, 2) m the world's own route, or None.
        rng: random generator (planning).
        where: the preset's config key (``flights.<name>``), for messages.

    Returns:
        (K, 2) m route.

    Raises:
        ValueError: bad waypoints or route settings, or a free space too small for any
            flight (naming ``where``.route and the setting to change).
    """
    preset = as_config(FlightConfig, preset, where)
    route = preset.route
    if isinstance(route, str) and route == "auto":
        if own_route is not None:
            return np.asarray(own_route, dtype=np.float64)
        base = preset.route_settings
        fastest = replace(base, min_length=max(base.min_length, _route_needed(preset)))
        fallbacks = [(fastest, False),
                     (replace(base, min_length=_route_needed(preset, fastest=False)), False),
                     (fastest, True)]
        for i, (settings, fit) in enumerate(fallbacks):
            try:
                planned = plan_route(free, rng, settings, fit=fit)
                break
            except ValueError as err:
                if fit:
                    raise ValueError(f"{where}.route: {err}") from None
                log.warning("%s.route: %s; trying %s", where, err,
                            "the slowest flight's length" if i == 0
                            else "a route fitted to the free space")
        return _stretch_with_turns(planned, preset)
    if isinstance(route, str):
        raise ValueError(f"{where}.route must be 'auto' or waypoints [[x, y], ...] (m), got "
                         f"{route!r}")
    try:
        return route_from_waypoints(free, route, preset.route_settings)
    except ValueError as err:
        raise ValueError(f"{where}.route: {err}") from None


# ---------------------------------------------------------------------- flights


def _sway_room(route: np.ndarray, s: np.ndarray, free: OccupancyMap,
               reach: float) -> np.ndarray:
    """(N,) m a flight may sway across the route at arc lengths s (N,): the free run along
    both normals (at most ``reach``), the smaller side, its minimum over +/- 1 m of route,
    averaged over +/- 0.5 m (so never more than the room at s)."""
    lo, hi = float(s.min()), float(s.max())
    grid = np.arange(lo, hi + ROOM_STEP, ROOM_STEP)
    xy, tangent = route_at(route, grid)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], 1)  # right of the route
    sides = [np.minimum(first_blocked(free, xy, xy + sign * reach * normal), reach)
             for sign in (1, -1)]
    room = np.maximum(np.minimum(*sides) - free.cell / 2, 0.0)
    window = int(round(1.0 / ROOM_STEP))
    room = ndimage.minimum_filter1d(room, 2 * window + 1, mode="nearest")
    room = ndimage.uniform_filter1d(room, window + 1, mode="nearest")
    return np.interp(s, grid, room)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _back_and_forth(rng: np.random.Generator, t: np.ndarray, cum: np.ndarray, L: float,
                    h: HarderFlightConfig) -> tuple[np.ndarray, np.ndarray]:
    """Arc lengths of a flight flown back and forth along a route of length L (m), and its
    heading offset from the route's forward tangent (rad).

    The flight starts at a uniform place along the route, either way, and flies at a mean
    speed drawn from ``h.speed``, its progress shaped by ``cum`` (N,) (the preset's smooth
    speed profile, cumulated). At each end it slows down over ``h.turn_m`` metres, hovers
    ``h.turn_s`` seconds while it turns its heading by 180 deg (left or right, drawn per turn),
    and flies back.

    Returns:
        (N,) m arc lengths, (N,) rad heading offsets.
    """
    margin = min(0.05 * L, END_MARGIN)
    a, W = margin, max(L - 2 * margin, 1e-6)
    speed = rng.uniform(*_pair(h, "speed", "realism.flight"))
    X = speed * max(t[-1], 1e-9)  # m of flight, a turn counting as speed x turn_s
    rho = min(max(h.turn_m, 0.0) / W, 0.45)
    eps = min(0.1 / W, rho / 2) if rho > 0 else 0.1 / W  # v-span of a turn (m / W)
    # one period of v in [0, 2): along the route on [0, 1), back on [1, 2); the speed along
    # the route eases to 0 within rho of each end
    g = np.linspace(0.0, 2.0, 4001)
    ease = _smoothstep(np.abs(g - np.round(g)) / max(rho, 1e-9))
    vel = ease * np.where(g < 1.0, 1.0, -1.0)
    fold = np.concatenate([[0.0], np.cumsum((vel[1:] + vel[:-1]) / 2)])
    fold = np.clip(fold / fold[len(g) // 2], 0.0, 1.0)  # 1 at the far end (g = 1)
    # effort e(v) = W v + a hover of speed x turn_s m at each integer v: inverted on a grid
    v0 = rng.uniform(0.0, 2.0)
    v_grid = np.linspace(v0, v0 + X / W + 1e-9, max(int(X / W * 4000), 2000))
    turns = np.arange(1, int(np.ceil(v_grid[-1])) + 1)
    step = _smoothstep((v_grid[:, None] - turns[None] + eps) / (2 * eps))
    e_grid = W * (v_grid - v0) + speed * max(h.turn_s, 0.0) * step.sum(1)
    v = np.interp(X * (cum / cum[-1] if cum[-1] > 0 else np.zeros(len(cum))), e_grid, v_grid)
    s = a + W * np.interp(np.mod(v, 2.0), g, fold)
    sign = rng.choice([-1.0, 1.0], len(turns))
    offset = np.pi * (_smoothstep((v[:, None] - turns[None] + eps) / (2 * eps)) @ sign)
    return s, offset


def check_harder(settings: HarderFlightConfig | Mapping | None,
                 where: str = "realism.flight") -> HarderFlightConfig:
    """``realism.flight`` typed and checked (None: the defaults, off).

    Raises:
        ValueError: a bad setting, naming ``where.<key>`` and the fix.
    """
    h = as_config(HarderFlightConfig, settings, where)
    for key in ("speed", "yaw_rate_deg_s", "yaw_freq_hz"):
        lo, _ = _pair(h, key, where)
        if not lo > 0:
            raise ValueError(f"{where}.{key} = {getattr(h, key)} must be positive")
    for key in ("turn_m", "turn_s", "max_yaw_swing_deg"):
        value = float(getattr(h, key))
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{where}.{key} = {value} must be >= 0")
    if _pair(h, "speed", where)[1] > 5.0:
        raise ValueError(f"{where}.speed = {h.speed}: above 5 m/s is no indoor flight; give "
                         "m/s")
    return h


def flight_trajectory(rng: np.random.Generator, num_frames: int, fps: float,
                      route: np.ndarray, free: OccupancyMap, z_range: np.ndarray,
                      trajectory: TrajectoryConfig | Mapping | None = None,
                      harder: HarderFlightConfig | Mapping | None = None,
                      harder_rng: np.random.Generator | None = None) -> np.ndarray:
    """A smooth hand-flown copter flight along a route.

    The copter starts near the route's start (its end when ``reverse``) and flies along it
    with a smooth speed profile (speed-up, random variation, slow-down), speed x duration
    metres (less if the route is shorter), swaying across the route and in height and
    swinging its yaw about the direction of travel; roll and pitch follow the horizontal
    acceleration (a multirotor tilts to accelerate) plus a small wobble. The sway is
    bounded by the free run across the route (``_sway_room``), so every position lies in a
    free cell, and the height stays in z_range.

    Args:
        rng: random generator.
        num_frames: N.
        fps: frame rate (Hz).
        route: (K, 2) m, the route (``flight_route``), in free cells.
        free: where the camera may be.
        z_range: (2,) allowed heights (m).
        trajectory: a flight preset's ``trajectory`` (``TrajectoryConfig``, or a mapping of
            the keys that differ from its defaults; None: the defaults).
        harder: ``realism.flight`` (``HarderFlightConfig`` or a mapping; None or not
            ``enabled``: the preset's flight): flown back and forth along the route at
            ``harder.speed`` from a uniform start, either way, its yaw swings at a peak rate
            drawn from ``harder.yaw_rate_deg_s`` (``_back_and_forth``).
        harder_rng: the generator of ``harder``'s draws (the preset's come from ``rng`` as
            without it).

    Returns:
        (N, 4, 4) world_from_body.

    Raises:
        ValueError: bad settings, or a route whose points are not in free cells.
    """
    z = check_z(z_range)
    if num_frames < 1 or fps <= 0:
        raise ValueError(f"need num_frames >= 1 and fps > 0, got {num_frames}, {fps}")
    c = as_config(TrajectoryConfig, trajectory, "flight.trajectory")
    where = "flight.trajectory"
    N, dt = int(num_frames), 1.0 / float(fps)
    t = np.arange(N) * dt
    T = max(t[-1], dt)
    L = route_length(route)

    # along the route: smooth monotone progress over distance D
    speed = rng.uniform(*_pair(c, "speed", where))
    start = min(rng.uniform(*_pair(c, "start_offset", where)), 0.25 * L)
    D = min(speed * T, L - start - min(0.05 * L, END_MARGIN))
    ramp = min(c.ramp_s, T / 4)
    rise = np.clip(t / max(ramp, 1e-9), 0, 1)
    fall = np.clip((T - t) / max(ramp, 1e-9), 0, 1)
    envelope = (3 * rise**2 - 2 * rise**3) * (3 * fall**2 - 2 * fall**3) + 0.05
    var = min(c.speed_variation, 0.9)
    u = envelope * (1 + var * smooth_noise(rng, t, (0.03, 0.15)))
    cum = np.concatenate([[0.0], np.cumsum((u[1:] + u[:-1]) / 2)])
    progress = cum / cum[-1] if cum[-1] > 0 else np.zeros(N)
    s = start + D * progress if not c.reverse else L - start - D * progress
    h = None if harder is None else as_config(HarderFlightConfig, harder, "realism.flight")
    if h is not None and h.enabled:
        if harder_rng is None:
            raise ValueError("flight_trajectory: realism.flight needs its own generator "
                             "(harder_rng)")
        s, turn = _back_and_forth(harder_rng, t, cum, L, h)
    else:
        h = None
    centre, tangent = route_at(route, s)
    if not free.contains(centre).all():
        raise ValueError("flight: the route leaves the free space; plan it on this map "
                         "(flight_route)")

    # sway across the route (its right normal) and in height, centred so the extremes fit
    f_sway = _pair(c, "sway_freq_hz", where)
    room = _sway_room(route, s, free, reach=max(c.sway_x, 0.0) + DRIFT)
    mid_room = float(np.median(room))
    ax = min(c.sway_x, 0.9 * mid_room)
    offset = rng.uniform(-(mid_room - ax), mid_room - ax)
    across = offset + ax * smooth_noise(rng, t, f_sway)
    across *= np.minimum(1.0, room / max(abs(offset) + ax, 1e-9))
    right = np.stack([tangent[:, 1], -tangent[:, 0]], 1)
    xy = centre + across[:, None] * right
    for _ in range(4):  # the room is sampled every ROOM_STEP: where a position slipped out
        if free.contains(xy).all():
            break
        across *= 0.5
        xy = centre + across[:, None] * right
    else:
        xy = centre
    az = min(c.sway_z, 0.45 * (z[1] - z[0]))
    h_lo, h_hi = _pair(c, "height", where)
    lo, hi = max(h_lo, z[0] + az), min(h_hi, z[1] - az)
    zc = rng.uniform(lo, hi) if lo <= hi else float(np.clip((h_lo + h_hi) / 2, z[0] + az,
                                                            z[1] - az))
    height = zc + az * smooth_noise(rng, t, f_sway)

    # yaw about the direction of travel
    heading = np.arctan2(tangent[:, 1], tangent[:, 0]) + (np.pi if c.reverse else 0.0)
    yaw_amp = np.deg2rad(rng.uniform(*_pair(c, "yaw_amplitude_deg", where)))
    swing = yaw_amp * smooth_noise(rng, t, _pair(c, "yaw_freq_hz", where))
    if h is not None:
        heading = np.arctan2(tangent[:, 1], tangent[:, 0]) + turn
        unit = smooth_noise(harder_rng, t, _pair(h, "yaw_freq_hz", "realism.flight"))
        peak = float(np.abs(np.gradient(unit, dt)).max()) if N > 1 else 0.0
        rate = np.deg2rad(harder_rng.uniform(*_pair(h, "yaw_rate_deg_s", "realism.flight")))
        swing = min(rate / max(peak, 1e-9), np.deg2rad(h.max_yaw_swing_deg)) * unit
    yaw = wrap_angle(heading + swing)
    rpy = _tilts(rng, t, xy, yaw, c)
    return pose_from_xyz_rpy(np.column_stack([xy, height]), rpy)


def _tilts(rng: np.random.Generator, t: np.ndarray, xy: np.ndarray, yaw: np.ndarray,
           c: TrajectoryConfig) -> np.ndarray:
    """(N, 3) roll, pitch, yaw: roll / pitch from the horizontal acceleration of xy (N, 2) m at
    times t (N,) s, plus a little wobble, clipped to ``max_tilt_deg``."""
    N = len(t)
    dt = t[1] - t[0] if N > 1 else 1.0
    if N >= 3:
        acc = np.stack([np.gradient(np.gradient(xy[:, i], dt), dt) for i in (0, 1)], 1)
    else:
        acc = np.zeros((N, 2))
    a_fwd = np.cos(yaw) * acc[:, 0] + np.sin(yaw) * acc[:, 1]
    a_left = -np.sin(yaw) * acc[:, 0] + np.cos(yaw) * acc[:, 1]
    wobble = np.deg2rad(c.tilt_noise_deg)
    pitch = np.arctan(a_fwd / GRAVITY) + wobble * smooth_noise(rng, t, (0.2, 1.0))
    roll = -np.arctan(a_left / GRAVITY) + wobble * smooth_noise(rng, t, (0.2, 1.0))
    max_tilt = np.deg2rad(c.max_tilt_deg)
    return np.stack([np.clip(roll, -max_tilt, max_tilt), np.clip(pitch, -max_tilt, max_tilt),
                     yaw], 1)


def noisy_odometry(rng: np.random.Generator, groundtruth: np.ndarray, fps: float,
                   odometry: OdometryConfig | Mapping | None = None) -> np.ndarray:
    """Odometry as a copter's visual-inertial odometry would report it.

    Starts at groundtruth[0] and integrates the true frame-to-frame motion, expressed in
    the gravity-aligned heading frame (translation and yaw increment), corrupted by white
    noise, a scale error (constant plus random walk), a heading-rate bias (constant plus
    random walk) and a random-walk velocity bias, so it drifts away from the truth. Roll
    and pitch are the truth's (an IMU observes them; ``datagen.realism.ahrs.ahrs_odometry`` puts an
    AHRS's error on them, ``realism.ahrs``).

    Args:
        rng: random generator.
        groundtruth: (N, 4, 4) world_from_body.
        fps: frame rate (Hz).
        odometry: a flight preset's ``odometry`` (``OdometryConfig``, or a mapping of the keys
            that differ from its defaults; None: the defaults).

    Returns:
        (N, 4, 4) world_from_body odometry poses.
    """
    gt = np.asarray(groundtruth, dtype=np.float64)
    if gt.ndim != 3 or gt.shape[1:] != (4, 4):
        raise ValueError(f"groundtruth must be (N, 4, 4), got {gt.shape}")
    c = as_config(OdometryConfig, odometry, "flight.odometry")
    N, dt = len(gt), 1.0 / float(fps)
    if N < 2:
        return gt.copy()
    rpy = Rotation.from_matrix(gt[:, :3, :3]).as_euler("xyz")
    yaw, p = rpy[:, 2], gt[:, :3, 3]
    M = N - 1

    def walk(std_per_sqrt_s: float, shape: tuple[int, ...]) -> np.ndarray:
        return np.cumsum(rng.normal(0.0, std_per_sqrt_s * np.sqrt(dt), shape), axis=0)

    # true increments in the heading frame of the previous pose
    dp = np.diff(p, axis=0)
    cy, sy = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    d = np.stack([cy * dp[:, 0] + sy * dp[:, 1], -sy * dp[:, 0] + cy * dp[:, 1], dp[:, 2]], 1)
    dyaw = wrap_angle(np.diff(yaw))
    # corrupt them
    scale = rng.normal(0.0, c.scale_error) + walk(c.scale_walk, (M,))
    vel_bias = walk(c.velocity_bias_walk, (M, 3))
    d_odo = (d * (1 + scale)[:, None] + vel_bias * dt
             + rng.normal(0.0, c.trans_noise_m, (M, 3)))
    yaw_bias = (np.deg2rad(rng.normal(0.0, c.yaw_bias_deg_s))
                + np.deg2rad(walk(c.yaw_bias_walk_deg_s, (M,))))
    dyaw_odo = dyaw + yaw_bias * dt + np.deg2rad(rng.normal(0.0, c.yaw_noise_deg, M))
    # integrate
    yaw_odo = yaw[0] + np.concatenate([[0.0], np.cumsum(dyaw_odo)])
    co, so = np.cos(yaw_odo[:-1]), np.sin(yaw_odo[:-1])
    step = np.stack([co * d_odo[:, 0] - so * d_odo[:, 1], so * d_odo[:, 0] + co * d_odo[:, 1],
                     d_odo[:, 2]], 1)
    p_odo = p[0] + np.concatenate([np.zeros((1, 3)), np.cumsum(step, axis=0)])
    return pose_from_xyz_rpy(p_odo, np.stack([rpy[:, 0], rpy[:, 1], yaw_odo], 1))


def timestamps(num_frames: int, fps: float) -> np.ndarray:
    """(N,) frame times in seconds, starting at 0."""
    return np.arange(int(num_frames)) / float(fps)
