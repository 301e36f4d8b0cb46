"""Rival hypotheses kept beside a track: a loss when a far one outweighs it.

The fit gate (``filter.gate``, ``filter.lost_frames``) declares a loss only when no particle
fits the frames; a teleport into a stretch that still fits (a floor's repeated rooms and
corridors) passes it. ``Rivals`` keeps a global search (``global_search.GlobalSearch``: every
place of the floor, scored by the cheap floor-boundary table) running in the background of
the track and checks, every ``every`` frames:

1. the search moves by the odometry since the last check (the frames' increments composed,
   their noise scales summed) and is weighed by this frame's labels (injecting its coarse
   grid's best poses every ``inject_every`` checks, so a place the track never visited comes
   in within a few checks);
2. its ``count`` heaviest clusters farther than ``min_distance`` from the track (or off by
   more than the search's ``cluster_yaw_deg`` in heading) are the rivals;
3. the track (``particles`` of its particles, drawn by weight) and each rival (``particles``
   poses drawn from its cluster's hypotheses) are scored with the tracking filter's own edge
   likelihood on this frame; a hypothesis's score is its poses' mean likelihood
   (``logsumexp(log_w) - log n``);
4. when the best rival's score exceeds the track's by ``margin`` at ``checks`` checks in a
   row, the loss is declared and the rival's poses (``GlobalSearch.sample`` around it) are
   the filter's new particles.

Cost per check: one search update (4,000-60,000 hypotheses at ~0.3 us each, plus the coarse
grid on injection checks) and ``(count + 1) x particles`` edge-likelihood poses (~10 us each);
nothing between checks but composing the odometry.

Settings: ``localize.search.config.RivalsConfig`` (``filter.rivals``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.special import logsumexp

from core.poses import wrap_angle
from localize.filter.particle_filter import LogLikelihood, apply_increment, systematic_resample
from localize.filter.pose_stats import mean_pose
from localize.search.config import RivalsConfig
from localize.search.global_search import GlobalSearch


@dataclass(frozen=True)
class Check:
    """What one check found.

    Attributes:
        track: the track's score (mean edge likelihood of its poses, log).
        rival: the best rival's score (-inf: no rival far enough).
        rival_state: (4,) that rival's cluster mean pose (None: no rival).
        lead: checks in a row a rival has led by ``margin`` (after this one).
        lost: this check declared the track lost.
    """

    track: float
    rival: float
    rival_state: np.ndarray | None
    lead: int
    lost: bool


class Rivals:
    """A background global search and the check of its far clusters against the track.

    Args:
        search: the global search to keep running (a global start's, after its handover, or
            a fresh one for a start at a known pose); its injection is taken over here
            (``RivalsConfig.inject_every``).
        params: settings.
        rng: random generator (its only source of randomness; the search keeps its own).
    """

    def __init__(self, search: GlobalSearch, params: RivalsConfig, rng: np.random.Generator):
        self.search, self.params, self.rng = search, params, rng
        self._inject = search.params.inject_every
        search.params = replace(search.params, inject_every=0)
        self._delta = np.zeros(4)  # odometry composed since the last check
        self._scale = 0.0
        self._frames = 0  # frames since the last check
        self._checks = 0
        self.lead = 0

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
            The ``Check``; ``Check.lost``: the track is lost and ``take_over(n)`` gives the
            rival's particles.
        """
        if not self.due or labels is None or loglik is None:
            return None
        p, search = self.params, self.search
        if self._scale > 0:
            search.predict(self._delta, self._scale)
        self._delta, self._scale, self._frames = np.zeros(4), 0.0, 0
        if not search.update(labels, tilt):
            return None
        self._checks += 1
        if self._inject > 0 and self._checks % p.inject_every == 0:
            search._inject(labels, tilt)
            search._prune()
        track_state = mean_pose(particles, np.exp(logw - logsumexp(logw)))
        poses, _ = search.hypotheses(p.count + 1)
        far = (np.hypot(poses[:, 0] - track_state[0], poses[:, 1] - track_state[1])
               > p.min_distance) | (np.abs(wrap_angle(poses[:, 3] - track_state[3]))
                                    > np.deg2rad(search.params.cluster_yaw_deg))
        rivals = poses[far][:p.count]
        n = p.particles
        sets = [particles[systematic_resample(self.rng, logw, n)]]
        sets += [search.sample(n, r) for r in rivals]
        states = np.concatenate(sets)
        lw, _ = loglik(states, np.zeros((len(states), 2)))
        scores = logsumexp(lw.reshape(len(sets), n), axis=1) - np.log(n)
        track = float(scores[0])
        if len(rivals):
            best = int(np.argmax(scores[1:]))
            rival, rival_state = float(scores[1 + best]), rivals[best]
        else:
            rival, rival_state = float("-inf"), None
        self.lead = self.lead + 1 if rival > track + p.margin else 0
        lost = self.lead >= p.checks
        if lost:
            self.lead = 0
            self._winner = rival_state
        return Check(track, rival, rival_state, self.lead, lost)

    def take_over(self, n: int) -> np.ndarray:
        """(n, 4) particles drawn from the search's hypotheses around the rival that won the
        last check declaring a loss."""
        return self.search.sample(n, self._winner)

