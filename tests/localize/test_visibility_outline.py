"""Outlines in the visibility lists and the modes' edge models (core.imaging.outline)."""

from __future__ import annotations

import numpy as np

from datagen.worlds.corridor import build_world
from localize.config import LocalizerConfig, VisibilityConfig
from localize.filter.projection import sample_segments
from localize.filter.visibility import build_visibility
from localize.localizer import EdgeModel


def test_outlines_at_inner_corners_are_never_listed():
    """The corridor's outlines lie at the inner corners of its recesses: in view from its
    free space (listed when the facing test is left out), never turned as an outline is seen
    from there; the other samples' lists are unchanged."""
    w = build_world().world
    outline = ~np.isnan(w.outline).all(axis=(1, 2))
    s = sample_segments(w.segments, 0.1)
    mine = outline[s.segment]
    settings = VisibilityConfig(cell_xy=0.4, cell_z=0.6)
    plain = build_visibility(w, s.points, settings=settings)
    turned = build_visibility(w, s.points, settings=settings, outline=w.outline[s.segment])
    inside = w.free.contains(plain.centres()[:, :2])
    seen_plain, seen_turned = plain.union(np.flatnonzero(inside)), turned.union(
        np.flatnonzero(inside))
    assert (seen_plain & mine).any()
    assert not (seen_turned & mine).any()
    np.testing.assert_array_equal(seen_plain & ~mine, seen_turned & ~mine)


def test_mode_none_scores_the_plain_crease():
    """Mode none samples every segment but the outlines (each is there as its plain crease);
    the label modes score the outlines, between two classes."""
    w = build_world().world
    model = EdgeModel.build(w, LocalizerConfig(), occlusion=False)
    outline = ~np.isnan(w.outline).all(axis=(1, 2))
    none = model.for_mode(w, "none").samples.segment
    labels = model.for_mode(w, "oracle").samples.segment
    assert not outline[none].any() and outline[labels].any()
    assert set(np.flatnonzero(~outline)) <= set(none)
