"""The pose hypotheses of a weighted set of poses: its few heaviest modes and their mass.

A global start holds many poses at once (a particle set, or the cells of a search), and its
weighted mean says nothing while they gather on two or more places. ``top_hypotheses``
finds the heaviest modes, one after the other: the weighted mean of the coarse bin of (x, y,
yaw) holding the most remaining mass, moved to the weighted mean of the poses within the kernel
around it
(two mean-shift steps with a flat ellipsoidal kernel of ``radius_m`` horizontally and
``yaw_deg`` in heading), whose poses are then the hypothesis and leave the set. Each
hypothesis reports its mean pose, its spread and the share of the whole mass it holds, so
a uniform start over a floor gives hypotheses of tiny mass and a converged track one of
mass ~1.

``Dominance`` turns the masses into a status: ``tracking`` once one hypothesis has held at
least ``dominant_mass`` for ``dominant_frames`` frames in a row, ``ambiguous`` until then
and whenever it falls below again.

Settings: ``localize.config.FilterConfig`` (``filter.hypotheses``, ``hypothesis_radius_m``,
``hypothesis_yaw_deg``, ``dominant_mass``, ``dominant_frames``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from core.poses import wrap_angle
from localize.filter.pose_stats import mean_pose, pose_spread

#: Mean-shift steps from a peak bin's centre to its mode.
SHIFT_STEPS = 2
#: A larger set is first thinned to this many poses by a deterministic systematic resample
#: (each mass then off by ~1 / sqrt of it, 0.007): a global set of 200,000 costs as 20,000.
MAX_POSES = 20000


@dataclass(frozen=True)
class Hypothesis:
    """One mode of a weighted pose set.

    Attributes:
        state: (4,) x, y, z (m), yaw (rad): the weighted mean of its poses (circular yaw).
        mass: in [0, 1], the share of the set's weight it holds.
        position_std: weighted horizontal spread of its poses, metres.
        yaw_std: circular spread of their yaw, radians.
        count: poses in it.
    """

    state: np.ndarray
    mass: float
    position_std: float
    yaw_std: float
    count: int

    def as_list(self) -> list[float]:
        """[x, y, z, yaw, mass], rounded for a run record (m, rad)."""
        return [round(float(v), 4) for v in (*self.state, self.mass)]


def _weighted_pose(p: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Weighted mean pose (4,), horizontal std (m) and circular yaw std (rad) of poses
    (N, 4) with positive weights (N,)."""
    w = w / w.sum()
    return (mean_pose(p, w), *pose_spread(p, w))


def _inside(p: np.ndarray, centre: np.ndarray, radius_m: float, yaw_rad: float) -> np.ndarray:
    """(N,) bool: poses (N, 4) within the ellipsoidal kernel around ``centre`` (4,)."""
    d2 = ((p[:, 0] - centre[0]) ** 2 + (p[:, 1] - centre[1]) ** 2) / radius_m ** 2
    return d2 + (wrap_angle(p[:, 3] - centre[3]) / yaw_rad) ** 2 <= 1.0


