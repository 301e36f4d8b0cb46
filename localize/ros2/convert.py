"""ROS messages <-> numpy for the live node, without a middleware: stamps, images, camera
info, poses, an initial pose's start, the covariance of the particles (or of a global
search's hypotheses) and the status the node reports.

Messages are read by their fields (a deserialized bag message and an rclpy one alike), with
the recordings' own decoders (``localize.recordings.bag``: ``decode_image``, ``source_camera``,
``pose_matrix``); what the node publishes is computed here as arrays and copied into the
messages by ``localize.ros2.node``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from core.poses import wrap_angle
from localize.filter.projection import corrected_tilts, tilt_from_pose, yaw_rotation
from localize.filter.start_hint import StartHint
from localize.localizer import Estimate
from localize.recordings.messages import decode_image, pose_matrix, source_camera
from localize.recordings.recording import SourceCamera

#: Message type names of the inputs, as ``decode_image`` and ``pose_matrix`` take them.
IMAGE_TYPE = {"raw": "sensor_msgs/msg/Image", "compressed": "sensor_msgs/msg/CompressedImage"}
POSE_TYPE = {"odometry": "nav_msgs/msg/Odometry", "pose": "geometry_msgs/msg/PoseStamped",
             "initial_pose": "geometry_msgs/msg/PoseWithCovarianceStamped"}
#: Statuses the node reports, and their diagnostic_msgs levels (OK, WARN, ERROR).
STATUS_LEVEL = {"tracking": 0, "ambiguous": 1, "lost": 2}
NS = 1_000_000_000
#: An orientation quaternion shorter than this has no direction to normalize (a zero one).
MIN_QUATERNION_NORM = 1e-6


def stamp_seconds(stamp) -> float:
    """A builtin_interfaces/Time as seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_parts(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds (nanosec in [0, 1e9))."""
    ns = int(round(float(seconds) * NS))
    return ns // NS, ns % NS


def image_of(msg, transport: str, where: str) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an Image (``transport`` raw) or CompressedImage (compressed);
    ValueError naming ``where`` and the encodings that work."""
    return decode_image(msg, IMAGE_TYPE[transport], where)


def camera_of(msg, where: str) -> SourceCamera:
    """The camera of a sensor_msgs/CameraInfo (K, size, distortion; ValueError naming
    ``where`` for a model OpenCV does not undistort)."""
    return source_camera(msg, where)


def pose_of(msg, kind: str, where: str) -> np.ndarray:
    """(4, 4) pose of an Odometry (``kind`` odometry), PoseStamped (pose) or
    PoseWithCovarianceStamped (initial_pose) message; ValueError naming ``where`` and the
    field for a position that is not finite or an orientation that is not a rotation (a
    quaternion not finite or of norm below ``MIN_QUATERNION_NORM``)."""
    pose = msg.pose if kind == "pose" else msg.pose.pose
    p, q = pose.position, pose.orientation
    position = np.array([p.x, p.y, p.z], dtype=np.float64)
    quaternion = np.array([q.x, q.y, q.z, q.w], dtype=np.float64)
    if not np.isfinite(position).all():
        raise ValueError(f"{where}: pose.position (x, y, z) = {position.tolist()} is not "
                         "finite; message dropped")
    if not (np.isfinite(quaternion).all()
            and np.linalg.norm(quaternion) >= MIN_QUATERNION_NORM):
        raise ValueError(f"{where}: pose.orientation (x, y, z, w) = {quaternion.tolist()} is "
                         "not a rotation: give a finite unit quaternion (w = 1 for none); "
                         "message dropped")
    return pose_matrix(msg, POSE_TYPE[kind])


def initial_pose_start(msg, init_std: Sequence[float], where: str) -> np.ndarray | StartHint:
    """What a geometry_msgs/PoseWithCovarianceStamped ``/initialpose`` starts
    (``StartHint.start_of_initial_pose``): (4,) x, y, z, yaw to track from, or a search
    around the pose; ValueError naming ``where`` and the field for a pose ``pose_of`` refuses
    or a covariance that is not 36 finite values of a positive semi-definite matrix.

    Args:
        msg: the message (map frame).
        init_std: ``filter.init_std`` (x, y, z m, yaw deg): the tracking start's noise.
        where: the topic, for messages.
    """
    T = pose_of(msg, "initial_pose", where)
    cov = np.asarray(msg.pose.covariance, dtype=np.float64)
    if cov.shape != (36,) or not np.isfinite(cov).all():
        raise ValueError(f"{where}: pose.covariance must be 36 finite values (row-major 6x6 "
                         "over x, y, z, roll, pitch, yaw; all zero to track from the pose), "
                         f"got {cov.ravel().tolist()}; message dropped")
    try:
        return StartHint.start_of_initial_pose(T, cov, init_std)
    except ValueError as err:
        raise ValueError(f"{where}: pose.covariance: {err}; message dropped") from None


def position_quaternion(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3,) translation and (4,) x, y, z, w quaternion of a (4, 4) pose."""
    T = np.asarray(T, dtype=np.float64)
    return T[:3, 3].copy(), Rotation.from_matrix(T[:3, :3]).as_quat()


def yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """(N, 4) x, y, z, w quaternions of rotations by ``yaw`` (N,) radians about z."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    q = np.zeros((len(half), 4))
    q[:, 2], q[:, 3] = np.sin(half), np.cos(half)
    return q


def world_from_body(estimate: Estimate, attitude: np.ndarray | None) -> np.ndarray:
    """(4, 4) map pose of the body: the estimate's position and yaw, with the odometry's roll
    and pitch (``attitude``: its (4, 4) pose; None: level) corrected by the estimate's tilt."""
    x, y, z, yaw = estimate.state
    tilt = None if attitude is None else tilt_from_pose(attitude)
    T = np.eye(4)
    T[:3, :3] = yaw_rotation(np.array([yaw]))[0] @ corrected_tilts(tilt, estimate.tilt[None])[0]
    T[:3, 3] = x, y, z
    return T


def particle_covariance(particles: np.ndarray, logw: np.ndarray, tilt: np.ndarray,
                        estimate: np.ndarray) -> np.ndarray:
    """(6, 6) covariance over x, y, z (m2), roll, pitch, yaw (rad2) in the map frame, the
    weighted spread of the particles (ROS's row-major pose covariance order).

    Args:
        particles: (N, 4) x, y, z, yaw.
        logw: (N,) normalized log-weights.
        tilt: (N, 2) each particle's roll, pitch correction, radians.
        estimate: (4,) the weighted mean (yaw differences are taken around its yaw).
    """
    w = np.exp(logw - np.max(logw))
    w /= w.sum()
    d = np.empty((len(particles), 6))
    d[:, :3] = particles[:, :3] - estimate[:3]
    d[:, 3:5] = tilt - (w @ tilt)
    d[:, 5] = wrap_angle(particles[:, 3] - estimate[3])
    return (d * w[:, None]).T @ d


def hypotheses_covariance(estimate: Estimate) -> np.ndarray:
    """(6, 6) covariance over x, y, z (m2), roll, pitch, yaw (rad2) in the map frame of a
    global search's estimate, around its pose ``estimate.state`` (the heaviest hypothesis):
    the mixture of its hypotheses (``estimate.hypotheses``), each weighted by its mass with its
    own spread plus its offset from the pose, squared; the mass no hypothesis holds weighs the
    whole set's spread (``estimate.position_std``, ``estimate.yaw_std``). A horizontal spread
    (m, the root of the x and y variances' sum) bounds each of x and y; roll and pitch carry
    none (the search holds no tilt). O(hypotheses): no pass over the search's poses.
    """
    centre = np.asarray(estimate.state, dtype=np.float64)
    cov = np.zeros((6, 6))
    held = 0.0
    for h in estimate.hypotheses:
        d = np.zeros(6)
        d[:3] = h.state[:3] - centre[:3]
        d[5] = wrap_angle(h.state[3] - centre[3])
        own = np.diag([h.position_std ** 2, h.position_std ** 2, 0.0, 0.0, 0.0,
                       h.yaw_std ** 2])
        cov += h.mass * (own + np.outer(d, d))
        held += h.mass
    rest = max(1.0 - held, 0.0)
    cov += rest * np.diag([estimate.position_std ** 2, estimate.position_std ** 2, 0.0, 0.0,
                           0.0, estimate.yaw_std ** 2])
    return cov / max(held, 1.0)


def shown_particles(particles: np.ndarray, most: int, rng: np.random.Generator) -> np.ndarray:
    """At most ``most`` of the particles (N, 4), a uniform draw without replacement (all of
    them when there are fewer), for display."""
    if len(particles) <= most:
        return particles
    return particles[np.sort(rng.choice(len(particles), most, replace=False))]


def live_status(estimate: Estimate, ambiguous_std_m: float) -> str:
    """``tracking``, ``ambiguous`` (the filter's: no hypothesis dominates yet; or tracking or
    coasting with the particles spread wider than ``ambiguous_std_m``) or ``lost``."""
    if estimate.status in ("lost", "ambiguous"):
        return estimate.status
    return "ambiguous" if estimate.position_std > ambiguous_std_m else "tracking"
