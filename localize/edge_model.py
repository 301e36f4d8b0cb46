"""The model edges a mode scores (``EdgeModel``): samples along a world's structural edge
segments, their visibility lists from the free space's cells, and the class pair of each;
built once per world and shared by every localizer on it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from core import classes as C
from core.classes import pair_code
from core.dataset import World
from core.occupancy import OccupancyMap
from localize.config import LocalizerConfig
from localize.filter.projection import ModelSamples, sample_segments
from localize.filter.visibility import SparseVisibility, load_or_build
from localize.filter.visibility_budget import fit_grid_cached

#: classes that make a segment worth scoring: one of its sides must be one of them (an edge
#: between clutter, people or void only is not part of the structural model).
STRUCTURAL = (C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW)


def scored_segments(world: World, min_length: float = 0.0) -> np.ndarray:
    """(M,) bool: the world's segments the model samples: a structural class on one side
    (``STRUCTURAL``) and at least ``min_length`` metres long."""
    seg = np.asarray(world.segments, dtype=np.float64).reshape(-1, 2, 3)
    sc = np.asarray(world.segment_classes).reshape(-1, 2)
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    return np.isin(sc, STRUCTURAL).any(axis=1) & (length >= min_length)


@dataclass
class EdgeModel:
    """The model edges a mode scores: samples, their visibility lists and class pairs.

    Attributes:
        samples: points along the world's structural edge segments (``scored_segments``).
        visibility: the samples visible from each camera cell (None: every sample in view
            counts as visible).
        pairs: (P,) uint8 ``edges.pair_code`` of the two classes each sample's segment
            separates.
    """

    samples: ModelSamples
    visibility: SparseVisibility | None
    pairs: np.ndarray
    _thinned: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, world: World, settings: LocalizerConfig, cache_dir: str | Path | None = None,
              occlusion: bool = True, free: OccupancyMap | None = None) -> EdgeModel:
        """The world's structural edges (``scored_segments``), sampled every
        ``settings.model_edges.spacing`` m, with their visibility lists (ray-cast from the
        cells of ``free``, default ``world.free``, on the grid that fits
        ``visibility.max_gb``: ``visibility_budget.fit_grid_cached``; cached under ``cache_dir``
        when given; ``occlusion=False`` skips them)."""
        me = settings.model_edges
        keep = scored_segments(world, me.min_length)
        if not keep.any():
            src = world.info.get("source")
            where = f" (from {src})" if src else ""
            raise ValueError(f"world {world.info.get('name', '?')!r}{where}: no edge segment "
                             "of world/edges.npz has a floor, wall, ceiling, door or window "
                             f"on a side and is >= model_edges.min_length ({me.min_length} m), "
                             "so there is no model edge to localize against; re-import the "
                             "building with its surfaces classed (world.name_rules, "
                             "docs/importers.md) or lower model_edges.min_length")
        samples, _ = sample_segments(world.segments, me.spacing).select(keep)
        vis = None
        if occlusion:
            v = settings.visibility
            free = world.free if free is None else free
            cell_xy, cell_z, max_range = v.cell_xy, v.cell_z, v.max_range
            if v.max_gb is not None:
                g = fit_grid_cached(cache_dir, world, samples.points, free, cell_xy, cell_z,
                                    v.pad, v.eps, max_range, v.max_gb, v.variant)
                cell_xy, cell_z, max_range = g.cell_xy, g.cell_z, g.max_range
            normals = None if world.normals is None else world.normals[samples.segment]
            vis = load_or_build(world, samples.points, free, cache_dir,
                                replace(v, cell_xy=cell_xy, cell_z=cell_z, max_range=max_range),
                                np.asarray(world.segment_classes)[samples.segment], normals)
        sc = np.asarray(world.segment_classes)[samples.segment]
        return cls(samples, vis, pair_code(sc[:, 0], sc[:, 1]))

    def class_change(self, world: World) -> EdgeModel:
        """The samples that can show two different classes (what label boundaries can match;
        a boundary with clutter falls on unknown pixels): those of segments between two, and
        with visibility lists those of creases with a structural face, an outline against
        what lies behind them (``core.imaging.outline``); the lists keep only the entries
        where a cell sees two classes, neither of them void. This model when there are
        none."""
        sc = np.asarray(world.segment_classes)
        keep = (sc[:, 0] != sc[:, 1]) & (sc.min(axis=1) > 0)
        if self.visibility is not None and world.normals is not None:
            crease = ~np.isnan(world.normals[:, 0, 0])
            keep |= crease & np.isin(sc, STRUCTURAL).any(axis=1)
        if not keep.any():
            return self
        sub = self._subset(keep)
        if sub.visibility is not None:  # the entries seen as two classes, none of them void
            lo, _ = C.pair_classes(sub.visibility.codes)
            sub.visibility = sub.visibility.entries((sub.visibility.codes > 0) & (lo > 0))
        return sub

    def _subset(self, keep: np.ndarray) -> EdgeModel:
        """The samples of the segments ``keep`` (M,) bool."""
        sub, cols = self.samples.select(keep)
        vis = None if self.visibility is None else self.visibility.select(cols)
        return EdgeModel(sub, vis, self.pairs[cols])

    def thin(self, step: int) -> EdgeModel:
        """Every ``step``-th sample of each segment (``ModelSamples.thin``); made once per
        step and kept, so localizers sharing this model share it too."""
        step = int(step)
        if step not in self._thinned:
            sub, cols = self.samples.thin(step)
            vis = None if self.visibility is None else self.visibility.select(cols)
            self._thinned[step] = EdgeModel(sub, vis, self.pairs[cols])
        return self._thinned[step]

    def for_mode(self, world: World, mode: str) -> EdgeModel:
        """The part of this model an edge mode scores: the class boundaries (``class_change``)
        for the label modes, whose edges are class boundaries only; all of it for ``none``."""
        return self if mode == "none" else self.class_change(world)
