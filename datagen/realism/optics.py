"""The optics of the flights' camera (``realism.lens``, ``realism.motion_blur``,
``realism.rolling_shutter``, ``realism.subframes``; ``RealismConfig``): lens distortion, motion
blur and a rolling shutter, rendered. Training images are not affected.

A flight frame at time t (frame i at t = i / fps) is made of S sub-frames:

- rows: row r of the H rows ends its exposure at t_r = t + (r / H - 0.5) * readout_s and is
  exposed over [t_r - exposure_s, t_r] (``row_times``); a global shutter has readout_s 0;
- sub-frames: the span [a, b] the rows' windows cover is cut into S equal intervals, and a
  sub-frame rendered at each interval's middle, at the pose interpolated along the flight's
  true trajectory (``core.poses.interpolate_poses``: position linear, rotation slerp,
  between the frames' poses; extrapolated from the first or last interval beyond them). S is
  the number that keeps the image's motion between sub-frames at most ``subframes.step_px``
  (``subframe_count``), at most ``subframes.max_count``;
- lens: each sub-frame is rendered by a pinhole camera of K's focal length large enough to
  hold every ray of the distorted image (``core.imaging.lens.cover_camera``) and resampled through
  the lens (``core.imaging.lens.distort_maps``, cv2.remap: bilinear in linear light, labels and
  depth nearest);
- rows: each row of the frame is the mean, in linear light, of the sub-frames weighted by how
  much of its exposure window their interval covers (``assemble``; a window of zero length
  takes the sub-frame whose interval holds t_r). Its label and depth come from the sub-frame
  nearest its mid-exposure time t_r - exposure_s / 2 (``pick_rows``), so labels match the
  image.

The result is the rendered frame the camera effects (core/imaging/camera_effects.py) then take.
The distractors stay where they are at frame i during its sub-frames (people walk 1-2 cm in a
blur window). A frame's sub-frames depend only on the flight's true poses and i, and their
render seeds are drawn from the frame's own generator: resume and shards give the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np

from core import classes as C
from core.config import as_config
from core.dataset import Camera
from core.imaging import lens
from core.imaging.colour import linear_to_srgb8
from core.imaging.realism import RealismConfig
from core.poses import interpolate_poses
from datagen.rendering.render import Traced

WHERE = "realism"
#: m, the depth the sub-frame count assumes for the nearest surfaces in view: the image
#: motion of a translation d is about f d / NEAR_M pixels.
NEAR_M = 1.0


# --------------------------------------------------------------------------- settings


def _non_negative(value: float, key: str, what: str) -> float:
    value = float(value)
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"{key} = {value} must be a time >= 0 s ({what}); 0 turns it off")
    return value


def lens_coefficients(settings: RealismConfig) -> np.ndarray:
    """(5,) float64 plumb_bob coefficients (k1, k2, p1, p2, k3) of ``realism.lens``."""
    c = settings.lens
    return np.array([c.k1, c.k2, c.p1, c.p2, c.k3], dtype=np.float64)


def check_settings(settings: RealismConfig | Mapping | None, camera: Camera,
                   fps: Mapping[str, float], where: str = WHERE) -> RealismConfig:
    """The realism settings typed, with their optics checked against the flights' camera and
    the frame rates of the flights rendered.

    Args:
        settings: ``RealismConfig`` or a mapping of the keys that differ from its defaults.
        camera: the flights' camera (K, size).
        fps: flight name -> frame rate (Hz) of each flight rendered.
        where: the settings' config key, for messages.

    Raises:
        ValueError: naming the key and the fix: lens coefficients that fold the image or see
            too wide a field, an exposure or readout time < 0 or not shorter than a flight's
            frame interval, a sub-frame step <= 0 or a count < 1.
    """
    c = as_config(RealismConfig, settings, where)
    d = lens_coefficients(c)
    lens.check_plumb_bob(d, camera.K, camera.width, camera.height, f"{where}.lens")
    if lens.is_distorted(d):
        lens.cover_camera(camera.K, d, camera.width, camera.height, f"{where}.lens")
    exposure = _non_negative(c.motion_blur.exposure_s, f"{where}.motion_blur.exposure_s",
                             "the exposure time")
    readout = _non_negative(c.rolling_shutter.readout_s, f"{where}.rolling_shutter.readout_s",
                            "top to bottom row")
    for name, rate in fps.items():
        interval = 1.0 / float(rate)
        if exposure >= interval:
            raise ValueError(f"{where}.motion_blur.exposure_s = {exposure:g} s is not shorter "
                             f"than flights.{name}'s frame interval 1 / fps = {interval:g} s; "
                             "a camera exposes each frame within its interval: shorten it "
                             "(indoors 0.005-0.02 s) or lower the fps")
        if readout >= interval:
            raise ValueError(f"{where}.rolling_shutter.readout_s = {readout:g} s is not shorter "
                             f"than flights.{name}'s frame interval 1 / fps = {interval:g} s; "
                             "a sensor reads a frame out before the next: shorten it "
                             "(0.01-0.03 s) or lower the fps")
    step = float(c.subframes.step_px)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"{where}.subframes.step_px = {step} must be > 0 pixels (1: no visible "
                         "steps in a blur)")
    n = c.subframes.max_count
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"{where}.subframes.max_count = {n} must be an integer >= 1")
    return c


def is_active(settings: RealismConfig) -> bool:
    """Whether the flights' frames are rendered through the optics (a distorting lens, an
    exposure or a readout time)."""
    return (lens.is_distorted(lens_coefficients(settings))
            or settings.motion_blur.exposure_s > 0 or settings.rolling_shutter.readout_s > 0)


# --------------------------------------------------------------------------- time and poses


def row_times(t: float, height: int, readout_s: float) -> np.ndarray:
    """(H,) s, when each row of a frame at time t ends its exposure:
    t + (r / H - 0.5) * readout_s."""
    return t + (np.arange(int(height)) / float(height) - 0.5) * float(readout_s)


def frame_span(t: float, height: int, exposure_s: float, readout_s: float
               ) -> tuple[float, float]:
    """(a, b) s, the times the rows' exposure windows cover."""
    ends = row_times(t, height, readout_s)
    return float(ends[0] - exposure_s), float(ends[-1])


