"""The global search's settings (``filter.global_search``): the schema node ``FilterConfig``
holds, apart from the search (``localize.search.global_search``) so the settings read it
without the search's imports."""

from __future__ import annotations

from dataclasses import dataclass, field

from core.config import check_positive


@dataclass
class GlobalSearchConfig:
    """Settings of the global search (``filter.global_search``).

    Attributes:
        cell: m, the table's cell (the start grid's spacing).
        rays: azimuth bins of the table (2 pi / rays each).
        headings: headings per cell of the start grid.
        sigma_deg: angle noise of a boundary pixel's bin, degrees.
        outlier: most a bin's error costs, in units of its Gaussian's exponent.
        class_cost: what a bin costs whose class above the floor (wall, door, window) is not
            the table's (added to its error, within ``outlier``).
        evidence: log-likelihood scale of a frame that shows ``max_bins`` bins or more (one
            that shows fewer counts for their share).
        frame_floor: most log-weight a frame takes from a hypothesis against the best one.
        min_bins: fewer observed azimuth bins: the frame is not weighed.
        max_bins: most azimuth bins scored (evenly spaced among the observed ones).
        motion_std: (3,) per ``filter.motion_period_s``: horizontal m, vertical m, yaw degrees.
        motion_rel: (2,) more noise per m of translation and per rad of yaw change.
        jitter: (2,) m and degrees of the jitter of a copy.
        prune_band: hypotheses more than this below the best in log-weight are dropped.
        inject_every: frames between injections of the best poses of a coarse grid (0: none).
        inject_headings: headings per cell of that grid.
        inject_count: poses injected.
        inject_below: log-weight under the best they start with.
        per_bin: hypotheses per occupied 0.5 m x 0.5 m x 20 deg bin after pruning.
        min_hypotheses, max_hypotheses: bounds of the count after resampling.
        cluster_radius: m, a cluster's radius (the mass of a hypothesis).
        cluster_yaw_deg: degrees, its half-width in yaw.
        handover_mass: share of the settled weight (injected hypotheses count once weighed
            for ``handover_frames`` frames) the ``handover_places`` heaviest clusters must
            hold together to converge...
        handover_frames: ...for this many frames in a row.
        handover_places: the most places handed over to the tracking filter: the search
            converges once this many clusters hold ``handover_mass``; the filter's particles
            are split evenly between them and its edge likelihood (door frames, windows, the
            ceiling line: what the floor boundary does not see) chooses, ``ambiguous`` until
            one holds ``filter.dominant_mass`` (1: one place must dominate the search).
        confirm_within: frames after a handover within which the track must be reported
            ``tracking`` (the quality's gate passed: ``filter.tracking_quality``) for
            ``filter.dominant_frames`` frames in a row; otherwise the handover went to a
            wrong place the floor boundary could not tell from the right one, and the track
            is declared lost and a fresh search starts (0: never).
        stride: pixel step of the boundary search in the label image.
    """

    cell: float = 0.25
    rays: int = 180
    headings: int = 60
    sigma_deg: float = 1.5
    outlier: float = 2.0
    class_cost: float = 1.0
    evidence: float = 3.0
    frame_floor: float = 3.0
    min_bins: int = 8
    max_bins: int = 16
    motion_std: list[float] = field(default_factory=lambda: [0.03, 0.02, 1.0])
    motion_rel: list[float] = field(default_factory=lambda: [0.1, 0.1])
    jitter: list[float] = field(default_factory=lambda: [0.05, 1.0])
    prune_band: float = 30.0
    inject_every: int = 10
    inject_headings: int = 24
    inject_count: int = 1000
    inject_below: float = 10.0
    per_bin: int = 40
    min_hypotheses: int = 4000
    max_hypotheses: int = 60000
    cluster_radius: float = 0.6
    cluster_yaw_deg: float = 25.0
    handover_mass: float = 0.999
    handover_frames: int = 10
    handover_places: int = 1
    confirm_within: int = 40
    stride: int = 2

    def __post_init__(self) -> None:
        check_positive(self, ("rays", "headings", "min_bins", "max_bins", "inject_headings",
                              "per_bin", "min_hypotheses", "max_hypotheses", "handover_frames",
                              "handover_places",
                              "stride", "cell", "sigma_deg", "outlier", "evidence",
                              "cluster_radius", "cluster_yaw_deg"), "filter.global_search")
        if self.min_bins > self.max_bins or self.min_hypotheses > self.max_hypotheses:
            raise ValueError("filter.global_search: min_bins <= max_bins and min_hypotheses <= "
                             f"max_hypotheses, got {self.min_bins}, {self.max_bins}, "
                             f"{self.min_hypotheses}, {self.max_hypotheses}")
        if not 0.0 < self.handover_mass <= 1.0:
            raise ValueError(f"filter.global_search.handover_mass must be in (0, 1], got "
                             f"{self.handover_mass}")
        for key, n in (("motion_std", 3), ("motion_rel", 2), ("jitter", 2)):
            if len(getattr(self, key)) != n:
                raise ValueError(f"filter.global_search.{key} needs {n} values, got "
                                 f"{list(getattr(self, key))}")


@dataclass
class RivalsConfig:
    """Settings of the rival hypotheses kept beside a track (``filter.rivals``,
    ``localize.search.rivals``).

    Attributes:
        enabled: keep them (a loss is then also declared when a far rival outweighs the
            track); false: only the fit gate's ``filter.lost_frames`` declares a loss.
        every: frames between checks (the background search's update and the edge scoring).
        count: most rivals scored per check (the background search's heaviest far clusters).
        particles: poses per hypothesis scored with the edge likelihood (the track's drawn
            from its particles by weight, a rival's from its cluster's hypotheses).
        min_distance: m, a cluster is a rival only this far from the track's estimate (or
            more than the search's ``cluster_yaw_deg`` off in heading).
        margin: log-likelihood (the edge likelihood's ``k * score``) by which a rival's mean
            likelihood must exceed the track's...
        checks: ...at this many checks in a row to declare the track lost (the background
            search then re-localizes in the foreground); after a loss, the track is ``ambiguous``
            until it has led every rival by ``margin`` at this many checks in a row
            (``search.rivals.doubt_after``).
        inject_every: the background search injects its coarse grid's best poses every this
            many checks (``global_search.inject_every`` counts the search's own updates).
        max_hypotheses: most hypotheses the background search keeps
            (``global_search.max_hypotheses`` for it, and its ``min_hypotheses`` at most this).
    """

    enabled: bool = False
    every: int = 3
    count: int = 3
    particles: int = 64
    min_distance: float = 1.0
    margin: float = 3.0
    checks: int = 3
    inject_every: int = 2
    max_hypotheses: int = 5000

    def __post_init__(self) -> None:
        check_positive(self, ("every", "count", "particles", "min_distance", "checks",
                              "inject_every", "max_hypotheses"),
                       "filter.rivals")
        if self.margin < 0:
            raise ValueError(f"filter.rivals.margin must be >= 0 (log-likelihood), got "
                             f"{self.margin}")
