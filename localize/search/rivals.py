"""Rival hypotheses kept beside a track: a loss when a far one outweighs it.

The fit gate (``filter.gate``, ``filter.lost_frames``) declares a loss only when no particle
fits the frames; a teleport into a stretch that still fits (a floor's repeated rooms and
corridors) passes it. ``Rivals`` keeps a global search (``global_search.GlobalSearch``: every
place of the floor, scored by the cheap floor-boundary table) running in the background of
the track, and up to ``count`` small particle sets (``particles`` poses each) at the places it
holds away from the track. Every ``every`` frames, a check:

1. the search and the sets move by the odometry since the last check (the frames' increments
   composed, their noise scales summed; the search's motion noise); the search is weighed by
   this frame's labels (injecting its coarse grid's best poses every ``inject_every`` checks,
   so a place the track never visited comes in within a few checks);
2. the search's heaviest clusters farther than ``min_distance`` from the track (or off by more
   than the search's ``cluster_yaw_deg`` in heading) that no set covers yet seed new sets
   (``GlobalSearch.sample`` around them); sets that came near the track are dropped;
3. the track (``particles`` of its particles, drawn by weight) and every set are scored with
   the tracking filter's own edge likelihood on this frame: a hypothesis's score is its best
   pose's log-likelihood (the same number of poses each); the ``count`` best sets are kept,
   each resampled by its weights and jittered (a small particle filter: the sets settle on
   the pose their place fits best);
4. when the best set's score exceeds the track's by ``margin`` at ``checks`` checks in a row,
   the loss is declared and the background search is handed over as the re-localization's
   search (``hand_over``; the filter takes over when one place dominates it); the new
   track is then doubted (``doubt_after``) until it has led every rival by ``margin`` at
   ``checks`` checks in a row.

Cost per check: one search update (at most ``max_hypotheses`` hypotheses at ~0.3 us each,
plus the coarse grid on injection checks) and at most
``(2 count + 1) x particles`` edge-likelihood poses (~10 us each); nothing between checks
but composing the odometry.

Settings: ``localize.search.config.RivalsConfig`` (``filter.rivals``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from core.poses import wrap_angle
from localize.filter.particle_filter import LogLikelihood, apply_increment, systematic_resample
from localize.filter.pose_stats import mean_pose, normalize_log_weights
from localize.search.config import RivalsConfig
from localize.search.global_search import GlobalSearch, motion_noise


def own_stream(rng: np.random.Generator) -> np.random.Generator:
    """A child stream of ``rng`` for the rivals, its parent's state not advanced (the track
    draws the same numbers with and without them)."""
    try:
        return rng.spawn(1)[0]
    except TypeError:  # a generator made without a seed sequence
        return np.random.default_rng(rng.bit_generator.state["state"]["state"])


#: (4,) std of the jitter of a rival set's poses after resampling: x, y, z (m), yaw (degrees):
#: wide enough that a set seeded from the search's cells (0.25 m, a lag along a corridor)
#: climbs to the pose its place fits best within a few checks.
JITTER = (0.15, 0.15, 0.05, 4.0)


@dataclass(frozen=True)
class Check:
    """What one check found.

    Attributes:
        track: the track's score (mean edge likelihood of its poses, log).
        rival: the best rival set's score (-inf: no rival far enough).
        rival_state: (4,) that set's mean pose after its refinement (None: no rival).
        lead: checks in a row a rival has led by ``margin`` (after this one).
        lost: this check declared the track lost.
    """

    track: float
    rival: float
    rival_state: np.ndarray | None
    lead: int
    lost: bool


def doubt_after(doubt: int | None, chk: Check | None, params: RivalsConfig) -> int | None:
    """The doubt in a track after a loss, updated by a check: the checks in a row at which the
    track led every rival by ``margin`` (None: no doubt, after ``checks`` such checks; a loss
    declared by ``chk`` starts it at 0). While there is doubt the track is not reported
    ``tracking``: the set that outweighed a wrong track, or a search that converged, may sit
    at a copy of the true place, and a rival there keeps within the margin of it.

    Args:
        doubt: the doubt before the check (None: none).
        chk: the check (None: none was made at this frame).
        params: settings (``margin``, ``checks``).
    """
    if chk is not None and chk.lost:
        return 0
    if doubt is None or chk is None:
        return doubt
    doubt = doubt + 1 if chk.track > chk.rival + params.margin else 0
    return None if doubt >= params.checks else doubt


class Rivals:
    """A background global search and the check of its far clusters against the track.

    Args:
        search: the global search to keep running (a global start's, after its handover, or
            a fresh one for a start at a known pose); its injection is taken over here
            (``RivalsConfig.inject_every``) and its count capped
            (``RivalsConfig.max_hypotheses``).
        params: settings.
        rng: random generator (its only source of randomness; the search keeps its own).
    """

    def __init__(self, search: GlobalSearch, params: RivalsConfig, rng: np.random.Generator):
        self.search, self.params, self.rng = search, params, rng
        self._search_params = sp = search.params  # its own, back on ``hand_over``
        search.params = replace(sp, inject_every=0,
                                max_hypotheses=min(sp.max_hypotheses, params.max_hypotheses),
                                min_hypotheses=min(sp.min_hypotheses, params.max_hypotheses))
        self._delta = np.zeros(4)  # odometry composed since the last check
        self._scale = 0.0
        self._frames = 0  # frames since the last check
        self._checks = 0
        self.lead = 0
        self.sets: list[np.ndarray] = []  # (particles, 4) poses of each rival place

    def predict(self, delta: np.ndarray | None, time_scale: float = 1.0) -> None:
        """Add a frame's odometry increment (4,) (None: no move) to the move of the next
        check."""
        self._frames += 1
        if delta is not None:
            self._delta = apply_increment(self._delta[None], np.asarray(delta, np.float64))[0]
            self._scale += float(time_scale)

    @property
    def due(self) -> bool:
        """A check is due at this frame (``every`` frames since the last)."""
        return self._frames >= self.params.every

    def check(self, labels: np.ndarray | None, tilt: np.ndarray | None,
              particles: np.ndarray, logw: np.ndarray, loglik: LogLikelihood | None
              ) -> Check | None:
        """The check of this frame (module docstring), or None when none is due or the frame
        cannot be weighed (no labels, or no edge likelihood: the odometry waits for the next).

        Args:
            labels: (H, W) uint8 class labels of the frame (the search's measurement).
            tilt: (3, 3) roll/pitch of the IMU, or None.
            particles: (N, 4) the track's particles; ``logw`` (N,) their log-weights.
            loglik: the tracking filter's likelihood of this frame (``states (n, 4),
                corrections (n, 2) -> (log_w (n,), score (n,))``).

        Returns:
            The ``Check``; ``Check.lost``: the track is lost and ``hand_over()`` gives the
            search to re-localize with.
        """
        if not self.due or labels is None or loglik is None:
            return None
        p, search = self.params, self.search
        if self._scale > 0:
            search.predict(self._delta, self._scale)
            self._move_sets(self._delta, self._scale)
        self._delta, self._scale, self._frames = np.zeros(4), 0.0, 0
        if not search.update(labels, tilt):
            return None
        self._checks += 1
        if self._search_params.inject_every > 0 and self._checks % p.inject_every == 0:
            search.inject(labels, tilt)
        track_state = mean_pose(particles, np.exp(normalize_log_weights(logw)))
        self._seed(track_state)
        n = p.particles
        sets = [particles[systematic_resample(self.rng, logw, n)], *self.sets]
        lw, _ = loglik(np.concatenate(sets), np.zeros((n * len(sets), 2)))
        lw = lw.reshape(len(sets), n)
        scores = lw.max(axis=1)
        track = float(scores[0])
        order = np.argsort(-scores[1:], kind="stable")[:p.count]
        self.sets = [self._refine(self.sets[i], lw[1 + i]) for i in order]
        if len(order):
            rival = float(scores[1 + order[0]])
            rival_state = mean_pose(self.sets[0], np.full(n, 1.0 / n))
        else:
            rival, rival_state = float("-inf"), None
        self.lead = self.lead + 1 if rival > track + p.margin else 0
        lost = self.lead >= p.checks
        if lost:
            self.lead = 0
        return Check(track, rival, rival_state, self.lead, lost)

    def hand_over(self) -> GlobalSearch:
        """The background search for the re-localization after a loss: its own settings back
        (injection, count), its dominance counted afresh (it converges only when one place
        holds ``handover_frames`` frames of its own, updated at every frame from now on)."""
        self.search.params = self._search_params
        self.search.forget_dominance()
        return self.search

    def _far(self, states: np.ndarray, track_state: np.ndarray) -> np.ndarray:
        """(M,) bool: poses (M, 4) farther than ``min_distance`` from ``track_state`` (4,) or
        off by more than the search's ``cluster_yaw_deg`` in heading."""
        return (np.hypot(states[:, 0] - track_state[0], states[:, 1] - track_state[1])
                > self.params.min_distance) | (np.abs(wrap_angle(states[:, 3] - track_state[3]))
                                               > np.deg2rad(self.search.params.cluster_yaw_deg))

    def _seed(self, track_state: np.ndarray) -> None:
        """Drop the sets that came near the track; add a set for each of the search's
        ``count`` heaviest far clusters that no set covers (within the search's cluster
        radius and yaw)."""
        p, search = self.params, self.search
        n = p.particles
        means = [mean_pose(s, np.full(n, 1.0 / n)) for s in self.sets]
        keep = [i for i, m in enumerate(means) if self._far(m[None], track_state)[0]]
        self.sets = [self.sets[i] for i in keep]
        means = np.array([means[i] for i in keep]).reshape(-1, 4)
        poses, _ = search.hypotheses(p.count + 1)
        radius, yaw = search.params.cluster_radius, np.deg2rad(search.params.cluster_yaw_deg)
        for c in poses[self._far(poses, track_state)][:p.count]:
            covered = ((np.hypot(means[:, 0] - c[0], means[:, 1] - c[1]) <= radius)
                       & (np.abs(wrap_angle(means[:, 3] - c[3])) <= yaw)).any()
            if not covered:
                self.sets.append(search.sample(n, c))

    def _refine(self, poses: np.ndarray, lw: np.ndarray) -> np.ndarray:
        """(n, 4) a set resampled by its log-weights ``lw`` (n,) and jittered (``JITTER``); its
        best pose is kept as it is."""
        out = poses[systematic_resample(self.rng, lw, len(poses))]
        out = out + self.rng.normal(0.0, 1.0, out.shape) * np.r_[JITTER[:3],
                                                                np.deg2rad(JITTER[3])]
        out[0] = poses[np.argmax(lw)]
        out[:, 3] = wrap_angle(out[:, 3])
        return out

    def _move_sets(self, delta: np.ndarray, scale: float) -> None:
        """Move every set by the composed odometry ``delta`` (4,) with the search's motion
        noise of ``scale`` frames."""
        std = motion_noise(self.search.params, delta, scale)
        self.sets = [apply_increment(s, delta + self.rng.normal(0.0, 1.0, s.shape) * std)
                     for s in self.sets]
