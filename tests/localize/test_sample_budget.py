"""The budget of visible samples per particle (``likelihood.max_samples``): it bounds what a
particle scores, leaves a particle within it untouched, and keeps the truth on top."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from localize.config import LikelihoodConfig, VisibilityConfig
from localize.filter.likelihood import EdgeLikelihood
from localize.filter.projection import (
    cam_from_world,
    camera_centres,
    in_cone,
    sample_segments,
    view_half_width,
)
from localize.filter.sample_budget import line_minimum, strides
from localize.filter.visibility import build_visibility
from localize.frontend.boundaries import label_edges

TRUE = np.array([0.2, 0.8, 1.2, np.deg2rad(80.0)])


@pytest.fixture(scope="module")
def model(small_world):
    """Samples every 2 cm: a view holds a few thousand of them."""
    s = sample_segments(small_world.segments, 0.02)
    s, _ = s.select(small_world.segment_classes[:, 0] != small_world.segment_classes[:, 1])
    return s, build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.2, cell_z=0.3))


@pytest.fixture(scope="module")
def obs(model, renderer, camera):
    s, vis = model
    labels, _ = renderer.render(np.linalg.inv(cam_from_world(TRUE[None],
                                                             camera.body_from_cam)[0]))
    return EdgeLikelihood(s, camera, LikelihoodConfig(), vis).observe(label_edges(labels))


@pytest.fixture(scope="module")
def states():
    """Particles around the truth and some spread over the room, every heading."""
    rng = np.random.default_rng(3)
    near = TRUE + rng.normal(0, 1, (96, 4)) * [0.1, 0.1, 0.05, 0.1]
    far = np.column_stack([rng.uniform(-0.5, 1.0, 64), rng.uniform(0.0, 1.6, 64),
                           rng.uniform(1.0, 1.4, 64), rng.uniform(-np.pi, np.pi, 64)])
    return np.concatenate([near, far])


def lik(model, camera, **kw) -> EdgeLikelihood:
    s, vis = model
    return EdgeLikelihood(s, camera, LikelihoodConfig(**kw), vis)


def test_the_budget_bounds_the_samples_scored(model, camera, obs, states):
    """Without a budget particles score over 500 samples; with 300 or 120 none scores more,
    and every particle that sees some still scores some."""
    free = lik(model, camera, max_samples=0).visible_samples(states, obs)
    assert free.max() > 500
    for budget in (300, 120):
        seen = lik(model, camera, max_samples=budget).visible_samples(states, obs)
        assert seen.max() <= budget
        assert (seen[free > 0] > 0).all()
        assert seen.max() > budget / 4  # thinned by the smallest stride that fits, not more


def test_within_the_budget_scores_are_bit_identical(model, camera, obs, states):
    """A budget no particle exceeds changes nothing, to the bit; one some exceed changes only
    those particles."""
    base = lik(model, camera, max_samples=0)
    s0, q0 = base.scores(states, obs)
    top = int(base.visible_samples(states, obs).max())
    s1, q1 = lik(model, camera, max_samples=100_000).scores(states, obs)
    np.testing.assert_array_equal(s0, s1)
    np.testing.assert_array_equal(q0, q1)
    b = lik(model, camera, max_samples=top // 2)
    s2, _ = b.scores(states, obs)
    s, vis = model
    c = camera_centres(states, camera.body_from_cam, None)
    from localize.filter.projection import view_half_width

    st = strides(vis, s.points, vis.rows(c), c, states[:, 3],
                 view_half_width(camera.K, camera.width, camera.height, camera.body_from_cam),
                 top // 2)
    assert (st > 1).any() and (st == 1).any()
    # particles within the budget, scored in blocks with thinned ones: the same to float64
    # rounding of their mean over lines
    np.testing.assert_allclose(s2[st == 1], s0[st == 1], rtol=0, atol=1e-12)
    assert not np.allclose(s2[st > 1], s0[st > 1], rtol=0, atol=1e-6)


def test_strides_do_not_depend_on_blocks_or_threads(model, camera, obs, states):
    """Under an active budget the scores are the same for any chunk and workers (up to the
    float32 rounding of a line's sum)."""
    a, _ = lik(model, camera, max_samples=300, chunk=256, workers=1).scores(states, obs)
    b, _ = lik(model, camera, max_samples=300, chunk=16, workers=2).scores(states, obs)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)


def test_a_thinned_likelihood_still_peaks_at_the_truth(model, camera, obs):
    """With a budget a tenth of what the particles see, the truth outscores poses 10 cm or
    3 degrees off."""
    offsets = np.array([[0.1, 0, 0, 0], [-0.1, 0, 0, 0], [0, 0.1, 0, 0], [0, -0.1, 0, 0],
                        [0, 0, 0, np.deg2rad(3)], [0, 0, 0, -np.deg2rad(3)]])
    states = np.concatenate([TRUE[None], TRUE + offsets])
    full = lik(model, camera, max_samples=0)
    budget = int(full.visible_samples(states, obs).max()) // 10
    thin = lik(model, camera, max_samples=budget)
    assert (thin.visible_samples(states, obs) <= budget).all()
    score, _ = thin.scores(states, obs)
    assert score[0] > score[1:].max()


