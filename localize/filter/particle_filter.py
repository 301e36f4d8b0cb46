"""A particle filter over body poses (x, y, z, yaw), in pure numpy with log-weights.

Each particle also carries a correction of the IMU's roll and pitch (``tilt``, (N, 2)
radians): an AHRS is off by a bias and a slow drift (0.2-1 deg), which moves the model's edges
by pixels. The corrections start around zero and walk a little each frame (``move_tilt``);
the likelihood scores each particle with its own corrected attitude, so resampling keeps the
corrections the image agrees with (``filter.tilt_std``; both 0: the IMU's roll and pitch as
given, and no corrections are drawn). A global start's large set keeps the IMU's attitude (two
more dimensions would thin its search); the corrections are drawn when it is thinned.

Three functions make the filter (as in nchopin's ``particles``): an initial draw (around a
known start for tracking, or uniform over the free space for global localization), a move
(odometry increment plus noise) and a log-likelihood (``likelihood.EdgeLikelihood``). Around
them: effective-sample-size triggered systematic resampling, a free-space prior (a prior, not
a wall: a hypothesis outside the free space loses log-weight with its distance, and none is
removed or moved), recovery from depletion (random particles are injected when the recent
best edge score falls well below its long-run level, as in augmented MCL), and the estimate,
the weighted mean with a circular mean for yaw.

Knowing when it is lost: a frame whose best particle fits the image far worse than the
long-run level (below ``gate`` of it: a dropout, a covered lens, a wrong pose) does not weigh
the particles; the filter *coasts* on the odometry. ``lost_frames`` such frames in a row
declare the track lost; the ``Localizer`` then re-localizes as it starts from nowhere: the
global search where it applies, else ``relocalize_uniform`` (a uniform set over the free space
joined by the tracked particles).
Each step reports its status and a confidence in [0, 1] (``StepInfo``), and the heaviest
pose hypotheses of the weighted set with their mass (``localize.filter.hypotheses``): the status is
``ambiguous`` until one hypothesis has held ``dominant_mass`` of the mass for
``dominant_frames`` frames in a row, and the estimate is the top hypothesis's pose whenever
it holds less than ``dominant_mass`` (the weighted mean of two modes lies between them).

Motion: the odometry increment between two frames is expressed in the gravity-aligned heading
frame of the earlier pose (forward, left, up, yaw change), the frame a VIO's increments are
integrated in; each particle applies it in its own heading frame. The noise of a move follows
the time it spans (``noise_scale``: ``motion_std`` per ``motion_period_s``, its variance
growing with the time elapsed) and the increment (``motion_rel``), not the number of moves: a
frame not weighed (the live node's frames it has no time for) still moves the particles
(``predict``), and moving twice over 0.05 s spreads them as once over 0.1 s.

Settings: ``localize.config.FilterConfig`` (``filter``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import wrap_angle
from localize.filter.config import FilterConfig
from localize.filter.hypotheses import Dominance, Hypothesis, top_hypotheses
from localize.filter.pose_stats import estimate, log_sum_exp, normalize_log_weights, spread
from localize.filter.start_hint import StartHint

# --- the three model functions ---------------------------------------------------------------


def init_tracking(rng: np.random.Generator, start: np.ndarray, n: int,
                  std: Sequence[float]) -> np.ndarray:
    """Particles around a known start.

    Args:
        rng: random generator.
        start: (4,) x, y, z (metres), yaw (radians).
        n: number of particles.
        std: (4,) x, y, z (metres), yaw (degrees).

    Returns:
        (n, 4) float64.
    """
    s = np.array([std[0], std[1], std[2], np.deg2rad(std[3])], dtype=np.float64)
    p = np.asarray(start, dtype=np.float64)[None] + rng.normal(0.0, 1.0, (n, 4)) * s
    p[:, 3] = wrap_angle(p[:, 3])
    return p


def init_global(rng: np.random.Generator, free: OccupancyMap, n: int) -> np.ndarray:
    """Particles uniform over the free space: its free cells x its band of heights x yaw.

    Args:
        rng: random generator.
        free: the world's free space (``World.free``).
        n: number of particles.

    Returns:
        (n, 4) float64.
    """
    xy = free.sample(rng, n)
    z = rng.uniform(free.band[0], free.band[1], n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    return np.column_stack([xy, z, yaw])


def apply_increment(poses: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Poses moved by odometry increments in their own frames.

    Args:
        poses: (N, 4) x, y, z, yaw.
        delta: (4,) or (N, 4) forward, left, up (m) and yaw change (rad).

    Returns:
        (N, 4) moved poses, yaw wrapped.
    """
    d = np.broadcast_to(np.asarray(delta, dtype=np.float64), poses.shape)
    yaw = poses[:, 3]
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.empty_like(poses)
    out[:, 0] = poses[:, 0] + c * d[:, 0] - s * d[:, 1]
    out[:, 1] = poses[:, 1] + s * d[:, 0] + c * d[:, 1]
    out[:, 2] = poses[:, 2] + d[:, 2]
    out[:, 3] = wrap_angle(yaw + d[:, 3])
    return out


