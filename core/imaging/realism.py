"""How far a camera and a flight are from a perfect simulation: the ``realism`` settings
(conf/realism/: ``ideal``, the default, or ``real``) of datagen's flights and of train's
camera-effects augmentation, and ``load_realism``, which reads a preset by name.

Lengths are in metres, angles in degrees, times in seconds.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

from omegaconf import OmegaConf

# --------------------------------------------------------------------------- realism


@dataclass
class AhrsConfig:
    """The roll and pitch a drone's AHRS (IMU and attitude filter) reports, written into the
    flights' odometry (``realism.ahrs``, datagen/realism/ahrs.py): per axis the truth plus a
    constant bias, white noise and a slow drift (a first-order Gauss-Markov process). Every std 0
    (the defaults, ``realism=ideal``): the true roll and pitch. ``realism=real``: a small drone's
    MEMS IMU (docs/realism.md)."""

    bias_deg: float = 0.0  # std of the constant error, drawn once per flight and axis
    noise_deg: float = 0.0  # std of the white noise of each frame's roll and pitch
    drift_deg: float = 0.0  # stationary std of the slow drift
    drift_time_s: float = 10.0  # s, correlation time of the drift: its autocorrelation at a
    # lag of t seconds is exp(-t / drift_time_s)


@dataclass
class SensorNoiseConfig:
    """Poisson-Gaussian sensor noise on the flights' images (``realism.noise``,
    core/imaging/camera_effects.py), added in linear light: a pixel's signal x (linear, 1 = the
    white level) collects x * full_well_e electrons, Poisson distributed, plus a normal read
    noise of read_noise_e electrons, so the variance is x / full_well_e + (read_noise_e /
    full_well_e)^2. full_well_e 0 (the default, ``realism=ideal``): no noise."""

    full_well_e: float = 0.0  # electrons at the white level: the sensor's full-well capacity
    # over the analog gain; 0: no sensor noise
    read_noise_e: float = 0.0  # std of the read noise, electrons (needs full_well_e > 0)


@dataclass
class ExposureConfig:
    """Auto-exposure and light changes during a flight (``realism.exposure``,
    core/imaging/camera_effects.py): the image's brightness is off by an exposure offset e(t) in
    EV stops (linear gain 2^e), the sum of a slow smooth drift and steps (a light switched on
    or off, which auto exposure then brings back), clipped to [-max_ev, max_ev]. Every
    magnitude 0 (the defaults, ``realism=ideal``): the rendered brightness."""

    drift_ev: float = 0.0  # stationary std of the slow drift, EV stops
    drift_time_s: float = 3.0  # s, time scale of the drift: its autocorrelation at a lag of
    # t seconds is exp(-t^2 / (2 drift_time_s^2))
    steps_per_min: float = 0.0  # mean number of steps per minute (a Poisson process)
    step_ev: float = 1.0  # size of a step, EV stops, its sign drawn (+: a light on)
    settle_s: float = 0.7  # s, time constant of auto exposure taking a step back out
    max_ev: float = 1.5  # EV stops; the offset is clipped to [-max_ev, max_ev]


@dataclass
class JpegConfig:
    """JPEG compression of the flights' images (``realism.jpeg``, OpenCV's encoder, 4:2:0
    chroma): the images are encoded and decoded again, and written as PNG."""

    quality: int | None = None  # 1-100 (OpenCV's IMWRITE_JPEG_QUALITY); None: no compression


@dataclass
class DropoutConfig:
    """Stretches of a flight where the camera's image is lost (``realism.dropout``,
    core/imaging/camera_effects.py): ``black`` (a dead link: all zeros), ``noise`` (uniform
    random pixels) or ``covered`` (something over the lens: the view dark and blurred). They
    come at a rate (``per_min``) or at given times (``at_s``), each lasting a uniform draw
    from ``duration_s``, its kind drawn from ``kinds``; flight.json's ``dropout`` lists them
    and their frames. per_min 0 and at_s empty (the defaults, ``realism=ideal``): none."""

    per_min: float = 0.0  # mean number of dropouts per minute (gaps exponential, from t = 0)
    at_s: list[float] = field(default_factory=list)  # s, start times of dropouts (instead of
    # per_min)
    duration_s: list[float] = field(default_factory=lambda: [1.0, 3.0])  # s, [min, max]
    kinds: list[str] = field(default_factory=lambda: ["black", "noise", "covered"])  # drawn
    # uniformly


@dataclass
class LensConfig:
    """Lens distortion of the flights' camera (``realism.lens``, core/imaging/lens.py,
    datagen/realism/optics.py): OpenCV's plumb_bob model, a normalized image point (x, y), r^2 = x^2
    + y^2, goes to x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2) (y likewise, p1
    and p2 swapped), with the camera's K. The frames are rendered through it; flight.json's
    ``camera`` holds the calibration and the localizer undistorts each frame back to K. Every
    coefficient 0 (the defaults, ``realism=ideal``): a pinhole. ``realism=real``: a wide MAV lens
    (docs/realism.md)."""

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0


@dataclass
class MotionBlurConfig:
    """Motion blur of the flights' frames (``realism.motion_blur``, datagen/realism/optics.py): the
    frame at time t is the mean, in linear light, of sub-frames rendered at poses along the
    flight's true trajectory over its exposure [t - exposure_s, t] (with a rolling shutter,
    each row's own window). 0 (the default, ``realism=ideal``): no blur."""

    exposure_s: float = 0.0  # s, the exposure time; < the frame interval 1 / fps


