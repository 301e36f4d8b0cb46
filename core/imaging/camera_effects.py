"""Image imperfections of a drone's camera on the flights' images (``realism.noise``,
``realism.exposure``, ``realism.jpeg``, ``realism.dropout``; ``RealismConfig``).

They post-process a rendered 8-bit sRGB frame, in this order (``apply_effects``):

1. exposure: linear light times 2^e, e the frame's exposure offset in EV stops
   (``exposure_ev``: a slow smooth drift plus steps that auto exposure takes back out);
2. a ``covered`` dropout: the view blurred and darkened, as through a finger on the lens;
3. sensor noise in linear light (``sensor_noise``, Poisson-Gaussian), then 8-bit sRGB again;
4. JPEG encoding and decoding (``jpeg``);
5. a ``black`` or ``noise`` dropout: the frame replaced (a lost link: zeros, or uniform random
   pixels).

A flight's exposure series and dropout stretches are drawn once per flight, from the flight's
own generators (``exposure_ev``, ``dropout_stretches``); the sensor noise from each frame's own
generator, so a frame's image depends only on the seed, the flight and the frame's index, not
on which frames were rendered before (datagen resumes and shards). Every magnitude 0 (the
defaults, ``realism=ideal``): ``is_active`` is False and the images are the rendered ones.
Magnitudes of ``realism=real`` and their source: docs/realism.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import cv2
import numpy as np

from core.config import as_config
from core.imaging.colour import linear_to_srgb8, to_linear
from core.imaging.realism import (
    DropoutConfig,
    ExposureConfig,
    JpegConfig,
    RealismConfig,
    SensorNoiseConfig,
)

WHERE = "realism"
KINDS = ("black", "noise", "covered")  # the dropout kinds
COVERED_GAIN = 0.05  # linear light reaching the sensor through a covered lens
COVERED_BLUR = 0.05  # Gaussian blur std of a covered lens, a fraction of the image's larger side
MAX_EV = 8.0  # EV stops; an exposure setting beyond is a mistake, not an imperfection
T = TypeVar("T")


# --------------------------------------------------------------------------- settings


def _finite(value: float, key: str, rule: str, fix: str, ok: bool) -> float:
    """``value`` as a float if finite and ``ok``, else a ValueError naming ``key``."""
    value = float(value)
    if not (math.isfinite(value) and ok):
        raise ValueError(f"{key} = {value} must be {rule}; {fix}")
    return value


def _noise_rules(c: SensorNoiseConfig, where: str) -> None:
    """``full_well_e`` and ``read_noise_e`` finite and >= 0; a read noise needs a full well."""
    fw = _finite(c.full_well_e, f"{where}.full_well_e", "electrons >= 0",
                 "0 turns the sensor noise off", c.full_well_e >= 0)
    rn = _finite(c.read_noise_e, f"{where}.read_noise_e", "electrons >= 0",
                 "0 turns the read noise off", c.read_noise_e >= 0)
    if rn > 0 and fw == 0:
        raise ValueError(f"{where}.read_noise_e = {rn} needs {where}.full_well_e > 0 (the "
                         "electrons at the white level); set both to 0 for no sensor noise")


def _exposure_rules(c: ExposureConfig, where: str) -> None:
    """EV magnitudes in [0, ``MAX_EV``] (``max_ev`` > 0), a rate >= 0, times > 0."""
    for key in ("drift_ev", "step_ev"):
        v = getattr(c, key)
        _finite(v, f"{where}.{key}", f"EV stops in [0, {MAX_EV}]", "0 turns it off",
                0 <= v <= MAX_EV)
    _finite(c.max_ev, f"{where}.max_ev", f"EV stops in (0, {MAX_EV}]",
            "it bounds the exposure offset", 0 < c.max_ev <= MAX_EV)
    _finite(c.steps_per_min, f"{where}.steps_per_min", "a rate >= 0 per minute",
            "0 turns the steps off", c.steps_per_min >= 0)
    for key, what in (("drift_time_s", "drift_ev: 0 to turn the drift off"),
                      ("settle_s", "steps_per_min: 0 to turn the steps off")):
        v = getattr(c, key)
        _finite(v, f"{where}.{key}", "a time > 0 s", f"set {what}", v > 0)


def _jpeg_rules(c: JpegConfig, where: str) -> None:
    """``quality`` None or an integer in [1, 100]."""
    q = c.quality
    if q is not None and not (isinstance(q, int) and not isinstance(q, bool) and 1 <= q <= 100):
        raise ValueError(f"{where}.quality = {q} must be an integer in [1, 100] (OpenCV's "
                         "JPEG quality, 75-95 for a video link); null turns JPEG off")


def _dropout_rules(c: DropoutConfig, where: str) -> None:
    """A rate >= 0, start times >= 0, 0 < min <= max durations, known kinds, not both a rate
    and start times (the fit to a flight: ``dropout_stretches``)."""
    _finite(c.per_min, f"{where}.per_min", "a rate >= 0 per minute", "0 turns it off",
            c.per_min >= 0)
    for t in c.at_s:
        _finite(t, f"{where}.at_s", "start times >= 0 s", "a dropout starts inside the flight",
                t >= 0)
    d = [float(x) for x in c.duration_s]
    if len(d) != 2 or not all(math.isfinite(x) for x in d) or not 0 < d[0] <= d[1]:
        raise ValueError(f"{where}.duration_s = {list(c.duration_s)} must be [min, max] "
                         "seconds with 0 < min <= max, e.g. [1.0, 3.0]")
    if not c.kinds or any(k not in KINDS for k in c.kinds):
        raise ValueError(f"{where}.kinds = {list(c.kinds)} must be a non-empty list of "
                         f"{list(KINDS)}")
    if c.at_s and c.per_min > 0:
        raise ValueError(f"{where}: give dropouts at a rate (per_min = {c.per_min}) or at "
                         f"times (at_s = {list(c.at_s)}), not both; set per_min: 0 or at_s: []")


_RULES = {SensorNoiseConfig: _noise_rules, ExposureConfig: _exposure_rules,
          JpegConfig: _jpeg_rules, DropoutConfig: _dropout_rules}


def checked(cls: type[T], settings: T | Mapping | None, where: str) -> T:
    """One effect's settings typed (``cls``: ``SensorNoiseConfig``, ``ExposureConfig``,
    ``JpegConfig`` or ``DropoutConfig``; a mapping of the keys that differ from its defaults;
    None: the defaults, the effect off) and checked.

    Raises:
        ValueError: a bad setting, naming ``where.<key>`` and the fix.
    """
    c = as_config(cls, settings, where)
    _RULES[cls](c, where)
    return c


def check_settings(settings: RealismConfig | Mapping | None,
                   where: str = WHERE) -> RealismConfig:
    """The realism settings typed (``RealismConfig``, or a mapping of the keys that differ
    from its defaults; None: the defaults) with their image effects checked (the AHRS's:
    ``datagen.realism.ahrs.check_settings``).

    Raises:
        ValueError: a bad setting, naming ``where.<key>`` and the fix.
    """
    c = as_config(RealismConfig, settings, where)
    for key in ("noise", "exposure", "jpeg", "dropout"):
        value = getattr(c, key)
        checked(type(value), value, f"{where}.{key}")
    return c


def exposure_active(c: ExposureConfig) -> bool:
    """Whether the exposure changes during a flight (a drift or steps)."""
    return c.drift_ev > 0 or (c.steps_per_min > 0 and c.step_ev > 0)


def dropout_active(c: DropoutConfig) -> bool:
    """Whether a flight may have dropouts."""
    return c.per_min > 0 or bool(c.at_s)


def is_active(settings: RealismConfig) -> bool:
    """Whether any image effect changes a flight's images."""
    return (settings.noise.full_well_e > 0 or exposure_active(settings.exposure)
            or settings.jpeg.quality is not None or dropout_active(settings.dropout))


