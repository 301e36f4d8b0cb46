"""Model edge samples and their projection into many particle cameras at once.

The world's 3D edge segments are sampled once into points (with the segment each belongs to and
its 3D direction). For N particle poses the points are moved into every camera with one batched
matrix product and projected with the pinhole model, giving (N, P) pixel coordinates, depths
and the image direction of the model line at each sample.

A particle's camera: ``world_from_cam = world_from_body @ body_from_cam`` with
``world_from_body = [Rz(yaw) @ R_tilt | (x, y, z)]``. The filter estimates x, y, z and yaw;
``R_tilt`` (roll and pitch) comes from the IMU, here the attitude of the frame's odometry pose
(see ``tilt_from_pose``): one (3, 3) for all particles of a frame, or (N, 3, 3), each particle's
own correction of it (``corrected_tilts``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class ModelSamples:
    """Points sampled along the world's edge segments.

    Attributes:
        points: (P, 3) float32 world points, metres.
        dirs: (P, 3) float32 unit direction of the segment at each point.
        segment: (P,) int64 index of the world segment each point lies on (non-decreasing).
        starts: (S,) int64 index of the first point of each sampled segment (for
            ``np.add.reduceat`` over the point axis).
        spacing: distance between neighbouring samples of a segment, metres.
    """

    points: np.ndarray
    dirs: np.ndarray
    segment: np.ndarray
    starts: np.ndarray
    spacing: float

    def __len__(self) -> int:
        return len(self.points)

    @cached_property
    def points_h(self) -> np.ndarray:
        """(4, P) float32 homogeneous points."""
        return homogeneous(self.points)

    @cached_property
    def run(self) -> np.ndarray:
        """(P,) int index into ``starts`` of the sampled segment each point belongs to."""
        return np.repeat(np.arange(len(self.starts)), np.diff(np.r_[self.starts, len(self)]))

    def thin(self, step: int) -> tuple[ModelSamples, np.ndarray]:
        """Every ``step``-th sample of each segment (at least its middle one).

        Returns:
            The thinned set and the (P',) indices of its samples in this set.
        """
        step = int(step)
        if step <= 1:
            return self, np.arange(len(self))
        within = np.arange(len(self)) - self.starts[self.run]
        count = np.diff(np.r_[self.starts, len(self)])[self.run]
        keep = (within % step == step // 2) | ((count <= step) & (within == count // 2))
        cols = np.flatnonzero(keep)
        seg = self.segment[cols]
        starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
        return (ModelSamples(self.points[cols], self.dirs[cols], seg, starts,
                             self.spacing * step), cols)

    def select(self, keep_segment: np.ndarray) -> tuple[ModelSamples, np.ndarray]:
        """The samples of a subset of the world segments.

        Args:
            keep_segment: (M,) bool over the world's segments.

        Returns:
            The subset and the (P',) indices of its samples in this set.
        """
        keep_segment = np.asarray(keep_segment, dtype=bool)
        cols = np.flatnonzero(keep_segment[self.segment])
        if len(cols) == 0:
            raise ValueError("no model edge segment is left after selecting by class; check "
                             "the world's segment classes")
        seg = self.segment[cols]
        starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
        return ModelSamples(self.points[cols], self.dirs[cols], seg, starts, self.spacing), cols


def sample_segments(segments: np.ndarray, spacing: float, min_per_segment: int = 2) -> ModelSamples:
    """Sample points along 3D segments at (about) a fixed spacing.

    Each segment of length L gets ``n = max(min_per_segment, ceil(L / spacing))`` points at the
    centres of n equal pieces, so no point sits exactly on a corner, where a segment meets others
    and its visibility is ambiguous.

    Args:
        segments: (M, 2, 3) endpoints in metres.
        spacing: target distance between samples, metres (> 0).
        min_per_segment: fewest samples of a segment.

    Returns:
        The samples; zero-length segments are skipped.
    """
    segments = np.asarray(segments, dtype=np.float64)
    if segments.ndim != 3 or segments.shape[1:] != (2, 3):
        raise ValueError(f"segments must be (M, 2, 3), got {segments.shape}")
    if spacing <= 0:
        raise ValueError(f"sample spacing must be positive, got {spacing}")
    vec = segments[:, 1] - segments[:, 0]
    length = np.linalg.norm(vec, axis=1)
    keep = np.flatnonzero(length > 1e-9)
    if len(keep) == 0:
        raise ValueError("the world has no edge segments to sample; check world/edges.npz")
    n = np.maximum(int(min_per_segment), np.ceil(length[keep] / spacing).astype(np.int64))
    seg = np.repeat(keep, n)
    starts = np.concatenate([[0], np.cumsum(n)[:-1]])
    within = np.arange(len(seg)) - np.repeat(starts, n)
    t = (within + 0.5) / np.repeat(n, n)
    points = segments[seg, 0] + t[:, None] * vec[seg]
    dirs = vec[seg] / length[seg, None]
    return ModelSamples(points.astype(np.float32), dirs.astype(np.float32), seg.astype(np.int64),
                        starts.astype(np.int64), float(spacing))


def yaw_rotation(yaw: np.ndarray) -> np.ndarray:
    """Rotations about world z.

    Args:
        yaw: (N,) radians.

    Returns:
        (N, 3, 3) float64.
    """
    yaw = np.asarray(yaw, dtype=np.float64).reshape(-1)
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros((len(yaw), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def tilt_from_pose(world_from_body: np.ndarray) -> np.ndarray:
    """Roll and pitch part of a pose: ``R_tilt = Rz(-yaw) @ R`` so ``R = Rz(yaw) @ R_tilt``.

    Args:
        world_from_body: (4, 4) or (3, 3) pose; yaw is the heading of the body x axis.

    Returns:
        (3, 3) rotation with no heading (it keeps the body x axis in the world x-z plane).
    """
    R = np.asarray(world_from_body, dtype=np.float64)[:3, :3]
    yaw = np.arctan2(R[1, 0], R[0, 0])
    return yaw_rotation(yaw)[0].T @ R


def corrected_tilts(tilt: np.ndarray | None, corrections: np.ndarray) -> np.ndarray:
    """The IMU's roll and pitch corrected per particle: ``Ry(pitch + dp) @ Rx(roll + dr)``
    (the extrinsic x-y-z Euler angles of ``core.poses``).

    Args:
        tilt: (3, 3) roll/pitch rotation (``tilt_from_pose``), None: level.
        corrections: (N, 2) roll, pitch corrections, radians.

    Returns:
        (N, 3, 3) float64.
    """
    if tilt is None:
        roll = pitch = 0.0
    else:
        T = np.asarray(tilt, dtype=np.float64)
        roll, pitch = np.arctan2(T[2, 1], T[2, 2]), np.arcsin(np.clip(-T[2, 0], -1.0, 1.0))
    c = np.asarray(corrections, dtype=np.float64)
    r, p = roll + c[:, 0], pitch + c[:, 1]
    cr, sr, cp, sp = np.cos(r), np.sin(r), np.cos(p), np.sin(p)
    R = np.empty((len(c), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = cp, sp * sr, sp * cr
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = 0.0, cr, -sr
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = -sp, cp * sr, cp * cr
    return R


def cam_from_world(states: np.ndarray, body_from_cam: np.ndarray,
                   tilt: np.ndarray | None = None) -> np.ndarray:
    """Camera poses of particles.

    Args:
        states: (N, 4) x, y, z (metres), yaw (radians) of the body.
        body_from_cam: (4, 4) camera mount.
        tilt: (3, 3) roll/pitch rotation shared by all particles, or (N, 3, 3) one per
            particle (identity if None).

    Returns:
        (N, 4, 4) float64 cam_from_world.
    """
    states = np.asarray(states, dtype=np.float64)
    if states.ndim != 2 or states.shape[1] != 4:
        raise ValueError(f"states must be (N, 4) [x, y, z, yaw], got {states.shape}")
    R = yaw_rotation(states[:, 3])
    if tilt is not None:
        R = R @ np.asarray(tilt, dtype=np.float64)
    world_from_body = np.tile(np.eye(4), (len(states), 1, 1))
    world_from_body[:, :3, :3] = R
    world_from_body[:, :3, 3] = states[:, :3]
    world_from_cam = world_from_body @ np.asarray(body_from_cam, dtype=np.float64)
    Rc = world_from_cam[:, :3, :3]
    tc = world_from_cam[:, :3, 3]
    out = np.tile(np.eye(4), (len(states), 1, 1))
    out[:, :3, :3] = Rc.transpose(0, 2, 1)
    out[:, :3, 3] = -np.einsum("nji,nj->ni", Rc, tc)
    return out


def camera_centres(states: np.ndarray, body_from_cam: np.ndarray,
                   tilt: np.ndarray | None = None) -> np.ndarray:
    """World positions (N, 3) of the particles' camera centres, metres."""
    states = np.asarray(states, dtype=np.float64)
    R = yaw_rotation(states[:, 3])
    if tilt is not None:
        R = R @ np.asarray(tilt, dtype=np.float64)
    return states[:, :3] + R @ np.asarray(body_from_cam, dtype=np.float64)[:3, 3]


def view_half_width(K: np.ndarray, width: int, height: int, body_from_cam: np.ndarray,
                    tilt: np.ndarray | None = None, margin_deg: float = 2.0) -> float:
    """Half-width (radians) of the world azimuths a camera sees about its body's heading.

    Azimuth has no extremum inside the image unless the vertical projects into it, so the
    largest |azimuth| of rays through the image border (17 per side, body yaw 0, roll and
    pitch ``tilt``) bounds it; ``margin_deg`` covers the spacing of those rays. With (N, 3, 3)
    tilts, the first one's, widened by twice the largest angle between it and the others.

    Returns:
        radians, at most pi (pi: the image holds the vertical and sees every azimuth).
    """
    R = np.asarray(body_from_cam, dtype=np.float64)[:3, :3]
    if tilt is not None:
        tilt = np.asarray(tilt, dtype=np.float64)
        if tilt.ndim == 3:
            cos = (np.einsum("ij,nij->n", tilt[0], tilt) - 1.0) / 2.0
            margin_deg += 2.0 * np.rad2deg(np.arccos(np.clip(cos.min(), -1.0, 1.0)))
            tilt = tilt[0]
        R = tilt @ R
    K = np.asarray(K, dtype=np.float64)
    lo, hi = np.array([-0.5, -0.5]), np.array([width - 0.5, height - 0.5])
    for up in (R.T[:, 2], -R.T[:, 2]):  # the vertical in the camera frame
        if up[2] > 0:
            uv = (K @ up)[:2] / up[2]
            if np.all(uv > lo - 1) and np.all(uv < hi + 1):
                return float(np.pi)
    t = np.linspace(0.0, 1.0, 17)
    u, v = lo[0] + t * (hi[0] - lo[0]), lo[1] + t * (hi[1] - lo[1])
    border = np.concatenate([np.stack([u, np.full(17, lo[1])], 1),
                             np.stack([u, np.full(17, hi[1])], 1),
                             np.stack([np.full(17, lo[0]), v], 1),
                             np.stack([np.full(17, hi[0]), v], 1)])
    rays = np.linalg.solve(K, np.c_[border, np.ones(len(border))].T)  # (3, 68) camera frame
    d = R @ rays
    half = np.abs(np.arctan2(d[1], d[0])).max() + np.deg2rad(margin_deg)
    return float(min(half, np.pi))


def in_view_cone(points: np.ndarray, centres: np.ndarray, yaws: np.ndarray,
                 half_width: float) -> np.ndarray:
    """Which points some camera of a group may see, by azimuth alone (conservative).

    A point is kept when, seen from the group's mean centre, its azimuth is within the
    group's yaws (their circular mean +- spread) widened by ``half_width`` and by how far the
    centres spread about their mean (``asin(spread / distance)``); points nearer than that
    spread are kept.

    Args:
        points: (C, 3) world points, metres.
        centres: (n, 3) camera centres, metres.
        yaws: (n,) body headings, radians.
        half_width: ``view_half_width``, radians.

    Returns:
        (C,) bool.
    """
    yaws = np.asarray(yaws, dtype=np.float64)
    mean_yaw = np.arctan2(np.sin(yaws).mean(), np.cos(yaws).mean())
    spread = np.abs(np.angle(np.exp(1j * (yaws - mean_yaw)))).max(initial=0.0)
    if half_width + spread >= np.pi:
        return np.ones(len(points), dtype=bool)
    c = np.asarray(centres, dtype=np.float64)[:, :2]
    mid = c.mean(axis=0)
    r = np.linalg.norm(c - mid, axis=1).max(initial=0.0)
    return in_cone(points, mean_yaw, spread, mid, r, half_width)


def in_cone(points: np.ndarray, mean_yaw: np.ndarray | float, spread: np.ndarray | float,
            mid: np.ndarray, r: np.ndarray | float, half_width: float,
            which: np.ndarray | None = None) -> np.ndarray:
    """``in_view_cone``'s test of points against given cones: one for all the points, one
    per point, or one per group of points (``which``).

    Args:
        points: (C, 3) world points, metres.
        mean_yaw, spread: the cameras' circular mean heading and their largest deviation
            from it, radians: scalars, (C,), or (G,) with ``which``.
        mid: (2,), (C, 2) or (G, 2) the cameras' mean centre, metres.
        r: the largest distance of a camera from ``mid``, metres: a scalar, (C,) or (G,).
        half_width: ``view_half_width``, radians.
        which: (C,) int the cone of each point, indexing the (G,) cones; None: as given.

    Returns:
        (C,) bool.
    """
    yaw = np.asarray(mean_yaw, dtype=np.float64)
    width = half_width + np.asarray(spread, np.float64)
    cos, sin = np.cos(yaw), np.sin(yaw)
    cos_w, sin_w = np.cos(np.minimum(width, np.pi)), np.sin(np.minimum(width, np.pi))
    r = np.asarray(r, dtype=np.float64)
    mid = np.asarray(mid, dtype=np.float64)
    if which is not None:
        cos, sin, cos_w, sin_w, width, mid, r = (a[which] for a in (cos, sin, cos_w, sin_w,
                                                                     width, mid, r))
    p = np.asarray(points, dtype=np.float64)[:, :2] - mid
    d2 = p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1]
    dist = np.sqrt(d2)
    rc = np.minimum(r, dist)
    # the azimuth off the mean heading within reach = width + asin(rc / dist), without
    # trigonometry per point: cos(off) >= cos(reach) while reach < pi, times dist
    near_side = p[:, 0] * cos + p[:, 1] * sin >= (cos_w * np.sqrt(np.maximum(d2 - rc * rc, 0.0))
                                                  - sin_w * rc)
    # reach >= pi: every azimuth (asin(rc / dist) >= pi - width needs width >= pi / 2)
    whole = (width >= np.pi) | ((width >= np.pi / 2) & (rc >= dist * sin_w))
    return whole | (dist <= r + 1e-6) | near_side


@dataclass
class Projection:
    """Model samples seen from N cameras; all arrays (N, P) float32 unless noted.

    Attributes:
        u, v: pixel coordinates (pixel centres at integers).
        depth: z in the camera frame, metres.
        du, dv: image direction of the model line at the sample (not normalised; zero where
            the line points at the camera).
        in_view: (N, P) bool, depth > near and inside the image.
    """

    u: np.ndarray
    v: np.ndarray
    depth: np.ndarray
    du: np.ndarray
    dv: np.ndarray
    in_view: np.ndarray


def project_samples(K: np.ndarray, width: int, height: int, cam_from_world: np.ndarray,
                    points: np.ndarray, dirs: np.ndarray | None = None,
                    near: float = 0.1) -> Projection:
    """Project sample points (and their line directions) into N cameras.

    Args:
        K: (3, 3) intrinsics.
        width, height: image size, pixels.
        cam_from_world: (N, 4, 4) camera poses.
        points: (P, 3) world points, metres.
        dirs: (P, 3) unit 3D line directions at the points (None: du, dv are zero).
        near: points closer than this depth (metres) are not in view.

    Returns:
        The projection (see ``Projection``).
    """
    T = np.asarray(cam_from_world, dtype=np.float32)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"cam_from_world must be (N, 4, 4), got {T.shape}")
    pts = np.asarray(points, dtype=np.float32)
    R, t = T[:, :3, :3], T[:, :3, 3:]
    pc = R @ pts.T + t  # (N, 3, P)
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    in_view = z > near
    inv = 1.0 / np.where(in_view, z, np.float32(1.0))
    fx, fy, cx, cy = (np.float32(K[0, 0]), np.float32(K[1, 1]), np.float32(K[0, 2]),
                      np.float32(K[1, 2]))
    u = x * inv * fx + cx
    v = y * inv * fy + cy
    in_view &= (u > -0.5) & (u < width - 0.5) & (v > -0.5) & (v < height - 0.5)
    if dirs is None:
        du = dv = np.zeros_like(u)
    else:
        dc = R @ np.asarray(dirs, dtype=np.float32).T  # (N, 3, P)
        # d/ds of (x/z, y/z) along the line, times z^2 (only the direction matters)
        du = (dc[:, 0] * z - x * dc[:, 2]) * fx
        dv = (dc[:, 1] * z - y * dc[:, 2]) * fy
    return Projection(u, v, z, du, dv, in_view)


