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

from core.config import register_schema
from localize.filter.config import MODES, FilterConfig, LikelihoodConfig

#: ``edges.cnn.refine`` choices.
REFINES = ("none", "union")
#: Command-line aliases of both localize apps (``core.config.expand_aliases``): ``world=FILE``.
ALIASES = {"world": "world.path"}
#: ``viz`` choices (``localize.viewers.viz``).
VIZ_KINDS = ("none", "rerun")


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
        segnet_int8: cnn mode runs the int8 copy of the SegNet (``segnet_int8.onnx`` beside
            the chosen segnet.onnx, made by ``python -m train.deploy.quantize`` of that file;
            ``localize.frontend.segmenter.int8_copy``) where one exists: half the float
            network's time at its tracking error (docs/notes/speed.md); false: the float one.
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
    segnet_int8: bool = True
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