@dataclass
class RollingShutterConfig:
    """A rolling shutter (``realism.rolling_shutter``, datagen/realism/optics.py): row r of an H-row
    frame at time t ends its exposure at t + (r / H - 0.5) * readout_s, so the top row is
    read readout_s / 2 before t and the bottom row about readout_s / 2 after. 0 (the default,
    ``realism=ideal``): a global shutter."""

    readout_s: float = 0.0  # s, top to bottom row; exposure + readout < the frame interval


@dataclass
class SubframeConfig:
    """How many sub-frames a blurred or rolling-shutter frame is rendered from
    (``realism.subframes``, datagen/realism/optics.py): enough that the image moves at most
    ``step_px`` between two (estimated from the motion over the frame's span), at most
    ``max_count``."""

    step_px: float = 1.0  # px of image motion between sub-frames (> 0)
    max_count: int = 16  # the most sub-frames of one frame (each costs a render)


@dataclass
class TimingConfig:
    """The clocks of the camera and the odometry (``realism.timing``, datagen/realism/timing.py):
    frames the link drops, jitter on the images' timestamps, and odometry at its own rate with
    occasional jumps, so a flight's reader (``core.dataset.Dataset.flight``) interpolates the
    odometry at each delivered image's timestamp, as for a user's recording. Every setting off (the
    defaults, ``realism=ideal``): every frame delivered at i / fps, the odometry at the frame times.
    ``realism=real``: docs/realism.md."""

    drop_rate: float = 0.0  # share of frames dropped (never delivered, not rendered), each
    # frame independently, in [0, 0.5]
    jitter_ms: float = 0.0  # ms, std of the error of an image's timestamp (normal, clipped to
    # +/- 3 std); its capture (the rendered pose) stays at i / fps
    odometry_hz: float | None = None  # Hz, the odometry's own rate (samples at k / odometry_hz
    # over the flight); None: at the camera's frame times
    jump_per_min: float = 0.0  # mean number of odometry jumps per minute (a Poisson process):
    # the odometry's pose jumps and stays off (a VIO re-initialization or a map correction)
    jump_m: float = 0.05  # m, size of a jump's translation (horizontal, its direction drawn;
    # each jump's size uniform in [0.5, 1] x this)
    jump_deg: float = 2.0  # deg, size of a jump's yaw change (its sign drawn; uniform in
    # [0.5, 1] x this)


