"""The visibility grid that fits a memory budget: the building decides the cell size.

The visibility lists (``visibility.SparseVisibility``) hold, per camera cell, the ids of the
samples seen within ``max_range``: their memory grows with the free area / the cell volume x
the samples a cell sees. A corridor's lists at the default 0.2 x 0.25 m cells and 15 m take
tens of MB; a hospital floor's would take several GB. ``fit_grid`` starts from the configured
cells and range and, while the lists are estimated above the budget (``visibility.max_gb``),
goes one level coarser: cells x ``CELL_STEP`` (both axes) at each level, range x ``RANGE_STEP``
from level 2 on (the range is what fixes a pose along a long corridor: its far door frames
and ends; coarser cells only blur the occlusion). The corridor stays at level 0, the AWS
hospital floor lands on level 1 (0.4 x 0.5 m, 15 m).

The estimate probes ``probe`` stored cells spread over the grid (rows are tile-ordered, so
evenly spaced rows spread over the floor): an upper bound counts every sample in range; only
when that exceeds the budget are the probes' rays cast (``visibility.RayCaster``) and the
mean visible count taken.
"""

from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from core.atomic import atomic_write_json
from core.dataset import World
from core.imaging.rays import RayCaster
from core.occupancy import OccupancyMap
from localize.filter.visibility import cache_key, free_bounds, grid_layout, stored_cells

log = logging.getLogger(__name__)

#: one coarser level: cells x CELL_STEP (xy and z); from level 2 on also max_range x RANGE_STEP.
CELL_STEP, RANGE_STEP = 2.0, 2.0 / 3.0
#: levels tried (level 0: the configured grid).
MAX_LEVELS = 4
#: bytes per listed sample (id uint32 + class pair uint8) and per stored row (flat int64 +
#: indptr int64).
ID_BYTES, ROW_BYTES = 5, 16


@dataclass(frozen=True)
class GridChoice:
    """A visibility grid and its estimated memory.

    Attributes:
        cell_xy, cell_z: cell sizes, metres.
        max_range: metres.
        level: coarsening steps from the configured grid (0: as configured).
        rows: stored cells.
        est_bytes: estimated bytes of the lists (ids, rows and the grid's row_of).
        exact: False when ``est_bytes`` is the in-range upper bound (no ray cast).
    """

    cell_xy: float
    cell_z: float
    max_range: float
    level: int
    rows: int
    est_bytes: float
    exact: bool


def estimate_grid(world: World, points: np.ndarray, free: OccupancyMap, cell_xy: float,
                  cell_z: float, pad: float, eps: float, max_range: float,
                  max_bytes: float | None = None, probe: int = 256,
                  variant: str = "auto") -> GridChoice:
    """The memory of the lists on one grid, from ``probe`` evenly spaced stored cells.

    Args:
        world: the model (mesh; ray-cast only when the upper bound exceeds ``max_bytes``).
        points: (P, 3) edge samples, metres.
        free: the camera's free space.
        cell_xy, cell_z, pad, eps, max_range: as ``visibility.build_visibility``.
        max_bytes: the budget; None casts the probes' rays always.
        probe: cells probed.
        variant: Mitsuba variant of the casts.

    Returns:
        The grid with its estimate (level 0).
    """
    origin, cell, shape = grid_layout(*free_bounds(free), cell_xy, cell_z, pad)
    flat, _ = stored_cells(free, origin, cell, shape, pad)
    R, G = len(flat), int(np.prod(shape))
    at = np.unique(np.linspace(0, R - 1, min(probe, R)).round().astype(np.int64))
    ijk = np.stack(np.unravel_index(flat[at], tuple(shape)), axis=1)
    centres = origin + ijk * cell
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    near = cKDTree(points).query_ball_point(centres, max_range)
    fixed = R * ROW_BYTES + G * 4
    upper = fixed + R * ID_BYTES * float(np.mean([len(n) for n in near]))
    if max_bytes is not None and upper <= max_bytes:
        return GridChoice(cell_xy, cell_z, max_range, 0, R, upper, False)
    i = np.repeat(np.arange(len(at)), [len(n) for n in near])
    j = np.concatenate([np.asarray(n, np.int64) for n in near])
    seen = (~RayCaster(world.vertices, world.faces, variant).hidden(centres[i], points[j], eps)
            if len(j) else j)
    est = fixed + R * ID_BYTES * float(np.count_nonzero(seen)) / len(at)
    return GridChoice(cell_xy, cell_z, max_range, 0, R, est, True)


def fit_grid(world: World, points: np.ndarray, free: OccupancyMap, cell_xy: float,
             cell_z: float, pad: float, eps: float, max_range: float, max_gb: float,
             variant: str = "auto") -> GridChoice:
    """The finest grid (level 0: the configured one) whose lists are estimated within
    ``max_gb`` GB (``estimate_grid``); each level coarsens cells by ``CELL_STEP``, and from
    level 2 on the range by ``RANGE_STEP``.

    Raises:
        ValueError: naming ``visibility.max_gb`` when even level ``MAX_LEVELS - 1`` does not
            fit.
    """
    if max_gb <= 0:
        raise ValueError(f"visibility.max_gb must be positive, got {max_gb}")
    budget = max_gb * 1e9
    for level in range(MAX_LEVELS):
        f, r = CELL_STEP ** level, RANGE_STEP ** max(level - 1, 0)
        g = estimate_grid(world, points, free, cell_xy * f, cell_z * f, pad, eps,
                          max_range * r, budget, variant=variant)
        choice = replace(g, level=level)
        if g.est_bytes <= budget:
            if level:
                log.info("visibility: cells %.2f x %.2f m, range %.1f m (level %d): about "
                         "%.2f GB (visibility.max_gb %.1f)", choice.cell_xy, choice.cell_z,
                         choice.max_range, level, g.est_bytes / 1e9, max_gb)
            return choice
    raise ValueError(f"visibility lists need about {g.est_bytes / 1e9:.1f} GB even with "
                     f"{g.cell_xy:.2f} x {g.cell_z:.2f} m cells and {g.max_range:.1f} m range, "
                     f"more than visibility.max_gb={max_gb}; raise visibility.max_gb or give "
                     "coarser visibility.cell_xy / cell_z or a shorter visibility.max_range")


def fit_grid_cached(cache_dir: str | Path | None, world: World, points: np.ndarray,
                    free: OccupancyMap, cell_xy: float, cell_z: float, pad: float, eps: float,
                    max_range: float, max_gb: float, variant: str = "auto") -> GridChoice:
    """``fit_grid``, remembered in ``cache_dir/grid_<key>.json`` (key: the mesh, the samples,
    the free space and these settings), so a start with a built cache casts no probe rays.
    ``cache_dir`` None: ``fit_grid`` itself."""
    if cache_dir is None:
        return fit_grid(world, points, free, cell_xy, cell_z, pad, eps, max_range, max_gb,
                        variant)
    settings = {"cell_xy": cell_xy, "cell_z": cell_z, "pad": pad, "eps": eps,
                "max_range": max_range, "max_gb": max_gb}
    path = Path(cache_dir) / f"grid_{cache_key(world, points, free, settings)}.json"
    if path.is_file():
        choice = GridChoice(**json.loads(path.read_text()))
        if choice.level:
            log.info("visibility: cells %.2f x %.2f m, range %.1f m (level %d, %s)",
                     choice.cell_xy, choice.cell_z, choice.max_range, choice.level, path.name)
        return choice
    choice = fit_grid(world, points, free, cell_xy, cell_z, pad, eps, max_range, max_gb,
                      variant)
    atomic_write_json(path, asdict(choice))
    return choice
