"""Folder recordings: ``images/``, ``camera.yaml``, ``odometry.txt`` and optional
``images.txt``, ``groundtruth.txt``, ``body_from_cam.txt`` (docs/recording.md).

``camera.yaml`` is in the ROS camera_calibration format (``image_width``, ``image_height``,
``camera_matrix: {rows, cols, data}``, ``distortion_model``, ``distortion_coefficients:
{data}``), with the camera mount as an extra ``body_from_cam`` (4x4, row-major ``data``) or in
``body_from_cam.txt`` beside it. Frame times come from ``images.txt`` (``timestamp filename``
lines, paths relative to the folder or to images/) or else from the file names (seconds, e.g.
``1700000000.125.jpg``). Frames are read from disk when asked.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from core.atomic import encoded_image_complete
from core.dataset import Camera
from core.poses import interpolate_poses
from localize.recordings.recording import (
    IMAGE_SUFFIXES,
    Recording,
    SourceCamera,
    UnreadableFrame,
    check_distortion,
    check_increasing,
    check_rigid,
    delivered_camera,
    read_trajectory,
    select_frames,
)

log = logging.getLogger(__name__)


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
        fix = "replace it or remove it (and its images.txt line)"
        try:
            data = path.read_bytes()
        except OSError as err:
            raise UnreadableFrame(f"cannot read image {path}: {err.strerror}; {fix}") from None
        if not encoded_image_complete(data):
            raise UnreadableFrame(f"cannot read image {path}: the file is cut short (no end "
                                  f"marker after {len(data)} bytes); {fix}")
        bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
        if bgr is None:
            raise UnreadableFrame(f"cannot read image {path}: not a readable PNG or JPEG; {fix}")
        if bgr.shape[:2] != (self.height, self.width):
            raise ValueError(f"{path}: image is {bgr.shape[1]}x{bgr.shape[0]}, but camera.yaml "
                             f"says {self.width}x{self.height}; fix image_width/image_height")
        return np.ascontiguousarray(bgr[..., ::-1])

    def iter(self) -> Iterator[np.ndarray | None]:
        for i in range(len(self)):
            try:
                yield self.read(i)
            except UnreadableFrame as err:
                log.warning("%s; frame %d dropped", err, i)
                yield None


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