def projection_matrices(cam_from_world: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pinhole projection matrices ``K @ [R | t]``.

    Args:
        cam_from_world: (N, 4, 4) camera poses.
        K: (3, 3) intrinsics.

    Returns:
        (N, 3, 4) float32.
    """
    return (np.asarray(K, dtype=np.float64) @ np.asarray(cam_from_world)[:, :3, :]).astype(
        np.float32)


def homogeneous(points: np.ndarray) -> np.ndarray:
    """(P, 3) points -> (4, P) float32 homogeneous columns."""
    points = np.asarray(points, dtype=np.float32)
    return np.ascontiguousarray(np.concatenate([points, np.ones((len(points), 1),
                                                                np.float32)], axis=1).T)


def pixel_index(proj: np.ndarray, points_h: np.ndarray, width: int, height: int,
                near: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest pixel of every point in every camera, as a flat index ``v * width + u``.

    This is the hot path of the likelihood: one (3N, 4) x (4, P) matrix product, a reciprocal
    and integer arithmetic on (N, P) arrays. A point maps to the pixel whose centre is nearest
    (points up to half a pixel beyond the left and top borders clamp onto the border pixel).

    Args:
        proj: (N, 3, 4) float32 projection matrices (``projection_matrices``).
        points_h: (4, P) float32 homogeneous points (``homogeneous``).
        width, height: image size, pixels.
        near: minimum depth, metres.

    Returns:
        idx (N, P) int32 flat pixel index (meaningless where not valid); valid (N, P) bool
        (in front of the near plane and inside the image); xh (N, 3, P) float32 the projected
        homogeneous coordinates (u * z, v * z, z).
    """
    N = len(proj)
    xh = (proj.reshape(3 * N, 4) @ points_h).reshape(N, 3, -1)
    return (*pixels_of(xh, width, height, near), xh)


def pixels_of(xh: np.ndarray, width: int, height: int,
              near: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel index (N, P) int32 and valid (N, P) bool of projected homogeneous points
    ``xh`` (N, 3, P) (see ``pixel_index``)."""
    z = xh[:, 2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = np.float32(1.0) / z
        ui = (xh[:, 0] * inv + np.float32(0.5)).astype(np.int32)
        vi = (xh[:, 1] * inv + np.float32(0.5)).astype(np.int32)
    valid = z > np.float32(near)
    valid &= ui.view(np.uint32) < np.uint32(width)
    valid &= vi.view(np.uint32) < np.uint32(height)
    vi *= np.int32(width)
    vi += ui
    return vi, valid


def image_directions(proj: np.ndarray, dirs: np.ndarray,
                     xh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image direction of 3D lines at projected points (up to a positive factor).

    With ``(a, b, c) = proj @ [X; 1]`` and ``(da, db, dc) = proj[:, :3] @ D`` the derivative of
    ``(a / c, b / c)`` along D is ``(da c - a dc, db c - b dc) / c^2``. The numerator is the
    same at every point ``X + t D`` of the line (the t terms cancel): a 3D line projects onto
    one image line, so one point per segment gives the whole segment's direction.

    Args:
        proj: (N, 3, 4) projection matrices.
        dirs: (P, 3) unit 3D directions.
        xh: (N, 3, P) projected homogeneous points (from ``pixel_index``).

    Returns:
        du, dv: (N, P) float32.
    """
    N = len(proj)
    d = (np.ascontiguousarray(proj[:, :, :3]).reshape(3 * N, 3)
         @ np.asarray(dirs, dtype=np.float32).T).reshape(N, 3, -1)
    du = d[:, 0] * xh[:, 2] - xh[:, 0] * d[:, 2]
    dv = d[:, 1] * xh[:, 2] - xh[:, 1] * d[:, 2]
    return du, dv
