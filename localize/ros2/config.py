"""The live node's settings: the schema of ``conf/ros2.yaml`` (``python -m localize.ros2``).

The settings both localize apps read (``localize.config.AppConfig``: ``dataset``,
``onnx_model``, the ``filter``, ``edges``, ``model_edges``, ``visibility``, the start ``hint``,
the viewer) plus the node's: one edge ``mode``, the topics, frame ids and QoS, the real-time
limits and the autopilot link; nothing the node does not read.
Defaults follow REP 105 (frame ids ``map``, ``odom``, ``base_link``), REP 103 (x forward, y
left, z up; the model's frame is the ``map`` frame) and nav2 AMCL (``/initialpose``, a
``global_localization`` service of ``std_srvs/Empty``, ``particle_cloud``). Documented in
docs/ros2.md. No rclpy here: the player and the tests read these settings too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from core.config import check_positive, register_schema
from localize.config import AppConfig
from localize.live.mavlink import check_url

#: ``topics.image_transport`` choices: sensor_msgs/Image or sensor_msgs/CompressedImage.
IMAGE_TRANSPORTS = ("raw", "compressed")
#: ``topics.odometry_type`` choices: nav_msgs/Odometry or geometry_msgs/PoseStamped.
ODOMETRY_TYPES = ("odometry", "pose")
#: ``qos.*`` reliability choices.
RELIABILITIES = ("best_effort", "reliable")


@dataclass
class NodeTopicsConfig:
    """``topics``: what the node subscribes and publishes (the player publishes the inputs).

    Attributes:
        image: the camera, sensor_msgs/Image (rgb8, bgr8, rgba8, bgra8, mono8) or, with
            ``image_transport: compressed``, sensor_msgs/CompressedImage.
        image_transport: ``raw`` or ``compressed``.
        camera_info: sensor_msgs/CameraInfo of the camera (plumb_bob / rational_polynomial).
        odometry: the odometry (a VIO, the autopilot's): nav_msgs/Odometry or, with
            ``odometry_type: pose``, geometry_msgs/PoseStamped; world_from_body of the body
            frame in the odometry's own gravity-aligned frame (z up).
        odometry_type: ``odometry`` or ``pose``.
        initial_pose: geometry_msgs/PoseWithCovarianceStamped in the map frame: (re)start
            tracking there (nav2 AMCL's and RViz's ``/initialpose``).
        global_localization: std_srvs/Empty service: re-localize over the whole free space
            (ROS 1 AMCL's name; the same as ``reinitialize_global_localization``).
        reinitialize_global_localization: std_srvs/Empty service, nav2 AMCL's name of the same
            re-localization.
        pose: geometry_msgs/PoseWithCovarianceStamped out, map frame, covariance from the
            particles.
        odometry_out: nav_msgs/Odometry out, map frame to ``frames.base``.
        particles: geometry_msgs/PoseArray of the particles, map frame.
        hypotheses: geometry_msgs/PoseArray of the pose hypotheses, heaviest first (at most
            ``filter.hypotheses``; during a global search its places), map frame, every frame.
        status: diagnostic_msgs/DiagnosticArray: status, confidence, latency, frame counts.
        free_space: nav_msgs/OccupancyGrid of the world's free space, latched (transient
            local; ``localize.ros2.world_display``).
        model_edges: visualization_msgs/MarkerArray of the model's edges by class, latched.
        groundtruth: geometry_msgs/PoseStamped of the true pose the player publishes when its
            source has one (empty: none); the node does not read it.
    """

    image: str = "/camera/image_raw"
    image_transport: str = "raw"
    camera_info: str = "/camera/camera_info"
    odometry: str = "/odom"
    odometry_type: str = "odometry"
    initial_pose: str = "/initialpose"
    global_localization: str = "/global_localization"
    reinitialize_global_localization: str = "/reinitialize_global_localization"
    pose: str = "/edgeloc/pose"
    odometry_out: str = "/edgeloc/odometry"
    particles: str = "/particle_cloud"
    hypotheses: str = "/edgeloc/hypotheses"
    status: str = "/diagnostics"
    free_space: str = "/edgeloc/free_space"
    model_edges: str = "/edgeloc/model_edges"
    groundtruth: str = "/groundtruth"

    def __post_init__(self) -> None:
        if self.image_transport not in IMAGE_TRANSPORTS:
            raise ValueError(f"topics.image_transport={self.image_transport!r}: use one of "
                             f"{IMAGE_TRANSPORTS}")
        if self.odometry_type not in ODOMETRY_TYPES:
            raise ValueError(f"topics.odometry_type={self.odometry_type!r}: use one of "
                             f"{ODOMETRY_TYPES}")


@dataclass
class FrameIdsConfig:
    """``frames``: the frame ids of what the node publishes (REP 105).

    Attributes:
        map: the model's frame (x, y, z up), the header of every output.
        base: the body frame, ``child_frame_id`` of the odometry out.
    """

    map: str = "map"
    base: str = "base_link"


@dataclass
class QosConfig:
    """``qos``: reliability and depth of the inputs and the outputs.

    Attributes:
        sensors: camera, CameraInfo and odometry (``best_effort``: the sensor-data profile; a
            reliable publisher reaches a best-effort subscriber, not the reverse).
        sensors_depth: messages kept per input topic (the node takes the newest frame anyway).
        outputs: pose, odometry, particles, hypotheses and status.
        outputs_depth: messages kept per output topic.
    """

    sensors: str = "best_effort"
    sensors_depth: int = 5
    outputs: str = "reliable"
    outputs_depth: int = 10

    def __post_init__(self) -> None:
        for key in ("sensors", "outputs"):
            if getattr(self, key) not in RELIABILITIES:
                raise ValueError(f"qos.{key}={getattr(self, key)!r}: use one of "
                                 f"{RELIABILITIES}")
        if self.sensors_depth < 1 or self.outputs_depth < 1:
            raise ValueError("qos.sensors_depth and qos.outputs_depth must be >= 1")


@dataclass
class RealTimeConfig:
    """``realtime``: how the node keeps up with the camera.

    Attributes:
        odometry_wait_s: how long a frame waits for the odometry to reach its capture time
            before it is dropped (the odometry is interpolated there, never extrapolated).
        odometry_keep_s: seconds of odometry kept for the interpolation.
        max_age_s: a frame older than this (capture to the start of its step) is dropped as
            stale.
        ambiguous_std_m: a tracking estimate whose particles spread wider (metres, horizontal)
            is reported ``ambiguous``.
        status_period_s: the status is also published this often while no frame comes.
        particles_period_s: the particle cloud is published at most this often (building
            its messages costs the worker about 0.1 ms a particle).
    """

    odometry_wait_s: float = 0.1
    odometry_keep_s: float = 5.0
    max_age_s: float = 0.5
    ambiguous_std_m: float = 0.5
    status_period_s: float = 1.0
    particles_period_s: float = 0.5

    def __post_init__(self) -> None:
        check_positive(self, ("odometry_wait_s", "odometry_keep_s", "max_age_s",
                              "ambiguous_std_m", "status_period_s", "particles_period_s"),
                       "realtime")


@dataclass
class Ros2Config(AppConfig):
    """The live node's config (``conf/ros2.yaml``): the ``AppConfig`` and the node's. The
    node starts from ``hint`` (a pose to track from, or where a search looks; none: a global
    start over the free space); ``/initialpose`` or the service restart it at any time.

    Attributes:
        node_name: the ROS node name (not a ROS parameter: ``-r __node:=NAME`` renames it).
        autostart: the node configures and activates itself on start (a lifecycle node,
            ``localize.ros2.node``); false: it waits for a lifecycle manager's transitions.
        mode: the edge mode (``cnn`` or ``none``: a live camera has no true labels).
        seed: the filter's random seed.
        body_from_cam: (4, 4) camera mount on the body; None: the dataset's.
        topics, frames, qos, realtime: the node's interface and limits.
        mavlink: the autopilot link (``localize.live.mavlink``), e.g.
            ``udpout:127.0.0.1:14550`` (``check_url``: checked at start-up); empty: off.
        mavlink_rate_hz: most MAVLink messages per second.

    With ``viz=rerun`` the node logs to ``<out_root>/<name>/live.rrd``.
    """

    node_name: str = "edgeloc"
    autostart: bool = True
    mode: str = "cnn"
    seed: int = 0
    body_from_cam: list[Any] | None = None
    topics: NodeTopicsConfig = field(default_factory=NodeTopicsConfig)
    frames: FrameIdsConfig = field(default_factory=FrameIdsConfig)
    qos: QosConfig = field(default_factory=QosConfig)
    realtime: RealTimeConfig = field(default_factory=RealTimeConfig)
    mavlink: str = ""
    mavlink_rate_hz: float = 30.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.mode not in ("cnn", "none"):
            raise ValueError(f"mode={self.mode!r}: a live camera has no true labels; use "
                             "mode=cnn (the SegNet) or mode=none (Canny)")
        if self.mavlink_rate_hz <= 0:
            raise ValueError(f"mavlink_rate_hz must be positive, got {self.mavlink_rate_hz}")
        if self.mavlink:
            try:
                check_url(self.mavlink)
            except ValueError as err:
                raise ValueError(f"mavlink={self.mavlink}: {err}; or mavlink='' for no "
                                 "autopilot link") from None


register_schema("ros2_schema", Ros2Config)