# --------------------------------------------------------------------------- flight series


def _flight_length(num_frames: int, fps: float) -> tuple[int, float]:
    """(num_frames, fps) as (int, float), checked: frames >= 0, fps > 0 Hz."""
    n, fps = int(num_frames), float(fps)
    if n < 0 or not (fps > 0 and math.isfinite(fps)):
        raise ValueError(f"a flight of {num_frames} frames at {fps} fps: frames must be >= 0 "
                         "and fps > 0")
    return n, fps


def exposure_ev(rng: np.random.Generator, num_frames: int, fps: float,
                settings: ExposureConfig | Mapping | None = None,
                where: str = f"{WHERE}.exposure") -> np.ndarray:
    """The exposure offset of each frame of a flight, the sum of

    - a drift: unit white noise convolved with a Gaussian kernel (std drift_time_s / sqrt(2)
      seconds), times ``drift_ev``: a stationary smooth process of std ``drift_ev`` whose
      autocorrelation at a lag of t seconds is exp(-t^2 / (2 drift_time_s^2));
    - steps: a Poisson process of ``steps_per_min``, each step +/-``step_ev`` (sign drawn)
      that decays as exp(-(t - t_step) / settle_s), auto exposure taking it back out;

    clipped to [-max_ev, max_ev].

    Draws, in this order and whatever the magnitudes: the drift's white noise (N + 2r, r the
    kernel's half-width in frames), the number of steps, their times and their signs.

    Args:
        rng: the flight's exposure generator.
        num_frames: N, frames of the flight (at times i / fps).
        fps: frame rate, Hz (> 0).
        settings: ``ExposureConfig`` or a mapping (None: the defaults, no change).
        where: the settings' config key, for messages.

    Returns:
        (N,) float64 EV stops (linear gain 2^ev); zeros when the exposure does not change.
    """
    c = checked(ExposureConfig, settings, where)
    n, fps = _flight_length(num_frames, fps)
    sigma = c.drift_time_s * float(fps) / math.sqrt(2.0)  # kernel std, frames
    r = max(1, math.ceil(4.0 * sigma))
    kernel = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    kernel /= np.sqrt((kernel**2).sum())  # unit variance out of unit white noise
    white = rng.standard_normal(n + 2 * r)
    duration = n / float(fps)
    count = int(rng.poisson(c.steps_per_min * duration / 60.0))
    times = rng.uniform(0.0, duration, count)
    signs = rng.choice(np.array([-1.0, 1.0]), count)
    ev = np.zeros(n)
    if c.drift_ev > 0:
        ev += c.drift_ev * np.convolve(white, kernel, mode="valid")
    if count and c.step_ev > 0:
        since = np.arange(n)[:, None] / float(fps) - times[None, :]  # (N, steps) s
        decay = np.where(since >= 0, np.exp(-np.maximum(since, 0.0) / c.settle_s), 0.0)
        ev += (c.step_ev * signs * decay).sum(axis=1)
    return np.clip(ev, -c.max_ev, c.max_ev)


