"""Settings at floor scale (issue 55): the visibility grid chosen by a memory budget and the
global start's particle count chosen by the free area."""

from __future__ import annotations

import numpy as np
import pytest

from localize.config import FilterConfig, VisibilityConfig
from localize.filter import visibility_budget
from localize.filter.projection import sample_segments
from localize.filter.visibility import build_visibility
from localize.filter.visibility_budget import (
    CELL_STEP,
    RANGE_STEP,
    estimate_grid,
    fit_grid,
    fit_grid_cached,
)
from tests.localize.test_visibility_scale import straight


@pytest.fixture(scope="module")
def long_corridor():
    world = straight(30.0)
    return world, sample_segments(world.segments, 0.2).points


def test_estimate_matches_the_built_lists(long_corridor):
    """The probes' estimate is within 15 % of the lists' bytes; the in-range bound is above."""
    world, pts = long_corridor
    vis = build_visibility(world, pts, world.free,
                           settings=VisibilityConfig(cell_xy=0.5, cell_z=0.6, max_range=6.0))
    est = estimate_grid(world, pts, world.free, 0.5, 0.6, 0.3, 0.02, 6.0)
    upper = estimate_grid(world, pts, world.free, 0.5, 0.6, 0.3, 0.02, 6.0, max_bytes=1e12)
    assert est.exact and not upper.exact and est.rows == len(vis.counts())
    assert abs(est.est_bytes / vis.nbytes - 1) < 0.15
    assert upper.est_bytes >= est.est_bytes


def test_budget_keeps_the_grid_that_fits_and_coarsens_the_one_that_does_not(long_corridor):
    world, pts = long_corridor
    fine = fit_grid(world, pts, world.free, 0.2, 0.25, 0.3, 0.02, 6.0, max_gb=2.0)
    assert (fine.cell_xy, fine.cell_z, fine.max_range, fine.level) == (0.2, 0.25, 6.0, 0)
    exact = estimate_grid(world, pts, world.free, 0.2, 0.25, 0.3, 0.02, 6.0)
    small = exact.est_bytes / 3 / 1e9  # the configured grid does not fit, the next one does
    coarse = fit_grid(world, pts, world.free, 0.2, 0.25, 0.3, 0.02, 6.0, max_gb=small)
    assert coarse.level >= 1 and coarse.est_bytes <= small * 1e9
    assert coarse.cell_xy == pytest.approx(0.2 * CELL_STEP ** coarse.level)
    assert coarse.max_range == pytest.approx(6.0 * RANGE_STEP ** max(coarse.level - 1, 0))
    with pytest.raises(ValueError, match="visibility.max_gb"):
        fit_grid(world, pts, world.free, 0.2, 0.25, 0.3, 0.02, 6.0, max_gb=1e-9)


def test_the_grid_choice_is_remembered_in_the_cache(long_corridor, tmp_path, monkeypatch):
    """A second start with the same cache reads the choice and casts no probe rays; other
    settings choose again."""
    world, pts = long_corridor
    args = (world, pts, world.free, 0.2, 0.25, 0.3, 0.02, 6.0)
    small = estimate_grid(*args).est_bytes / 3 / 1e9  # the configured grid does not fit
    first = fit_grid_cached(tmp_path, *args, max_gb=small)
    assert first.level >= 1 and len(list(tmp_path.glob("grid_*.json"))) == 1

    def no_probe(*a, **k):
        raise AssertionError("estimate_grid called with the choice in the cache")

    monkeypatch.setattr(visibility_budget, "estimate_grid", no_probe)
    assert fit_grid_cached(tmp_path, *args, max_gb=small) == first
    with pytest.raises(AssertionError, match="in the cache"):
        fit_grid_cached(tmp_path, *args, max_gb=2.0)


def test_global_particles_grow_with_the_free_area():
    """The corridor (16 m2 or less) keeps global_particles; a floor gets the same density up to
    global_max_particles."""
    p = FilterConfig()
    assert p.global_count(5.5) == p.global_count(16.0) == p.global_particles
    assert p.global_count(32.0) == 2 * p.global_particles
    assert p.global_count(1021.0) == p.global_max_particles
    few = FilterConfig(global_particles=600, global_max_particles=1000)
    assert few.global_count(1021.0) == 1000
    assert FilterConfig(global_particles=600, global_max_particles=100).global_count(1e3) == 600
    with pytest.raises(ValueError, match="global_area"):
        FilterConfig(global_area=0.0)
    assert np.isfinite(p.global_count(0.0))
