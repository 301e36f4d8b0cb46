"""ROS message contents as arrays, shared by the bag reader (``localize.recordings.bag``) and the
live node (``localize.ros2``): header stamps, images, poses, camera calibrations. The messages
are rosbags' or rclpy's; only their fields are read."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from core.atomic import encoded_image_complete
from localize.recordings.recording import SourceCamera, UnreadableFrame, check_distortion

#: Channels and the channel order to RGB of the raw encodings decoded.
ENCODINGS = {"rgb8": (3, [0, 1, 2]), "bgr8": (3, [2, 1, 0]), "rgba8": (4, [0, 1, 2]),
             "bgra8": (4, [2, 1, 0]), "mono8": (1, [0, 0, 0])}

def header_seconds(msg) -> float:
    """Header stamp of a message, seconds."""
    s = msg.header.stamp
    return s.sec + s.nanosec * 1e-9


def decode_image(msg, msgtype: str, where: str) -> np.ndarray:
    """A sensor_msgs/Image or CompressedImage as (H, W, 3) uint8 RGB.

    Args:
        msg: the deserialized message.
        msgtype: its type name.
        where: topic and message index, for messages.
    """
    if msgtype.endswith("CompressedImage"):
        data = np.asarray(msg.data, dtype=np.uint8)
        if not encoded_image_complete(data.tobytes()):
            raise UnreadableFrame(f"{where}: the CompressedImage ({msg.format!r}) is cut short "
                                  f"(no end marker after {data.size} bytes)")
        bgr = cv2.imdecode(data, cv2.IMREAD_COLOR)
        if bgr is None:
            raise UnreadableFrame(f"{where}: cannot decode the CompressedImage ({msg.format!r})")
        return np.ascontiguousarray(bgr[..., ::-1])
    if msg.encoding not in ENCODINGS:
        raise ValueError(f"{where}: image encoding {msg.encoding!r} is not supported; use one "
                         f"of {sorted(ENCODINGS)} (or a CompressedImage topic)")
    ch, order = ENCODINGS[msg.encoding]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * ch or data.size < h * step:
        raise UnreadableFrame(f"{where}: image data ({data.size} bytes, step {step}) too short for "
                         f"{w}x{h} {msg.encoding}")
    rows = data[: h * step].reshape(h, step)[:, : w * ch].reshape(h, w, ch)
    return np.ascontiguousarray(rows[..., order])


def pose_matrix(msg, msgtype: str) -> np.ndarray:
    """(4, 4) pose of an Odometry / PoseStamped / PoseWithCovarianceStamped message."""
    pose = msg.pose.pose if msgtype != "geometry_msgs/msg/PoseStamped" else msg.pose
    p, q = pose.position, pose.orientation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    T[:3, 3] = [p.x, p.y, p.z]
    return T


def source_camera(msg, where: str) -> SourceCamera:
    """The recorded camera of a sensor_msgs/CameraInfo (ROS 1 or ROS 2 field names)."""
    ros2 = hasattr(msg, "k")  # ROS 2 names the fields k, d; ROS 1 K, D
    K = np.asarray(msg.k if ros2 else msg.K, dtype=np.float64).reshape(3, 3)
    D = np.asarray(msg.d if ros2 else msg.D, dtype=np.float64)
    return SourceCamera(K, int(msg.width), int(msg.height),
                        check_distortion(msg.distortion_model, D, f"{where} distortion"))
