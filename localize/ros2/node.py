"""The ROS 2 node over the live localizer (``localize.live.loop.LiveLocalizer``).

Subscribes the camera (sensor_msgs/Image or CompressedImage), its CameraInfo and the odometry
(nav_msgs/Odometry or geometry_msgs/PoseStamped) with the sensor QoS, ``/initialpose``
(geometry_msgs/PoseWithCovarianceStamped) and serves ``/global_localization``
(std_srvs/Empty); publishes per processed frame, stamped with its capture time, in the map
frame: geometry_msgs/PoseWithCovarianceStamped, nav_msgs/Odometry (child frame
``frames.base``), a PoseArray of the particles, and a diagnostic_msgs/DiagnosticArray status
(also every ``realtime.status_period_s`` while no frame comes). Topic names, frame ids and QoS:
``localize.ros2.config``; docs/ros2.md.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

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
from nav_msgs.msg import Odometry
from omegaconf import DictConfig
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_srvs.srv import Empty

from localize.context import Context
from localize.filter.start_hint import StartHint
from localize.live.loop import LiveLocalizer, Output
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

log = logging.getLogger(__name__)

RELIABILITY = {"best_effort": ReliabilityPolicy.BEST_EFFORT,
               "reliable": ReliabilityPolicy.RELIABLE}


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


class LocalizerNode(Node):
    """The node: ROS topics in and out of a ``LiveLocalizer`` (module docstring).

    Args:
        cfg: the node's config (conf/ros2.yaml).
        ctx: the loaded context (``live.load_context``).
        start_s: seconds the start-up took (reported in the status).
        context: the rclpy context (None: the default one).
    """

    def __init__(self, cfg: DictConfig, ctx: Context, start_s: float = float("nan"),
                 context=None):
        super().__init__(str(cfg.node_name), context=context)
        self.live = LiveLocalizer(cfg, ctx, self._publish, self._publish_after)
        s = self.live.settings
        self.topics, self.frames, self.start_s = s.topics, s.frames, start_s
        t, q = s.topics, s.qos
        sensors, outputs = qos(q.sensors, q.sensors_depth), qos(q.outputs, q.outputs_depth)
        image_type = Image if t.image_transport == "raw" else CompressedImage
        self.create_subscription(image_type, t.image, self._guarded(t.image, self._on_image),
                                 sensors)
        self.create_subscription(CameraInfo, t.camera_info,
                                 self._guarded(t.camera_info, self._on_camera_info), sensors)
        odo_type = Odometry if t.odometry_type == "odometry" else PoseStamped
        self.create_subscription(odo_type, t.odometry,
                                 self._guarded(t.odometry, self._on_odometry), sensors)
        self.create_subscription(PoseWithCovarianceStamped, t.initial_pose,
                                 self._guarded(t.initial_pose, self._on_initial_pose),
                                 qos("reliable", 1))
        self.create_service(Empty, t.global_localization, self._on_global_localization)
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, t.pose, outputs)
        self.odometry_pub = self.create_publisher(Odometry, t.odometry_out, outputs)
        self.particles_pub = self.create_publisher(PoseArray, t.particles, outputs)
        self.status_pub = self.create_publisher(DiagnosticArray, t.status, outputs)
        self._status_lock = threading.Lock()
        self._last_publish = self._last_particles = 0.0
        self.create_timer(s.realtime.status_period_s, self._on_timer)
        self.live.start()
        log.info("node %s ready (start-up %.1f s): camera %s (%s), %s, odometry %s; pose out "
                 "on %s", cfg.node_name, start_s, t.image, t.image_transport, t.camera_info,
                 t.odometry, t.pose)

    def destroy_node(self) -> None:
        self.live.stop()
        super().destroy_node()

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
        log.info("%s: global localization over the free space", self.topics.global_localization)
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
        """The particles (at most every ``realtime.particles_period_s``) and the status, once
        the pose is out (not in its latency)."""
        now = time.monotonic()
        if now - self._last_particles >= self.live.settings.realtime.particles_period_s:
            self._last_particles = now
            cloud = PoseArray()
            self._header(cloud, out.stamp)
            q = yaw_quaternions(out.particles[:, 3])[:, 2:].tolist()
            cloud.poses = [Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(z=qz, w=qw))
                           for (x, y, z, _), (qz, qw) in zip(out.particles.tolist(), q,
                                                             strict=True)]
            self.particles_pub.publish(cloud)
        self._publish_status(out.stamp)

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