@dataclass
class HarderFlightConfig:
    """Harder flights for every preset (``realism.flight``, datagen/flights/trajectories.py
    ``flight_trajectory``): faster and with quicker yaw swings, flown back and forth along the
    route (turning around at its ends), from anywhere on it, either way. ``enabled`` false (the
    default, ``realism=ideal``): each preset's own ``trajectory``. Its draws come from the
    flight's own generator (stream key 8), so the preset's draws are unchanged."""

    enabled: bool = False
    speed: list[float] = field(default_factory=lambda: [0.6, 1.0])  # m/s, [min, max] mean
    # speed along the route (replacing the preset's trajectory.speed); the speed profile's
    # variation takes its peaks to about 1.5x the mean
    turn_m: float = 1.0  # m of route at each end over which the copter slows down to turn
    # around
    turn_s: float = 6.0  # s it hovers at an end while it turns its heading by 180 deg (left
    # or right; its peak rate 1.5 x 180 / turn_s deg/s: 45 at 6 s)
    yaw_rate_deg_s: list[float] = field(default_factory=lambda: [30.0, 60.0])  # deg/s, [min,
    # max] peak rate of the yaw swings about the direction of travel, drawn per flight
    yaw_freq_hz: list[float] = field(default_factory=lambda: [0.1, 0.3])  # frequencies of the
    # yaw swings (the preset's yaw_freq_hz is replaced)
    max_yaw_swing_deg: float = 60.0  # deg, the largest swing (a slower peak rate than drawn
    # where it would need more)


@dataclass
class MapErrorConfig:
    """The map the localizer reads differs from the rendered world (``realism.map``,
    datagen/realism/map_error.py): the dataset's ``world/`` is the true world edited as below (its
    edges and free space made from the edited mesh), the truth kept in ``world_truth/``; the
    edits are drawn from their own seeded stream and listed in dataset.json's ``map_error``.
    Rendering and the ground truth use the truth. Every setting 0 (the defaults,
    ``realism=ideal``): the map is the truth. ``realism=real``: a survey-grade floor plan's
    errors (docs/realism.md)."""

    wall_std_m: float = 0.0  # std of each wall's shift along its normal (a wall: a connected
    # flat piece of class wall; its doors' and windows' recesses move with it)
    ceiling_std_m: float = 0.0  # std of each ceiling's height error (up positive)
    missing_openings: int = 0  # doors or windows of the world left out of the map (their
    # recess flattened into the wall)
    extra_openings: int = 0  # doors or windows drawn in the map on plain walls where the
    # world has none
    extra_kinds: list[str] = field(default_factory=lambda: ["door", "window"])  # drawn
    # uniformly for each extra opening
    builtins: int = 0  # unmodelled built-in objects (boxes of class wall standing against a
    # wall) in the flights' rendered world, absent from the map
    builtin_kinds: list[str] = field(default_factory=lambda: ["cabinet", "pillar"])  # drawn
    # uniformly: a cabinet is builtin_cabinet_m, a pillar builtin_pillar_m to the ceiling
    builtin_cabinet_m: list[float] = field(default_factory=lambda: [1.0, 0.45, 2.0])  # m,
    # [along the wall, out of it, height]
    builtin_pillar_m: list[float] = field(default_factory=lambda: [0.4, 0.3])  # m, [along the
    # wall, out of it]; up to the ceiling
    builtin_clearance_m: float = 0.3  # m kept between a built-in object and every flight's
    # camera path


