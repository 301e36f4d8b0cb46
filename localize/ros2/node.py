"""The ROS 2 node over the live localizer (``localize.live.loop.LiveLocalizer``): a lifecycle
node (``rclpy.lifecycle``), as nav2 AMCL's and Beluga's.

Its settings are ROS parameters of the Hydra keys' names (``localize.ros2.parameters``),
read on configure. The transitions: *configure* reads the parameters, loads the dataset, the
model edges and the SegNet (``live.load_context``), makes the outputs and the services;
*activate* subscribes the inputs, starts the worker and publishes the free space and the
model's edges (latched); *deactivate* unsubscribes and stops the worker (the filter keeps its
state); *cleanup* releases what configure made; *shutdown* does what is left of both. With
``autostart`` (the default) the node configures and activates itself when made, as Beluga's;
without, a lifecycle manager (nav2's) drives it through ``~/change_state``.

Active, it subscribes the camera (sensor_msgs/Image or CompressedImage), its CameraInfo and the
odometry (nav_msgs/Odometry or geometry_msgs/PoseStamped) with the sensor QoS and
``/initialpose`` (geometry_msgs/PoseWithCovarianceStamped); it serves
``/reinitialize_global_localization`` (nav2 AMCL's) and ``/global_localization`` (ROS 1
AMCL's; std_srvs/Empty, both restart the global search); publishes per processed frame,
stamped with its capture time, in the map frame: geometry_msgs/PoseWithCovarianceStamped,
nav_msgs/Odometry (child frame ``frames.base``), a PoseArray of the particles, a PoseArray of
the pose hypotheses (heaviest first; during a global search, the places it still holds) and a
diagnostic_msgs/DiagnosticArray status with the estimate's calibrated ``quality`` (also every
``realtime.status_period_s`` while no frame comes); and, latched, the free space
(nav_msgs/OccupancyGrid) and the model's edges (visualization_msgs/MarkerArray;
``localize.ros2.world_display``). Topic names, frame ids and QoS: ``localize.ros2.config``;
docs/ros2.md.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseArray,
    PoseStamped,
    PoseWithCovarianceStamped,
    Quaternion,
)
from nav_msgs.msg import OccupancyGrid, Odometry
from omegaconf import DictConfig
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_srvs.srv import Empty
from visualization_msgs.msg import MarkerArray

from core.config import typed
from localize.context import Context
from localize.filter.start_hint import StartHint
from localize.live.loop import LiveLocalizer, Output, load_context
from localize.ros2.config import Ros2Config
from localize.ros2.convert import (
    STATUS_LEVEL,
    camera_of,
    image_of,
    initial_pose_start,
    pose_of,
    position_quaternion,
    stamp_parts,
    stamp_seconds,
    yaw_quaternions,
)
from localize.ros2.parameters import config_with, parameter_values, plain_value, same_context
from localize.ros2.world_display import edge_markers, occupancy_grid

log = logging.getLogger(__name__)

RELIABILITY = {"best_effort": ReliabilityPolicy.BEST_EFFORT,
               "reliable": ReliabilityPolicy.RELIABLE}
#: The QoS of the free space and the model's edges: reliable, transient local (latched: a
#: subscriber joining later, RViz, gets the last message).
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Parameters rclpy itself declares or reads: not settings of the node.
ROS_OWN = ("use_sim_time", "start_type_description_service", "qos_overrides.")


def qos(reliability: str, depth: int) -> QoSProfile:
    """A keep-last QoS of ``depth`` with the ``reliability`` of a ``qos.*`` setting."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(depth),
                      reliability=RELIABILITY[reliability],
                      durability=DurabilityPolicy.VOLATILE)


def set_pose(pose: Pose, T: np.ndarray) -> None:
    """Copy a (4, 4) pose into a geometry_msgs/Pose."""
    p, q = position_quaternion(T)
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        float(v) for v in q)