@dataclass(frozen=True)
class Dropout:
    """A stretch of a flight without a usable image: frames [first, stop) are those with
    start_s <= i / fps < start_s + duration_s (duration_s ends at the flight's end)."""

    kind: str  # one of KINDS
    start_s: float
    duration_s: float
    first: int
    stop: int

    def as_json(self) -> dict:
        return {"kind": self.kind, "start_s": round(self.start_s, 6),
                "duration_s": round(self.duration_s, 6), "frames": [self.first, self.stop]}


def dropout_stretches(rng: np.random.Generator, num_frames: int, fps: float,
                      settings: DropoutConfig | Mapping | None = None,
                      where: str = f"{WHERE}.dropout") -> list[Dropout]:
    """A flight's dropouts: at ``at_s`` (sorted), else at a rate of ``per_min`` (the first
    starts after an exponential gap from t = 0, each next one an exponential gap after the
    last one's end), each lasting a uniform draw in ``duration_s`` (cut at the flight's
    end) with its kind drawn uniformly from ``kinds``.

    Draws, per dropout in time order: (at a rate) the gap, then the duration and the kind.

    Args:
        rng: the flight's dropout generator.
        num_frames, fps: the flight's N frames, frame i at i / fps seconds (fps in Hz, > 0).
        settings: ``DropoutConfig`` or a mapping (None: the defaults, no dropout).
        where: the settings' config key, for messages.

    Returns:
        the dropouts in time order, none overlapping; [] when off.

    Raises:
        ValueError: bad settings (``checked``), a dropout longer than the flight, a
            start time outside it, or given start times closer than the longest dropout.
    """
    c = checked(DropoutConfig, settings, where)
    n, fps = _flight_length(num_frames, fps)
    if not dropout_active(c):
        return []
    duration = n / fps
    lo, hi = (float(x) for x in c.duration_s)
    if hi > duration:
        raise ValueError(f"{where}.duration_s = {[lo, hi]}: a dropout of up to {hi} s is longer "
                         f"than the flight ({n} frames at {fps:g} fps, {duration:g} s); shorten "
                         "duration_s or fly longer")
    starts = sorted(float(t) for t in c.at_s)
    for t in starts:
        if t >= duration:
            raise ValueError(f"{where}.at_s: a dropout at {t:g} s starts after the flight's end "
                             f"({duration:g} s); give times in [0, {duration:g})")
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        if b - a < hi:
            raise ValueError(f"{where}.at_s: dropouts at {a:g} s and {b:g} s may overlap (one "
                             f"lasts up to duration_s's {hi:g} s); space them further apart")
    out = []

    def add(start: float) -> float:
        length = min(float(rng.uniform(lo, hi)), duration - start)
        kind = c.kinds[int(rng.integers(len(c.kinds)))]
        first = min(n, math.ceil(round(start * fps, 6)))  # rounded: 0.3 s x 10 fps is frame 3
        stop = min(n, math.ceil(round((start + length) * fps, 6)))
        out.append(Dropout(kind, start, length, first, stop))
        return start + length

    if starts:
        for t in starts:
            add(t)
    else:
        t = float(rng.exponential(60.0 / c.per_min))
        while t < duration:
            t = add(t) + float(rng.exponential(60.0 / c.per_min))
    return out


def dropout_kind(stretches: Sequence[Dropout], i: int) -> str | None:
    """Frame i's dropout kind, None where the frame is not dropped."""
    return next((d.kind for d in stretches if d.first <= i < d.stop), None)