@dataclass
class CalibrationConfig:
    """The camera the localizer is told differs from the rendering's (``realism.calibration``,
    datagen/realism/calibration.py): dataset.json's ``camera`` (K, body_from_cam) is the rendering's
    camera with a calibration error drawn once per dataset from its own seeded stream; the
    truth is kept as ``camera_truth`` and the error in ``calibration_error``. Every std 0 (the
    defaults, ``realism=ideal``): the told camera is the truth. ``realism=real``: a checkerboard
    calibration's errors (docs/realism.md)."""

    focal_std: float = 0.0  # relative std of the focal length (fx and fy scaled by one
    # factor 1 + N(0, focal_std))
    principal_std_px: float = 0.0  # std of the principal point's error, px, per axis
    rotation_std_deg: float = 0.0  # std of body_from_cam's rotation error, degrees (an angle
    # N(0, std) about a uniformly random axis)
    translation_std_m: float = 0.0  # std of body_from_cam's translation error, m, per axis


@dataclass
class RealismConfig:
    """How far the flights are from a perfect simulation (``realism``, the conf/realism/
    group: ``ideal``, the default, or ``real``), for every flight: the imperfections are the
    drone's and the world's, not a flight preset's. The preset's name and settings are
    recorded in dataset.json's ``generator`` and in each flight.json's ``realism``."""

    name: str = "ideal"  # the preset's name, recorded with the flights
    ahrs: AhrsConfig = field(default_factory=AhrsConfig)
    noise: SensorNoiseConfig = field(default_factory=SensorNoiseConfig)  # the flights' images:
    # sensor noise, exposure changes, JPEG and dropouts (core/imaging/camera_effects.py)
    exposure: ExposureConfig = field(default_factory=ExposureConfig)
    jpeg: JpegConfig = field(default_factory=JpegConfig)
    dropout: DropoutConfig = field(default_factory=DropoutConfig)
    lens: LensConfig = field(default_factory=LensConfig)  # the flights' optics: lens
    # distortion, motion blur and a rolling shutter (datagen/realism/optics.py)
    motion_blur: MotionBlurConfig = field(default_factory=MotionBlurConfig)
    rolling_shutter: RollingShutterConfig = field(default_factory=RollingShutterConfig)
    subframes: SubframeConfig = field(default_factory=SubframeConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)  # dropped frames, timestamp
    # jitter, the odometry's own rate and jumps (datagen/realism/timing.py)
    flight: HarderFlightConfig = field(default_factory=HarderFlightConfig)  # faster flights,
    # quicker yaw, back and forth from anywhere on the route
    map: MapErrorConfig = field(default_factory=MapErrorConfig)  # what the localizer reads:
    # the map (datagen/realism/map_error.py) and the camera's calibration
    # (datagen/realism/calibration.py)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)


REALISM_DIR = Path(__file__).resolve().parents[2] / "conf" / "realism"


def load_realism(name: str, where: str = "realism") -> RealismConfig:
    """A realism preset by name: conf/realism/<name>.yaml over ``RealismConfig``'s defaults.

    Raises:
        ValueError: no such preset (names the ones there are), or a key the schema lacks.
    """
    path = REALISM_DIR / f"{name}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in REALISM_DIR.glob("*.yaml"))
        raise ValueError(f"{where} = {name!r}: no preset {path}; use one of {known}")
    merged = OmegaConf.merge(OmegaConf.structured(RealismConfig), OmegaConf.load(path))
    return OmegaConf.to_object(merged)


def realism_label(settings: RealismConfig) -> str:
    """The name a dataset records for its realism: the preset's name where the settings are
    that preset's (or the name names no preset), else the name and the keys changed, e.g.
    ``ideal + map.wall_std_m, map.builtins``."""
    if not (REALISM_DIR / f"{settings.name}.yaml").is_file():
        return settings.name

    def flat(d: dict, prefix: str = "") -> dict:
        out = {}
        for k, v in d.items():
            out.update(flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {prefix + k: v})
        return out

    have, preset = flat(asdict(settings)), flat(asdict(load_realism(settings.name)))
    changed = [k for k in have if k != "name" and have[k] != preset.get(k)]
    return settings.name if not changed else f"{settings.name} + {', '.join(changed)}"
