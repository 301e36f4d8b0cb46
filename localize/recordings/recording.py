"""Recorded flights of one's own camera as frames the localizer consumes (docs/recording.md).

A recording is a folder (``images/``, ``camera.yaml``, ``odometry.txt``, optional
``images.txt``, ``groundtruth.txt``, ``body_from_cam.txt``; ``localize.recordings.folder``) or a
ROS 1 ``.bag`` / ROS 2 bag folder (``localize.recordings.bag``). ``read.read_recording`` turns
either into a ``Recording``:

- frames are read lazily, one at a time, when asked (``image(i)``, ``images()``,
  ``steps()``: the ``core.frames.FrameSource`` a run loops over); a frame that cannot be
  decoded (``UnreadableFrame``; a PNG or JPEG cut short too) is dropped from ``steps()`` with a
  warning, as a camera's dropped frame;
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
from typing import Protocol

import cv2
import numpy as np

from core.dataset import Camera
from core.frames import Frame, delivered_frames
from core.imaging.camera import FORWARD_MOUNT_XYZ, forward_mount
from core.imaging.lens import Undistorter
from core.poses import read_tum

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
#: Distortion models OpenCV's pinhole undistortion implements, and their coefficient counts.
DISTORTION_MODELS = {"plumb_bob": (4, 5, 8), "rational_polynomial": (8,)}
#: Frames this close (seconds) beyond a pose stream's ends still count as inside it.
SPAN_SLACK = 1e-6


class UnreadableFrame(ValueError):
    """A recorded frame that cannot be decoded (a broken file or message, or one cut short:
    ``core.atomic.encoded_image_complete``): ``Recording.steps`` drops it as a dropped frame."""


class RawFrames(Protocol):
    """Raw recorded frames: ``read(i)`` gives frame i's (h, w, 3) uint8 RGB image (ValueError
    naming the frame, ``UnreadableFrame`` when it cannot be decoded); ``iter()`` gives them in
    order, None (with a warning naming the frame) for one that cannot be decoded."""

    def __len__(self) -> int: ...

    def read(self, index: int) -> np.ndarray: ...

    def iter(self) -> Iterator[np.ndarray | None]: ...


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

    Undistorts at the source size with the source K (``core.imaging.lens.Undistorter``: pixels the
    lens did not see repeat the border, so they add no edge), resizes by ``(sx, sy)`` (about
    the same factor on both axes: the smallest that covers the target) and crops the centre.
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
    def _undistorter(self) -> Undistorter:
        src = self.source
        return Undistorter(np.asarray(src.K, dtype=np.float64), src.distortion, src.width,
                           src.height)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """(h, w, 3) uint8 recorded frame -> (height, width, 3) uint8 delivered frame."""
        if self.identity:
            return image
        if self.distorted:
            image = self._undistorter.image(image)
        rw, rh, x0, y0 = self._plan
        if (rw, rh) != (self.source.width, self.source.height):
            shrink = rw < self.source.width
            image = cv2.resize(image, (rw, rh), interpolation=cv2.INTER_AREA if shrink
                               else cv2.INTER_LINEAR)
        return np.ascontiguousarray(image[y0:y0 + self.height, x0:x0 + self.width])


@dataclass(frozen=True)
class Recording:
    """A recorded flight, ready for the localizer (a ``core.frames.FrameSource``).

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
    frames: RawFrames
    rectifier: Rectifier

    def __len__(self) -> int:
        return len(self.timestamps)

    def image(self, index: int) -> np.ndarray:
        """Frame ``index`` as delivered: (camera.height, camera.width, 3) uint8 RGB."""
        if not 0 <= index < len(self):
            raise IndexError(f"{self.source}: frame {index} out of range [0, {len(self)})")
        return self.rectifier(self.frames.read(index))

    def images(self) -> Iterator[np.ndarray | None]:
        """All delivered frames in order, read one at a time (one pass over a bag); None for
        a frame that cannot be read (warned, naming it)."""
        for image in self.frames.iter():
            yield None if image is None else self.rectifier(image)

    def steps(self, limit: int | None = None, *, images: bool = True,
              labels: bool = False) -> Iterator[Frame]:
        """The first ``limit`` frames (all: None) in order with their odometry increments and
        attitudes (``core.frames.delivered_frames``; a frame that cannot be read is dropped),
        e.g. ``for f in rec.steps(): localizer.step(f.image, f.odometry_increment,
        f.attitude, f.timestamp)``. A recording has no true labels: ``labels`` gives None."""
        return delivered_frames(self, limit, self.images() if images else None)


# --- poses -----------------------------------------------------------------------------------


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
        target: the camera the frames are for (its size; its body_from_cam is the default: a
            dataset's camera; None there, as ``world_file.frames_target`` makes it, stands for
            the forward camera ``core.imaging.camera.forward_mount``, with a warning), or None
            to keep the recorded size.
        body_from_cam: (4, 4) the recording's camera mount, or None for the target's.
        where: the recording, for messages.
    """
    K = np.asarray(source.K, dtype=np.float64)
    if source.width <= 0 or source.height <= 0 or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"{where}: the camera needs a positive image size and focal lengths, "
                         f"got {source.width}x{source.height} and K {K.tolist()}; calibrate it")
    if body_from_cam is None:
        if target is None:
            raise ValueError(f"{where}: no body_from_cam: give the recording one (see "
                             f"docs/recording.md) or pass a target camera")
        body_from_cam = target.body_from_cam
    if body_from_cam is None:
        body_from_cam = forward_mount()
        log.warning("%s: no camera mount (body_from_cam) given; assuming a level forward camera "
                    "%.2f m ahead of the body centre. Give it: recording_body_from_cam=[[...]] "
                    "(python -m localize), body_from_cam=[[...]] (the node) or body_from_cam "
                    "in camera.yaml (docs/recording.md)", where, FORWARD_MOUNT_XYZ[0])
    w, h = (source.width, source.height) if target is None else (target.width, target.height)
    rect = Rectifier(source, int(w), int(h))
    return Camera(rect.K, int(w), int(h), check_rigid(body_from_cam, where)), rect
