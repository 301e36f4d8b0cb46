"""ROS 1 ``.bag`` and ROS 2 bag (``metadata.yaml`` + .db3/.mcap) recordings via rosbags.

Topics (``BagTopicsConfig``): an image topic (sensor_msgs/Image in rgb8, bgr8, rgba8, bgra8 or
mono8, or sensor_msgs/CompressedImage), a sensor_msgs/CameraInfo topic (its first message is
used), an odometry topic (nav_msgs/Odometry, geometry_msgs/PoseStamped or PoseWithCovarianceStamped:
world_from_body of the odometry's child frame) and an optional ground-truth topic of the same
kinds. Times are the messages' header stamps. Frames stay in the bag: the reader keeps each
frame's bag time and fetches it when asked (one pass for ``Recording.images()``), so memory
does not grow with the recording.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from core.config import as_config
from core.dataset import Camera
from core.poses import interpolate_poses
from localize.config import BagTopicsConfig
from localize.recordings.messages import decode_image, header_seconds, pose_matrix, source_camera
from localize.recordings.recording import (
    Recording,
    SourceCamera,
    UnreadableFrame,
    check_increasing,
    delivered_camera,
    select_frames,
)

log = logging.getLogger(__name__)

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
              "geometry_msgs/msg/PoseWithCovarianceStamped")
#: Where the topics are set in the localize config, for messages.
CONFIG_KEY = "recording_topics"


def _connections(reader: AnyReader, topic: str, key: str, types: tuple[str, ...], path: Path):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        listing = ", ".join(f"{t} ({i.msgtype})" for t, i in sorted(reader.topics.items()))
        raise ValueError(f"{path}: topic {topic!r} not in the bag; set {CONFIG_KEY}.{key} to one "
                         f"of its topics: {listing}")
    bad = {c.msgtype for c in conns} - set(types)
    if bad:
        raise ValueError(f"{path}: topic {topic!r} ({CONFIG_KEY}.{key}) carries {sorted(bad)}; "
                         f"expected one of {list(types)}")
    return conns


def _read_poses(reader: AnyReader, conns, path: Path, topic: str) -> tuple[np.ndarray, np.ndarray]:
    t, T = [], []
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        t.append(header_seconds(msg))
        T.append(pose_matrix(msg, conn.msgtype))
    if len(t) < 2:
        raise ValueError(f"{path}: topic {topic!r} has {len(t)} pose messages; at least 2 are "
                         f"needed to interpolate")
    t = np.asarray(t)
    check_increasing(t, f"{path} topic {topic}", lambda i: f"message {i}")
    return t, np.stack(T)


@contextmanager
def _open(path: Path) -> Iterator[AnyReader]:
    """The bag opened for reading; a file or folder rosbags cannot open (not a bag, cut short,
    a metadata.yaml missing keys) raises ValueError naming it and what rosbags found."""
    reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    try:
        reader.open()
    except Exception as err:  # rosbags raises its own errors, KeyError, UnicodeDecodeError...
        kind, whole = (("ROS 1 .bag file", "a whole bag, not cut short") if path.suffix == ".bag"
                       else ("ROS 2 bag folder", "its metadata.yaml as `ros2 bag record` "
                             "writes it, beside its .db3/.mcap files"))
        raise ValueError(f"{path}: cannot be read as a {kind} ({type(err).__name__}: {err}); "
                         f"give {whole}, or record it again") from err
    try:
        yield reader
    finally:
        reader.close()


@dataclass(frozen=True)
class BagFrames:
    """The frames of a bag's image topic, fetched when asked.

    Attributes:
        path: the bag.
        topic: the image topic.
        log_times: (N,) int64 bag (receive) times of the frames, nanoseconds.
        ranks: (N,) int64 position of each frame among the topic's messages with the same bag
            time (normally 0).
    """

    path: Path
    topic: str
    log_times: np.ndarray
    ranks: np.ndarray

    def __len__(self) -> int:
        return len(self.log_times)

    def read(self, index: int) -> np.ndarray:
        lt, rank = int(self.log_times[index]), int(self.ranks[index])
        with _open(self.path) as reader:
            conns = [c for c in reader.connections if c.topic == self.topic]
            msgs = list(reader.messages(connections=conns, start=lt, stop=lt + 1))
            conn, _, raw = msgs[rank]
            return decode_image(reader.deserialize(raw, conn.msgtype), conn.msgtype,
                                f"{self.path} topic {self.topic} frame {index}")

    def iter(self) -> Iterator[np.ndarray | None]:
        wanted = set(zip(self.log_times.tolist(), self.ranks.tolist(), strict=True))
        with _open(self.path) as reader:
            conns = [c for c in reader.connections if c.topic == self.topic]
            prev, rank, i = None, 0, 0
            for conn, lt, raw in reader.messages(connections=conns):
                rank = rank + 1 if lt == prev else 0
                prev = lt
                if (lt, rank) in wanted:
                    try:
                        yield decode_image(reader.deserialize(raw, conn.msgtype), conn.msgtype,
                                           f"{self.path} topic {self.topic} frame {i}")
                    except UnreadableFrame as err:
                        log.warning("%s; frame dropped", err)
                        yield None
                    i += 1


def _read_images(reader: AnyReader, conns, path: Path, topic: str):
    t, log_times, ranks, prev, rank = [], [], [], None, 0
    for conn, lt, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        rank = rank + 1 if lt == prev else 0
        prev = lt
        t.append(header_seconds(msg))
        log_times.append(lt)
        ranks.append(rank)
    if not t:
        raise ValueError(f"{path}: image topic {topic!r} has no messages")
    t = np.asarray(t)
    check_increasing(t, f"{path} topic {topic}", lambda i: f"message {i}")
    return t, np.asarray(log_times, np.int64), np.asarray(ranks, np.int64)


def read_bag(path: Path, target: Camera | None, *, topics: Mapping | BagTopicsConfig | None = None,
             body_from_cam: np.ndarray | None = None, name: str | None = None) -> Recording:
    """Read a ROS 1 or ROS 2 bag recording (see ``localize.recordings.read.read_recording``)."""
    topics = as_config(BagTopicsConfig, topics, CONFIG_KEY)
    path = Path(path)
    with _open(path) as reader:
        img = _connections(reader, topics.image, "image", IMAGE_TYPES, path)
        info = _connections(reader, topics.camera_info, "camera_info",
                            ("sensor_msgs/msg/CameraInfo",), path)
        odo = _connections(reader, topics.odometry, "odometry", POSE_TYPES, path)
        first = next(reader.messages(connections=info), None)
        if first is None:
            raise ValueError(f"{path}: camera_info topic {topics.camera_info!r} has no messages")
        source = source_camera(reader.deserialize(first[2], first[0].msgtype),
                               f"{path} topic {topics.camera_info}")
        t, log_times, ranks = _read_images(reader, img, path, topics.image)
        streams = {"odometry": _read_poses(reader, odo, path, topics.odometry)}
        if topics.groundtruth is not None:
            gt = _connections(reader, topics.groundtruth, "groundtruth", POSE_TYPES, path)
            streams["groundtruth"] = _read_poses(reader, gt, path, topics.groundtruth)
    camera, rect = delivered_camera(source, target, body_from_cam, str(path))
    keep = select_frames(t, {k: v[0] for k, v in streams.items()}, path)
    t = t[keep]
    poses = {k: interpolate_poses(t, *v) for k, v in streams.items()}
    frames = _SizedFrames(BagFrames(path, topics.image, log_times[keep], ranks[keep]), source)
    return Recording(name or path.stem, path, camera, t, poses["odometry"],
                     poses.get("groundtruth"), frames, rect)


@dataclass(frozen=True)
class _SizedFrames:
    """Checks that every frame has the CameraInfo's size."""

    frames: BagFrames
    camera: SourceCamera

    def __len__(self) -> int:
        return len(self.frames)

    def _check(self, image: np.ndarray, index: int) -> np.ndarray:
        if image.shape[:2] != (self.camera.height, self.camera.width):
            raise ValueError(f"{self.frames.path} topic {self.frames.topic} frame {index}: "
                             f"image is {image.shape[1]}x{image.shape[0]}, the CameraInfo says "
                             f"{self.camera.width}x{self.camera.height}")
        return image

    def read(self, index: int) -> np.ndarray:
        return self._check(self.frames.read(index), index)

    def iter(self) -> Iterator[np.ndarray | None]:
        for i, image in enumerate(self.frames.iter()):
            yield None if image is None else self._check(image, i)