def move(rng: np.random.Generator, particles: np.ndarray, delta: np.ndarray,
         std: Sequence[float], rel: Sequence[float]) -> np.ndarray:
    """Apply an odometry increment with noise to every particle.

    Args:
        rng: random generator.
        particles: (N, 4).
        delta: (4,) increment from ``odometry_increment``.
        std: (3,) noise of this move: horizontal (m), vertical (m), yaw (degrees).
        rel: (2,) extra noise per unit of translation and of yaw change.

    Returns:
        (N, 4) moved particles.
    """
    N = len(particles)
    step = float(np.hypot(delta[0], delta[1]))
    s_xy = std[0] + rel[0] * step
    s_z = std[1] + rel[0] * abs(delta[2])
    s_yaw = np.deg2rad(std[2]) + rel[1] * abs(delta[3])
    noise = rng.normal(0.0, 1.0, (N, 4)) * np.array([s_xy, s_xy, s_z, s_yaw])
    return apply_increment(particles, np.asarray(delta, dtype=np.float64) + noise)


def noise_scale(dt: float | None, period: float) -> float:
    """The factor of a move's time-driven noise over ``dt`` seconds: sqrt(dt / ``period``), the
    std of a random walk given per ``period`` (variances add over time, so moves of 0.05 s twice
    spread as one of 0.1 s). ``dt / period`` is rounded to 1e-6 (stamps at a steady rate then
    give exactly 1); ``dt`` None (no previous time): 1.

    Args:
        dt: seconds since the previous move, >= 0, or None.
        period: seconds ``motion_std`` is given for (``filter.motion_period_s``).
    """
    if dt is None:
        return 1.0
    if not np.isfinite(dt) or dt < 0:
        raise ValueError(f"the time since the previous move must be finite and >= 0 seconds, "
                         f"got {dt}")
    return float(np.sqrt(round(float(dt) / float(period), 6)))


def move_tilt(rng: np.random.Generator, tilt: np.ndarray, step_std: float) -> np.ndarray:
    """Random walk of the roll and pitch corrections.

    Args:
        rng: random generator (not drawn from when ``step_std`` is 0).
        tilt: (N, 2) roll, pitch corrections, radians.
        step_std: std of a frame's step, radians.

    Returns:
        (N, 2) moved corrections.
    """
    if step_std <= 0:
        return tilt
    return tilt + rng.normal(0.0, step_std, tilt.shape)


def draw_tilt(rng: np.random.Generator, n: int, std: float) -> np.ndarray:
    """(n, 2) roll, pitch corrections (radians) drawn around zero with ``std`` (radians); zeros
    with no draw when ``std`` is 0."""
    if std <= 0:
        return np.zeros((n, 2))
    return rng.normal(0.0, std, (n, 2))