def subframe_count(world_from_cam: np.ndarray, f_px: float, step_px: float,
                   max_count: int) -> int:
    """Sub-frames for a span whose camera moves from pose [0] to pose [1]: ceil(motion /
    step_px) within [1, max_count], motion = f (angle + distance / ``NEAR_M``) pixels (the
    rotation's angle in radians, the translation in metres).

    Args:
        world_from_cam: (2, 4, 4) the camera at the span's start and end.
        f_px: focal length, pixels.
        step_px: image motion allowed between sub-frames, pixels.
        max_count: the most sub-frames.
    """
    a, b = np.asarray(world_from_cam, dtype=np.float64)
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    motion = f_px * (math.acos(cos) + np.linalg.norm(b[:3, 3] - a[:3, 3]) / NEAR_M)
    return int(min(max(math.ceil(motion / step_px - 1e-9), 1), max_count))


@dataclass(frozen=True)
class FramePlan:
    """The sub-frames of one frame.

    times: (S,) s, the sub-frames' times (their intervals' middles). weights: (H, S) float32,
    each row's share of each sub-frame (rows sum to 1). nearest: (H,) int64, the sub-frame each
    row's label and depth come from.
    """

    times: np.ndarray
    weights: np.ndarray
    nearest: np.ndarray


def frame_plan(t: float, height: int, exposure_s: float, readout_s: float,
               count: int) -> FramePlan:
    """The ``count`` sub-frames of a frame at time t (s) with H = ``height`` rows (module
    docstring): equal intervals over the rows' span, each row's weights the share of its
    exposure window each interval covers (with no exposure, the interval holding its time),
    its nearest sub-frame the one whose interval holds its mid-exposure time (the interval's
    middle is the nearest sub-frame time; the later one at a boundary)."""
    H, S = int(height), int(count)
    ends = row_times(t, H, readout_s)
    a, b = frame_span(t, H, exposure_s, readout_s)
    edges = a + (b - a) * np.arange(S + 1) / S
    times = 0.5 * (edges[:-1] + edges[1:])
    width = (b - a) / S if b > a else 1.0

    def interval(x: np.ndarray) -> np.ndarray:  # the interval holding each time
        return np.clip(np.floor((x - a) / width + 1e-9).astype(np.int64), 0, S - 1)

    if exposure_s > 0:
        lo = np.maximum(ends[:, None] - exposure_s, edges[None, :-1])
        hi = np.minimum(ends[:, None], edges[None, 1:])
        weights = np.clip(hi - lo, 0.0, None) / exposure_s
        weights /= weights.sum(axis=1, keepdims=True)
    else:
        weights = np.zeros((H, S))
        weights[np.arange(H), interval(ends)] = 1.0
    nearest = interval(ends - 0.5 * exposure_s)  # the interval's middle is the nearest time
    return FramePlan(times, weights.astype(np.float32), nearest)


# --------------------------------------------------------------------------- images


