"""The localize settings: ``LocalizerConfig`` (what a ``Localizer`` reads; ``LocalizerConfig()``
is the defaults), ``AppConfig`` (what both apps read) and ``LocalizeConfig``, the schema of
``conf/localize.yaml`` (``python -m localize``; the live node's is ``localize.ros2.config``).

The field defaults below are the only defaults: Hydra composes conf/ and the command line onto
them, ``localize.resolve.resolve`` adds the settings a model carries, and a typo or a wrong type
fails at start-up naming the key; library code types a partial mapping with
``core.config.typed``. Why the defaults are what they are: docs/localize.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from core.config import register_schema, typed
from localize.search.config import GlobalSearchConfig

#: The edge modes (``localize.frontend.extractor``).
MODES = ("none", "cnn", "oracle")
#: ``edges.cnn.refine`` choices.
REFINES = ("none", "union")
#: Command-line aliases of both localize apps (``core.config.expand_aliases``): ``world=FILE``.
ALIASES = {"world": "world.path"}
#: ``viz`` choices (``localize.viewers.viz``).
VIZ_KINDS = ("none", "rerun")


@dataclass
class LikelihoodConfig:
    """The edge likelihood (``filter.likelihood``; ``localize.filter.likelihood``).

    Attributes:
        k: weight ``W = exp(k * score)`` (the paper's ``alpha * exp(k * score)``: a constant
            factor alpha cancels when the weights are normalized).
        sigma: tolerance of g(d), a fraction of ``search_px`` (0.1: 1 px; the paper's 0.3: 3 px).
        search_px: reach of the edge search, pixels; d is truncated there and divided by it.
        min_quality_samples: known visible samples needed to judge the fit (recovery).
        min_line_samples: visible samples a line needs to count (5: 0.4 m of it at the 0.1 m
            spacing; a detail of an imported model, a 6 cm door handle, must not weigh as
            much as a wall's whole base line).
        min_lines: particles seeing fewer lines are padded with the chance score.
        lines_ref: a frame whose particles see fewer lines than this (their median) has its k
            scaled by that count / ``lines_ref`` (0 = off).
        orientation_bins: 0: a plain distance transform; B: directional, B bins over 180 deg.
        class_pairs: match each model sample only to image edges between its own two classes
            (label modes).
        near: samples closer to the camera than this are dropped, metres.
        max_samples: most model samples a particle scores (0: no budget). A particle that may
            see more (its cell's visible samples in the azimuths its cell's particles face)
            scores every s-th sample along each segment, s the smallest power of two that
            brings the count within it; a line then needs ``min_line_samples / s`` of them
            (``localize.filter.sample_budget``). Bounds a frame's time whatever the building's
            size; a particle within the budget scores as without it.
        chunk: particles scored per block (a block projects the samples its particles' cells
            see: with visibility lists, larger blocks cost less per particle while tracking).
        workers: threads scoring the blocks and the score maps (1: the calling thread).
            Neither ``chunk`` nor ``workers`` changes a result (with visibility lists, the
            samples a block culls may move a score by float64 rounding, ~1e-16).
    """

    k: float = 25.0
    sigma: float = 0.1
    search_px: float = 10.0
    min_quality_samples: int = 30
    min_line_samples: int = 5
    min_lines: int = 5
    lines_ref: int = 15
    orientation_bins: int = 0
    class_pairs: bool = False
    near: float = 0.1
    max_samples: int = 2000
    chunk: int = 256
    workers: int = 2

    def __post_init__(self) -> None:
        if self.sigma <= 0 or self.search_px <= 0:
            raise ValueError("likelihood.sigma and likelihood.search_px must be positive, got "
                             f"{self.sigma}, {self.search_px}")
        if self.workers < 1:
            raise ValueError(f"likelihood.workers must be >= 1, got {self.workers}")
        if self.max_samples < 0:
            raise ValueError(f"likelihood.max_samples must be >= 0 (0 = no budget), got "
                             f"{self.max_samples}")
        if self.lines_ref < 0:
            raise ValueError(f"likelihood.lines_ref must be >= 0 (0 = off), got {self.lines_ref}")


@dataclass
class FilterConfig:
    """The particle filter (``filter``; ``localize.filter.particle_filter``). Presets:
    conf/filter/*.yaml (``filter=paper``: the paper's settings).

    Attributes:
        num_particles: particles while tracking.
        global_particles: particles of the initial uniform draw of a global start over up to
            ``global_area`` m2 of free space; thinned to ``num_particles`` by resampling after
            ``global_frames`` frames.
        global_area: m2 of free space ``global_particles`` cover (the corridor's ~16); a
            larger free space (a whole floor) gets proportionally more particles, at the same
            density, up to ``global_max_particles`` (``global_count``).
        global_max_particles: most particles of a global start (time: a global update of
            the hospital floor costs about 10 ms per 1,000 particles in mode oracle).
        global_frames: frames the global set is kept.
        global_likelihood: ``likelihood`` keys that differ while the global set is kept
            (``global_likelihood_config``); null: the tracking likelihood.
        mode_likelihood: ``likelihood`` keys that differ per edge mode, ``{mode: {key: value}}``
            (``likelihood_for``); null: every mode scores with ``likelihood``.
        global_motion_scale: motion noise multiplier while the global set is kept (the uniform
            set is sparse and must move to find the peak).
        global_thin: the global phase scores every n-th model sample.
        global_method: how a global start searches: ``table`` (``global_search``: every free
            cell x heading weighed by the floor boundary against a precomputed table; the label
            modes) or ``particles`` (the uniform set above; always for mode ``none``).
        global_search: the global search (``GlobalSearchConfig``, ``localize.search``).
        hypotheses: pose hypotheses reported per frame (``localize.filter.hypotheses``: the
            heaviest modes of the weighted set and their mass).
        hypothesis_radius_m, hypothesis_yaw_deg: a hypothesis's kernel: horizontal radius
            (m) and heading half-width (degrees).
        dominant_mass: the status is ``tracking`` only once one hypothesis has held at least
            this share of the mass...
        dominant_frames: ...for this many frames in a row (``ambiguous`` until then; a start
            at a known pose is dominant at once).
        quality_model: the calibration file of ``Estimate.quality`` (``localize.filter.quality``,
            fitted by benchmarks/quality.py); null: the shipped ``localize/filter/quality.json``.
        tracking_quality: a frame the filter calls ``tracking`` is reported ``ambiguous`` when
            its quality is below this (in modes the calibration covers).
        init_std: (4,) tracking start noise: x, y, z (metres), yaw (degrees).
        motion_std: (3,) motion noise per ``motion_period_s``: horizontal (metres), vertical
            (metres), yaw (degrees); a move over ``dt`` seconds draws it times
            sqrt(dt / motion_period_s), so the noise follows the time elapsed, not the number of
            moves (``particle_filter.noise_scale``).
        mode_motion_std: ``motion_std`` per edge mode where it differs, ``{mode: (3,)}``; null:
            ``motion_std`` for every mode.
        motion_rel: (2,) extra noise per unit of odometry translation and of yaw change.
        motion_period_s: the time ``motion_std`` (and ``tilt_std``'s random walk) is given for,
            seconds: a frame of the 10 fps flights.
        resample_ess: resample when ESS < this fraction of the particle count.
        free_space_slack: metres beyond the free space (cells and band) before the free-space prior
            applies.
        outside_log_penalty_per_m: log-weight a particle loses per metre beyond the slack (a
            prior, not a wall: no particle is removed or moved; 0: no prior).
        recovery: inject particles when the best particle's fit collapses (augmented MCL).
        recovery_fast, recovery_slow: smoothing factors of the short and long averages of the
            best fit per frame.
        recovery_threshold: inject when the fast average is below this fraction of the slow...
        recovery_patience: ...for this many frames in a row.
        recovery_max_fraction: most particles replaced in one frame.
        recovery_log_penalty: injected particles start this much lower in log-weight.
        recovery_local_std: (4,) noise of the half of the injected particles drawn around the
            estimate (x, y, z metres, yaw degrees); the other half is uniform.
        gate: a frame whose best particle fits below this fraction of the long-run fit does
            not weigh the particles (the filter coasts on the odometry; 0: every frame
            weighs).
        lost_frames: that many such frames in a row declare the track lost: the filter
            re-localizes over the free space (0: never).
        tilt_std: (2,) each particle's correction of the IMU's roll and pitch, degrees: its
            start noise and its random walk per ``motion_period_s`` (an AHRS is off by a bias
            and a slow drift, ``particle_filter.move_tilt``); 0, 0: the IMU's roll and pitch as
            given (an exact attitude source: a simulation's truth, motion capture).
        likelihood: the edge likelihood of tracking.
    """

    num_particles: int = 500
    global_particles: int = 40000
    global_area: float = 16.0
    global_max_particles: int = 200000
    global_frames: int = 40
    global_likelihood: dict[str, Any] | None = field(default_factory=lambda: {
        "k": 20.0, "sigma": 0.3, "class_pairs": True, "min_line_samples": 2})
    mode_likelihood: dict[str, dict[str, Any]] | None = field(default_factory=lambda: {
        "cnn": {"k": 40.0, "orientation_bins": 12}, "none": {"sigma": 0.3},
        "oracle": {"k": 50.0}})
    global_motion_scale: float = 15.0
    global_thin: int = 3
    global_method: str = "table"
    global_search: GlobalSearchConfig = field(default_factory=GlobalSearchConfig)
    hypotheses: int = 3
    hypothesis_radius_m: float = 0.5
    hypothesis_yaw_deg: float = 20.0
    dominant_mass: float = 0.9
    dominant_frames: int = 10
    quality_model: str | None = None
    tracking_quality: float = 0.8
    init_std: list[float] = field(default_factory=lambda: [0.1, 0.1, 0.05, 3.0])
    motion_std: list[float] = field(default_factory=lambda: [0.01, 0.005, 0.5])
    mode_motion_std: dict[str, list[float]] | None = field(default_factory=lambda: {
        "cnn": [0.01, 0.005, 0.2], "oracle": [0.01, 0.005, 0.2]})
    motion_rel: list[float] = field(default_factory=lambda: [0.1, 0.1])
    motion_period_s: float = 0.1
    resample_ess: float = 0.5
    free_space_slack: float = 0.25
    outside_log_penalty_per_m: float = 20.0
    recovery: bool = True
    recovery_fast: float = 0.3
    recovery_slow: float = 0.02
    recovery_threshold: float = 0.5
    recovery_patience: int = 5
    recovery_max_fraction: float = 0.2
    recovery_log_penalty: float = 5.0
    recovery_local_std: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.2, 20.0])
    gate: float = 0.3
    lost_frames: int = 30
    tilt_std: list[float] = field(default_factory=lambda: [0.5, 0.05])
    likelihood: LikelihoodConfig = field(default_factory=LikelihoodConfig)

    def __post_init__(self) -> None:
        if self.num_particles < 1 or self.global_particles < 1:
            raise ValueError(f"filter.num_particles ({self.num_particles}) and "
                             f"filter.global_particles ({self.global_particles}) must be >= 1")
        if self.global_area <= 0:
            raise ValueError(f"filter.global_area must be positive (m2), got {self.global_area}")
        if not 0.0 <= self.tracking_quality <= 1.0:
            raise ValueError(f"filter.tracking_quality must be in [0, 1], got "
                             f"{self.tracking_quality}")
        if self.global_method not in ("table", "particles"):
            raise ValueError(f"filter.global_method must be table or particles, got "
                             f"{self.global_method!r}")
        if self.motion_period_s <= 0:
            raise ValueError(f"filter.motion_period_s must be positive (seconds), got "
                             f"{self.motion_period_s}")
        if not 0.0 < self.resample_ess <= 1.0:
            raise ValueError(f"filter.resample_ess must be in (0, 1], got {self.resample_ess}")
        for key in ("mode_likelihood", "mode_motion_std"):
            bad_modes = set(getattr(self, key) or {}) - set(MODES)
            if bad_modes:
                raise ValueError(f"filter.{key}: unknown edge modes {sorted(bad_modes)}; "
                                 "use none, cnn, oracle")
        sized = [(key, getattr(self, key), n) for key, n in
                 (("init_std", 4), ("motion_std", 3), ("motion_rel", 2), ("recovery_local_std", 4),
                  ("tilt_std", 2))]
        sized += [(f"mode_motion_std.{mode}", std, 3)
                  for mode, std in (self.mode_motion_std or {}).items()]
        for key, values, n in sized:
            if len(values) != n:
                raise ValueError(f"filter.{key} needs {n} values, got {list(values)}")
        if not 0.0 <= self.gate < 1.0 or self.lost_frames < 0:
            raise ValueError(f"filter.gate must be in [0, 1) and filter.lost_frames >= 0, got "
                             f"{self.gate}, {self.lost_frames}")
        if self.free_space_slack < 0 or self.outside_log_penalty_per_m < 0:
            raise ValueError(f"filter.free_space_slack ({self.free_space_slack}) and "
                             f"filter.outside_log_penalty_per_m "
                             f"({self.outside_log_penalty_per_m}) must be >= 0")
        if (self.hypotheses < 1 or self.hypothesis_radius_m <= 0 or self.hypothesis_yaw_deg <= 0
                or not 0.0 < self.dominant_mass <= 1.0 or self.dominant_frames < 1):
            raise ValueError(f"filter.hypotheses ({self.hypotheses}) and filter.dominant_frames "
                             f"({self.dominant_frames}) must be >= 1, filter.hypothesis_radius_m "
                             f"({self.hypothesis_radius_m}) and hypothesis_yaw_deg "
                             f"({self.hypothesis_yaw_deg}) positive, filter.dominant_mass "
                             f"({self.dominant_mass}) in (0, 1]")
        if min(self.tilt_std) < 0:
            raise ValueError(f"filter.tilt_std must be >= 0 degrees, got {list(self.tilt_std)}")
        for mode in MODES:  # a typo or a bad value in an override fails here, at start-up
            self.likelihood_for(mode)
        self.global_likelihood_config()

    def likelihood_for(self, mode: str) -> LikelihoodConfig:
        """The likelihood settings of one edge mode: ``likelihood`` updated by
        ``mode_likelihood[mode]`` (a typo or a bad value raises naming
        ``filter.mode_likelihood.<mode>``)."""
        over = (self.mode_likelihood or {}).get(mode)
        if not over:
            return self.likelihood
        return typed(LikelihoodConfig, {**asdict(self.likelihood), **over},
                     f"filter.mode_likelihood.{mode}")

    def global_likelihood_config(self, base: LikelihoodConfig | None = None) -> LikelihoodConfig:
        """The global phase's likelihood settings: ``base`` (default ``likelihood``) updated by
        ``global_likelihood`` (a typo or a bad value raises naming it)."""
        base = self.likelihood if base is None else base
        if not self.global_likelihood:
            return base
        return typed(LikelihoodConfig, {**asdict(base), **self.global_likelihood},
                     "filter.global_likelihood")

    def global_count(self, free_area: float) -> int:
        """Particles of a global start over ``free_area`` m2 of free space:
        ``global_particles`` x max(1, free_area / ``global_area``), at most
        ``global_max_particles`` (never fewer than ``global_particles`` nor ``num_particles``)."""
        n = self.global_particles * max(1.0, float(free_area) / self.global_area)
        n = min(int(round(n)), max(self.global_max_particles, self.global_particles))
        return max(n, self.global_particles, self.num_particles)

    def for_mode(self, mode: str) -> FilterConfig:
        """These settings with ``motion_std`` replaced by ``mode_motion_std[mode]`` if set."""
        std = (self.mode_motion_std or {}).get(mode)
        return self if std is None else replace(self, motion_std=[float(v) for v in std])


@dataclass
class CannyConfig:
    """``edges.canny``: Canny on the grey image (mode none).

    Attributes:
        low, high: hysteresis thresholds on the gradient magnitude.
        blur: Gaussian kernel before Canny, pixels (odd; <= 1: none).
    """

    low: float = 50.0
    high: float = 150.0
    blur: int = 3


@dataclass
class HoughConfig:
    """Hough line segments of an edge map (``cv2.HoughLinesP``), drawn 1 px wide.

    Attributes:
        threshold: votes.
        min_length: shortest segment, pixels.
        max_gap: largest gap bridged within a segment, pixels.
    """

    threshold: int = 30
    min_length: int = 20
    max_gap: int = 3


@dataclass
class LabelsConfig:
    """``edges.labels``: class boundaries of a label map (modes cnn and oracle).

    Attributes:
        dilate_px: the unknown mask (clutter, person, void) grows by this many pixels.
        median: median filter on predicted labels, pixels (cnn only; 0 = off).
    """

    dilate_px: int = 3
    median: int = 3


@dataclass
class CnnConfig:
    """``edges.cnn``: how the cnn mode makes edges of the SegNet's output
    (``localize.frontend.extractor``, ``localize.frontend.boundaries``).

    Attributes:
        prior_correction: strength s: structural labels by the argmax of logit - s * log(class
            weight of the training); 1 undoes the class weighting exactly; 0 = off (plain
            argmax). Needs the model's ``class_weights`` metadata.
        snap_px: each predicted boundary pixel moves along its normal, up to this many pixels,
            onto the strongest colour gradient across it (0 = off); one already on an image
            edge stays.
        snap_min_gradient: smallest gradient across the boundary that counts (RMS over R, G, B
            of the 3x3 Sobel; a step of h grey levels gives about 3 h); weaker boundaries stay.
        snap_nearest: snap to the nearest image edge within ``snap_px`` (a gradient peak of at
            least ``snap_min_gradient``) instead of the strongest; stay if none (for networks
            trained without class weights, whose boundaries are unbiased).
        refine: ``union``: the snapped class boundaries and the Canny edges of the colour image
            within ``refine_px`` of them (those carry no class pair); ``none``: the snapped
            class boundaries alone.
        refine_px: reach of ``union``, pixels.
        refine_low, refine_high: the hysteresis thresholds of the union's Canny (mode none has
            its own, ``edges.canny``).
    """

    prior_correction: float = 0.75
    snap_px: int = 2
    snap_min_gradient: float = 8.0
    snap_nearest: bool = False
    refine: str = "union"
    refine_px: int = 6
    refine_low: float = 25.0
    refine_high: float = 75.0

    def __post_init__(self) -> None:
        if self.refine not in REFINES:
            raise ValueError(f"edges.cnn.refine={self.refine!r}: use one of {REFINES}")
        for key in ("prior_correction", "snap_px", "snap_min_gradient", "refine_px",
                    "refine_low", "refine_high"):
            if getattr(self, key) < 0:
                raise ValueError(f"edges.cnn.{key} must be >= 0, got {getattr(self, key)}")


@dataclass
class EdgesConfig:
    """``edges``: the image edges of each mode (``localize.frontend.extractor``).

    Attributes:
        canny: mode none's Canny.
        hough: mode none keeps only the Hough line segments of its Canny edges.
        labels: the label modes' class boundaries.
        cnn: mode cnn only.
    """

    canny: CannyConfig = field(default_factory=CannyConfig)
    hough: HoughConfig = field(default_factory=HoughConfig)
    labels: LabelsConfig = field(default_factory=LabelsConfig)
    cnn: CnnConfig = field(default_factory=CnnConfig)


@dataclass
class ModelEdgesConfig:
    """``model_edges``: the world's 3D edge segments as sample points. The label modes score
    only the segments whose two sides differ in class; mode none scores every segment.

    Attributes:
        spacing: metres between samples along a segment.
        min_length: metres; shorter segments are not sampled (tessellation crumbs of curved
            surfaces: an imported building's many short edges; the procedural corridor's
            shortest is 0.08 m). Segments with no structural class on either side (clutter,
            people, void only) never are.
    """

    spacing: float = 0.1
    min_length: float = 0.05


@dataclass
class VisibilityConfig:
    """``visibility``: the samples visible from each camera cell (``localize.filter.visibility``;
    cached under ``<report>/cache/``).

    Attributes:
        cell_xy, cell_z: grid cell size, metres.
        pad: metres the grid extends beyond the free space.
        eps: metres of surface tolerance at a sample.
        max_range: metres; samples farther from a cell are not cast nor scored (memory and
            time grow with the samples within it).
        max_gb: memory budget of the lists, GB: while they are estimated above it, the
            cells double, and from the second coarsening on the range shrinks by 2/3
            (``localize.filter.visibility_budget``; the corridor keeps ``cell_xy``, ``cell_z``,
            ``max_range``; a hospital floor gets 0.4 x 0.5 m and 15 m). None: the configured
            grid whatever its size.
        variant: Mitsuba variant of the ray casts.
    """

    cell_xy: float = 0.2
    cell_z: float = 0.25
    pad: float = 0.3
    eps: float = 0.02
    max_range: float = 15.0
    max_gb: float | None = 2.0
    variant: str = "auto"


@dataclass
class LocalizerConfig:
    """What a ``Localizer`` is configured by: the localize config's ``filter``, ``edges``,
    ``model_edges`` and ``visibility`` nodes (``LocalizerConfig()``: the defaults)."""

    filter: FilterConfig = field(default_factory=FilterConfig)
    edges: EdgesConfig = field(default_factory=EdgesConfig)
    model_edges: ModelEdgesConfig = field(default_factory=ModelEdgesConfig)
    visibility: VisibilityConfig = field(default_factory=VisibilityConfig)

    @property
    def likelihood(self) -> LikelihoodConfig:
        """The tracking likelihood (``filter.likelihood``)."""
        return self.filter.likelihood

    def with_particles(self, n: int) -> LocalizerConfig:
        """These settings with ``n`` tracking particles (and at least ``n`` global ones)."""
        f = replace(self.filter, num_particles=int(n),
                    global_particles=max(int(n), self.filter.global_particles))
        return replace(self, filter=f)


@dataclass
class BagTopicsConfig:
    """``recording_topics``: the topics a ROS bag recording is read from (ignored for
    folders; ``localize.recordings.bag``).

    Attributes:
        image: sensor_msgs/Image or CompressedImage.
        camera_info: sensor_msgs/CameraInfo (its first message is used).
        odometry: nav_msgs/Odometry, geometry_msgs/PoseStamped or PoseWithCovarianceStamped.
        groundtruth: one of the odometry's kinds; None: no ground truth.
    """

    image: str = "/camera/image_raw"
    camera_info: str = "/camera/camera_info"
    odometry: str = "/odom"
    groundtruth: str | None = None


@dataclass
class MetricsConfig:
    """``metrics``: what the report counts as converged and failed.

    Attributes:
        converge_threshold_m: a global start has converged when its error stays below this.
        converge_within_frames: the target: converged within this many frames.
        failure_threshold_m: a frame with a larger error counts as a failure.
        lost_after_s: a run lost track when its error stayed above ``failure_threshold_m``
            for longer than this (``metrics.lost_track``).
        calibration_within_m: the error bound of the confidence calibration
            (``metrics.calibration``): the share of frames within it per confidence bin.
    """

    converge_threshold_m: float = 0.3
    converge_within_frames: int = 30
    failure_threshold_m: float = 1.0
    lost_after_s: float = 1.0
    calibration_within_m: float = 0.3


@dataclass
class ReportConfig:
    """``report``: the report's figure and reference figures.

    Attributes:
        figure_frame: the frame drawn in the Fig. 2 panel, a fraction of the flight.
        paper_error_m: Buyval et al. 2017, mean position error.
        paper_time_ms: Buyval et al. 2017, per frame with a GTX 1050.
        lidar_error_m: a LIDAR method's error.
    """

    figure_frame: float = 0.5
    paper_error_m: float = 0.32
    paper_time_ms: float = 177.0
    lidar_error_m: float = 0.1


@dataclass
class HintConfig:
    """``hint``: where a start begins (``localize.filter.start_hint.start_of_settings``): a pose
    to track from, or where a global search looks; every key null: anywhere in the free space.

    Attributes:
        pose: [x, y, z, yaw_deg] in the model's frame, at most ``START_MAX_OUTSIDE_M`` (1 m)
            outside the free space: alone, tracking starts there (as ROS's ``/initialpose``
            with a narrow covariance)...
        pose_std: ...with [sx, sy, sz (m), syaw (deg)] wider than the tracking start's noise
            (``filter.init_std``), a search around it (e.g. [0.5, 0.5, 0.1, 15]).
        region: [xmin, ymin, xmax, ymax] or a polygon [[x, y], ...], metres (the model's
            frame), overlapping the free space: a search inside it.
        space: a space (room) the world names (world.json ``spaces``), instead of ``region``.
        heading_deg: [from, to] degrees: a search over the headings counter-clockwise from
            ``from`` to ``to``.
    """

    pose: list[float] | None = None
    pose_std: list[float] | None = None
    region: list[Any] | None = None
    space: str | None = None
    heading_deg: list[float] | None = None


@dataclass
class WorldFileConfig:
    """``world``: a building model file to localize in instead of a dataset's model
    (``localize.world_file``: imported with no dataset rendered, cached by content).
    ``world=FILE`` on the command line is ``world.path=FILE``.

    The import keys are datagen's ``world=file`` keys (``datagen.config.FileWorldConfig``,
    docs/worlds.md and docs/importers.md); one left null takes the importer's default, so the
    defaults are written there alone.

    Attributes:
        path: the file (a Gazebo .world / .sdf, a mesh .glb .gltf .obj .ply .dae .stl, an
            .ifc); null: the dataset's model (``dataset``).
        cache: the folder of the imported maps; null: ``$XDG_CACHE_HOME/edgeloc/worlds``, else
            ``~/.cache/edgeloc/worlds`` (``localize.world_file``).
        model_path, units, up_axis, storey, doors, ceiling, floor_tolerance, name_rules: how
            the file is read and classed (``ImportConfig``).
        crease_deg, camera_margin, z_range, free_cell, free_close, free_max_hole,
            obstacle_span: the model edges and the free space (``FileWorldConfig``).
    """

    path: str | None = None
    cache: str | None = None
    model_path: list[str] | None = None
    units: float | None = None
    up_axis: str | None = None
    storey: str | None = None
    doors: str | None = None
    ceiling: str | None = None
    floor_tolerance: float | None = None
    name_rules: list[Any] | None = None
    crease_deg: float | None = None
    camera_margin: float | None = None
    z_range: list[float] | None = None
    free_cell: float | None = None
    free_close: float | None = None
    free_max_hole: float | None = None
    obstacle_span: float | None = None

    def import_settings(self) -> dict[str, Any]:
        """The import keys given (not null), for ``python -m datagen.worlds.file_map``."""
        return {k: v for k, v in asdict(self).items()
                if v is not None and k not in ("path", "cache")}


@dataclass
class AppConfig(LocalizerConfig):
    """What both localize apps read, ``python -m localize`` (``LocalizeConfig``) and the live
    node ``python -m localize.ros2`` (``localize.ros2.config.Ros2Config``): the
    ``LocalizerConfig``, the dataset and model, where outputs and caches go, the start, the
    viewer.

    Attributes:
        name: output folder ``<out_root>/<name>/`` (reports; the visibility cache under
            ``cache/``, shared by the offline runs and the node of one name).
        dataset: the dataset made by ``python -m datagen`` (the model, the camera).
        onnx_model: the SegNet of cnn mode, a segnet.onnx made by ``python -m train``; the
            localize settings it carries apply under the command line's. ``auto``: the
            dataset's own, ``outputs/models/<dataset folder name>/segnet.onnx``, where it
            exists, else the generalist shipped in ``models/generalist/``
            (``localize.frontend.segmenter.model_path``).
        out_root: where output folders go.
        hint: where a start begins (``HintConfig``): a pose to track from, or where a global
            search looks; all null: anywhere in the free space.
        threads: onnxruntime intra-op threads.
        viz: ``rerun``: log frames, labels, model edges at the estimate, particles,
            trajectory and the model in 3D (``localize.viewers.viz``); ``none``: no viewer.
        viz_connect: with ``viz=rerun``, a running rerun viewer to stream to instead of the
            file, e.g. ``rerun+http://127.0.0.1:9876/proxy``.
        set_by: written by the app (``localize.resolve.resolve``), not read: for each setting
            whose value differs from its default, the layer that set it (``conf/...yaml``,
            ``model <file>``, ``onnx_model=auto``, ``command line``).
        world: a building model file to localize in instead of the dataset's model
            (``WorldFileConfig``; ``world=FILE`` is ``world.path=FILE``); the camera then comes
            from the recording or the CameraInfo, the frames are delivered at the SegNet's
            input size and ``onnx_model=auto`` is the shipped generalist. Not with
            ``dataset=`` on the command line.
    """

    name: str = "demo"
    dataset: str = "outputs/datasets/demo"
    world: WorldFileConfig = field(default_factory=WorldFileConfig)
    onnx_model: str = "auto"
    out_root: str = "outputs/reports"
    hint: HintConfig = field(default_factory=HintConfig)
    threads: int = 2
    viz: str = "none"
    viz_connect: str | None = None
    set_by: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.viz not in VIZ_KINDS:
            raise ValueError(f"viz={self.viz!r}: use one of {', '.join(VIZ_KINDS)}")


@dataclass
class LocalizeConfig(AppConfig):
    """The offline app's config (``conf/localize.yaml``, ``python -m localize``): the
    ``AppConfig`` and the runs over a dataset's flights or a recording.

    Attributes:
        flight_set: the dataset's flights to run: ``test`` (the default: ``render_flights``,
            the flights figures are reported on) or ``val`` (``val_flights``, ``<name>_val``:
            the flights settings are tuned on). The report names the set.
        flight_names: flights of that set to run; None: every flight of the set.
        modes: edge modes: none (Canny + Hough), cnn (the SegNet), oracle (true labels).
        inits: tracking (start around the first true pose) and/or global (from ``hint``).
            A recording starts from ``hint`` where one is set, else from its first true pose,
            else globally.
        seeds: one filter run per seed.
        recording: a recording (a folder or a ROS 1/2 bag, docs/recording.md) to localize
            instead of the dataset's flights; outputs go to
            ``<out_root>/<name>/recordings/<recording>/``.
        recording_topics: the bag topics.
        recording_body_from_cam: (4, 4) camera mount; None: the recording's, else the
            dataset's.
        max_frames: only the first N >= 1 frames of each flight or recording (quick runs,
            tests); null: every frame; 0 is refused, naming the key.
        overwrite: re-run trajectories that already exist.
        progress: tqdm progress bars.
        metrics, report: the report's settings.

    With ``viz=rerun`` each pass logs to ``<report>/viz/<source>_<mode>.rrd``.
    """

    flight_set: str = "test"
    flight_names: list[str] | None = None
    modes: list[str] = field(default_factory=lambda: list(MODES))
    inits: list[str] = field(default_factory=lambda: ["tracking", "global"])
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    recording: str | None = None
    recording_topics: BagTopicsConfig = field(default_factory=BagTopicsConfig)
    recording_body_from_cam: list[Any] | None = None
    max_frames: int | None = None
    overwrite: bool = False
    progress: bool = True
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    report: ReportConfig = field(default_factory=ReportConfig)


register_schema("localize_schema", LocalizeConfig)