def top_hypotheses(poses: np.ndarray, logw: np.ndarray, k: int, radius_m: float,
                   yaw_deg: float, min_mass: float = 1e-4,
                   max_poses: int = MAX_POSES) -> list[Hypothesis]:
    """The ``k`` heaviest modes of a weighted pose set, heaviest first.

    Args:
        poses: (N, 4) x, y, z (m), yaw (rad).
        logw: (N,) log-weights (any scale).
        k: most hypotheses.
        radius_m: horizontal radius of a hypothesis's kernel (and size of the peak bins), m.
        yaw_deg: its half-width in heading, degrees.
        min_mass: a mode holding less than this share ends the list (the first is always
            given).
        max_poses: a larger set is thinned to this many equally weighted poses first
            (systematic resampling at fixed offsets: no randomness drawn).

    Returns:
        Up to ``k`` ``Hypothesis`` (at least one for a non-empty set); their masses sum to at
        most 1 (the rest lies outside every kernel). Cost: one binning and ``k`` x
        (1 + ``SHIFT_STEPS``) passes over N.
    """
    p = np.asarray(poses, dtype=np.float64)
    lw = np.asarray(logw, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 4 or lw.shape != (len(p),):
        raise ValueError(f"top_hypotheses: poses must be (N, 4) and logw (N,), got {p.shape} "
                         f"and {lw.shape}")
    if radius_m <= 0 or yaw_deg <= 0:
        raise ValueError(f"hypothesis kernel must be positive, got {radius_m} m, {yaw_deg} deg")
    if len(p) == 0:
        return []
    w = np.exp(lw - logsumexp(lw))
    if len(p) > max_poses:
        cdf = np.cumsum(w)
        idx = np.searchsorted(cdf, (np.arange(max_poses) + 0.5) / max_poses * cdf[-1])
        p = p[np.minimum(idx, len(p) - 1)]
        w = np.full(max_poses, 1.0 / max_poses)
    yaw_rad = np.deg2rad(min(float(yaw_deg), 180.0))
    # coarse bins: radius_m in x, y; 2 x yaw_deg in heading (the kernel's widths)
    lo = p[:, :2].min(axis=0)
    ij = np.floor((p[:, :2] - lo) / radius_m).astype(np.int64)
    n_yaw = max(int(np.floor(2 * np.pi / (2 * yaw_rad))), 1)
    iy = np.minimum(((p[:, 3] + np.pi) / (2 * np.pi) * n_yaw).astype(np.int64), n_yaw - 1)
    dims = (int(ij[:, 0].max()) + 1, int(ij[:, 1].max()) + 1, n_yaw)
    key = np.ravel_multi_index((ij[:, 0], ij[:, 1], iy), dims)
    n_bins = int(np.prod(dims))
    left = w.copy()
    out: list[Hypothesis] = []
    for _ in range(int(k)):
        mass = np.bincount(key, weights=left, minlength=n_bins)
        peak = int(np.argmax(mass))
        if mass[peak] <= 0:
            break
        in_bin = (key == peak) & (left > 0)
        centre, _, _ = _weighted_pose(p[in_bin], left[in_bin])
        for _ in range(SHIFT_STEPS):
            near = _inside(p, centre, radius_m, yaw_rad) & (left > 0)
            if not near.any():
                break
            centre, _, _ = _weighted_pose(p[near], left[near])
        members = _inside(p, centre, radius_m, yaw_rad) & (left > 0)
        held = float(left[members].sum())
        if held < min_mass and out:
            break
        state, pos_std, yaw_std = _weighted_pose(p[members], left[members])
        out.append(Hypothesis(state, held, pos_std, yaw_std, int(members.sum())))
        left[members] = 0.0
    return out


class Dominance:
    """``tracking`` once one hypothesis has held at least ``mass`` for ``frames`` frames in a
    row, ``ambiguous`` before and whenever it falls below.

    Args:
        mass: the share of the mass the top hypothesis must hold (``filter.dominant_mass``).
        frames: frames in a row it must hold it (``filter.dominant_frames``).
    """

    def __init__(self, mass: float, frames: int):
        self.mass, self.frames = float(mass), int(frames)
        self.held = 0

    def confirm(self) -> None:
        """A start at a known pose: dominant at once."""
        self.held = self.frames

    def clear(self) -> None:
        """A global start: ambiguous until a hypothesis has held for ``frames``."""
        self.held = 0

    @property
    def confirmed(self) -> bool:
        return self.held >= self.frames

    def update(self, top_mass: float) -> str:
        """The status after a frame whose top hypothesis holds ``top_mass``."""
        self.held = self.held + 1 if top_mass >= self.mass else 0
        return "tracking" if self.confirmed else "ambiguous"