def assemble(linear: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each row the weighted mean of the sub-frames' rows.

    Args:
        linear: (S, H, W, C) float32 sub-frames in linear light.
        weights: (H, S) each row's weights (``FramePlan.weights``).

    Returns:
        (H, W, C) float32.
    """
    linear = np.asarray(linear, dtype=np.float32)
    w = np.asarray(weights, dtype=np.float32)
    if linear.ndim != 4 or w.shape != (linear.shape[1], linear.shape[0]):
        raise ValueError(f"assemble: sub-frames {linear.shape} (S, H, W, C) and weights "
                         f"{w.shape} (H, S) do not match")
    return np.einsum("hs,shwc->hwc", w, linear, optimize=True)


def pick_rows(images: np.ndarray, nearest: np.ndarray) -> np.ndarray:
    """Row r of ``images[nearest[r]]`` for each row: (S, H, W, ...) -> (H, W, ...)."""
    H = images.shape[1]
    return images[np.asarray(nearest), np.arange(H)]


@dataclass(frozen=True)
class FlightOptics:
    """One flight's optics, resolved once (numpy only: a pipeline worker may use it).

    settings: the realism settings. camera: the flights' camera (the frames' K and size).
    render_camera: the pinhole camera the sub-frames are rendered with (``camera`` itself
    without distortion). maps: (H, W) float32 x and y maps from the frame into a
    render_camera image, or None without distortion. groundtruth: (N, 4, 4) world_from_body.
    fps: Hz.
    """

    settings: RealismConfig
    camera: Camera
    render_camera: Camera
    maps: tuple[np.ndarray, np.ndarray] | None
    groundtruth: np.ndarray
    fps: float

    @classmethod
    def build(cls, settings: RealismConfig, camera: Camera, groundtruth: np.ndarray,
              fps: float, where: str = WHERE) -> FlightOptics:
        d = lens_coefficients(settings)
        render_camera, maps = camera, None
        if lens.is_distorted(d):
            Kc, wc, hc = lens.cover_camera(camera.K, d, camera.width, camera.height,
                                           f"{where}.lens")
            render_camera = Camera(Kc, wc, hc, camera.body_from_cam)
            maps = lens.distort_maps(camera.K, d, camera.width, camera.height, Kc,
                                     f"{where}.lens")
        return cls(settings, camera, render_camera, maps, np.asarray(groundtruth), float(fps))

    @property
    def stamps(self) -> np.ndarray:
        """(N,) s, the frames' times i / fps."""
        return np.arange(len(self.groundtruth)) / self.fps

    def subframes(self, i: int) -> tuple[FramePlan, np.ndarray]:
        """Frame i's plan and its sub-frames' (S, 4, 4) world_from_body poses."""
        c = self.settings
        exposure, readout = c.motion_blur.exposure_s, c.rolling_shutter.readout_s
        t = i / self.fps
        H = self.camera.height
        a, b = frame_span(t, H, exposure, readout)
        count = 1
        if b > a:
            ends = interpolate_poses(np.array([a, b]), self.stamps, self.groundtruth,
                                     extrapolate=True)
            count = subframe_count(ends @ self.camera.body_from_cam,
                                   float(self.render_camera.K[0, 0]), c.subframes.step_px,
                                   c.subframes.max_count)
        plan = frame_plan(t, H, exposure, readout, count)
        return plan, interpolate_poses(plan.times, self.stamps, self.groundtruth, extrapolate=True)

    def finish(self, developer, traced: list[Traced], plan: FramePlan, exposure: float,
               sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The frame from its traced sub-frames (``Developer.develop_linear`` each, through the
        lens, rows assembled).

        Returns:
            rgb (H, W, 3) uint8 sRGB, label (H, W) uint8, depth (H, W) float32 metres.
        """
        H, W = self.camera.height, self.camera.width
        S = len(traced)
        linear = np.empty((S, H, W, 3), np.float32)
        labels = np.full((S, H, W), C.IGNORE, np.uint8)
        depth = np.zeros((S, H, W), np.float32)
        used = set(np.unique(plan.nearest).tolist())
        for s, tr in enumerate(traced):
            rgb, label, z = developer.develop_linear(tr, exposure, sigma)
            if self.maps is None:
                linear[s] = rgb
                if s in used:
                    labels[s], depth[s] = label, z
                continue
            mx, my = self.maps
            linear[s] = cv2.remap(rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            if s in used:
                labels[s] = cv2.remap(label, mx, my, cv2.INTER_NEAREST,
                                      borderMode=cv2.BORDER_CONSTANT, borderValue=C.IGNORE)
                depth[s] = cv2.remap(z, mx, my, cv2.INTER_NEAREST,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
        rgb = linear_to_srgb8(assemble(linear, plan.weights))
        return rgb, pick_rows(labels, plan.nearest), pick_rows(depth, plan.nearest)
