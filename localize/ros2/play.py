"""``python -m localize.ros2.play PATH [rate=2] [key=value ...]``: publish a recording or a
rendered flight as ROS 2 topics, at real time or ``rate`` times faster, for the live node
(``python -m localize.ros2``) without a drone (docs/ros2.md).

PATH is a rendered flight (``<dataset>/flights/<name>``, ``core.dataset.Flight``: its frames
undistorted to the dataset's camera), a recording folder or a ROS 1 / ROS 2 bag
(``localize.recordings.read.read_recording``: its frames as recorded, with their own calibration,
which the node undistorts and rescales). Per frame, at its time on the wall clock: the
odometry (nav_msgs/Odometry, frame ``odom`` to ``base_link``, or PoseStamped with
``topics.odometry_type=pose``, at the frame's time), the
CameraInfo and the image (sensor_msgs/Image rgb8, or CompressedImage JPEG with
``topics.image_transport=compressed``), all stamped with the wall-clock time the frame is
published at (a live camera's capture time), and the true pose (PoseStamped, map frame) when
the source has one. Topics: ``localize.ros2.config.NodeTopicsConfig``, as the node reads them.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from omegaconf import OmegaConf

from core.config import typed, user_errors
from core.dataset import Dataset
from localize.live.sync import wait_until
from localize.recordings.read import read_recording
from localize.recordings.recording import SourceCamera
from localize.ros2.config import NodeTopicsConfig
from localize.ros2.convert import position_quaternion, stamp_parts

log = logging.getLogger(__name__)


@dataclass
class PlayConfig:
    """The player's ``key=value`` settings.

    Attributes:
        rate: playback speed, a multiple of real time.
        max_frames: only the first N frames; None: all.
        loop: start over at the end (until Ctrl-C).
        wait_s: seconds to wait for a subscriber of the image topic before playing.
        camera_frame, odom_frame, base_frame, map_frame: frame ids (REP 105).
        topics: the topics (the node's defaults).
    """

    rate: float = 1.0
    max_frames: int | None = None
    loop: bool = False
    wait_s: float = 10.0
    camera_frame: str = "camera"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    map_frame: str = "map"
    topics: NodeTopicsConfig = field(default_factory=NodeTopicsConfig)

    def __post_init__(self) -> None:
        if self.rate <= 0:
            raise ValueError(f"rate={self.rate}: give a positive multiple of real time")


@dataclass
class Playback:
    """What the player publishes: per frame its time (s), odometry and true pose ((N, 4, 4);
    groundtruth None without truth) and image (``frames()``), with the camera's calibration.
    """

    name: str
    timestamps: np.ndarray
    odometry: np.ndarray
    groundtruth: np.ndarray | None
    camera: SourceCamera
    frames: Callable[[], Iterator[np.ndarray | None]]

    def __len__(self) -> int:
        return len(self.timestamps)


def open_playback(path: str | Path) -> Playback:
    """A flight folder (``<dataset>/flights/<name>`` with flight.json) or a recording."""
    path = Path(path)
    if (path / "flight.json").is_file() and path.parent.name == "flights":
        dataset = Dataset(path.parent.parent)
        flight = dataset.flight(path.name)
        cam = dataset.camera
        source = SourceCamera(cam.K, cam.width, cam.height, np.zeros(5))

        def frames() -> Iterator[np.ndarray | None]:
            return (flight.image(i) for i in range(len(flight)))

        return Playback(flight.name, flight.timestamps, flight.odometry, flight.groundtruth,
                        source, frames)
    rec = read_recording(path, body_from_cam=np.eye(4))  # the mount is the node's business
    return Playback(rec.name, rec.timestamps, rec.odometry, rec.groundtruth,
                    rec.rectifier.source, rec.frames.iter)


class Player:
    """Publishes a ``Playback`` on a node's publishers (rclpy)."""

    def __init__(self, node, settings: PlayConfig):
        from geometry_msgs.msg import PoseStamped
        from nav_msgs.msg import Odometry
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import CameraInfo, CompressedImage, Image

        self.node, self.s = node, settings
        t = settings.topics
        q = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
        self.compressed = t.image_transport == "compressed"
        self.odometry_as_pose = t.odometry_type == "pose"
        self._types = {"image": CompressedImage if self.compressed else Image,
                       "info": CameraInfo, "odometry": Odometry, "pose": PoseStamped}
        self.image_pub = node.create_publisher(self._types["image"], t.image, q)
        self.info_pub = node.create_publisher(CameraInfo, t.camera_info, q)
        self.odometry_pub = node.create_publisher(
            PoseStamped if self.odometry_as_pose else Odometry, t.odometry, q)
        self.truth_pub = (node.create_publisher(PoseStamped, t.groundtruth, q)
                          if t.groundtruth else None)

    def wait_for_subscriber(self) -> bool:
        """Wait up to ``wait_s`` for a subscriber of the image, CameraInfo and odometry
        topics each."""
        pubs = (self.image_pub, self.info_pub, self.odometry_pub)
        return wait_until(lambda: all(p.get_subscription_count() > 0 for p in pubs),
                          self.s.wait_s)

    def play(self, pb: Playback, stop=None) -> list[float]:
        """Publish every frame (up to ``max_frames``) at its time scaled by ``rate``;
        ``stop()`` returning True ends early. Returns the stamps used, one per frame
        published (seconds)."""
        n = len(pb) if self.s.max_frames is None else min(len(pb), int(self.s.max_frames))
        # the calibration first, as a camera driver latches it: the first frame finds it
        self.info_pub.publish(self.camera_info(pb.camera, time.time()))
        t0, wall0 = float(pb.timestamps[0]), time.time() + 0.2
        stamps = []
        for i, image in zip(range(n), pb.frames(), strict=False):
            if stop is not None and stop():
                break
            stamp = wall0 + (float(pb.timestamps[i]) - t0) / self.s.rate
            delay = stamp - time.time()
            if delay > 0:
                time.sleep(delay)
            self._publish(pb, i, image, stamp)
            stamps.append(stamp)
        return stamps

    def _publish(self, pb: Playback, i: int, image: np.ndarray | None, stamp: float) -> None:
        T = self._types
        self.odometry_pub.publish(self.odometry_message(pb.odometry[i], stamp))
        if self.truth_pub is not None and pb.groundtruth is not None:
            gt = T["pose"]()
            self._header(gt, stamp, self.s.map_frame)
            _set_pose(gt.pose, pb.groundtruth[i])
            self.truth_pub.publish(gt)
        self.info_pub.publish(self.camera_info(pb.camera, stamp))
        if image is None:  # a frame the recording cannot decode: the camera dropped it
            return
        self.image_pub.publish(self.image_message(image, stamp))

    def odometry_message(self, pose: np.ndarray, stamp: float):
        """nav_msgs/Odometry (``odom`` to ``base_link``) or, with ``topics.odometry_type=pose``,
        PoseStamped (``odom``) of a (4, 4) odometry pose."""
        if self.odometry_as_pose:
            msg = self._types["pose"]()
            _set_pose(msg.pose, pose)
        else:
            msg = self._types["odometry"]()
            msg.child_frame_id = self.s.base_frame
            _set_pose(msg.pose.pose, pose)
        self._header(msg, stamp, self.s.odom_frame)
        return msg

    def _header(self, msg, stamp: float, frame: str) -> None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_parts(stamp)
        msg.header.frame_id = frame

    def camera_info(self, cam: SourceCamera, stamp: float):
        """sensor_msgs/CameraInfo of a calibration (plumb_bob unless 8 coefficients)."""
        msg = self._types["info"]()
        self._header(msg, stamp, self.s.camera_frame)
        msg.width, msg.height = int(cam.width), int(cam.height)
        d = np.asarray(cam.distortion, dtype=np.float64).reshape(-1)
        msg.distortion_model = "rational_polynomial" if len(d) == 8 else "plumb_bob"
        msg.d = (d if len(d) else np.zeros(5)).tolist()
        msg.k = np.asarray(cam.K, dtype=np.float64).ravel()
        msg.r = np.eye(3).ravel()
        P = np.zeros((3, 4))
        P[:, :3] = cam.K
        msg.p = P.ravel()
        return msg

    def image_message(self, image: np.ndarray, stamp: float):
        """sensor_msgs/Image (rgb8) or CompressedImage (JPEG) of an (H, W, 3) uint8 RGB."""
        msg = self._types["image"]()
        self._header(msg, stamp, self.s.camera_frame)
        if self.compressed:
            ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image[..., ::-1]))
            msg.format = "jpeg"
            msg.data = buf.tobytes()
        else:
            h, w = image.shape[:2]
            msg.height, msg.width, msg.encoding, msg.step = h, w, "rgb8", 3 * w
            msg.data = np.ascontiguousarray(image, dtype=np.uint8).tobytes()
        return msg


def _set_pose(pose, T: np.ndarray) -> None:
    p, q = position_quaternion(T)
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (float(v) for v in q)


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    paths = [a for a in args if "=" not in a]
    usage = ("usage: python -m localize.ros2.play RECORDING_OR_FLIGHT [rate=1.0] "
             "[max_frames=N] [loop=true] [topics.image=/camera/image_raw] ... "
             "(every key: localize/ros2/play.py, class PlayConfig; docs/ros2.md)")
    if any(a in ("-h", "--help") for a in args):
        print(usage)
        return
    if len(paths) != 1:
        raise SystemExit(usage)
    settings = typed(PlayConfig, OmegaConf.from_dotlist([a for a in args if "=" in a]),
                     "ros2_play")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    pb = open_playback(paths[0])
    import rclpy

    rclpy.init()
    node = rclpy.create_node("edgeloc_player")
    try:
        player = Player(node, settings)
        if not player.wait_for_subscriber():
            log.warning("no subscriber of %s after %.0f s; playing anyway",
                        settings.topics.image, settings.wait_s)
        while True:
            log.info("playing %s: %d frames at %.2fx", pb.name, len(pb), settings.rate)
            player.play(pb)
            if not settings.loop:
                break
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == "__main__":
    with user_errors():
        main()
