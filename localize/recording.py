"""Recorded flights of one's own camera as frames the localizer consumes (docs/recording.md).

A recording is a folder (``images/``, ``camera.yaml``, ``odometry.txt``, optional
``images.txt``, ``groundtruth.txt``, ``body_from_cam.txt``) or a ROS 1 ``.bag`` / ROS 2 bag
folder (``localize.recording_bag``). ``read_recording`` turns either into a ``Recording``:

- frames are read lazily, one at a time, when asked (``image(i)``, ``images()``);
- every frame is rectified to the target camera (the dataset's, which the SegNet was trained
  on): undistorted at the recorded size (OpenCV ``plumb_bob`` / ``rational_polynomial``),
  then scaled to cover the target size and centre-cropped (the aspect ratio is kept, the
  excess of one axis is cut off equally on both sides). ``Recording.camera`` is the camera of
  the delivered frames: the resulting K, the target size, the recording's body_from_cam;
- odometry and ground truth are interpolated at the frame times (linear translation, slerp
  rotation); frames outside their time span are dropped with a warning (a VIO starts after
  the camera), and it is an error when no frame is left. The odometry stays in its own frame
  (any start position and heading; z must be up, since roll and pitch are read from it): the
  localizer uses its increments and its attitude only.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import NamedTuple, Protocol

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation, Slerp

from core.dataset import Camera
from core.poses import read_tum
from localize.particle_filter import odometry_increment

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
#: Distortion models OpenCV's pinhole undistortion implements, and their coefficient counts.
DISTORTION_MODELS = {"plumb_bob": (4, 5, 8), "rational_polynomial": (8,)}
#: Frames this close (seconds) beyond a pose stream's ends still count as inside it.
SPAN_SLACK = 1e-6


class FrameSource(Protocol):
    """Raw recorded frames: ``read(i)`` and ``iter()`` give (h, w, 3) uint8 RGB images."""

    def __len__(self) -> int: ...

    def read(self, index: int) -> np.ndarray: ...

    def iter(self) -> Iterator[np.ndarray]: ...


@dataclass(frozen=True)
class SourceCamera:
    """The recorded camera: K (3,3), image size (pixels), distortion coefficients (k,) in
    OpenCV order (k1, k2, p1, p2[, k3[, k4, k5, k6]]), zeros or empty for none."""

    K: np.ndarray
    width: int
    height: int
    distortion: np.ndarray


@dataclass(frozen=True)
class Rectifier:
    """Maps recorded frames (source size) to delivered frames (width x height).

    Undistorts at the source size with the source K, resizes by ``(sx, sy)`` (about the same
    factor on both axes: the smallest that covers the target) and crops the centre.
    """

    source: SourceCamera
    width: int
    height: int

    @cached_property
    def _plan(self) -> tuple[int, int, int, int]:
        w, h = self.source.width, self.source.height
        s = max(self.width / w, self.height / h)
        rw, rh = max(self.width, round(w * s)), max(self.height, round(h * s))
        return rw, rh, (rw - self.width) // 2, (rh - self.height) // 2

    @property
    def distorted(self) -> bool:
        return bool(np.any(np.asarray(self.source.distortion) != 0))

    @property
    def identity(self) -> bool:
        return not self.distorted and (self.source.width, self.source.height) == (
            self.width, self.height)

    @cached_property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsics of the delivered frames (pixel centres at integers)."""
        rw, rh, x0, y0 = self._plan
        sx, sy = rw / self.source.width, rh / self.source.height
        K = np.asarray(self.source.K, dtype=np.float64).copy()
        K[0, :2] *= sx
        K[1, 1] *= sy
        K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5 - x0
        K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5 - y0
        return K

    @cached_property
    def _maps(self) -> tuple[np.ndarray, np.ndarray]:
        src = self.source
        K = np.asarray(src.K, dtype=np.float64)
        return cv2.initUndistortRectifyMap(K, np.asarray(src.distortion, dtype=np.float64), None,
                                           K, (src.width, src.height), cv2.CV_32FC1)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """(h, w, 3) uint8 recorded frame -> (height, width, 3) uint8 delivered frame."""
        if self.identity:
            return image
        if self.distorted:
            image = cv2.remap(image, *self._maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        rw, rh, x0, y0 = self._plan
        if (rw, rh) != (self.source.width, self.source.height):
            shrink = rw < self.source.width
            image = cv2.resize(image, (rw, rh), interpolation=cv2.INTER_AREA if shrink
                               else cv2.INTER_LINEAR)
        return np.ascontiguousarray(image[y0:y0 + self.height, x0:x0 + self.width])


class RecordedFrame(NamedTuple):
    """One frame with what ``Localizer.step`` takes.

    Attributes:
        index: frame index in the recording.
        timestamp: seconds.
        image: (H, W, 3) uint8 RGB as delivered (``Recording.camera``).
        odometry_increment: (4,) forward, left, up (metres), yaw change (radians) since the
            previous frame in its heading frame (``particle_filter.odometry_increment``); None
            for the first frame.
        attitude: (4, 4) world_from_body odometry pose of the frame (its roll and pitch).
    """

    index: int
    timestamp: float
    image: np.ndarray
    odometry_increment: np.ndarray | None
    attitude: np.ndarray


@dataclass(frozen=True)
class Recording:
    """A recorded flight, ready for the localizer.

    Attributes:
        name: recording name (the folder or bag name without suffix).
        source: the folder or bag it was read from.
        camera: camera of the delivered frames (after undistortion, scaling and cropping).
        timestamps: (N,) frame times, seconds, strictly increasing.
        odometry: (N, 4, 4) world_from_body in the odometry's own (gravity-aligned) frame at the
            frame times; only increments and roll/pitch are meaningful.
        groundtruth: (N, 4, 4) world_from_body in the model's frame, or None.
        frames: the raw frames (lazy).
        rectifier: raw frame -> delivered frame.
    """

    name: str
    source: Path
    camera: Camera
    timestamps: np.ndarray
    odometry: np.ndarray
    groundtruth: np.ndarray | None
    frames: FrameSource
    rectifier: Rectifier

    def __len__(self) -> int:
        return len(self.timestamps)

    def image(self, index: int) -> np.ndarray:
        """Frame ``index`` as delivered: (camera.height, camera.width, 3) uint8 RGB."""
        if not 0 <= index < len(self):
            raise IndexError(f"{self.source}: frame {index} out of range [0, {len(self)})")
        return self.rectifier(self.frames.read(index))

    def images(self) -> Iterator[np.ndarray]:
        """All delivered frames in order, read one at a time (one pass over a bag)."""
        for image in self.frames.iter():
            yield self.rectifier(image)

    def steps(self) -> Iterator[RecordedFrame]:
        """The frames in order with their odometry increments and attitudes, e.g.
        ``for f in rec.steps(): localizer.step(f.image, f.odometry_increment, f.attitude,
        f.timestamp)``."""
        for i, image in enumerate(self.images()):
            inc = odometry_increment(self.odometry[i - 1], self.odometry[i]) if i else None
            yield RecordedFrame(i, float(self.timestamps[i]), image, inc, self.odometry[i])


# --- poses -----------------------------------------------------------------------------------


def interpolate_poses(times: np.ndarray, stamps: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses at given times: linear in translation, slerp in rotation.

    Args:
        times: (N,) query times, seconds, within ``[stamps[0], stamps[-1]]`` (clamped).
        stamps: (M,) strictly increasing sample times, seconds, M >= 2.
        poses: (M, 4, 4) sampled poses.

    Returns:
        (N, 4, 4) float64 poses.
    """
    stamps = np.asarray(stamps, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    if poses.shape != (len(stamps), 4, 4) or len(stamps) < 2:
        raise ValueError(f"need (M, 4, 4) poses with M >= 2 matching (M,) stamps, got "
                         f"{poses.shape} and {stamps.shape}")
    t = np.clip(np.asarray(times, dtype=np.float64), stamps[0], stamps[-1])
    out = np.tile(np.eye(4), (len(t), 1, 1))
    out[:, :3, :3] = Slerp(stamps, Rotation.from_matrix(poses[:, :3, :3]))(t).as_matrix()
    for k in range(3):
        out[:, k, 3] = np.interp(t, stamps, poses[:, k, 3])
    return out


def data_lines(path: Path) -> list[int]:
    """1-based line numbers of the data lines of a text file (not blank, not ``#`` comments)."""
    return [n for n, s in enumerate(path.read_text().splitlines(), 1)
            if s.split("#", 1)[0].strip()]


def check_increasing(times: np.ndarray, where: str, position) -> None:
    """Raise ValueError if ``times`` does not strictly increase.

    Args:
        times: (N,) seconds.
        where: the file or topic, for the message.
        position: index -> text locating sample ``index`` (e.g. ``"line 12"``).
    """
    bad = np.flatnonzero(np.diff(np.asarray(times, dtype=np.float64)) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise ValueError(f"{where}: timestamps must strictly increase, but {position(i)} has "
                         f"{times[i]:.9f} after {times[i - 1]:.9f} ({position(i - 1)}); sort the "
                         f"samples by time and remove duplicates")


def read_trajectory(path: Path, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory (``timestamp tx ty tz qx qy qz qw``, world_from_body) and check it.

    Args:
        path: the file.
        what: its role for messages, e.g. ``"odometry"``.

    Returns:
        (M,) seconds, (M, 4, 4) poses.
    """
    try:
        t, T = read_tum(path)
    except ValueError as err:
        raise ValueError(f"{path}: the {what} file is not TUM ({err}); write one pose per line "
                         f"as `timestamp tx ty tz qx qy qz qw` (world_from_body, quaternion "
                         f"x y z w, non-zero), `#` comments allowed") from err
    if len(t) < 2:
        raise ValueError(f"{path}: the {what} needs at least 2 poses to interpolate, found "
                         f"{len(t)}")
    lines = data_lines(path)
    check_increasing(t, str(path), lambda i: f"line {lines[i]}")
    return t, T


def select_frames(times: np.ndarray, spans: Mapping[str, np.ndarray], source: Path) -> np.ndarray:
    """Frames inside the time span of every pose stream, with a warning for the others.

    Args:
        times: (N,) frame times, seconds.
        spans: stream name -> its (M,) sample times.
        source: the recording, for messages.

    Returns:
        (N,) bool, True for the frames kept.

    Raises:
        ValueError: if no frame is inside, with the time spans.
    """
    keep = np.ones(len(times), dtype=bool)
    for name, stamps in spans.items():
        inside = (times >= stamps[0] - SPAN_SLACK) & (times <= stamps[-1] + SPAN_SLACK)
        if not inside.all():
            log.warning("%s: %d of %d frames lie outside the %s time span [%.6f, %.6f] s and are "
                        "dropped", source, int((~inside).sum()), len(times), name, stamps[0],
                        stamps[-1])
        keep &= inside
    if not keep.any():
        desc = ", ".join(f"{k} [{v[0]:.6f}, {v[-1]:.6f}]" for k, v in spans.items())
        raise ValueError(f"{source}: no frame (times {times[0]:.6f} .. {times[-1]:.6f} s) lies "
                         f"inside the pose streams' time spans ({desc}); the streams must share "
                         f"one clock")
    return keep


# --- cameras ---------------------------------------------------------------------------------


def check_rigid(T: np.ndarray, where: str) -> np.ndarray:
    """(4, 4) rigid transform check; returns it as float64."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"{where}: body_from_cam must be a 4x4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    if (not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0
            or not np.allclose(T[3], [0, 0, 0, 1])):
        raise ValueError(f"{where}: body_from_cam is not a rigid transform (rotation with "
                         f"det +1, last row 0 0 0 1): {T.tolist()}")
    return T


def check_distortion(model: str, coeffs: np.ndarray, where: str) -> np.ndarray:
    """Validate a distortion model and its coefficients; returns (k,) float64."""
    coeffs = np.asarray(coeffs, dtype=np.float64).reshape(-1)
    if not np.any(coeffs):
        return np.zeros(0)
    if model not in DISTORTION_MODELS:
        raise ValueError(f"{where}: distortion_model {model!r} is not supported; use one of "
                         f"{sorted(DISTORTION_MODELS)} (OpenCV's pinhole models) or rectify the "
                         f"images first")
    if len(coeffs) not in DISTORTION_MODELS[model]:
        raise ValueError(f"{where}: {model} needs {DISTORTION_MODELS[model]} coefficients, got "
                         f"{len(coeffs)}")
    return coeffs


def delivered_camera(source: SourceCamera, target: Camera | None,
                     body_from_cam: np.ndarray | None, where: str) -> tuple[Camera, Rectifier]:
    """The delivered camera and the rectifier from a recorded camera to the target's size.

    Args:
        source: the recorded camera.
        target: the camera the frames are for (its size; its body_from_cam is the default), or
            None to keep the recorded size.
        body_from_cam: (4, 4) the recording's camera mount, or None for the target's.
        where: the recording, for messages.
    """
    if body_from_cam is None:
        if target is None:
            raise ValueError(f"{where}: no body_from_cam: give the recording one (see "
                             f"docs/recording.md) or pass a target camera")
        body_from_cam = target.body_from_cam
    w, h = (source.width, source.height) if target is None else (target.width, target.height)
    rect = Rectifier(source, int(w), int(h))
    return Camera(rect.K, int(w), int(h), check_rigid(body_from_cam, where)), rect


def _field(d: Mapping, key: str, path: Path):
    if key not in d:
        raise ValueError(f"{path}: field {key!r} missing; camera.yaml follows ROS "
                         f"camera_calibration (image_width, image_height, camera_matrix: "
                         f"{{rows, cols, data}}, distortion_model, distortion_coefficients: "
                         f"{{data}})")
    return d[key]


def _matrix(value, key: str, shape: tuple[int, int], path: Path) -> np.ndarray:
    data = value.get("data") if isinstance(value, Mapping) else value
    try:
        m = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {key} is not numeric: {err}") from err
    if m.size != shape[0] * shape[1]:
        raise ValueError(f"{path}: {key} must have {shape[0] * shape[1]} values ({shape[0]}x"
                         f"{shape[1]}, row-major `data`), got {m.size}")
    return m.reshape(shape)


def read_camera_yaml(path: Path) -> tuple[SourceCamera, np.ndarray | None]:
    """Read a ROS camera_calibration ``camera.yaml``.

    Returns:
        The recorded camera and its (4, 4) body_from_cam (a ``body_from_cam`` key, or a
        ``body_from_cam.txt`` beside the file), None if neither is there.
    """
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: a folder recording needs the camera "
                                f"calibration in ROS camera_calibration YAML (docs/recording.md)")
    try:
        d = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML: {err}") from err
    if not isinstance(d, Mapping):
        raise ValueError(f"{path}: expected a mapping of calibration fields")
    K = _matrix(_field(d, "camera_matrix", path), "camera_matrix", (3, 3), path)
    width, height = int(_field(d, "image_width", path)), int(_field(d, "image_height", path))
    dist = d.get("distortion_coefficients") or {}
    coeffs = np.asarray(dist.get("data", []) if isinstance(dist, Mapping) else dist, float)
    model = d.get("distortion_model", "plumb_bob" if coeffs.size else "none")
    coeffs = check_distortion(str(model), coeffs, f"{path}: distortion_coefficients")
    body = None
    if "body_from_cam" in d:
        body = _matrix(d["body_from_cam"], "body_from_cam", (4, 4), path)
    elif (path.parent / "body_from_cam.txt").is_file():
        txt = path.parent / "body_from_cam.txt"
        try:
            body = np.loadtxt(txt, comments="#", ndmin=2)
        except ValueError as err:
            raise ValueError(f"{txt}: expected 4 rows of 4 numbers: {err}") from err
        body = check_rigid(body, str(txt))
    return SourceCamera(K, width, height, coeffs), body


# --- folder recordings -----------------------------------------------------------------------


@dataclass(frozen=True)
class FolderFrames:
    """Frames stored as image files, read when asked."""

    paths: tuple[Path, ...]
    width: int
    height: int

    def __len__(self) -> int:
        return len(self.paths)

    def read(self, index: int) -> np.ndarray:
        path = self.paths[index]
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ValueError(f"cannot read image {path}: not a readable PNG or JPEG; replace it "
                             f"or remove it (and its images.txt line)")
        if bgr.shape[:2] != (self.height, self.width):
            raise ValueError(f"{path}: image is {bgr.shape[1]}x{bgr.shape[0]}, but camera.yaml "
                             f"says {self.width}x{self.height}; fix image_width/image_height")
        return np.ascontiguousarray(bgr[..., ::-1])

    def iter(self) -> Iterator[np.ndarray]:
        for i in range(len(self)):
            yield self.read(i)


def _frames_from_list(root: Path) -> tuple[list[Path], np.ndarray]:
    index = root / "images.txt"
    lines = [(n, s.split("#", 1)[0].split()) for n, s in
             enumerate(index.read_text().splitlines(), 1)]
    lines = [(n, parts) for n, parts in lines if parts]
    paths, times = [], []
    for n, parts in lines:
        try:
            if len(parts) != 2:
                raise ValueError(f"{len(parts)} fields")
            times.append(float(parts[0]))
        except ValueError as err:
            raise ValueError(f"{index} line {n}: expected `timestamp filename` ({err})") from err
        p = root / parts[1]
        if not p.is_file() and (root / "images" / parts[1]).is_file():
            p = root / "images" / parts[1]
        if not p.is_file():
            raise FileNotFoundError(f"{index} line {n}: image {parts[1]} not found in {root} "
                                    f"or {root / 'images'}")
        paths.append(p)
    if not paths:
        raise ValueError(f"{index}: no `timestamp filename` lines")
    t = np.array(times)
    check_increasing(t, str(index), lambda i: f"line {lines[i][0]}")
    return paths, t


def _frames_from_names(root: Path) -> tuple[list[Path], np.ndarray]:
    d = root / "images"
    paths = [p for p in d.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES] if d.is_dir() else []
    if not paths:
        raise FileNotFoundError(f"{d}: no PNG or JPEG images (a folder recording keeps its "
                                f"frames in images/)")
    times = []
    for p in paths:
        try:
            times.append(float(p.stem))
        except ValueError as err:
            raise ValueError(f"{p}: the file name is not a time in seconds (e.g. "
                             f"1700000000.125{p.suffix}); name the frames by time or list them "
                             f"in {root / 'images.txt'} as `timestamp filename` lines") from err
    order = np.argsort(times, kind="stable")
    paths, t = [paths[i] for i in order], np.asarray(times)[order]
    check_increasing(t, str(d), lambda i: f"file {paths[i].name}")
    return paths, t


def read_folder(root: Path, target: Camera | None, body_from_cam: np.ndarray | None,
                name: str | None = None) -> Recording:
    """Read a folder recording (layout in the module docstring and docs/recording.md)."""
    source, own_body = read_camera_yaml(root / "camera.yaml")
    camera, rect = delivered_camera(source, target,
                                    body_from_cam if body_from_cam is not None else own_body,
                                    str(root / "camera.yaml"))
    paths, t = (_frames_from_list if (root / "images.txt").is_file() else _frames_from_names)(root)
    if not (root / "odometry.txt").is_file():
        raise FileNotFoundError(f"{root / 'odometry.txt'} not found: a recording needs the "
                                f"odometry as a TUM file (world_from_body, any start frame)")
    streams = {"odometry": read_trajectory(root / "odometry.txt", "odometry")}
    if (root / "groundtruth.txt").is_file():
        streams["groundtruth"] = read_trajectory(root / "groundtruth.txt", "ground truth")
    keep = select_frames(t, {k: v[0] for k, v in streams.items()}, root)
    t = t[keep]
    poses = {k: interpolate_poses(t, *v) for k, v in streams.items()}
    frames = FolderFrames(tuple(p for p, k in zip(paths, keep, strict=True) if k),
                          source.width, source.height)
    return Recording(name or root.name, root, camera, t, poses["odometry"],
                     poses.get("groundtruth"), frames, rect)


def read_recording(path: str | Path, target: Camera | None = None, *,
                   topics: Mapping | None = None, body_from_cam: np.ndarray | None = None,
                   name: str | None = None) -> Recording:
    """Read a recording: a folder, a ROS 1 ``.bag`` or a ROS 2 bag folder.

    Args:
        path: the recording.
        target: camera the frames are delivered for (size; default body_from_cam), usually the
            dataset's; None keeps the recorded size (frames are still undistorted).
        topics: bag topics (``localize.recording_bag.BagTopics`` keys: image, camera_info,
            odometry, groundtruth); ignored for folders.
        body_from_cam: (4, 4) camera mount overriding the recording's own.
        name: recording name (default: the file or folder name without suffix).

    Returns:
        The recording (frames not read yet).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"recording not found: {path}")
    if path.suffix == ".bag" or (path / "metadata.yaml").is_file():
        from localize.recording_bag import read_bag

        return read_bag(path, target, topics=topics, body_from_cam=body_from_cam, name=name)
    if path.is_dir() and ((path / "images").is_dir() or (path / "images.txt").is_file()):
        return read_folder(path, target, body_from_cam, name)
    raise ValueError(f"{path}: not a recording: expected a folder with images/ and camera.yaml, "
                     f"a ROS 1 .bag file or a ROS 2 bag folder with metadata.yaml "
                     f"(docs/recording.md)")
