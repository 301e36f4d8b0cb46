"""The live localizer: camera frames and odometry as they come, one ``Localizer`` step per
newest frame, free of any middleware (``localize.ros2.node`` feeds it from ROS topics).

Start-up (``load_context``) opens the map (a dataset's, or a building file's: ``world=FILE``),
samples the model edges, loads or builds the visibility grid (cached under
``<out_root>/<name>/cache/``, shared with offline runs of that name) and loads the SegNet (mode
cnn). The first CameraInfo gives the camera: frames are undistorted and rescaled to the
dataset's camera (with ``world=FILE``: the SegNet's input size) as recordings are
(``localize.recordings.recording.delivered_camera``) and the ``Localizer`` is made for it.

Per frame (``LiveLocalizer.image`` on the receiving thread, ``step_once`` on the worker):
the frame goes into a single slot (``sync.LatestSlot``; a frame not taken yet is replaced and
counted as superseded); the worker takes the newest one, drops it when it is older than
``realtime.max_age_s`` (stale) or the odometry does not reach its stamp within
``realtime.odometry_wait_s``, decodes and rectifies it, steps the filter with the odometry
interpolated at its capture time (``sync.OdometryBuffer``) and hands an ``Output`` stamped with
that capture time to ``publish``; the capture-to-publish latency is measured when ``publish``
returns. A frame dropped after the first CameraInfo (superseded, stale, undecodable, or whose
odometry came late) still moves the filter: before its next step the worker moves the
particles by the odometry at each such frame's capture time (``Localizer.predict``, counted
``predicted``), so every frame's motion is predicted with the noise of its own time span and
only the frames processed weigh. Re-localizations (``request_reset``: an initial pose or a
global start; a track declared lost) increment the autopilot link's reset counter.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from omegaconf import DictConfig

from core.config import typed
from core.frames import FrameSource
from core.poses import odometry_increment
from localize.context import Context, open_map, report_folder
from localize.edge_model import EdgeModel
from localize.filter.start_hint import StartHint, start_of_settings
from localize.frontend.segmenter import load_segmenter, model_path, runtime_model
from localize.live.mavlink import MavlinkSender, quality_of
from localize.live.sync import LatencyWindow, LatestSlot, OdometryBuffer, Throttle
from localize.localizer import Estimate, Localizer, start_pose
from localize.recordings.recording import Rectifier, SourceCamera, check_rigid, delivered_camera
from localize.ros2.config import Ros2Config
from localize.ros2.convert import (
    hypotheses_covariance,
    live_status,
    particle_covariance,
    shown_particles,
    world_from_body,
)
from localize.viewers.viz import open_viewer
from localize.world_file import frames_target, segnet_size

log = logging.getLogger(__name__)

#: Particles an ``Output`` carries for display at most.
SHOWN_PARTICLES = 200


def load_context(cfg: DictConfig) -> Context:
    """The map (the dataset's, or ``world.path``'s: ``context.open_map``), typed settings, model
    edges (visibility cached under ``<out_root>/<name>/cache``; those of ``cfg.mode`` made
    here, as they take seconds on a large building) and, in mode cnn, the SegNet of ``cfg``.
    The context's camera is what the frames are delivered as: the dataset's, or with
    ``world.path`` the SegNet's input size with the mount ``body_from_cam`` (null: the forward
    camera, with a warning), its K from the first CameraInfo (``world_file.frames_target``)."""
    settings = typed(Ros2Config, cfg, "ros2 config")
    dataset, world, classes, digest = open_map(cfg)
    if dataset is None:
        camera = frames_target(segnet_size(model_path(cfg.onnx_model, cfg.dataset)))
    else:
        camera = dataset.camera
    out_dir = report_folder(cfg)
    model = EdgeModel.build(world, settings, out_dir / "cache")
    segmenter = None
    if cfg.mode == "cnn":
        segmenter = load_segmenter(runtime_model(cfg.onnx_model, cfg.dataset,
                                                 cfg.segnet_int8), classes,
                                   int(cfg.threads))
    ctx = Context(cfg, dataset, camera, world, settings, model, out_dir, segmenter,
                  world_digest=digest)
    ctx.model_for(cfg.mode)
    return ctx


@dataclass(frozen=True)
class Output:
    """What one frame publishes.

    Attributes:
        stamp: the frame's capture time, seconds (the stamp of every output).
        estimate: the filter's estimate.
        pose: (4, 4) map world_from_body (the odometry's roll and pitch, corrected).
        covariance: (6, 6) over x, y, z, roll, pitch, yaw (``convert.particle_covariance``; in
            a global search's frames ``convert.hypotheses_covariance``).
        particles: (K, 4) x, y, z, yaw, at most ``SHOWN_PARTICLES`` (of the search's poses in
            a global search's frames).
        status: ``tracking``, ``ambiguous`` or ``lost`` (``convert.live_status``).
        image: (H, W, 3) uint8 the delivered frame.
        labels: (H, W) uint8 the SegNet's labels, or None (mode none).
    """

    stamp: float
    estimate: Estimate
    pose: np.ndarray
    covariance: np.ndarray
    particles: np.ndarray
    status: str
    image: np.ndarray
    labels: np.ndarray | None


@dataclass
class Counts:
    """Frames received and what became of them."""

    received: int = 0
    processed: int = 0
    superseded: int = 0  # replaced in the slot by a newer frame
    stale: int = 0  # older than realtime.max_age_s when taken
    no_odometry: int = 0  # the odometry did not cover the capture time
    rejected: int = 0  # no CameraInfo yet, a stamp not after the previous, undecodable
    resets: int = 0  # re-localizations (initial pose, global start, track lost)
    #: dropped frames whose odometry moved the particles without weighing them
    predicted: int = 0
    #: messages dropped by their callback: an odometry or initial pose that is not a finite
    #: pose, an odometry stamp not after the previous one, a CameraInfo that cannot be used
    messages_rejected: int = 0

    @property
    def dropped(self) -> int:
        return self.superseded + self.stale + self.no_odometry + self.rejected


@dataclass
class _Pending:
    stamp: float
    decode: Callable[[], np.ndarray]
    where: str


@dataclass
class LiveLocalizer:
    """One ``Localizer`` fed by a live camera and odometry (module docstring).

    Args:
        cfg: the node's config (``localize.ros2.config.Ros2Config``).
        ctx: ``load_context(cfg)``.
        publish: called with each frame's ``Output`` on the worker thread.
        report: called on the worker thread with each frame's ``Output`` once its pose is
            published and its latency counted (the node publishes the particles and the status
            there); None: nothing.
        clock: the capture stamps' clock, seconds (the system clock, as ROS stamps).
    """

    cfg: DictConfig
    ctx: Context
    publish: Callable[[Output], None]
    report: Callable[[Output], None] | None = None
    clock: Callable[[], float] = time.time
    counts: Counts = field(default_factory=Counts)
    latency: LatencyWindow = field(default_factory=LatencyWindow)

    def __post_init__(self):
        self.settings: Ros2Config = typed(Ros2Config, self.cfg, "ros2 config")
        rt = self.settings.realtime
        self.odometry_buffer = OdometryBuffer(rt.odometry_keep_s)
        self.slot = LatestSlot()
        self.warn = Throttle()
        self.localizer: Localizer | None = None
        self.rectifier: Rectifier | None = None
        self.source_camera: SourceCamera | None = None
        self.last_latency = float("nan")
        #: the last frame's latency in parts, ms: capture to taken by the worker (transport
        #: and the slot), the odometry wait, decoding and rectifying, the step, publishing
        self.last_split: dict[str, float] = {}
        self.last_output: Output | None = None
        self._lock = threading.Lock()
        self._reset: tuple[bool, np.ndarray | None] | None = None
        self._last_stamp = -np.inf
        self._last_odometry: np.ndarray | None = None
        #: capture times of the frames dropped since the last step (moved through before it)
        self._passed: list[float] = []
        self._moved_to = -np.inf  # the last capture time the filter moved to
        self._last_status = ""
        self._front = self.ctx.front_end(self.cfg.mode)
        # made here, not in ``camera_info``: the receiving thread must not stop for seconds
        self._model = self.ctx.model_for(self.cfg.mode)
        self._rng = np.random.default_rng(int(self.cfg.seed))  # the filter's alone
        self._display_rng = np.random.default_rng([int(self.cfg.seed), 1])
        s = self.settings  # the start is this config's (the context may be shared)
        self._start = start_of_settings(s.hint, self.ctx.world.info, self.ctx.world.free,
                                        s.filter.init_std)
        self._worker: threading.Thread | None = None
        self._stop = threading.Event()
        self.mavlink = (MavlinkSender(str(self.cfg.mavlink), float(self.cfg.mavlink_rate_hz),
                                      clock=self.clock) if self.cfg.mavlink else None)
        self.viewer = open_viewer(str(self.cfg.viz), self.ctx.world,
                                  self.ctx.out_dir / "live.rrd", connect=self.cfg.viz_connect)

    # --- inputs (any thread) -----------------------------------------------------------

    def camera_info(self, source: SourceCamera, where: str) -> None:
        """The camera (a CameraInfo): the first makes the localizer; a later different one is
        ignored with a warning."""
        with self._lock:
            if self.localizer is not None:
                if not _same_camera(source, self.source_camera) and self.warn("camera_info"):
                    log.warning("%s: the CameraInfo changed (%dx%d, K %s); the first one is "
                                "kept: restart the node for a new calibration", where,
                                source.width, source.height, source.K.ravel().tolist())
                return
            mount = self.settings.body_from_cam
            mount = None if mount is None else check_rigid(np.asarray(mount), "body_from_cam")
            camera, rect = delivered_camera(source, self.ctx.camera, mount, where)
            loc = Localizer(self.ctx.world, camera, self._front, self.ctx.settings, self._rng,
                            model=self._model)
            loc.reset(self._start)
            self.localizer, self.rectifier, self.source_camera = loc, rect, source
        log.info("camera %dx%d from %s, frames delivered at %dx%d; %s", source.width,
                 source.height, where, camera.width, camera.height,
                 "global start" if self._start is None else
                 f"search inside {self._start}" if isinstance(self._start, StartHint) else
                 f"tracking from {self._start}")

    def odometry(self, stamp: float, pose: np.ndarray, where: str) -> None:
        """An odometry sample (world_from_body in the odometry's frame); one the buffer
        refuses is counted in ``messages_rejected``."""
        why = self.odometry_buffer.add(stamp, pose)
        if why:
            self.counts.messages_rejected += 1
            if self.warn(f"odometry {why[:20]}"):
                log.warning("%s: %s", where, why)

    def reject_message(self, where: str, err: Exception) -> None:
        """A message whose callback failed with ``err`` (on topic ``where``): counted in
        ``messages_rejected`` and logged, at most once per 5 s per topic (with the traceback
        unless ``err`` is a ValueError, which says what is wrong with the message)."""
        self.counts.messages_rejected += 1
        if self.warn(f"message {where}"):
            why = str(err) if str(err).startswith(where) else f"{where}: message dropped: {err}"
            log.warning("%s", why, exc_info=not isinstance(err, ValueError))

    def image(self, stamp: float, decode: Callable[[], np.ndarray], where: str) -> None:
        """A frame captured at ``stamp``; ``decode()`` gives its (h, w, 3) uint8 RGB (called
        on the worker, only for the frame processed)."""
        self.counts.received += 1
        if self.localizer is None:
            self.counts.rejected += 1
            if self.warn("no camera_info"):
                log.warning("%s: frame dropped: no CameraInfo received yet on %s (the node "
                            "needs the camera's calibration first)", where,
                            self.settings.topics.camera_info)
            return
        if stamp <= self._last_stamp:
            self.counts.rejected += 1
            if self.warn("image stamp"):
                log.warning("%s: frame dropped: its stamp %.6f s is not after the previous "
                            "frame's %.6f s", where, stamp, self._last_stamp)
            return
        self._last_stamp = stamp
        replaced = self.slot.put(_Pending(stamp, decode, where))
        if replaced is not None:
            self.counts.superseded += 1
            self._pass(replaced.stamp)

    def request_reset(self, start: np.ndarray | StartHint | None) -> None:
        """Re-localize: track from ``start`` ((4,) x, y, z, yaw, or a (4, 4) map pose), search
        inside a ``StartHint``, or, None, globally; applied before the next frame. ValueError
        for a pose that is not a finite (4,) or (4, 4) (nothing changes then)."""
        if start is not None and not isinstance(start, StartHint):
            try:
                start = start_pose(start, "re-localization")
            except ValueError:
                raise ValueError(f"re-localization from {np.asarray(start).tolist()} refused: "
                                 "give a finite (4,) x, y, z, yaw or (4, 4) map pose; the "
                                 "current state is kept") from None
        with self._lock:
            self._reset = (True, start)

    # --- the worker --------------------------------------------------------------------

    def start(self) -> None:
        """Start the worker thread (again after ``pause``: with an empty slot)."""
        if self._worker is not None:
            return
        self._stop = threading.Event()
        self.slot = LatestSlot()
        self._worker = threading.Thread(target=self._work, args=(self._stop,),
                                        name="edgeloc-worker", daemon=True)
        self._worker.start()

    def pause(self) -> None:
        """Stop the worker thread after its frame in progress; the filter keeps its state."""
        self._stop.set()
        self.slot.close()
        if self._worker is not None:
            self._worker.join(timeout=10.0)
            self._worker = None

    def stop(self) -> None:
        """Stop the worker; close the autopilot link and the viewer."""
        self.pause()
        for sink in (self.mavlink, self.viewer):
            if sink is not None:
                sink.close()

    def _work(self, stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                self.step_once(0.2)
            except Exception:  # a bug must not stop a flying drone's localizer silently
                log.exception("frame failed; the node goes on with the next frame")

    def step_once(self, timeout_s: float) -> Output | None:
        """Take the newest frame (waiting up to ``timeout_s``), step the filter and publish;
        None when no frame came or it was dropped."""
        item = self.slot.take(timeout_s)
        if item is None:
            return None
        self._apply_reset()
        taken = self.clock()
        age = taken - item.stamp
        rt = self.settings.realtime
        if age > rt.max_age_s:
            self.counts.stale += 1
            self._pass(item.stamp)
            if self.warn("stale"):
                log.warning("%s: frame dropped: %.3f s old when taken (realtime.max_age_s = "
                            "%.3f s; is the stamp the capture time, on this machine's clock?)",
                            item.where, age, rt.max_age_s)
            return None
        attitude, why = self.odometry_buffer.wait_for(item.stamp, rt.odometry_wait_s)
        if attitude is None:
            self.counts.no_odometry += 1
            self._pass(item.stamp)
            if self.warn("odometry"):
                log.warning("%s: frame dropped: %s (topic %s)", item.where, why,
                            self.settings.topics.odometry)
            return None
        try:
            image = self.rectifier(self._checked_size(item.decode(), item.where))
        except ValueError as err:
            self.counts.rejected += 1
            self._pass(item.stamp)
            if self.warn(f"decode {str(err)[-40:]}"):
                log.warning("frame dropped: %s", err)
            return None
        self._move_through(item.stamp)
        stepped_at = self.clock()
        out = self._step(item.stamp, image, attitude)
        published_at = self.clock()
        self.publish(out)
        done = self.clock()
        self.last_latency = done - item.stamp
        self.last_split = {"wait_ms": 1e3 * age, "prepare_ms": 1e3 * (stepped_at - taken),
                           "step_ms": 1e3 * (published_at - stepped_at),
                           "publish_ms": 1e3 * (done - published_at)}
        self.latency.add(self.last_latency)
        self.counts.processed += 1
        if self.report is not None:
            self.report(out)
        if self.mavlink is not None and out.status in ("tracking", "ambiguous"):
            self.mavlink.send(out.stamp, out.pose, out.covariance,
                              quality_of(out.estimate.confidence, out.status))
        if self.viewer is not None:
            self.viewer.log_step(out.stamp, out.image, out.labels, out.estimate, out.particles)
        return out

    def _checked_size(self, image: np.ndarray, where: str) -> np.ndarray:
        """The decoded frame, if it has the CameraInfo's size (ValueError naming both)."""
        cam = self.source_camera
        if image.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"{where}: the image is {image.shape[1]}x{image.shape[0]}, the "
                             f"CameraInfo ({self.settings.topics.camera_info}) says "
                             f"{cam.width}x{cam.height}; publish the calibration of this "
                             "camera at this resolution")
        return image

    def _pass(self, stamp: float) -> None:
        """A frame dropped at capture time ``stamp``: its odometry moves the filter before
        the next step (``_move_through``)."""
        with self._lock:
            self._passed.append(stamp)

    def _move_through(self, stamp: float) -> None:
        """Move the filter by the odometry at each dropped frame's capture time before
        ``stamp`` (``Localizer.predict``; a frame the kept odometry does not cover is skipped,
        its motion joins the next increment)."""
        with self._lock:
            passed, self._passed = sorted(self._passed), []
        for t in passed:
            if not self._moved_to < t < stamp:
                continue
            pose = self.odometry_buffer.at(t)
            if pose is None:
                continue
            if self._last_odometry is not None:
                self.localizer.predict(odometry_increment(self._last_odometry, pose), t)
                self.counts.predicted += 1
            self._last_odometry, self._moved_to = pose, t

    def _apply_reset(self) -> None:
        with self._lock:
            reset, self._reset = self._reset, None
            if reset is not None:
                self._passed = []  # frames before the re-localization do not move its start
        if reset is None or self.localizer is None:
            if reset is not None:
                self._start = reset[1]
            return
        self.localizer.reset(reset[1])
        self._last_odometry = None
        why = ("global start" if reset[1] is None else
               "initial pose search" if isinstance(reset[1], StartHint) else "initial pose")
        self._relocalized(why)

    def _relocalized(self, why: str) -> None:
        self.counts.resets += 1
        log.info("re-localization (%s): reset counter %d", why, self.counts.resets)
        if self.mavlink is not None:
            self.mavlink.reset()

    def _step(self, stamp: float, image: np.ndarray, attitude: np.ndarray) -> Output:
        loc = self.localizer
        inc = (None if self._last_odometry is None
               else odometry_increment(self._last_odometry, attitude))
        self._last_odometry, self._moved_to = attitude, stamp
        frame = self._front.frame(image, None)
        search = loc.search  # a global search steps this frame, not the particle filter
        est = loc.step(frame, inc, attitude, stamp)
        if est.status == "lost" and self._last_status != "lost":
            self._relocalized("track lost")
        self._last_status = est.status
        if search is not None:
            covariance = hypotheses_covariance(est)
            poses = search.states
        else:
            f = loc.filter
            covariance = particle_covariance(f.particles, f.logw, f.tilt, est.state)
            poses = f.particles
        out = Output(stamp, est, world_from_body(est, attitude), covariance,
                     shown_particles(poses, SHOWN_PARTICLES, self._display_rng),
                     live_status(est, self.settings.realtime.ambiguous_std_m), image,
                     frame.labels)
        self.last_output = out
        return out

    # --- the status --------------------------------------------------------------------

    def status(self) -> tuple[str, dict[str, str]]:
        """(status, values): ``waiting`` before the first frame's estimate, else the last
        output's status; the values the status message carries."""
        c, out = self.counts, self.last_output
        values = {"frames_received": c.received, "frames_processed": c.processed,
                  "frames_dropped": c.dropped, "dropped_superseded": c.superseded,
                  "dropped_stale": c.stale, "dropped_no_odometry": c.no_odometry,
                  "frames_rejected": c.rejected, "frames_predicted": c.predicted,
                  "messages_rejected": c.messages_rejected,
                  "reset_counter": c.resets,
                  "latency_ms": 1e3 * self.last_latency,
                  "latency_median_ms": 1e3 * self.latency.percentile(50),
                  "latency_p95_ms": 1e3 * self.latency.percentile(95)}
        if out is None:
            status = "waiting"
            values["waiting_for"] = ("CameraInfo" if self.localizer is None else "frames")
        else:
            status = out.status
            e = out.estimate
            values.update(filter_status=e.status, quality=e.quality,
                          confidence=e.confidence, position_std_m=e.position_std,
                          yaw_std_deg=np.degrees(e.yaw_std), hypotheses=len(e.hypotheses),
                          hypothesis_masses=" ".join(f"{h.mass:.3f}" for h in e.hypotheses),
                          **self.last_split)
        return status, {k: _text(v) for k, v in values.items()}


def _text(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _same_camera(a: SourceCamera, b: SourceCamera | None) -> bool:
    return (b is not None and (a.width, a.height) == (b.width, b.height)
            and np.allclose(a.K, b.K) and np.allclose(np.resize(a.distortion, 8),
                                                      np.resize(b.distortion, 8)))



def offline_estimates(ctx: Context, cfg: DictConfig, source: FrameSource,
                      limit: int | None = None, stamps: np.ndarray | None = None) -> np.ndarray:
    """The node's filter run offline over a frame source: the same settings, seed and start
    (``start``; None: a global start), every frame in order, as the live node would with
    nothing dropped; the reference of the tests and benchmarks/live.py.

    Args:
        stamps: (T,) the frames' capture times, seconds, instead of the source's (those a
            player gave them: the motion noise follows the time between frames).

    Returns:
        (T, 4) x, y, z, yaw estimates of the first ``limit`` frames (all: None).
    """
    loc = Localizer(ctx.world, ctx.camera, ctx.front_end(cfg.mode), ctx.settings,
                    np.random.default_rng(int(cfg.seed)), model=ctx.model_for(cfg.mode))
    s = ctx.settings
    loc.reset(start_of_settings(s.hint, ctx.world.info, ctx.world.free, s.filter.init_std))
    frames = source.steps(limit)
    if stamps is not None:
        frames = (f._replace(timestamp=float(t)) for f, t in zip(frames, stamps, strict=False))
    return np.stack([loc.step(f.image, f.odometry_increment, f.attitude, f.timestamp).state
                     for f in frames])
