"""The particle filter's settings: ``FilterConfig`` (``filter``: particles, motion, recovery,
the global start) and ``LikelihoodConfig`` (``filter.likelihood``: the edge likelihood).

Part of the localize schema (``localize.config.LocalizerConfig.filter``); the field defaults
below are the only defaults. Why they are what they are: docs/filter.md, docs/localize.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from core.config import typed
from localize.search.config import GlobalSearchConfig, RivalsConfig

#: The edge modes (``localize.frontend.extractor``).
MODES = ("none", "cnn", "oracle")


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
        rivals: the rival hypotheses kept beside a track (``RivalsConfig``,
            ``localize.search.rivals``): a loss when a far one outweighs the track.
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
    rivals: RivalsConfig = field(default_factory=RivalsConfig)
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
        cw = self.global_search.confirm_within
        if cw < 0 or 0 < cw <= self.dominant_frames:
            raise ValueError(f"filter.global_search.confirm_within ({cw}) must be 0 (never) or "
                             f"more than filter.dominant_frames ({self.dominant_frames}): the "
                             "track must be able to be reported tracking for that many frames")
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