def test_line_minimum_keeps_the_metres():
    np.testing.assert_array_equal(line_minimum(5, np.array([1, 2, 4, 8])), [5, 3, 2, 1])
    np.testing.assert_array_equal(line_minimum(0, np.array([1, 2])), [0, 1])


def test_a_negative_budget_is_refused():
    with pytest.raises(ValueError, match="max_samples"):
        LikelihoodConfig(max_samples=-1)


def test_the_default_budget_is_documented():
    assert replace(LikelihoodConfig()).max_samples > 0


def test_blocks_of_far_apart_particles_split_without_changing_a_score(model, camera, obs,
                                                                      states, monkeypatch):
    """Particles spread over the room see many samples together: each projected block stays
    within ``BLOCK_COLUMNS`` times what its most seeing particle may see alone (or within the
    budget, or is one particle), and every score is what it is in one block, to the float32
    rounding of a line's sum."""
    import localize.filter.likelihood as L

    top = int(lik(model, camera, max_samples=0).visible_samples(states, obs).max())
    budget = top // 2
    whole, _ = lik(model, camera, max_samples=budget, chunk=1024).scores(states, obs)
    seen = []
    project = L.EdgeLikelihood._project

    def spy(self, st, near, tilt, bins, cols=None):
        out = project(self, st, near, tilt, bins, cols)
        seen.append((len(st), len(out[2]), max(L.BLOCK_COLUMNS * near[3].own.max(), budget)))
        return out

    monkeypatch.setattr(L.EdgeLikelihood, "_project", spy)
    monkeypatch.setattr(L, "BLOCK_COLUMNS", 1.0)
    split, _ = lik(model, camera, max_samples=budget, chunk=1024).scores(states, obs)
    assert len(seen) > 2
    assert all(n == 1 or c <= cap for n, c, cap in seen)
    np.testing.assert_allclose(split, whole, rtol=0, atol=1e-6)


def test_blocks_score_the_counted_samples_as_their_own(model, camera, obs, states,
                                                       monkeypatch):
    """The blocks take their columns from the budget's counting (``Budget.columns``): the
    same scores and visible samples as when each block selects its own (lists not kept)."""
    import localize.filter.sample_budget as B

    s, vis = model
    c = camera_centres(states, camera.body_from_cam, None)
    half = view_half_width(camera.K, camera.width, camera.height, camera.body_from_cam)
    counted = B.count(vis, s.points, vis.rows(c), c, states[:, 3], half, 300)
    assert (counted.group >= 0).mean() > 0.5 and counted.ids is not None
    assert counted.columns(np.arange(len(states)), 1) is None or (counted.group >= 0).all()
    shared = lik(model, camera, max_samples=300)
    s0, q0 = shared.scores(states, obs)
    v0 = shared.visible_samples(states, obs)
    monkeypatch.setattr(B, "KEEP_ENTRIES", 0)
    own = lik(model, camera, max_samples=300)
    s1, q1 = own.scores(states, obs)
    np.testing.assert_array_equal(own.visible_samples(states, obs), v0)
    np.testing.assert_allclose(s1, s0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(q1, q0, rtol=0, atol=1e-9)


def test_the_cone_test_is_the_azimuth_test():
    """``in_cone`` without trigonometry per point keeps what the azimuth formula keeps (the
    offset of a point's azimuth from the mean heading within the half-width, the spread and
    asin(r / distance)), away from its boundary; per point and per group of points."""
    rng = np.random.default_rng(7)
    n, G = 20_000, 50
    pts = rng.uniform(-10, 10, (n, 3))
    which = np.sort(rng.integers(0, G, n))
    yaw, spread = rng.uniform(-np.pi, np.pi, G), rng.uniform(0, 2.5, G)
    mid, r = rng.uniform(-3, 3, (G, 2)), rng.uniform(0, 2, G) * (rng.random(G) < 0.7)
    half = 0.6
    p = pts[:, :2] - mid[which]
    dist = np.linalg.norm(p, axis=1)
    off = np.abs(np.angle(np.exp(1j * (np.arctan2(p[:, 1], p[:, 0]) - yaw[which]))))
    reach = half + spread[which] + np.arcsin(np.clip(r[which] / np.maximum(dist, 1e-12), 0, 1))
    want = (half + spread[which] >= np.pi) | (dist <= r[which] + 1e-6) | (off <= reach)
    clear = np.abs(off - reach) > 1e-9
    got = in_cone(pts, yaw, spread, mid, r, half, which)
    np.testing.assert_array_equal(got[clear], want[clear])
    assert 0.2 < want.mean() < 0.9
    np.testing.assert_array_equal(
        in_cone(pts, yaw[which], spread[which], mid[which], r[which], half), got)