class LocalizerNode(LifecycleNode):
    """The lifecycle node: ROS topics in and out of a ``LiveLocalizer`` (module docstring).

    Args:
        cfg: the node's config as Hydra composed it (conf/ros2.yaml and its overrides): the
            parameters' values unless ROS gives others.
        ctx: a context loaded from ``cfg`` (``live.load_context``), used when the parameters
            leave ``cfg`` as it is; None: configure loads it.
        overrides: the Hydra command line's overrides; given, configure resolves the config
            (``localize.resolve.resolve``: ``onnx_model=auto``, the model's settings under the
            command line's and the ROS parameters'); None: ``cfg`` is used as it is.
        choices: the Hydra config groups' choices (for ``resolve``).
        context: the rclpy context (None: the default one).
        cli_args: ROS arguments of this node (``["--ros-args", "--params-file", FILE]``);
            None: the context's.

    Raises:
        ValueError: with ``autostart``, a configuration that fails (the message names the
            setting and the fix).
    """

    def __init__(self, cfg: DictConfig, ctx: Context | None = None, *,
                 overrides: Sequence[str] | None = None, choices: dict | None = None,
                 context=None, cli_args: list[str] | None = None):
        super().__init__(str(cfg.node_name), context=context, cli_args=cli_args)
        self._cfg, self._ctx = cfg, ctx
        self._overrides, self._choices = overrides, choices
        self.live: LiveLocalizer | None = None
        self.configure_error: Exception | None = None
        self.start_s = float("nan")
        self._inputs: list = []
        self._servers: list = []
        self._outputs: list = []
        self._status_timer = None
        self._status_lock = threading.Lock()
        self._last_publish = self._last_particles = 0.0
        hydra = typed(Ros2Config, cfg, "")  # configure may change them (ROS parameters)
        self.topics, self.frames = hydra.topics, hydra.frames
        self._defaults = parameter_values(cfg)
        dynamic = ParameterDescriptor(dynamic_typing=True)  # the schema checks the types
        for name, value in self._defaults.items():
            self.declare_parameter(name, value, dynamic)
        if self.get_parameter("autostart").value:
            if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                raise self.configure_error or RuntimeError("the node's configuration failed")
            self.trigger_activate()

    # --- the lifecycle -------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Read the parameters, load the context, make the outputs and the services; on an
        error, log it (``configure_error``) and stay unconfigured."""
        t0 = time.perf_counter()
        try:
            cfg = self._configured()
            ctx = (self._ctx if self._ctx is not None and same_context(self._ctx.cfg, cfg)
                   else load_context(cfg))
            self.live = LiveLocalizer(cfg, ctx, self._publish, self._publish_after)
            self._make_outputs(ctx)
        except Exception as err:  # a lifecycle manager gets FAILURE, the log says why
            self.configure_error = err
            log.error("%s: configure failed: %s", self.get_name(), err,
                      exc_info=not isinstance(err, ValueError))
            self._release()
            return TransitionCallbackReturn.FAILURE
        self.configure_error = None
        self.start_s = time.perf_counter() - t0
        log.info("node %s configured in %.1f s: camera %s (%s), %s, odometry %s; pose out on "
                 "%s", self.get_name(), self.start_s, self.topics.image,
                 self.topics.image_transport, self.topics.camera_info, self.topics.odometry,
                 self.topics.pose)
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Enable the outputs, subscribe the inputs, start the worker, publish the free space
        and the model's edges."""
        ret = super().on_activate(state)
        if ret != TransitionCallbackReturn.SUCCESS:
            return ret
        self.live.start()  # before the subscriptions: its slot takes their first frame
        self._subscribe()
        self._status_timer = self.create_timer(self.live.settings.realtime.status_period_s,
                                               self._on_timer)
        self.grid_pub.publish(self._grid)
        self.edges_pub.publish(self._edges)
        log.info("node %s active", self.get_name())
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Unsubscribe, stop the worker (the filter keeps its state), disable the outputs."""
        self._unsubscribe()
        log.info("node %s inactive", self.get_name())
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release what configure made."""
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything, from any state."""
        self._unsubscribe()
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: release everything; back to unconfigured."""
        self._unsubscribe()
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def destroy_node(self) -> None:
        """Stop and release everything; ``live`` stays for its counts and last output."""
        self._unsubscribe()
        self._release(keep_live=True)
        super().destroy_node()

    def _configured(self) -> DictConfig:
        """The Hydra config with the ROS parameters' values, resolved when ``overrides`` were
        given, checked (``Ros2Config``; ValueError naming the setting)."""
        where = f"ROS parameters of node {self.get_name()}"
        own = {n for n in self._parameter_overrides if not n.startswith(ROS_OWN)}
        values = {n: plain_value(self.get_parameter(n).value) for n in self._defaults}
        given = {n: v for n, v in values.items() if n in own or v != self._defaults[n]}
        given.update({n: plain_value(self._parameter_overrides[n].value)
                      for n in own - set(values)})
        cfg = config_with(self._cfg, given, where) if given else self._cfg
        if given:
            log.info("%s: %s", where, " ".join(f"{n}={v}" for n, v in sorted(given.items())))
        if self._overrides is not None:
            from localize.resolve import resolve

            cfg = cfg.copy()
            resolve(cfg, [*self._overrides, *(f"{n}=" for n in given)], self._choices,
                    Ros2Config, "conf/ros2.yaml")
        typed(Ros2Config, cfg, "")
        return cfg

    def _make_outputs(self, ctx: Context) -> None:
        s = self.live.settings
        self.topics, self.frames = s.topics, s.frames
        t = s.topics
        outputs = qos(s.qos.outputs, s.qos.outputs_depth)
        pub = self.create_lifecycle_publisher
        self.pose_pub = pub(PoseWithCovarianceStamped, t.pose, outputs)
        self.odometry_pub = pub(Odometry, t.odometry_out, outputs)
        self.particles_pub = pub(PoseArray, t.particles, outputs)
        self.hypotheses_pub = pub(PoseArray, t.hypotheses, outputs)
        self.status_pub = pub(DiagnosticArray, t.status, outputs)
        self.grid_pub = pub(OccupancyGrid, t.free_space, LATCHED)
        self.edges_pub = pub(MarkerArray, t.model_edges, LATCHED)
        self._outputs = [self.pose_pub, self.odometry_pub, self.particles_pub,
                         self.hypotheses_pub, self.status_pub, self.grid_pub, self.edges_pub]
        stamp = stamp_parts(time.time())
        self._grid = occupancy_grid(ctx.world.free, s.frames.map, stamp)
        self._edges = edge_markers(ctx.world, s.frames.map, stamp, s.model_edges.min_length)
        self._servers = [self.create_service(Empty, name, self._on_global_localization)
                          for name in (t.reinitialize_global_localization,
                                       t.global_localization)]

    def _subscribe(self) -> None:
        t, q = self.topics, self.live.settings.qos
        sensors = qos(q.sensors, q.sensors_depth)
        image_type = Image if t.image_transport == "raw" else CompressedImage
        odo_type = Odometry if t.odometry_type == "odometry" else PoseStamped
        sub = self.create_subscription
        self._inputs = [
            sub(image_type, t.image, self._guarded(t.image, self._on_image), sensors),
            sub(CameraInfo, t.camera_info, self._guarded(t.camera_info, self._on_camera_info),
                sensors),
            sub(odo_type, t.odometry, self._guarded(t.odometry, self._on_odometry), sensors),
            sub(PoseWithCovarianceStamped, t.initial_pose,
                self._guarded(t.initial_pose, self._on_initial_pose), qos("reliable", 1))]

    def _unsubscribe(self) -> None:
        """Undo ``on_activate``'s subscriptions, timer and worker (nothing when inactive)."""
        for sub in self._inputs:
            self.destroy_subscription(sub)
        self._inputs = []
        if self._status_timer is not None:
            self.destroy_timer(self._status_timer)
            self._status_timer = None
        if self.live is not None:
            self.live.pause()

    def _release(self, keep_live: bool = False) -> None:
        """Undo ``on_configure``: the outputs, the services, the live localizer (stopped;
        dropped unless ``keep_live``)."""
        for pub in self._outputs:
            self.destroy_lifecycle_publisher(pub)
        for srv in self._servers:
            self.destroy_service(srv)
        self._outputs, self._servers = [], []
        if self.live is not None:
            self.live.stop()
            if not keep_live:
                self.live = None

    # --- inputs --------------------------------------------------------------------------

    def _guarded(self, topic: str, callback: Callable[[object], None]
                 ) -> Callable[[object], None]:
        """``callback`` with any error it raises on a message logged and counted
        (``LiveLocalizer.reject_message``): a bad message is dropped, never raised into the
        executor, where it would stop the node."""
        def guarded(msg) -> None:
            try:
                callback(msg)
            except Exception as err:  # a bad message must not stop a flying drone's node
                self.live.reject_message(topic, err)
        return guarded

    def _on_image(self, msg) -> None:
        stamp = stamp_seconds(msg.header.stamp)
        where = f"{self.topics.image} frame at {stamp:.6f} s"
        transport = self.topics.image_transport
        self.live.image(stamp, lambda: image_of(msg, transport, where), where)

    def _on_camera_info(self, msg: CameraInfo) -> None:
        self.live.camera_info(camera_of(msg, self.topics.camera_info), self.topics.camera_info)

    def _on_odometry(self, msg) -> None:
        self.live.odometry(stamp_seconds(msg.header.stamp),
                           pose_of(msg, self.topics.odometry_type, self.topics.odometry),
                           self.topics.odometry)

    def _on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        frame = msg.header.frame_id
        if frame not in ("", self.frames.map):
            log.warning("%s: initial pose in frame %r ignored: give it in the map frame %r",
                        self.topics.initial_pose, frame, self.frames.map)
            return
        start = initial_pose_start(msg, self.live.ctx.settings.filter.init_std,
                                   self.topics.initial_pose)
        self.live.request_reset(start)
        if isinstance(start, StartHint):
            sx, sy, _, syaw = np.sqrt(np.diag(start.covariance))
            log.info("%s: searching around x %.2f, y %.2f (std %.2f, %.2f m, yaw %.0f deg)",
                     self.topics.initial_pose, *start.pose[:2], sx, sy, np.degrees(syaw))
        else:
            log.info("%s: tracking from x %.2f, y %.2f, z %.2f", self.topics.initial_pose,
                     *start[:3])

    def _on_global_localization(self, request, response):
        log.info("%s: global localization over the free space",
                 self.topics.reinitialize_global_localization)
        self.live.request_reset(None)
        return response

    # --- outputs -------------------------------------------------------------------------

    def _header(self, msg, stamp: float) -> None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_parts(stamp)
        msg.header.frame_id = self.frames.map

    def _publish(self, out: Output) -> None:
        pose = PoseWithCovarianceStamped()
        self._header(pose, out.stamp)
        set_pose(pose.pose.pose, out.pose)
        pose.pose.covariance = out.covariance.ravel().astype(np.float64)
        odo = Odometry()
        self._header(odo, out.stamp)
        odo.child_frame_id = self.frames.base
        odo.pose = pose.pose
        self.pose_pub.publish(pose)
        self.odometry_pub.publish(odo)

    def _publish_after(self, out: Output) -> None:
        """The particles (at most every ``realtime.particles_period_s``), the hypotheses and
        the status, once the pose is out (not in its latency)."""
        now = time.monotonic()
        if now - self._last_particles >= self.live.settings.realtime.particles_period_s:
            self._last_particles = now
            self.particles_pub.publish(self._pose_array(out.particles, out.stamp))
        hyps = np.array([h.state for h in out.estimate.hypotheses]).reshape(-1, 4)
        self.hypotheses_pub.publish(self._pose_array(hyps, out.stamp))
        self._publish_status(out.stamp)

    def _pose_array(self, poses: np.ndarray, stamp: float) -> PoseArray:
        """A PoseArray in the map frame of poses (N, 4) x, y, z, yaw."""
        msg = PoseArray()
        self._header(msg, stamp)
        q = yaw_quaternions(poses[:, 3])[:, 2:].tolist()
        msg.poses = [Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(z=qz, w=qw))
                     for (x, y, z, _), (qz, qw) in zip(poses.tolist(), q, strict=True)]
        return msg

    def _publish_status(self, stamp: float) -> None:
        status, values = self.live.status()
        values["start_s"] = f"{self.start_s:.2f}"
        msg = DiagnosticArray()
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_parts(stamp)
        d = DiagnosticStatus()
        d.level = bytes([STATUS_LEVEL.get(status, 1)])
        d.name = f"{self.get_name()}: localization"
        d.message = status
        d.hardware_id = self.topics.image
        d.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        msg.status = [d]
        with self._status_lock:
            self.status_pub.publish(msg)
            self._last_publish = time.monotonic()

    def _on_timer(self) -> None:
        if time.monotonic() - self._last_publish >= self.live.settings.realtime.status_period_s:
            self._publish_status(time.time())
