"""The Localizer: the one object that turns camera frames into poses.

A ``Localizer`` holds one particle filter (``particle_filter.ParticleFilter``) over body poses
(x, y, z, yaw), the edge likelihood of its edge mode (``likelihood.EdgeLikelihood``, and the
thinned one of the global phase) and a front end (``frontend.FrontEnd``: image -> labels ->
edge image). ``reset(start)`` starts it around a known pose or globally: with None or a
``start_hint.StartHint`` (a region, a pose with covariance, a heading range), by a global
search over the free space (``global_search``, handing over to the filter once one pose
dominates; the filter's uniform set, or the hint's, for mode ``none``,
``filter.global_method: particles``, or a building the search cannot run on, with a warning:
``global_search.start_search``);
``step(image, odometry_increment, attitude, timestamp)`` moves the particles by the odometry,
weighs them by how well the model's edges fall on the frame's edges and returns an
``Estimate``; while tracking, rival hypotheses (``search.rivals``: a global search kept
running beside the track) are checked every few frames and a far one that outweighs the track
declares it lost; ``predict(odometry_increment, timestamp)`` moves them only (a frame that is not
weighed). The motion noise follows the time between frames (``filter.motion_period_s``). No
file is read or written.

Several filters on the same frames (the runner's inits x seeds of one flight and mode) share
the costly per-frame work: they share one ``FrontEnd`` and one ``EdgeModel``; the caller makes
each frame once, ``frame = front_end.frame(image, labels)``, and passes the ``EdgeFrame`` to every
localizer's ``step`` instead of the image. An ``EdgeFrame`` makes each likelihood's score maps (the
distance transforms) once and hands them to every filter with the same map settings, so N
filters cost one segmentation, one edge image and one set of score maps per frame, plus N
filter updates. Given an image, ``step`` makes the frame itself.

Settings (``localize.config.LocalizerConfig``) are the localize config's ``filter`` (particle filter
and likelihood), ``edges``, ``model_edges`` and ``visibility`` nodes; a mode's own likelihood and
motion noise (``filter.mode_likelihood``, ``filter.mode_motion_std``) apply by the front end's
mode.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np
from threadpoolctl import ThreadpoolController

from core.dataset import Camera, World
from core.poses import pose_from_xyzyaw, xyzyaw_from_pose
from localize.config import LocalizerConfig
from localize.edge_model import EdgeModel
from localize.filter import quality
from localize.filter.hypotheses import Hypothesis
from localize.filter.likelihood import EdgeLikelihood
from localize.filter.particle_filter import LogLikelihood, ParticleFilter, noise_scale
from localize.filter.projection import (
    corrected_tilts,
    tilt_from_pose,
)
from localize.filter.start_hint import StartHint
from localize.frontend.edge_image import EdgeImage
from localize.frontend.front_end import EdgeFrame, FrontEnd
from localize.search.global_search import GlobalSearch, start_search
from localize.search.rivals import Rivals, doubt_after, own_stream

#: ``(edge image, tilt (3, 3) or None) -> (states (N, 4) -> (log_w (N,), quality (N,)))``: a
#: likelihood that replaces the edge likelihood
#: (``localize.paper.faithful.PaperFaithfulLikelihood``).
LikelihoodOverride = Callable[[EdgeImage, np.ndarray | None], LogLikelihood]

_BLAS = ThreadpoolController()
log = logging.getLogger(__name__)

#: A frame shows nothing to weigh the particles by (a black or covered lens: no edges; sensor
#: noise: edges near every pixel) when fewer than this fraction of its known pixels are edges...
MIN_EDGE_FRACTION = 0.001
#: ...or when the chance score of its edges (``Observation.chance``) is above this.
MAX_CHANCE = 0.5


def start_pose(start, where: str) -> np.ndarray:
    """(4,) x, y, z (m), yaw (rad) of a start pose: (4,) as given, or a (4, 4) world_from_body's
    position and heading (roll and pitch ignored). ValueError naming ``where`` for another
    shape or a value that is not finite."""
    s = np.asarray(start, dtype=np.float64)
    if s.shape == (4, 4) and np.isfinite(s).all():
        s = xyzyaw_from_pose(s)[0]
    if s.shape != (4,) or not np.isfinite(s).all():
        raise ValueError(f"{where}: expected (4,) x, y, z, yaw or a (4, 4) world_from_body, "
                         f"finite, got {s.shape}")
    return s


@dataclass(frozen=True)
class Estimate:
    """The pose estimate of one frame.

    Attributes:
        timestamp: seconds, as given to ``step``.
        state: (4,) x, y, z (metres), yaw (radians): the particles' weighted mean, or the top
            hypothesis's pose while it holds less than ``filter.dominant_mass``.
        pose: (4, 4) world_from_body of ``state`` (zero roll and pitch).
        position_std: weighted horizontal spread of the particles, metres.
        yaw_std: circular spread of their yaw, radians.
        ess: effective sample size of the weights.
        num_particles: particles after the step.
        best_score: fit quality of the most likely particle (NaN: too little seen to tell).
        injected: particles injected by depletion recovery in this step.
        status: ``tracking``, ``ambiguous``, ``coasting`` or ``lost``
            (``particle_filter.StepInfo``): ``tracking`` only once one hypothesis has held
            ``filter.dominant_mass`` for ``filter.dominant_frames`` frames, and while
            ``quality`` is at least ``filter.tracking_quality``.
        confidence: in [0, 1], how much the images back the estimate
            (``particle_filter.StepInfo``).
        tilt: (2,) roll, pitch correction of the IMU's attitude, radians.
        timing_ms: ``segmentation`` (the edge source's labels), ``preprocessing`` (edge image
            and score maps) and ``filter`` (motion, likelihood, resampling), ms.
        hypotheses: the heaviest pose hypotheses of the particle set with their mass,
            heaviest first (``hypotheses.Hypothesis``).
        quality: in [0, 1], the probability that ``state`` is within 0.3 m of the truth
            (``localize.filter.quality``: calibrated on validation floors); NaN in an edge
            mode the calibration does not cover.
        quality_inputs: what it was computed from (``quality.INPUTS``).
    """

    timestamp: float
    state: np.ndarray
    pose: np.ndarray
    position_std: float
    yaw_std: float
    ess: float
    num_particles: int
    best_score: float
    injected: int
    status: str
    confidence: float
    tilt: np.ndarray
    timing_ms: Mapping[str, float]
    hypotheses: tuple[Hypothesis, ...] = ()
    quality: float = float("nan")
    quality_inputs: tuple[float, ...] = ()


class Localizer:
    """An edge particle filter localizing a camera against a building model.

    Args:
        world: the structural model (free space, edge segments).
        camera: the camera to project with (K, size, body_from_cam); frames must be its size.
        front_end: a ``FrontEnd`` (shared with other localizers), or an edge source for a
            front end of its own: ``"none"``, ``"oracle"``, an ``EdgeSource`` or a callable
            ``rgb -> labels`` (``frontend.edge_source``; for ``"cnn"`` pass a FrontEnd or a
            ``SegmenterLabels``).
        settings: the filter, likelihood, edges and model settings.
        rng: the filter's random generator (its only source of randomness).
        model: the model edges this mode scores (``EdgeModel.for_mode``), shared with other
            localizers; None builds them (``EdgeModel.build``, ray-casting the visibility
            grid, uncached, then ``for_mode``).
        likelihood_override: replaces the edge likelihood in every phase (the paper-faithful
            comparison).
    """

    def __init__(self, world: World, camera: Camera, front_end, settings: LocalizerConfig,
                 rng: np.random.Generator, *, model: EdgeModel | None = None,
                 likelihood_override: LikelihoodOverride | None = None):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a np.random.Generator, got {type(rng).__name__}")
        self.front_end = (front_end if isinstance(front_end, FrontEnd)
                          else FrontEnd(front_end, settings.edges))
        if not np.isfinite(np.asarray(camera.K, dtype=np.float64)).all():
            raise ValueError(f"the camera's K is not finite ({np.asarray(camera.K).tolist()}): "
                             "with world=FILE the intrinsics come with the frames (camera.yaml, "
                             "a CameraInfo); make the Localizer with that camera")
        self.world, self.camera, self.settings = world, camera, settings
        mode = self.front_end.mode
        self.filter_params = settings.filter.for_mode(mode)
        if model is None:
            model = EdgeModel.build(world, settings).for_mode(world, mode)
        self.model = model
        lp = self.filter_params.likelihood_for(mode)
        self.likelihood = EdgeLikelihood(model.samples, camera, lp, model.visibility,
                                         model.pairs)
        self._global_likelihood = None
        self.likelihood_override = likelihood_override
        self.filter = ParticleFilter(self.filter_params, world.free, rng)
        self.quality_model = quality.load(self.filter_params.quality_model, mode)
        self.search: GlobalSearch | None = None  # a global start's search, until its handover
        self.rivals: Rivals | None = None  # the hypotheses kept beside the track, while tracking
        self._last_time = None
        self._lost_at = None  # timestamp the track was last declared lost
        # after a loss with rivals: checks in a row the track has led every rival by
        # ``filter.rivals.margin`` (None: no doubt; ``rivals.doubt_after``)
        self._doubt: int | None = None
        # since a search's handover, until confirmed (``global_search.confirm_within``):
        # [frames since it, frames in a row reported ``tracking``]; None: nothing to confirm
        self._unconfirmed: list[int] | None = None

    @property
    def global_likelihood(self) -> EdgeLikelihood:
        """The global phase's likelihood: thinned samples (``filter.global_thin``) and
        ``filter.global_likelihood`` settings; the tracking one when neither is set."""
        fp = self.filter_params
        if not (fp.global_likelihood or fp.global_thin > 1):
            return self.likelihood
        if self._global_likelihood is None:
            coarse = self.model.thin(fp.global_thin)
            gp = fp.global_likelihood_config(self.likelihood.params)
            self._global_likelihood = EdgeLikelihood(coarse.samples, self.camera, gp,
                                                     coarse.visibility, coarse.pairs)
        return self._global_likelihood

    def reset(self, start: np.ndarray | StartHint | None = None) -> None:
        """Start tracking around ``start`` or globally: with None over the whole free space,
        with a ``StartHint`` inside it (the global search, or the filter's uniform set:
        ``_start_search``; status ``ambiguous`` until a hypothesis dominates).

        Args:
            start: (4,) x, y, z (metres), yaw (radians), or (4, 4) world_from_body (its
                heading taken; roll and pitch ignored), or a ``StartHint``, or None.
        """
        self.search = self.rivals = None
        if start is None or isinstance(start, StartHint):
            if not self._start_search(start):
                self.filter.init_global(start)
        else:
            self.filter.init_tracking(start_pose(start, "reset(start)"))
            self._keep_rivals(None)
        self._last_time = self._lost_at = self._doubt = self._unconfirmed = None

    def step(self, image: np.ndarray | EdgeFrame | None, odometry_increment: np.ndarray | None,
             attitude: np.ndarray | None, timestamp: float,
             labels: np.ndarray | None = None) -> Estimate:
        """One frame: move by the odometry, weigh by the edges, resample; the estimate.

        Args:
            image: (H, W, 3) uint8 RGB of the camera's size, or an ``EdgeFrame`` of the shared
                front end (``FrontEnd.frame``), or None for a source that reads no image
                (``TrueLabels``).
            odometry_increment: (4,) forward, left, up (metres), yaw change (radians) since
                the previous frame, in that frame's heading frame
                (``core.poses.odometry_increment``); None on the first frame.
            attitude: (4, 4) world_from_body (or its (3, 3) rotation) from the IMU/odometry at
                this frame; only its roll and pitch are used (``tilt_from_pose``); None: level.
            timestamp: seconds; not before the previous frame's.
            labels: (H, W) uint8 true class ids for sources that read them (``oracle``); with
                an ``EdgeFrame``, give them to ``FrontEnd.frame`` instead.

        Returns:
            The estimate, computed before resampling.
        """
        if len(self.filter.particles) == 0 and self.search is None:
            raise RuntimeError("Localizer.step before reset(): call reset(start) for tracking "
                               "or reset(None) for a global start")
        timestamp = float(timestamp)
        delta = _check_increment(odometry_increment)
        time_scale = self._time_scale(timestamp)
        tilt = None if attitude is None else _tilt(attitude)
        frame = self._frame(image, labels)
        if self.search is not None:
            return self._search_step(frame, delta, tilt, timestamp, time_scale)
        loglik, obs_ms = self._log_likelihood(frame, tilt)
        t0 = time.perf_counter()
        with _BLAS.limit(limits=1, user_api="blas"):  # tiny GEMMs: threads only hurt
            if delta is not None:
                self.filter.predict(delta, time_scale)
            info = self.filter.update(loglik) if loglik is not None else self.filter.coast()
            gate_lost = info.status == "lost"  # the fit gate's loss (filter.lost_frames)
            if not gate_lost:
                info = self._check_rivals(info, frame, delta, tilt, time_scale, loglik, timestamp)
        filter_ms = (time.perf_counter() - t0) * 1e3
        if gate_lost:
            self._doubt = None if self.rivals is None else 0
            self.rivals = None
            if not self._start_search():  # the one re-localization
                self.filter.relocalize_uniform(info.estimate)
        self._log_events(info.status, timestamp, gate_lost)
        self._last_time = timestamp
        timing = {"segmentation": frame.timing_ms["segmentation"],
                  "preprocessing": frame.timing_ms["edges"] + obs_ms, "filter": filter_ms}
        return self._confirmed(self._rated(Estimate(
            timestamp, info.estimate, pose_from_xyzyaw(info.estimate)[0], info.position_std,
            info.yaw_std, info.ess, info.num_particles, info.best_score, info.injected,
            info.status, info.confidence, info.tilt, timing, info.hypotheses), search=False))

    def _confirmed(self, est: Estimate) -> Estimate:
        """``est`` after the check of a handover not yet confirmed
        (``global_search.confirm_within``): status ``lost`` and a fresh search when the track
        has not been reported ``tracking`` for ``filter.dominant_frames`` frames in a row
        within that many frames of the handover."""
        u = self._unconfirmed
        if u is None or self.search is not None:
            return est
        if est.status == "lost":
            self._unconfirmed = None
            return est
        u[0] += 1
        u[1] = u[1] + 1 if est.status == "tracking" else 0
        if u[1] >= self.filter_params.dominant_frames:
            self._unconfirmed = None
        elif u[0] >= self.filter_params.global_search.confirm_within:
            log.warning("t = %.2f s: the place the search handed over was not confirmed within "
                        "%d frames: searching again", est.timestamp, u[0])
            self._unconfirmed = None
            self.rivals = None
            if self._start_search():
                self._lost_at = est.timestamp
                return replace(est, status="lost", confidence=0.0)
        return est

    def _rated(self, est: Estimate, search: bool) -> Estimate:
        """``est`` with its ``quality`` (``self.quality_model`` of its inputs; NaN without a
        model) and, where the filter says ``tracking`` but the quality is below
        ``filter.tracking_quality``, the status ``ambiguous``."""
        h = est.hypotheses
        x = quality.inputs(search, est.status, [v.mass for v in h], est.position_std,
                           h[0].position_std if h else float("nan"), est.yaw_std,
                           est.confidence, est.best_score, est.ess, est.num_particles)
        if self.quality_model is None:
            return replace(est, quality_inputs=tuple(x.tolist()))
        q = float(self.quality_model(x)[0])
        status = est.status
        if status == "tracking" and q < self.filter_params.tracking_quality:
            status = "ambiguous"
        return replace(est, status=status, quality=q, quality_inputs=tuple(x.tolist()))

    def predict(self, odometry_increment: np.ndarray, timestamp: float) -> None:
        """Move by the odometry of a frame that is not weighed (the live node's frames it has
        no time to process): the particles, or the global search's poses, move by the
        increment with the noise of the time since the previous frame
        (``particle_filter.noise_scale``); no image is read and nothing is estimated. Moving
        at every frame and weighing some of them spreads the particles as stepping at every
        frame does.

        Args:
            odometry_increment: (4,) forward, left, up (metres), yaw change (radians) since the
                previous frame (``core.poses.odometry_increment``).
            timestamp: seconds, this frame's; not before the previous frame's.
        """
        if len(self.filter.particles) == 0 and self.search is None:
            raise RuntimeError("Localizer.predict before reset(): call reset(start) first")
        timestamp = float(timestamp)
        delta = _check_increment(odometry_increment)
        if delta is None:
            raise ValueError("Localizer.predict needs an odometry increment (4,), got None")
        time_scale = self._time_scale(timestamp)
        with _BLAS.limit(limits=1, user_api="blas"):
            if self.search is not None:
                self.search.predict(delta, time_scale)
            else:
                self.filter.predict(delta, time_scale)
                if self.rivals is not None:
                    self.rivals.predict(delta, time_scale)
        self._last_time = timestamp

    def _time_scale(self, timestamp: float) -> float:
        """The motion noise's factor for a move from the previous frame to ``timestamp``
        (``particle_filter.noise_scale``; 1 with no previous frame); ValueError for a
        timestamp before the previous frame's."""
        last = self._last_time
        if last is not None and timestamp < last:
            raise ValueError(f"timestamp {timestamp} is before the previous frame's {last}; "
                             "frames must come in time order")
        return noise_scale(None if last is None else timestamp - last,
                           self.filter_params.motion_period_s)

    def _start_search(self, hint: StartHint | None = None) -> bool:
        """Start a global search (``filter.global_method: table``, a label mode, no likelihood
        override), inside ``hint`` (its ``log_prior``) if given; False when the uniform
        particle set serves instead (also where the search cannot run on this building:
        ``start_search`` warns once and returns None)."""
        fp = self.filter_params
        if (fp.global_method != "table" or self.front_end.mode == "none"
                or self.likelihood_override is not None):
            return False
        self.search = start_search(self.world, self.camera, fp.global_search, self.filter.rng,
                                   None if hint is None else hint.log_prior)
        return self.search is not None

    def _keep_rivals(self, search: GlobalSearch | None) -> None:
        """Keep rival hypotheses beside the track (``filter.rivals``, ``search.rivals``): the
        global start's ``search`` after its handover, or a fresh one (None: a start at a known
        pose), with a random stream of their own (the track's draws are the same with and
        without them); none where the search does not run (``_start_search``'s conditions)."""
        fp = self.filter_params
        self.rivals = None
        if (not fp.rivals.enabled or fp.global_method != "table"
                or self.front_end.mode == "none" or self.likelihood_override is not None):
            return
        rng = own_stream(self.filter.rng)
        if search is None:
            search = start_search(self.world, self.camera, fp.global_search, rng)
            if search is None:
                return
        self.rivals = Rivals(search, fp.rivals, rng)

    def _check_rivals(self, info, frame: EdgeFrame, delta: np.ndarray | None,
                      tilt: np.ndarray | None, time_scale: float,
                      loglik: LogLikelihood | None, timestamp: float):
        """``info`` after this frame's check of the rivals (``Rivals.check``): status ``lost``
        when one outweighed the track, the background search then re-localizing (``ambiguous``
        until one place dominates it: ``Rivals.hand_over``). After a loss (a rival's or the
        fit gate's) ``tracking`` is reported as ``ambiguous`` until the track has led every
        rival by ``margin`` at ``checks`` checks in a row (``rivals.doubt_after``)."""
        rivals, rp = self.rivals, self.filter_params.rivals
        if rivals is None:
            return info
        rivals.predict(delta, time_scale)
        chk = rivals.check(frame.labels, tilt, self.filter.particles, self.filter.logw, loglik)
        self._doubt = doubt_after(self._doubt, chk, rp)
        if chk is not None and chk.lost:
            log.warning("t = %.2f s: a hypothesis %.1f m away outweighs the track "
                        "(log-likelihood %.1f against %.1f for %d checks): track lost, "
                        "re-localizing with the background search", timestamp,
                        float(np.hypot(*(chk.rival_state[:2] - info.estimate[:2]))),
                        chk.rival, chk.track, rp.checks)
            self.search, self.rivals = rivals.hand_over(), None
            return replace(info, status="lost", confidence=0.0)
        if self._doubt is not None and info.status == "tracking":
            return replace(info, status="ambiguous")
        return info

    def _search_step(self, frame: EdgeFrame, delta: np.ndarray | None, tilt: np.ndarray | None,
                     timestamp: float, time_scale: float) -> Estimate:
        """A frame of the global search; on its convergence the tracking filter takes over
        from the hypotheses of the places that held the mass (status ``ambiguous`` until then,
        and after a handover of several places until one dominates the filter; the hypotheses
        the search's heaviest clusters, the estimate the heaviest one's pose, the spreads the
        whole set's)."""
        t0 = time.perf_counter()
        search = self.search
        with _BLAS.limit(limits=1, user_api="blas"):
            if delta is not None:
                search.predict(delta, time_scale)
            if frame.labels is not None:
                search.update(frame.labels, tilt)
            _, pos_std, yaw_std = search.estimate()
            n = len(search.logw)
            hyps = search.clusters(self.filter_params.hypotheses)
            state = hyps[0].state  # the heaviest place
            if search.converged:
                self.filter.init_particles(search.sample(self.filter_params.num_particles),
                                           dominant=search.places == 1)
                self.search = None
                self._keep_rivals(search)
                if self.rivals is None:
                    self._doubt = None
                if self.filter_params.global_search.confirm_within > 0:
                    self._unconfirmed = [0, 0]
        filter_ms = (time.perf_counter() - t0) * 1e3
        self._last_time = timestamp
        timing = {"segmentation": frame.timing_ms["segmentation"],
                  "preprocessing": frame.timing_ms["edges"], "filter": filter_ms}
        return self._rated(Estimate(timestamp, state, pose_from_xyzyaw(state)[0], pos_std,
                                    yaw_std, float("nan"), n, float("nan"), 0, "ambiguous", 0.0,
                                    np.zeros(2), timing, hyps), search=True)

    def _log_events(self, status: str, timestamp: float, gate_lost: bool) -> None:
        """Log a loss (``gate_lost``: the fit gate's; a rival's is logged where found) and the
        re-localization that follows it."""
        if status == "lost":
            self._lost_at = timestamp
            if gate_lost:
                log.warning("t = %.2f s: track lost (%d frames fit no particle); "
                            "re-localizing over the free space", timestamp,
                            self.filter_params.lost_frames)
        elif status == "tracking" and self._lost_at is not None:
            log.warning("t = %.2f s: re-localized, %.1f s after the loss", timestamp,
                        timestamp - self._lost_at)
            self._lost_at = None

    def _frame(self, image, labels) -> EdgeFrame:
        """The frame of ``image``: itself if already a EdgeFrame, else made by the front end."""
        if isinstance(image, EdgeFrame):
            if labels is not None:
                raise ValueError("step(EdgeFrame, labels=...): the frame is made already; pass the "
                                 "labels to FrontEnd.frame(image, labels)")
            frame = image
        else:
            frame = self.front_end.frame(image, labels)
        shape = frame.edge.edges.shape
        if shape != (self.camera.height, self.camera.width):
            raise ValueError(f"frame {shape[1]}x{shape[0]} does not match the camera "
                             f"{self.camera.width}x{self.camera.height}; give frames of the "
                             "camera's size (or the Localizer the camera of the frames)")
        return frame

    def _log_likelihood(self, frame: EdgeFrame, tilt: np.ndarray | None
                        ) -> tuple[LogLikelihood | None, float]:
        """The likelihood of this step (override, global phase or tracking) over the frame,
        or None when the frame shows nothing to weigh by (``MIN_EDGE_FRACTION``,
        ``MAX_CHANCE``); and the ms its score maps took."""
        if self.likelihood_override is not None:
            override = self.likelihood_override(frame.edge, tilt)
            return (lambda states, corrections: override(states)), 0.0
        lik = self.global_likelihood if self.filter.in_global_phase else self.likelihood
        obs, ms = frame.observation(lik)
        edge = frame.edge
        known = max(int(np.count_nonzero(edge.known)), 1)
        if (np.count_nonzero(edge.edges & edge.known) < MIN_EDGE_FRACTION * known
                or obs.chance > MAX_CHANCE):
            return None, ms
        corrected = any(self.filter_params.tilt_std)

        def loglik(states: np.ndarray, corrections: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
            # the global phase's set carries no corrections yet: one shared tilt serves it
            t = corrected_tilts(tilt, corrections) if corrected and corrections.any() else tilt
            return lik.log_likelihood(states, obs, t)

        return loglik, ms


def _check_increment(delta) -> np.ndarray | None:
    """The odometry increment as (4,) float64, or None; raises naming the shape received."""
    if delta is None:
        return None
    d = np.asarray(delta, dtype=np.float64)
    if d.shape != (4,) or not np.isfinite(d).all():
        raise ValueError(f"odometry_increment must be (4,) finite forward, left, up, yaw "
                         f"change (core.poses.odometry_increment) or None, got {d.shape}")
    return d


def _tilt(attitude) -> np.ndarray:
    """(3, 3) roll and pitch of a (4, 4) or (3, 3) world_from_body."""
    a = np.asarray(attitude, dtype=np.float64)
    if a.shape not in ((4, 4), (3, 3)) or not np.isfinite(a).all():
        raise ValueError(f"attitude must be a (4, 4) world_from_body or its (3, 3) rotation "
                         f"(roll and pitch from the IMU), got {a.shape}")
    return tilt_from_pose(a)
