"""Turn a rendered flight into a recording, in the formats ``localize.recordings.recording`` reads.

``python -m localize.recordings.export DATASET FLIGHT OUT [--bag | --bag1]`` writes a folder
recording (JPEG frames, images.txt, camera.yaml, odometry.txt, groundtruth.txt), a ROS 2 bag
folder or a ROS 1 .bag, so users can see the expected format and test their setup. Options move
the odometry into another start frame (only its increments matter), and render the frames
through a larger, distorted camera (to exercise undistortion and rescaling).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from core.atomic import atomic_write_bytes, atomic_write_text, read_png
from core.config import user_errors
from core.dataset import Camera, Dataset, Flight
from core.imaging.lens import coefficients
from core.poses import pose_from_xyzyaw, write_tum
from localize.recordings.bag import BagTopicsConfig

#: Nanoseconds per second (ROS stamps and bag times are integer nanoseconds).
NS = 1_000_000_000


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Path]:
    """Yield a path to write a file or folder at; it is moved onto ``out`` if all went well.

    Raises:
        FileExistsError: if ``out`` exists.
    """
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} exists; choose another output path or delete it")
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield stage / out.name
        os.replace(stage / out.name, out)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def scaled_camera(camera: Camera, scale: float) -> Camera:
    """The camera with its image scaled by ``scale`` (pixel centres at integers)."""
    K = camera.K.copy()
    K[:2, :2] *= scale
    K[:2, 2] = (K[:2, 2] + 0.5) * scale - 0.5
    return Camera(K, round(camera.width * scale), round(camera.height * scale),
                  camera.body_from_cam)


def distort_image(image: np.ndarray, K_image: np.ndarray, K: np.ndarray, D: np.ndarray,
                  width: int, height: int) -> np.ndarray:
    """Render an ideal pinhole image through a distorted camera.

    Args:
        image: (h, w, 3) uint8 ideal image with intrinsics ``K_image``.
        K_image: (3, 3) its intrinsics.
        K: (3, 3) intrinsics of the distorted camera.
        D: (k,) OpenCV distortion coefficients (plumb_bob: k1, k2, p1, p2, k3).
        width, height: size of the distorted image.

    Returns:
        (height, width, 3) uint8; pixels that see beyond the ideal image are black.
    """
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)[:, None]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
    norm = cv2.undistortPoints(pts, K, np.asarray(D, np.float64), criteria=crit)[:, 0]
    mx = (norm[:, 0] * K_image[0, 0] + K_image[0, 2]).reshape(height, width).astype(np.float32)
    my = (norm[:, 1] * K_image[1, 1] + K_image[1, 2]).reshape(height, width).astype(np.float32)
    return cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def camera_yaml(camera: Camera, distortion: Sequence[float] = (0.0,) * 5) -> str:
    """ROS camera_calibration YAML of a camera, with its body_from_cam."""
    d = [float(x) for x in distortion]
    doc = {"image_width": int(camera.width), "image_height": int(camera.height),
           "camera_name": "edgeloc",
           "camera_matrix": {"rows": 3, "cols": 3, "data": camera.K.ravel().tolist()},
           "distortion_model": "plumb_bob",
           "distortion_coefficients": {"rows": 1, "cols": len(d), "data": d},
           "body_from_cam": {"rows": 4, "cols": 4,
                             "data": np.asarray(camera.body_from_cam).ravel().tolist()}}
    return yaml.safe_dump(doc, sort_keys=False)


class FlightFrames:
    """The frames of a flight as a recorded camera would deliver them: the flight's own frames
    and lens (``distortion`` None, scale 1), or its frames undistorted to the pinhole K
    (``Flight.image``) and rendered through another camera."""

    def __init__(self, flight: Flight, camera: Camera, scale: float = 1.0,
                 distortion: Sequence[float] | None = None):
        self.flight, self.ideal = flight, camera
        self.camera = scaled_camera(camera, scale) if scale != 1.0 else camera
        own = flight.distortion
        self.distortion = own if distortion is None else coefficients(distortion)
        self.raw = scale == 1.0 and np.array_equal(self.distortion, own)

    def __call__(self, index: int) -> np.ndarray:
        if self.raw:
            return read_png(self.flight.rgb[index])
        rgb = self.flight.image(index)
        c = self.camera
        if np.any(self.distortion) or c.width != self.ideal.width:
            rgb = distort_image(rgb, self.ideal.K, c.K, self.distortion, c.width, c.height)
        return rgb


def export_folder(dataset: str | Path, flight: str, out: str | Path, *,
                  odometry_frame: np.ndarray | None = None, jpeg_quality: int = 95,
                  scale: float = 1.0, distortion: Sequence[float] | None = None) -> Path:
    """Write a flight as a folder recording.

    Args:
        dataset: the dataset made by ``python -m datagen``.
        flight: flight name.
        out: the folder to create (must not exist).
        odometry_frame: (4, 4) odom_from_world applied to every odometry pose (None: identity).
        jpeg_quality: JPEG quality of images/NNNNNN.jpg (0: PNG).
        scale: image scale of the recorded camera against the dataset's.
        distortion: plumb_bob coefficients (k1, k2, p1, p2, k3) of the recorded camera.

    Returns:
        ``out``.
    """
    ds = Dataset(dataset)
    f = ds.flight(flight)
    frames = FlightFrames(f, ds.camera, scale, distortion)
    M = np.eye(4) if odometry_frame is None else np.asarray(odometry_frame, dtype=np.float64)
    ext = ".jpg" if jpeg_quality else ".png"
    params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)] if jpeg_quality else []
    with staged(Path(out)) as d:
        lines = ["# timestamp filename"]
        for i, t in enumerate(f.timestamps):
            ok, buf = cv2.imencode(ext, np.ascontiguousarray(frames(i)[..., ::-1]), params)
            if not ok:
                raise OSError(f"could not encode frame {i} of {flight} as {ext}")
            atomic_write_bytes(d / "images" / f"{i:06d}{ext}", buf.tobytes())
            lines.append(f"{t:.9f} images/{i:06d}{ext}")
        atomic_write_text(d / "images.txt", "\n".join(lines) + "\n")
        atomic_write_text(d / "camera.yaml", camera_yaml(frames.camera, frames.distortion))
        write_tum(d / "odometry.txt", f.timestamps, M @ f.odometry)
        write_tum(d / "groundtruth.txt", f.timestamps, f.groundtruth)
    return Path(out)


def _time(types, ns: int):
    return types["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS)


def _header(types, ros1: bool, ns: int, frame_id: str, seq: int):
    H = types["std_msgs/msg/Header"]
    stamp = _time(types, ns)
    return H(seq=seq, stamp=stamp, frame_id=frame_id) if ros1 else H(stamp=stamp,
                                                                      frame_id=frame_id)


def _odometry(types, header, T: np.ndarray):
    g = "geometry_msgs/msg/"
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    pose = types[g + "Pose"](position=types[g + "Point"](*T[:3, 3].tolist()),
                             orientation=types[g + "Quaternion"](*q.tolist()))
    zero = types[g + "Vector3"](0.0, 0.0, 0.0)
    return types["nav_msgs/msg/Odometry"](
        header=header, child_frame_id="base_link",
        pose=types[g + "PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        twist=types[g + "TwistWithCovariance"](twist=types[g + "Twist"](linear=zero,
                                                                         angular=zero),
                                               covariance=np.zeros(36)))


def _camera_info(types, ros1: bool, header, camera: Camera, D: np.ndarray):
    P = np.zeros((3, 4))
    P[:, :3] = camera.K
    arrays = {"d": np.asarray(D, np.float64), "k": camera.K.ravel().astype(np.float64),
              "r": np.eye(3).ravel(), "p": P.ravel()}
    if ros1:
        arrays = {k.upper(): v for k, v in arrays.items()}
    roi = types["sensor_msgs/msg/RegionOfInterest"](0, 0, 0, 0, False)
    return types["sensor_msgs/msg/CameraInfo"](
        header=header, height=camera.height, width=camera.width, distortion_model="plumb_bob",
        binning_x=0, binning_y=0, roi=roi, **arrays)


def _image(types, header, rgb: np.ndarray, jpeg_quality: int):
    if jpeg_quality:
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]),
                               [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        if not ok:
            raise OSError("could not encode a frame as JPEG")
        return types["sensor_msgs/msg/CompressedImage"](header=header, format="jpeg",
                                                        data=buf.reshape(-1))
    return types["sensor_msgs/msg/Image"](
        header=header, height=rgb.shape[0], width=rgb.shape[1], encoding="rgb8",
        is_bigendian=0, step=rgb.shape[1] * 3, data=rgb.reshape(-1))


def export_bag(dataset: str | Path, flight: str, out: str | Path, *, ros1: bool = False,
               mcap: bool = False, jpeg_quality: int = 0, topics: BagTopicsConfig | None = None,
               odometry_frame: np.ndarray | None = None, scale: float = 1.0,
               distortion: Sequence[float] | None = None) -> Path:
    """Write a flight as a ROS 2 bag folder (sqlite3 or MCAP storage) or a ROS 1 ``.bag``.

    sensor_msgs/Image (rgb8; with ``jpeg_quality`` > 0 sensor_msgs/CompressedImage JPEG) and
    one CameraInfo per frame, nav_msgs/Odometry for the odometry and, on
    ``topics.groundtruth`` (default ``/groundtruth``), for the ground truth; header stamps and
    bag times are the flight times. Other arguments as ``export_folder``.
    """
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    topics = topics or BagTopicsConfig(groundtruth="/groundtruth")
    ds = Dataset(dataset)
    f = ds.flight(flight)
    frames = FlightFrames(f, ds.camera, scale, distortion)
    M = np.eye(4) if odometry_frame is None else np.asarray(odometry_frame, dtype=np.float64)
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types, ser = store.types, (store.serialize_ros1 if ros1 else store.serialize_cdr)
    with staged(Path(out)) as path:
        plugin = StoragePlugin.MCAP if mcap else StoragePlugin.SQLITE3
        writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=plugin)
        with writer:
            def conn(topic, msgtype):
                return writer.add_connection(topic, msgtype, typestore=store)

            image_type = "sensor_msgs/msg/" + ("CompressedImage" if jpeg_quality else "Image")
            c = {"image": conn(topics.image, image_type),
                 "info": conn(topics.camera_info, "sensor_msgs/msg/CameraInfo"),
                 "odom": conn(topics.odometry, "nav_msgs/msg/Odometry")}
            if topics.groundtruth:
                c["gt"] = conn(topics.groundtruth, "nav_msgs/msg/Odometry")
            for i, t in enumerate(f.timestamps):
                ns = round(float(t) * NS)
                rgb = frames(i)
                h = _header(types, ros1, ns, "camera", i)
                msgs = [("image", _image(types, h, rgb, jpeg_quality), image_type),
                        ("info", _camera_info(types, ros1, h, frames.camera, frames.distortion),
                         "sensor_msgs/msg/CameraInfo"),
                        ("odom", _odometry(types, _header(types, ros1, ns, "odom", i),
                                           M @ f.odometry[i]), "nav_msgs/msg/Odometry")]
                if "gt" in c:
                    msgs.append(("gt", _odometry(types, _header(types, ros1, ns, "world", i),
                                                 f.groundtruth[i]), "nav_msgs/msg/Odometry"))
                for key, msg, msgtype in msgs:
                    writer.write(c[key], ns, ser(msg, msgtype))
    return Path(out)


def main(argv: Sequence[str] | None = None) -> Path:
    p = argparse.ArgumentParser(prog="python -m localize.recordings.export",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("dataset", help="dataset folder made by `python -m datagen`")
    p.add_argument("flight", help="flight name (a folder under DATASET/flights)")
    p.add_argument("out", help="recording to create (folder, ROS 2 bag folder or .bag file)")
    kind = p.add_mutually_exclusive_group()
    kind.add_argument("--bag", action="store_true", help="write a ROS 2 bag (sqlite3)")
    kind.add_argument("--bag1", action="store_true", help="write a ROS 1 .bag")
    p.add_argument("--mcap", action="store_true", help="ROS 2 bag: MCAP storage, not sqlite3")
    p.add_argument("--jpeg-quality", type=int, default=None,
                   help="JPEG quality of the frames, 0: lossless (folder: PNG files, default "
                        "95; bag: sensor_msgs/Image rgb8, the default)")
    p.add_argument("--image-topic", default=None,
                   help="bag: image topic (default /camera/image_raw)")
    p.add_argument("--odometry-frame", type=float, nargs=4, default=None,
                   metavar=("X", "Y", "Z", "YAW_DEG"),
                   help="express the odometry in a frame moved by this from the world's")
    p.add_argument("--scale", type=float, default=1.0, help="image scale of the recorded camera")
    p.add_argument("--distortion", type=float, nargs=5, default=None,
                   metavar=("K1", "K2", "P1", "P2", "K3"), help="plumb_bob distortion")
    a = p.parse_args(argv)
    frame = None
    if a.odometry_frame is not None:
        x, y, z, yaw = a.odometry_frame
        frame = pose_from_xyzyaw([x, y, z, np.deg2rad(yaw)])[0]
    common = {"odometry_frame": frame, "scale": a.scale, "distortion": a.distortion}
    if a.bag or a.bag1:
        topics = BagTopicsConfig(groundtruth="/groundtruth")
        if a.image_topic:
            topics = replace(topics, image=a.image_topic)
        out = export_bag(a.dataset, a.flight, a.out, ros1=a.bag1, mcap=a.mcap, topics=topics,
                         jpeg_quality=a.jpeg_quality or 0, **common)
    else:
        quality = 95 if a.jpeg_quality is None else a.jpeg_quality
        out = export_folder(a.dataset, a.flight, a.out, jpeg_quality=quality, **common)
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    with user_errors():
        main()