def free_space_log_prior(particles: np.ndarray, free: OccupancyMap, slack: float,
                         per_m: float) -> np.ndarray:
    """Log prior (N,): 0 inside the free space grown by ``slack`` m, ``-per_m`` per metre
    beyond it (continuous, so a hypothesis just outside loses little and one far outside a
    lot; nothing is removed or moved).

    The distance is ``OccupancyMap.outside_distance_xyz``: the larger of the horizontal one
    to the free cells and the vertical one to the band.

    Args:
        particles: (N, 4) x, y, z (m), yaw.
        free: the free space.
        slack: m beyond the free space without a penalty.
        per_m: log-weight per metre beyond the slack (>= 0; 0: no prior).
    """
    return -per_m * np.maximum(free.outside_distance_xyz(particles[:, :3]) - slack, 0.0)


# --- weights ---------------------------------------------------------------------------------


def effective_sample_size(logw: np.ndarray) -> float:
    """ESS = 1 / sum(w^2) of normalized weights, from log-weights (N,)."""
    lw = normalize_log_weights(logw)
    return float(np.exp(-log_sum_exp(2.0 * lw)))


def systematic_resample(rng: np.random.Generator, logw: np.ndarray, n: int) -> np.ndarray:
    """Systematic (low-variance) resampling.

    Args:
        rng: random generator.
        logw: (N,) log-weights (any scale).
        n: number of indices to draw.

    Returns:
        (n,) int64 indices into the particles.
    """
    w = np.exp(normalize_log_weights(logw))
    cdf = np.cumsum(w)
    cdf[-1] = 1.0
    u = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(cdf, u, side="right"), len(w) - 1)


# --- the filter ------------------------------------------------------------------------------

#: log_likelihood(states (N, 4), tilt corrections (N, 2) radians) -> (log_w (N,), score (N,))
LogLikelihood = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class StepInfo:
    """Diagnostics of one filter step (of the weighted set before resampling, but
    ``num_particles``).

    Attributes:
        estimate: (4,) weighted mean pose, or the top hypothesis's pose when it holds less
            than ``dominant_mass``; while a re-localization keeps its global set, the lost
            track's pose moved by the odometry.
        ess: effective sample size.
        best_score: quality of the most likely particle.
        resampled: the set was resampled.
        injected: particles injected by recovery.
        num_particles: particles after the step.
        position_std: weighted horizontal spread, metres (``spread``).
        yaw_std: circular yaw spread, radians.
        tilt: (2,) weighted mean roll, pitch correction of the IMU's attitude, radians.
        status: ``tracking`` (the frame weighed the particles and one hypothesis has
            dominated for ``dominant_frames``), ``ambiguous`` (no hypothesis has yet: a
            global start or a re-localization, or the set split), ``coasting`` (a dominated
            track the frame did not weigh: the image showed nothing usable or fit no
            particle; odometry only) or ``lost`` (this frame declared the track lost and
            started a re-localization).
        confidence: in [0, 1], how much the estimate is backed by the images: the smoothed fit
            of the best particle over its long-run level (0 while coasting or ambiguous),
            times ``1 - position_std / 1 m``.
        hypotheses: the heaviest modes of the weighted set, heaviest first
            (``hypotheses.top_hypotheses``).
    """

    estimate: np.ndarray
    ess: float
    best_score: float
    resampled: bool
    injected: int
    num_particles: int
    position_std: float = float("nan")
    yaw_std: float = float("nan")
    tilt: np.ndarray | None = None
    status: str = "tracking"
    confidence: float = float("nan")
    hypotheses: tuple[Hypothesis, ...] = ()


#: The fit gate needs a long-run fit level this far above chance: mode none's raw image edges
#: hold clutter everywhere and its best fit stays near 0.1-0.2, so there a poor fit does not
#: tell a lost track.
MIN_GATED_FIT = 0.25
#: Smoothing factor of the confidence's fit average.
CONFIDENCE_RATE = 0.3
#: Metres of particle spread at which the confidence is 0.
CONFIDENCE_SPREAD_M = 1.0


