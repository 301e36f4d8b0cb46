"""Global localization over a whole floor: every pose of the free space, scored by a table.

A ``GlobalSearch`` keeps a large set of weighted pose hypotheses (x, y, z, yaw of the body, as
the particle filter's states) that starts as a dense grid: every cell of the table
(``ray_table.RayTable``) inside the free space times ``headings`` headings, jittered within
its cell and heading bin, so the true pose always has hypotheses within half a cell and half a
heading step of it. Each frame the hypotheses move by the odometry (with noise, as particles)
and are weighed by the floor boundary the frame shows (``ray_table.floor_boundary``) against
the table's distances: one look-up per azimuth bin, no projection of the model, so a
hypothesis costs ~0.3 us against the edge likelihood's ~10 us and the whole floor fits a frame.

Measurement (per hypothesis, over the frame's J azimuth bins): the camera height h that fits
best (least squares of the first-order angle errors, a second time without the bins that are
outliers at the first height; clamped to the free space's band), then the angle errors
``e_j = atan(tan_j) - atan(h / D_j)`` and ``log L = -evidence * min(1, J / max_bins) *
mean_j min(e_j^2 / 2 sigma^2 + class_cost [class_j != table's], outlier)`` (the class above
the floor: wall, door or window); a frame takes at most ``frame_floor`` from any hypothesis
against the best one, so a few bad frames (a person in front of the wall, a wrong label) never
remove the truth.

The weights are never reset: each frame the hypotheses more than ``prune_band`` below the best
are dropped and the count is brought to an adaptive one (KLD-style: ``per_bin`` per occupied
bin of 0.5 m x 0.5 m x 20 deg, within [``min_hypotheses``, ``max_hypotheses``]) by jittered
copies of the survivors that share their parent's weight, or by a uniform thinning; so a pose
that fits as well as the best keeps its share however few hypotheses it started with. It
converges when at most ``handover_places`` clusters (``cluster_radius`` m, ``cluster_yaw_deg``)
hold ``handover_mass`` of the weight together for ``handover_frames`` frames in a row (the
weight of the settled hypotheses: those of the start, and the injected ones once they have
been weighed for ``handover_frames`` frames);
``sample`` then splits the tracking filter's particles evenly between those places, and the
filter's edge likelihood chooses between them.

Interface (what the Localizer wires):

- ``search = start_search(world, camera, params, rng, prior)``: the search, reset; None where
  it cannot run (``ray_table.SearchUnavailable``: the model has no floor-to-wall, door or window
  segment, or no pose of the grid lies in the free space or the prior), with one warning per
  world and reason: the caller starts the uniform particle set instead (as
  ``filter.global_method: particles``). It makes
  ``GlobalSearch(ray_table_for(world, params), camera, world.free, params, rng)`` (the table
  built once per world and kept).
- ``search.reset(weights=None)``: the dense start; ``weights`` is an optional callable
  ``(N, 4) states -> (N,) log prior`` (a region, a pose with covariance, a heading range:
  ``-inf`` removes a hypothesis).
- ``search.predict(delta)``: (4,) odometry increment (``core.poses.odometry_increment``).
- ``search.update(labels, tilt) -> bool``: (H, W) uint8 class labels (oracle or the SegNet's),
  (3, 3) roll/pitch of the IMU or None; False when the frame shows too little floor boundary
  (nothing weighed).
- ``search.hypotheses(k) -> (poses (k', 4), mass (k',))``: the heaviest clusters, their
  weighted mean poses and the share of the weight each holds (k' <= k);
  ``search.clusters(k)``: the same as ``hypotheses.Hypothesis`` (with their spreads), the
  Localizer's ``Estimate.hypotheses`` during the search.
- ``search.converged``: the ``handover_places`` heaviest clusters held ``handover_mass``
  together for ``handover_frames`` frames; ``search.places``: how many places they are.
- ``search.sample(n, centre=None) -> (n, 4)``: particles split evenly between the places
  (or drawn from the cluster around ``centre``: a rival's, ``localize.search.rivals``).
- ``search.states``, ``search.logw``: (N, 4), (N,) the hypotheses and their normalized
  log-weights.

Settings: ``localize.search.config.GlobalSearchConfig`` (``filter.global_search``).
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.special import logsumexp

from core.dataset import Camera, World
from core.occupancy import OccupancyMap
from core.poses import wrap_angle
from localize.filter.hypotheses import Hypothesis
from localize.filter.particle_filter import apply_increment, systematic_resample
from localize.filter.pose_stats import mean_pose, pose_spread, spread
from localize.search.config import GlobalSearchConfig
from localize.search.ray_table import RayTable, SearchUnavailable, floor_boundary

log = logging.getLogger(__name__)
_TABLES: dict = {}
#: [world, reasons]: the fallbacks already warned about (one world at a time, as ``_TABLES``).
_WARNED: list = [None, set()]
#: Hypotheses scored at once (bounds the (n, J) temporaries to a few MB).
CHUNK = 32768


def ray_table_for(world: World, params: GlobalSearchConfig) -> RayTable:
    """The world's ``RayTable`` at the params' cell and rays, built once and kept while the
    world lives (the runner's localizers of one world share it)."""
    key = (id(world), params.cell, params.rays)
    hit = _TABLES.get(key)
    if hit is not None and hit[0] is world:
        return hit[1]
    table = RayTable.build(world, params.cell, params.rays)
    _TABLES.clear()  # one world at a time: a run localizes one dataset
    _TABLES[key] = (world, table)
    return table


def start_search(world: World, camera: Camera, params: GlobalSearchConfig,
                 rng: np.random.Generator, prior=None) -> GlobalSearch | None:
    """A global search over ``world``, reset with ``prior`` (``GlobalSearch.reset``); None
    where it cannot run (``SearchUnavailable``), after one warning per world and reason (the
    localizers of one run share it): the caller then starts the uniform particle set, as with
    ``filter.global_method: particles``. The one place a search is made."""
    try:
        search = GlobalSearch(ray_table_for(world, params), camera, world.free, params, rng)
        search.reset(prior)
    except SearchUnavailable as err:
        if _WARNED[0] is not world:
            _WARNED[:] = [world, set()]
        if str(err) not in _WARNED[1]:
            _WARNED[1].add(str(err))
            log.warning("%s; the global start falls back to the uniform particle spread "
                        "(filter.global_method=particles; set it to start so without this "
                        "warning)", err)
        return None
    return search


def motion_noise(params: GlobalSearchConfig, delta: np.ndarray, time_scale: float = 1.0
                 ) -> np.ndarray:
    """(4,) std of the noise of a move by an odometry increment (4,): x, y, z (m), yaw (rad)
    (``motion_std`` times ``time_scale``, plus ``motion_rel`` per m and per rad of it)."""
    step = float(np.hypot(delta[0], delta[1]))
    s_xy = time_scale * params.motion_std[0] + params.motion_rel[0] * step
    s_yaw = time_scale * np.deg2rad(params.motion_std[2]) + params.motion_rel[1] * abs(delta[3])
    return np.array([s_xy, s_xy, time_scale * params.motion_std[1], s_yaw])


def bin_keys(states: np.ndarray, size: float = 0.5, yaw_deg: float = 20.0) -> np.ndarray:
    """(N,) int64 dense key of each state's (size m x size m x yaw_deg) bin, from 0 (for
    ``np.bincount``)."""
    ij = np.floor(states[:, :2] / size).astype(np.int64)
    ij -= ij.min(axis=0)
    ny = int(ij[:, 1].max()) + 1
    nb = int(np.ceil(360.0 / yaw_deg))
    kb = np.floor((wrap_angle(states[:, 3]) + np.pi) / np.deg2rad(yaw_deg)).astype(np.int64)
    return (ij[:, 0] * ny + ij[:, 1]) * nb + np.minimum(kb, nb - 1)


class GlobalSearch:
    """The hypothesis set of a global start (module docstring).

    Args:
        table: the floor's ray table.
        camera: K, size, body_from_cam.
        free: the free space (the start's cells; its band bounds the fitted heights).
        params: settings.
        rng: random generator (its only source of randomness).
    """

    def __init__(self, table: RayTable, camera: Camera, free: OccupancyMap,
                 params: GlobalSearchConfig, rng: np.random.Generator):
        self.table, self.camera, self.params, self.rng = table, camera, params, rng
        self.free = free
        self.band = (float(free.band[0]), float(free.band[1]))
        d = np.maximum(np.nan_to_num(table.dist.astype(np.float32), nan=table.max_range), 0.05)
        d = d.reshape(-1, table.rays)
        self._wrap = M = table.rays // 4  # azimuth bins either side of the heading scored
        # (cells * (R + 2M),) float32 1 / D, each cell's row wrapped by M bins both ways
        self._inv_dist = (1.0 / np.concatenate([d[:, -M:], d, d[:, :M]], axis=1)).ravel()
        k = table.kind.reshape(-1, table.rays)
        self._kind = np.concatenate([k[:, -M:], k, k[:, :M]], axis=1).ravel()
        self.states = np.zeros((0, 4))
        self.logw = np.zeros(0)
        # (N,) the frame each hypothesis (or its parent) was injected at; -1: the start's
        self._born = np.zeros(0, np.int64)
        self._held = self._frames = 0
        self._dominant = None  # (k, 4) mean poses of the places that held the mass
        self._clusters = None  # ((version, k), hypotheses) of the last call
        self._version = 0  # counts the changes of the set: reset, predict, update

    def reset(self, weights=None) -> None:
        """The dense start: every free cell of the table x ``headings`` headings, jittered
        within its cell and heading bin; ``weights``: optional ``(N, 4) -> (N,)`` log prior.
        ``SearchUnavailable`` when no pose is left (no cell centre in the free space, or none
        the prior allows)."""
        self._version += 1
        self.states = self._grid(self.params.headings)
        if not len(self.states):
            raise SearchUnavailable(f"no cell centre of the global search's grid "
                                    f"(filter.global_search.cell = {self.table.cell} m) lies in "
                                    "the free space")
        self.logw = np.zeros(len(self.states))
        self._prior = weights
        if weights is not None:
            self.logw = np.asarray(weights(self.states), dtype=np.float64)
            keep = np.isfinite(self.logw)
            if not keep.any():
                raise SearchUnavailable("global search: the hint's prior leaves no pose of "
                                        "its grid (filter.global_search.cell = "
                                        f"{self.table.cell} m) in the free space")
            self.states, self.logw = self.states[keep], self.logw[keep]
        self.logw -= logsumexp(self.logw)
        self._born = np.full(len(self.states), -1, np.int64)  # the start: no injection
        self._held, self._dominant, self._frames = 0, None, 0

    def _grid(self, headings: int) -> np.ndarray:
        """(V * headings, 4) the free cells of the table x ``headings`` headings, jittered
        within their cell and heading bin, at the band's middle height."""
        t = self.table
        xy = t.centres()
        xy = xy[self.free.contains(xy)]
        n = len(xy) * headings
        xy = np.repeat(xy, headings, axis=0) + self.rng.uniform(-0.5, 0.5, (n, 2)) * t.cell
        yaw = (np.tile(np.arange(headings), n // headings) + self.rng.uniform(-0.5, 0.5, n)) \
            * (2 * np.pi / headings)
        z = np.full(n, 0.5 * (self.band[0] + self.band[1]))
        return np.column_stack([xy, z, wrap_angle(yaw)])

    def inject(self, labels: np.ndarray, tilt: np.ndarray | None) -> None:
        """Score a coarse grid (``inject_headings`` per cell) on this frame alone, add its
        ``inject_count`` best poses ``inject_below`` under the best log-weight (a pose lost to
        a run of bad frames comes back when a good one shows it), then prune (``update`` does
        it every ``inject_every`` frames)."""
        self._version += 1
        self._inject(labels, tilt)
        self._prune()

    def _inject(self, labels: np.ndarray, tilt: np.ndarray | None) -> None:
        """``inject``'s additions, without the pruning."""
        p = self.params
        kept_S, kept_lw = self.states, self.logw
        self.states = self._grid(p.inject_headings)
        out = self.log_likelihood(labels, tilt)
        S = self.states
        self.states = kept_S
        if out is None:
            return
        ll, z = out
        if self._prior is not None:  # a hint's prior: injections stay inside it
            ll = ll + self._prior(S)
        top = np.argpartition(-ll, min(p.inject_count, len(ll) - 1))[:p.inject_count]
        top = top[np.isfinite(ll[top])]
        S[top, 2] = z[top]
        lw = np.full(len(top), kept_lw.max() - p.inject_below)
        self.states = np.concatenate([kept_S, S[top]])
        self.logw = np.concatenate([kept_lw, lw])
        self._born = np.concatenate([self._born, np.full(len(top), self._frames)])
        self.logw -= logsumexp(self.logw)

    def predict(self, delta: np.ndarray, time_scale: float = 1.0) -> None:
        """Move every hypothesis by an odometry increment (4,) with noise; ``time_scale``
        multiplies ``motion_std`` (``particle_filter.noise_scale`` of the time the move spans;
        1: one frame)."""
        self._version += 1
        std = motion_noise(self.params, delta, time_scale)
        noise = self.rng.normal(0.0, 1.0, self.states.shape) * std
        self.states = apply_increment(self.states, np.asarray(delta, np.float64) + noise)

    def log_likelihood(self, labels: np.ndarray, tilt: np.ndarray | None
                       ) -> tuple[np.ndarray, np.ndarray] | None:
        """(N,) log-likelihood of the hypotheses and (N,) their fitted body heights (m), or
        None when the frame shows fewer than ``min_bins`` azimuth bins of floor boundary."""
        p, t = self.params, self.table
        fb = floor_boundary(labels, self.camera, tilt, t.rays, p.stride)
        if len(fb) < p.min_bins:
            return None
        if len(fb) > p.max_bins:  # evenly spaced bins: neighbours tell nearly the same
            keep = np.unique(np.linspace(0, len(fb) - 1, p.max_bins).round().astype(int))
            fb = fb.take(keep)
        S = self.states
        c, s = np.cos(S[:, 3]), np.sin(S[:, 3])
        cx = S[:, 0] + c * fb.camera[0] - s * fb.camera[1]
        cy = S[:, 1] + s * fb.camera[0] + c * fb.camera[1]
        cells = t.cells(np.column_stack([cx, cy]))
        R, M = t.rays, self._wrap
        k = np.rint(fb.offsets * (R / (2 * np.pi))).astype(np.int32)  # (J,) bin offsets
        k = np.clip(k, -M, M)
        start = (np.maximum(cells, 0) * (R + 2 * M) + M
                 + np.rint(S[:, 3] * (R / (2 * np.pi))).astype(np.int64) % R).astype(np.int32)
        tan = fb.tan.astype(np.float32)
        slope = np.float32(1.0) / (1 + tan * tan)  # d(angle) / d(tan)
        w2 = slope * slope
        w2_tan = w2 * tan
        lo, hi = self.band[0] + fb.camera[2], self.band[1] + fb.camera[2]
        inv_s2 = np.float32(1.0 / (2 * np.deg2rad(p.sigma_deg) ** 2))
        rho = np.empty(len(S), dtype=np.float32)
        h = np.empty(len(S), dtype=np.float32)
        for a in range(0, len(S), CHUNK):  # chunks of rows: the (n, J) temporaries stay small
            b = slice(a, a + CHUNK)
            idx = start[b, None] + k[None]
            inv_d = self._inv_dist[idx]  # (n, J) 1 / D
            # the height that fits best: least squares of the first-order angle errors, then
            # again without the bins that are outliers at the first height
            num = np.einsum("ij,j->i", inv_d, w2_tan)
            den = np.einsum("ij,ij,j->i", inv_d, inv_d, w2)
            hb = np.clip(num / np.maximum(den, np.float32(1e-9)), lo, hi)
            err = (tan[None] - hb[:, None] * inv_d) * slope[None]  # angle error, first order
            inl = (err * err * inv_s2 < np.float32(p.outlier)).astype(np.float32)
            inl_d = inl * inv_d
            num = np.einsum("ij,j->i", inl_d, w2_tan)
            den = np.einsum("ij,ij,j->i", inl_d, inv_d, w2)
            hb = np.where(den > 0, np.clip(num / np.maximum(den, np.float32(1e-9)), lo, hi), hb)
            err = (tan[None] - hb[:, None] * inv_d) * slope[None]
            r = err * err * inv_s2
            if p.class_cost > 0:  # a door seen where the table has a wall, ...
                r += np.where(self._kind[idx] != fb.kind[None], np.float32(p.class_cost),
                              np.float32(0.0))
            rho[b] = np.minimum(r, np.float32(p.outlier)).mean(1)
            h[b] = hb
        rho = np.where(cells >= 0, rho, np.float32(p.outlier))
        ll = -p.evidence * min(1.0, len(fb) / p.max_bins) * rho.astype(np.float64)
        return np.maximum(ll, ll.max() - p.frame_floor), h - fb.camera[2]

    def update(self, labels: np.ndarray, tilt: np.ndarray | None) -> bool:
        """Weigh the hypotheses by a frame's labels (module docstring), resample when the
        effective size falls under half; False when the frame was not weighed."""
        p = self.params
        self._version += 1
        out = self.log_likelihood(labels, tilt)
        if out is None:
            self._track_dominant()
            return False
        ll, z = out
        self.states[:, 2] = z
        lw = self.logw + ll
        self.logw = lw - logsumexp(lw)
        self._frames += 1
        if p.inject_every > 0 and self._frames % p.inject_every == 0:
            self._inject(labels, tilt)
        self._prune()
        self._track_dominant()
        return True

    def _prune(self) -> None:
        """Drop the hypotheses more than ``prune_band`` below the best in log-weight, then
        bring the count to ``per_bin`` per occupied bin (within the bounds): copies of the
        survivors drawn by weight, jittered, each copy sharing its parent's weight (cluster
        masses are kept), or a uniform random thinning when there are too many (it keeps every
        cluster's share in expectation)."""
        p = self.params
        keep = self.logw >= self.logw.max() - p.prune_band
        S, lw, born = self.states[keep], self.logw[keep], self._born[keep]
        occupied = int(np.count_nonzero(np.bincount(bin_keys(S))))
        n = int(np.clip(occupied * p.per_bin, p.min_hypotheses, p.max_hypotheses))
        if len(S) > n:
            sel = np.sort(self.rng.choice(len(S), n, replace=False))
            S, lw, born = S[sel], lw[sel], born[sel]
        elif len(S) < n:
            parent = systematic_resample(self.rng, lw, n - len(S))
            copies = 1 + np.bincount(parent, minlength=len(S))
            lw = lw - np.log(copies)
            new = S[parent] + self.rng.normal(0.0, 1.0, (len(parent), 4)) * np.array(
                [p.jitter[0], p.jitter[0], 0.0, np.deg2rad(p.jitter[1])])
            new[:, 3] = wrap_angle(new[:, 3])
            S, lw = np.concatenate([S, new]), np.concatenate([lw, lw[parent]])
            born = np.concatenate([born, born[parent]])
        self.states, self.logw, self._born = S, lw - logsumexp(lw), born

    def hypotheses(self, k: int = 5) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` heaviest clusters (non-maximum suppression): (k', 4) weighted mean poses,
        (k',) the share of the weight within ``cluster_radius`` and ``cluster_yaw_deg`` of each,
        heaviest first (computed once per state of the set and k)."""
        return self._cluster_list(k)[:2]

    def clusters(self, k: int) -> tuple[Hypothesis, ...]:
        """The ``k`` heaviest clusters of ``hypotheses`` as pose hypotheses
        (``hypotheses.Hypothesis``: mean pose, mass, horizontal and yaw spread, count),
        heaviest first (the clusters are found densest bin first; their masses may differ in
        order): the places the search holds."""
        poses, mass, spreads, counts, _ = self._cluster_list(k)
        order = np.argsort(-mass, kind="stable")
        return tuple(Hypothesis(poses[i], float(mass[i]), float(spreads[i, 0]),
                                float(spreads[i, 1]), int(counts[i])) for i in order)

    def _cluster_list(self, k: int) -> tuple:
        """(poses (k', 4), mass (k',), spreads (k', 2) m and rad, counts (k',), settled mass
        (k',): the share of the settled hypotheses' weight, see ``_track_dominant``) of the
        ``k`` heaviest clusters, computed once per state of the set and k."""
        key = (self._version, int(k))
        if self._clusters is None or self._clusters[0] != key:
            self._clusters = (key, self._find_clusters(int(k)))
        return self._clusters[1]

    def _find_clusters(self, k: int) -> tuple:
        """``_cluster_list``, computed."""
        w = np.exp(self.logw)
        S = self.states
        settled = (self._born < 0) | (self._born <= self._frames - self.params.handover_frames)
        w_settled = np.where(settled, w, 0.0)
        total_settled = w_settled.sum()
        left = np.ones(len(S), bool)
        left_settled = settled.copy()
        poses, mass, spreads, counts, settled_mass = [], [], [], [], []
        for _ in range(k):  # k clusters, each vectorized over the hypotheses
            if not left.any():
                break
            near = left & self._in_cluster(S, self._densest(S[left], w[left]))
            m = float(w[near].sum())
            if m <= 0:
                break
            poses.append(mean_pose(S[near], w[near] / m))
            spreads.append(pose_spread(S[near], w[near] / m))
            mass.append(m)
            counts.append(int(near.sum()))
            # the settled weight around the cluster's mean pose, each settled hypothesis in
            # the first cluster it falls in (around the densest bin instead, handovers come
            # later: docs/notes/global_places.md)
            near_settled = left_settled & self._in_cluster(S, poses[-1])
            settled_mass.append(w_settled[near_settled].sum() / total_settled
                                if total_settled > 0 else 0.0)
            left_settled &= ~near_settled
            left &= ~near
        return (np.array(poses).reshape(-1, 4), np.array(mass),
                np.array(spreads).reshape(-1, 2), np.array(counts, dtype=int),
                np.array(settled_mass))

    def _densest(self, S: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(4,) the weighted mean pose of the heaviest 0.5 m x 0.5 m x 20 deg bin of (S, w)."""
        inv = bin_keys(S)
        best = np.argmax(np.bincount(inv, weights=w))
        sel = inv == best
        return mean_pose(S[sel], w[sel] / w[sel].sum())

    def _in_cluster(self, S: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """(N,) bool: poses (N, 4) within ``cluster_radius`` and ``cluster_yaw_deg`` of
        ``centre`` (4,)."""
        p = self.params
        return (np.hypot(S[:, 0] - centre[0], S[:, 1] - centre[1]) <= p.cluster_radius) \
            & (np.abs(wrap_angle(S[:, 3] - centre[3])) <= np.deg2rad(p.cluster_yaw_deg))

    def _track_dominant(self) -> None:
        """Count the frames in a row the ``handover_places`` heaviest clusters hold
        ``handover_mass`` of the settled weight together (the start's hypotheses, and the
        injected ones weighed for at least ``handover_frames`` frames since: a fresh injection
        is a proposal, not yet evidence, and does not hold a handover back); the places are
        those of them holding at least ``1 - handover_mass`` of it."""
        p = self.params
        poses, _, _, _, mass = self._cluster_list(p.handover_places)
        if len(mass) and mass.sum() >= p.handover_mass:
            self._held += 1
            self._dominant = poses[(mass >= 1.0 - p.handover_mass) | (mass == mass.max())]
        else:
            self._held, self._dominant = 0, None

    def estimate(self) -> tuple[np.ndarray, float, float]:
        """The heaviest cluster's mean pose (4,), and the weighted horizontal spread (m) and
        circular yaw spread (rad) of the whole set."""
        poses, _ = self.hypotheses(1)
        return poses[0], *spread(self.states, self.logw)

    def forget_dominance(self) -> None:
        """Count the dominance afresh (a search handed over from the background of a track
        converges only on its own frames from here)."""
        self._held, self._dominant = 0, None

    @property
    def converged(self) -> bool:
        """The places held ``handover_mass`` for ``handover_frames`` frames in a row."""
        return self._held >= self.params.handover_frames

    @property
    def places(self) -> int:
        """How many places ``sample`` hands over (0 before the search has converged)."""
        return 0 if self._dominant is None else len(self._dominant)

    def sample(self, n: int, centre: np.ndarray | None = None) -> np.ndarray:
        """(n, 4) particles for the tracking filter: resampled from the hypotheses of the
        cluster around ``centre`` (4,), or split evenly between the places that held the mass
        (``places``; all the hypotheses when there is none or a place holds no hypothesis)."""
        if centre is not None:
            return self._sample_near(int(n), np.asarray(centre, dtype=np.float64))
        if self._dominant is None:
            return self._sample_near(int(n), None)
        k = len(self._dominant)
        counts = np.full(k, int(n) // k)
        counts[: int(n) - counts.sum()] += 1
        return np.concatenate([self._sample_near(int(c), d)
                               for c, d in zip(counts, self._dominant, strict=True)])

    def _sample_near(self, n: int, centre: np.ndarray | None) -> np.ndarray:
        """(n, 4) hypotheses resampled by weight from the cluster around ``centre`` (4,)
        (all of them with None or an empty cluster)."""
        S, lw = self.states, self.logw
        if centre is not None:
            near = self._in_cluster(S, centre)
            if near.any():
                S, lw = S[near], lw[near]
        return S[systematic_resample(self.rng, lw, n)].copy()