# --------------------------------------------------------------------------- one image


def _check_image(rgb: np.ndarray) -> None:
    if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3
            and rgb.shape[2] == 3):
        raise ValueError("an image must be an (H, W, 3) uint8 array, got "
                         f"{getattr(rgb, 'shape', None)} {getattr(rgb, 'dtype', type(rgb))}")



def sensor_noise(rng: np.random.Generator, linear: np.ndarray,
                 settings: SensorNoiseConfig | Mapping | None = None,
                 where: str = f"{WHERE}.noise") -> np.ndarray:
    """Poisson-Gaussian noise in linear light: a value x becomes
    (Poisson(x * full_well_e) + Normal(0, read_noise_e)) / full_well_e, clipped to [0, 1],
    so its variance is x / full_well_e + (read_noise_e / full_well_e)^2 (before clipping).
    Each pixel and channel is drawn apart.

    Draws the Poisson counts, then the read noise (both of ``linear``'s shape).

    Args:
        rng: the frame's generator.
        linear: (...) float linear light, 1 = the white level.
        settings: ``SensorNoiseConfig`` or a mapping (None: the defaults, no noise).
        where: the settings' config key, for messages.

    Returns:
        float32 of ``linear``'s shape; ``linear`` as float32 when full_well_e is 0.
    """
    c = checked(SensorNoiseConfig, settings, where)
    x = np.asarray(linear, dtype=np.float32)
    if c.full_well_e == 0:
        return x
    fw = float(c.full_well_e)
    electrons = rng.poisson(np.clip(x, 0.0, None).astype(np.float64) * fw).astype(np.float32)
    electrons += rng.normal(0.0, float(c.read_noise_e), x.shape).astype(np.float32)
    return np.clip(electrons * np.float32(1.0 / fw), 0.0, 1.0)


def jpeg(rgb: np.ndarray, quality: int) -> np.ndarray:
    """``rgb`` JPEG-encoded at ``quality`` (1-100, OpenCV's defaults: 4:2:0 chroma) and
    decoded: (H, W, 3) uint8 in and out."""
    _check_image(rgb)
    _jpeg_rules(JpegConfig(quality), f"{WHERE}.jpeg")
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]),
                           [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise OSError("OpenCV could not encode a JPEG image")
    return np.ascontiguousarray(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])


def covered_lens(linear: np.ndarray) -> np.ndarray:
    """The view through a covered lens: (H, W, 3) float32 linear light blurred (Gaussian std
    ``COVERED_BLUR`` of the larger side) and darkened to ``COVERED_GAIN``."""
    sigma = COVERED_BLUR * max(linear.shape[:2])
    blurred = cv2.GaussianBlur(np.asarray(linear, dtype=np.float32), (0, 0), sigma,
                               borderType=cv2.BORDER_REFLECT)
    return blurred * np.float32(COVERED_GAIN)


def apply_effects(rgb: np.ndarray, rng: np.random.Generator,
                  settings: RealismConfig | Mapping | None = None, ev: float = 0.0,
                  dropout: str | None = None, where: str = WHERE) -> np.ndarray:
    """One flight frame as the drone's camera delivers it (the module's steps 1-5).

    Args:
        rgb: (H, W, 3) uint8 sRGB, the rendered frame.
        rng: the frame's own generator; draws a ``noise`` dropout's pixels, else the sensor
            noise (``sensor_noise``).
        settings: ``RealismConfig`` or a mapping (None: the defaults, nothing changes).
        ev: the frame's exposure offset, EV stops (``exposure_ev``).
        dropout: None, or the frame's dropout kind (one of ``KINDS``).
        where: the settings' config key, for messages.

    Returns:
        (H, W, 3) uint8 sRGB; ``rgb`` itself when nothing applies.
    """
    c = check_settings(settings, where)
    _check_image(rgb)
    if dropout is not None and dropout not in KINDS:
        raise ValueError(f"dropout = {dropout!r} must be None or one of {list(KINDS)}")
    ev = float(ev)
    if not math.isfinite(ev):
        raise ValueError(f"ev = {ev} must be a finite exposure offset in EV stops")
    if dropout == "black":
        return np.zeros_like(rgb)
    if dropout == "noise":
        return rng.integers(0, 256, rgb.shape, dtype=np.uint8)
    out = rgb
    noisy = c.noise.full_well_e > 0
    if ev != 0.0 or noisy or dropout == "covered":
        x = to_linear(rgb)
        if ev != 0.0:
            x = x * np.float32(2.0**ev)
        if dropout == "covered":
            x = covered_lens(x)
        x = sensor_noise(rng, x, c.noise, f"{where}.noise")
        out = linear_to_srgb8(x)
    if c.jpeg.quality is not None:
        out = jpeg(out, c.jpeg.quality)
    return out