class ParticleFilter:
    """The particle filter's state and its per-frame step.

    Args:
        params: settings.
        free: the world's free space (init_global, prior, recovery).
        rng: random generator (the only source of randomness).
    """

    def __init__(self, params: FilterConfig, free: OccupancyMap, rng: np.random.Generator):
        self.params, self.rng, self.free = params, rng, free
        self.particles = np.zeros((0, 4))
        self.logw = np.zeros(0)
        self.tilt = np.zeros((0, 2))
        self.frame = 0
        self._fast = self._slow = None
        self._low = 0
        self._thin_at = 0
        self._poor = 0  # frames in a row whose fit was below the gate
        self._fit = 0.0  # smoothed fit ratio of the confidence
        self._reckoned = None  # (4,) the lost track's pose moved by the odometry, reported
        # while a re-localization's global set is kept
        self.dominance = Dominance(params.dominant_mass, params.dominant_frames)

    def init_tracking(self, start: np.ndarray) -> None:
        """Start around a known pose (4,) x, y, z, yaw."""
        p = self.params
        self.init_particles(init_tracking(self.rng, start, p.num_particles, p.init_std))

    def init_particles(self, particles: np.ndarray, dominant: bool = True) -> None:
        """Start tracking from a given set (N, 4) x, y, z, yaw, equally weighted (a tracking
        start, or a global search's handover): status ``tracking`` when ``dominant`` (one
        place), else ``ambiguous`` until one hypothesis has held ``dominant_mass`` for
        ``dominant_frames`` (a handover of several places)."""
        p = self.params
        self.particles = np.array(particles, dtype=np.float64)
        n = len(self.particles)
        self.tilt = draw_tilt(self.rng, n, np.deg2rad(p.tilt_std[0]))
        self.logw = np.full(n, -np.log(n))
        self.frame, self._fast, self._slow, self._thin_at, self._low = 0, None, None, 0, 0
        self._poor, self._fit, self._reckoned = 0, 1.0, None
        if dominant:
            self.dominance.confirm()
        else:
            self.dominance.clear()

    def init_global(self, hint: StartHint | None = None) -> None:
        """Start uniform over the free space, or inside ``hint`` (``StartHint.draw``), with
        ``global_count(area)`` particles (``global_particles``, more over a free space, or a
        hinted area, larger than ``global_area``)."""
        p = self.params
        if hint is None:
            n = p.global_count(self.free.area)
            self.particles = init_global(self.rng, self.free, n)
        else:
            n = p.global_count(hint.area(self.free))
            self.particles = hint.draw(self.rng, self.free, n)
        self.tilt = np.zeros((n, 2))
        self.logw = np.full(n, -np.log(n))
        self.frame, self._fast, self._slow, self._low = 0, None, None, 0
        self._thin_at = p.global_frames
        self._poor, self._fit, self._reckoned = 0, 0.0, None
        self.dominance.clear()

    @property
    def in_global_phase(self) -> bool:
        """True while the large global set is kept (before thinning)."""
        return self._thin_at > 0 and self.frame < self._thin_at

    def predict(self, delta: np.ndarray, time_scale: float = 1.0) -> None:
        """Move the particles by an odometry increment (4,); ``time_scale`` multiplies the
        time-driven noise (``motion_std``, the tilt's walk): ``noise_scale`` of the time the
        move spans (1: one ``motion_period_s``)."""
        p = self.params
        scale = time_scale * (p.global_motion_scale if self.in_global_phase else 1.0)
        std = tuple(scale * np.asarray(p.motion_std, dtype=np.float64))
        self.particles = move(self.rng, self.particles, delta, std, p.motion_rel)
        if self._reckoned is not None:
            self._reckoned = apply_increment(self._reckoned[None], delta)[0]
        if not self.in_global_phase:
            self.tilt = move_tilt(self.rng, self.tilt, time_scale * np.deg2rad(p.tilt_std[1]))

    def update(self, log_likelihood: LogLikelihood) -> StepInfo:
        """Weight by the measurement, resample if needed, inject on collapse.

        Args:
            log_likelihood: maps (N, 4) states and their (N, 2) roll, pitch corrections
                (radians) to (log_w (N,), quality (N,)); the quality of the most likely
                particle drives recovery.

        Returns:
            Diagnostics, with the estimate computed before resampling.
        """
        p = self.params
        loglik, score = log_likelihood(self.particles, self.tilt)
        global_phase = self.in_global_phase
        prior = free_space_log_prior(self.particles, self.free, p.free_space_slack,
                                     p.outside_log_penalty_per_m)
        best = float(score[np.argmax(loglik + prior)]) if len(score) else float("nan")
        if not global_phase and self._below_gate(best):
            self._poor += 1
            if self._poor >= p.lost_frames > 0:
                return self._relocalize(best)
            return self.coast(best)
        self._poor = 0
        self.logw = normalize_log_weights(self.logw + loglik + prior)
        mean = estimate(self.particles, self.logw)
        hyps = self.hypotheses()
        top = hyps[0].mass if hyps else 0.0
        status = self.dominance.update(top)
        est = self._reported(mean if top >= p.dominant_mass else hyps[0].state, global_phase)
        pos_std, yaw_std = spread(self.particles, self.logw)
        tilt = np.exp(self.logw) @ self.tilt
        ess = effective_sample_size(self.logw)
        inject_frac = self._collapse(best)
        self._smooth_fit(best)
        self.frame += 1
        N = len(self.particles)
        large = self._thin_at > 0 and self.frame < self._thin_at  # keep the global set
        thin = self._thin_at > 0 and not large
        resampled = thin or ess < p.resample_ess * N or inject_frac > 0
        injected = 0
        if resampled:
            n = N if large else p.num_particles
            idx = systematic_resample(self.rng, self.logw, n)
            self.particles, self.tilt = self.particles[idx], self.tilt[idx]
            injected = int(round(inject_frac * n))
            self.logw = np.zeros(n)
            if injected:
                slots = self._inject(injected, mean)
                self.logw[slots] = -p.recovery_log_penalty
            self.logw = normalize_log_weights(self.logw)
            if thin:
                self._thin_at, self._reckoned = 0, None
                self.tilt = draw_tilt(self.rng, n, np.deg2rad(p.tilt_std[0]))
        return StepInfo(est, ess, best, resampled, injected, len(self.particles), pos_std,
                        yaw_std, tilt, status,
                        self._confidence(pos_std, status != "tracking"), tuple(hyps))

    def hypotheses(self) -> list[Hypothesis]:
        """The heaviest modes of the weighted set (``filter.hypotheses`` of them)."""
        p = self.params
        return top_hypotheses(self.particles, self.logw, p.hypotheses, p.hypothesis_radius_m,
                              p.hypothesis_yaw_deg)

    def coast(self, best: float = float("nan")) -> StepInfo:
        """A frame that does not weigh the particles (nothing usable in the image, or no
        particle fits it): odometry only; the confidence's fit average decays towards 0.

        Args:
            best: the best particle's fit of the frame, if scored (reported only).
        """
        global_phase = self.in_global_phase
        hyps = self.hypotheses()
        mean = estimate(self.particles, self.logw)
        dominant = bool(hyps) and hyps[0].mass >= self.params.dominant_mass
        est = self._reported(mean if dominant else hyps[0].state, global_phase)
        pos_std, yaw_std = spread(self.particles, self.logw)
        self._fit *= 1.0 - CONFIDENCE_RATE
        self.frame += 1
        status = "coasting" if self.dominance.confirmed else "ambiguous"
        return StepInfo(est, effective_sample_size(self.logw), best, False, 0,
                        len(self.particles), pos_std, yaw_std,
                        np.exp(self.logw) @ self.tilt, status,
                        self._confidence(pos_std, status != "coasting"), tuple(hyps))

    def _below_gate(self, best: float) -> bool:
        """The best fit is below ``gate`` of its long-run level (once that level is known and
        at least ``MIN_GATED_FIT``; a NaN fit, too little seen to judge, is not)."""
        p = self.params
        if p.gate <= 0 or self._slow is None or self._slow < MIN_GATED_FIT:
            return False
        return bool(np.isfinite(best) and best < p.gate * self._slow)

    def _relocalize(self, best: float) -> StepInfo:
        """Declare the track lost: the estimate of the poor frames is reported; the particles
        stay as they are until the caller re-localizes (``Localizer``: the global search, or
        ``relocalize_uniform`` where the search does not apply)."""
        info = self.coast(best)
        info.status, info.confidence = "lost", 0.0
        return info

    def relocalize_uniform(self, lost_pose: np.ndarray) -> None:
        """Re-localize after a declared loss with the uniform set: a global start over the free
        space joined by the tracked particles (so that a track that was right after all wins
        back at once); until a hypothesis dominates, the lost track's pose (4,), moved by the
        odometry, is reported."""
        kept, tilt = self.particles, self.tilt
        self.init_global()
        self._reckoned = np.asarray(lost_pose, dtype=np.float64).copy()
        self.particles = np.concatenate([self.particles, kept])
        self.tilt = np.concatenate([self.tilt, tilt])
        self.logw = np.full(len(self.particles), -np.log(len(self.particles)))

    def _reported(self, est: np.ndarray, global_phase: bool) -> np.ndarray:
        """The pose a step reports: while a re-localization keeps its global set, the lost
        track's pose moved by the odometry until a hypothesis dominates (the global set's
        mean is the middle of the free space until it gathers), else ``est``."""
        if global_phase and self._reckoned is not None and not self.dominance.confirmed:
            return self._reckoned.copy()
        return est

    def _smooth_fit(self, best: float) -> None:
        """The confidence's fit average: the best fit over its long-run level, in [0, 1]."""
        if self._slow is None or not np.isfinite(best):
            return
        ratio = float(np.clip(best / self._slow, 0.0, 1.0)) if self._slow > 0.05 else 1.0
        self._fit += CONFIDENCE_RATE * (ratio - self._fit)

    def _confidence(self, pos_std: float, ambiguous: bool) -> float:
        """``StepInfo.confidence``: 0 while no hypothesis dominates."""
        if ambiguous:
            return 0.0
        return float(self._fit * max(0.0, 1.0 - pos_std / CONFIDENCE_SPREAD_M))

    def _collapse(self, best: float) -> float:
        """Fraction of particles to inject: 1 - fast / slow average of the best score, when that
        ratio is below ``recovery_threshold``."""
        p = self.params
        if not np.isfinite(best):  # too little seen to judge (e.g. view blocked by people)
            return 0.0
        if self._fast is None:
            self._fast = self._slow = best
            return 0.0
        self._fast += p.recovery_fast * (best - self._fast)
        self._slow += p.recovery_slow * (best - self._slow)
        if not p.recovery or self._slow <= 0.05:
            return 0.0
        ratio = self._fast / self._slow
        self._low = self._low + 1 if ratio < p.recovery_threshold else 0
        if self._low < p.recovery_patience:
            return 0.0
        self._low, self._fast = 0, self._slow  # re-arm: at most once per patience window
        return float(min(1.0 - ratio, p.recovery_max_fraction))

    def _inject(self, n: int, around: np.ndarray) -> np.ndarray:
        """Replace n random particles: half near ``around``, half uniform over free space.

        Returns:
            (n,) indices of the replaced particles.
        """
        p = self.params
        slots = self.rng.choice(len(self.particles), size=n, replace=False)
        n_local = n // 2
        local = init_tracking(self.rng, around, n_local, p.recovery_local_std)
        uniform = init_global(self.rng, self.free, n - n_local)
        self.particles[slots] = np.concatenate([local, uniform])
        self.tilt[slots] = draw_tilt(self.rng, n, np.deg2rad(p.tilt_std[0]))
        return slots

    def estimate(self) -> np.ndarray:
        """Weighted mean pose (4,)."""
        return estimate(self.particles, self.logw)
