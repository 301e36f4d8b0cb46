"""The particle filter: draws, motion, weights, resampling, recovery, a live filter on bad input."""

from __future__ import annotations

import numpy as np
import pytest

from core.config import typed
from core.occupancy import OccupancyMap
from core.poses import (
    odometry_increment,
    pose_from_xyz_rpy,
    pose_from_xyzyaw,
    wrap_angle,
    xyzyaw_from_pose,
)
from localize.filter.particle_filter import (
    FilterConfig,
    ParticleFilter,
    apply_increment,
    effective_sample_size,
    free_space_log_prior,
    init_global,
    init_tracking,
    move,
    noise_scale,
    systematic_resample,
)
from localize.filter.pose_stats import estimate
from localize.offline.metrics import convergence_frame, error_stats, timing_stats, yaw_errors_deg

BOXES = np.array([[-0.7, 0.3, 0.7, 9.7], [-2.7, 5.7, -0.7, 6.7]])
Z = np.array([0.5, 2.2])
FREE = OccupancyMap.from_boxes(BOXES, Z, 0.05, margin=0.3)
HALF = 0.025  # m, half a cell: a free cell's points may lie this far beyond its box


class TestDraws:
    def test_init_global_inside_free_space(self):
        p = init_global(np.random.default_rng(0), FREE, 5000)
        assert p.shape == (5000, 4)
        lo, hi = BOXES[:, :2] - HALF, BOXES[:, 2:] + HALF
        inside = ((p[:, None, :2] >= lo) & (p[:, None, :2] <= hi)).all(2).any(1)
        assert inside.all() and (p[:, 2] >= Z[0]).all() and (p[:, 2] <= Z[1]).all()
        assert FREE.contains(p[:, :2]).all()
        assert abs(np.mean(p[:, 0] < -0.725) - 2.0 / (2.0 + 13.16)) < 0.03  # by area
        assert np.abs(p[:, 3]).max() <= np.pi

    def test_init_tracking_spread(self):
        p = init_tracking(np.random.default_rng(0), np.array([0, 1, 1, 3.1]), 4000,
                          (0.1, 0.2, 0.05, 3.0))
        np.testing.assert_allclose(p[:, :3].std(0), [0.1, 0.2, 0.05], rtol=0.1)
        np.testing.assert_allclose(np.degrees(np.abs(wrap_angle(p[:, 3] - 3.1))).mean(),
                                   3.0 * np.sqrt(2 / np.pi), rtol=0.1)

    def test_no_free_space(self):
        empty = OccupancyMap(np.zeros((4, 4), bool), np.zeros((4, 4), np.float32),
                             np.zeros(2), 0.1, (0.5, 2.2), 0.3)
        with pytest.raises(ValueError, match="no free cells"):
            init_global(np.random.default_rng(0), empty, 10)


class TestMotion:
    def test_noise_free_odometry_is_reproduced(self):
        rng = np.random.default_rng(0)
        xyz = np.cumsum(rng.normal(0, 0.05, (20, 3)), 0) + [0, 1, 1]
        rpy = np.column_stack([rng.normal(0, 0.05, 20), rng.normal(0, 0.05, 20),
                               np.cumsum(rng.normal(0, 0.1, 20))])
        odo = pose_from_xyz_rpy(xyz, rpy)
        state = xyzyaw_from_pose(odo[:1])
        for t in range(1, 20):
            state = move(rng, state, odometry_increment(odo[t - 1], odo[t]), (0, 0, 0), (0, 0))
        np.testing.assert_allclose(state[0], xyzyaw_from_pose(odo[-1:])[0], atol=1e-9)

    def test_noise_scales_with_step(self):
        rng = np.random.default_rng(1)
        p = np.zeros((5000, 4))
        a = move(rng, p, np.array([0.0, 0, 0, 0]), (0.01, 0.0, 0.0), (0.1, 0.1))
        b = move(rng, p, np.array([0.5, 0, 0, 0]), (0.01, 0.0, 0.0), (0.1, 0.1))
        assert b[:, 1].std() == pytest.approx(0.01 + 0.05, rel=0.1)
        assert a[:, 1].std() == pytest.approx(0.01, rel=0.1)
        assert b[:, 0].mean() == pytest.approx(0.5, abs=0.01)

    def test_noise_follows_the_time_elapsed(self):
        """Two moves over 0.05 s spread the particles as one over 0.1 s (the frame period
        ``motion_std`` is given for), and one over 0.2 s as two over 0.1 s: the noise follows
        the time, not the number of moves."""
        params = FilterConfig(motion_std=[0.02, 0.01, 1.0], motion_rel=[0.0, 0.0],
                              tilt_std=[0.0, 0.0], motion_period_s=0.1)

        def spread(dts):
            pf = ParticleFilter(params, FREE, np.random.default_rng(5))
            pf.init_particles(np.zeros((20000, 4)))
            for dt in dts:
                pf.predict(np.zeros(4), noise_scale(dt, params.motion_period_s))
            return pf.particles.std(0)

        one = spread([0.1])
        np.testing.assert_allclose(one, [0.02, 0.02, 0.01, np.deg2rad(1.0)], rtol=0.03)
        np.testing.assert_allclose(spread([0.05, 0.05]), one, rtol=0.03)
        np.testing.assert_allclose(spread([0.2]), spread([0.1, 0.1]), rtol=0.03)
        np.testing.assert_allclose(spread([0.2]), np.sqrt(2) * one, rtol=0.03)

    def test_noise_scale(self):
        assert noise_scale(None, 0.1) == 1.0
        assert noise_scale(0.30000000000000004 - 0.2, 0.1) == 1.0  # stamps' float rounding
        assert noise_scale(0.4, 0.1) == pytest.approx(2.0)
        assert noise_scale(0.0, 0.1) == 0.0
        with pytest.raises(ValueError, match="finite and >= 0 seconds, got -0.1"):
            noise_scale(-0.1, 0.1)

    def test_free_space_prior(self):
        p = np.array([[0, 5, 1, 0], [0.9, 5, 1, 0], [1.5, 5, 1, 0], [0, 5, 3.0, 0],
                      [40.0, 5, 1, 0]])
        lp = free_space_log_prior(p, FREE, slack=0.25, per_m=20.0)
        assert lp[0] == 0 and lp[1] == 0  # inside, and within the slack
        # 0.8 m beyond the free cells, 0.8 m above the band: 20 / m x 0.55 m, to within a cell
        assert lp[2] == pytest.approx(-11.0, abs=20 * 0.05)
        assert lp[3] == pytest.approx(-11.0, abs=1e-9)
        assert lp[4] < lp[2]  # beyond the map: its distance to the map counts too
        np.testing.assert_array_equal(free_space_log_prior(p, FREE, 0.25, 0.0), 0.0)

    def test_prior_penalises_and_never_moves(self):
        """A filter step with a flat likelihood: a particle outside the free space loses
        log-weight in proportion to its distance beyond the slack, one inside keeps its
        weight, and none is removed, clamped or moved."""
        params = FilterConfig(num_particles=200, recovery=False, free_space_slack=0.25,
                              outside_log_penalty_per_m=20.0, tilt_std=[0.0, 0.0])
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_tracking(np.array([0.0, 5.0, 1.0, 0.0]))
        pf.particles[:4] = [[1.5, 5, 1, 0], [2.5, 5, 1, 0], [0.0, 5, 2.7, 0], [0.0, 5, 1, 0]]
        before = pf.particles.copy()
        flat = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.5))  # noqa: E731
        info = pf.update(flat)
        assert not info.resampled and len(pf.particles) == 200
        np.testing.assert_array_equal(pf.particles, before)  # nothing moved or removed
        rel = pf.logw - pf.logw[3]  # relative to a particle inside
        d = np.array([0.8, 1.8, 0.5])  # m outside (horizontal to within a cell; vertical)
        np.testing.assert_allclose(rel[:3], -20.0 * (d - 0.25), atol=20 * 0.05)
        inside = FREE.contains(before[:, :2]) & (before[:, 2] >= Z[0]) & (before[:, 2] <= Z[1])
        np.testing.assert_allclose(rel[inside], 0.0, atol=1e-9)

    def test_prior_settings(self):
        with pytest.raises(ValueError, match="outside_log_penalty_per_m"):
            FilterConfig(outside_log_penalty_per_m=-1.0)


class TestWeights:
    def test_ess(self):
        assert effective_sample_size(np.zeros(100)) == pytest.approx(100)
        lw = np.full(100, -1e3)
        lw[3] = 0.0
        assert effective_sample_size(lw) == pytest.approx(1.0)

    def test_systematic_resample(self):
        rng = np.random.default_rng(0)
        w = np.array([0.1, 0.2, 0.3, 0.4])
        idx = systematic_resample(rng, np.log(w), 1000)
        np.testing.assert_allclose(np.bincount(idx, minlength=4) / 1000, w, atol=0.002)
        idx = systematic_resample(rng, np.array([0.0, -np.inf, -np.inf]), 7)
        assert (idx == 0).all()

    def test_estimate_circular_yaw(self):
        p = np.array([[0, 0, 1, np.pi - 0.1], [2, 0, 1, -np.pi + 0.1]])
        e = estimate(p, np.log([0.5, 0.5]))
        np.testing.assert_allclose(e[:3], [1, 0, 1])
        assert abs(abs(e[3]) - np.pi) < 1e-9

    def test_params(self):
        with pytest.raises(ValueError, match="init_std"):
            FilterConfig(init_std=(0.1, 0.1))
        with pytest.raises(ValueError, match="filter.particles: Key 'particles' not in"):
            typed(FilterConfig, {"particles": 3}, "filter")
        assert typed(FilterConfig, {"motion_std": [0.1, 0.1, 1.0]}, "filter").motion_std == [
            0.1, 0.1, 1.0]
        with pytest.raises(ValueError, match="mode_likelihood: unknown edge modes"):
            FilterConfig(mode_likelihood={"segnet": {"k": 5.0}})
        per_mode = typed(FilterConfig, {"mode_likelihood": {"cnn": {"k": 5.0}}}, "filter")
        assert per_mode.mode_likelihood["cnn"] == {"k": 5.0, "orientation_bins": 12}  # merged

    def test_mode_motion_std(self):
        fp = FilterConfig(motion_std=[0.01, 0.005, 0.5],
                          mode_motion_std={"cnn": [0.01, 0.005, 0.2]})
        assert fp.for_mode("cnn").motion_std == [0.01, 0.005, 0.2]
        assert fp.for_mode("cnn").num_particles == fp.num_particles
        assert fp.for_mode("none") is fp  # modes without an entry keep motion_std
        with pytest.raises(ValueError, match="mode_motion_std: unknown edge modes"):
            FilterConfig(mode_motion_std={"segnet": [0.01, 0.005, 0.2]})
        with pytest.raises(ValueError, match="mode_motion_std.cnn needs 3 values"):
            FilterConfig(mode_motion_std={"cnn": [0.01, 0.2]})


def bowl(target: np.ndarray, k: float = 50.0):
    """A log-likelihood peaked at target (x, y, z, yaw)."""
    def f(states, tilt=None):
        d2 = ((states[:, :3] - target[:3]) ** 2).sum(1) + wrap_angle(states[:, 3] - target[3]) ** 2
        return -k * d2, np.exp(-d2)
    return f


class TestParticleFilter:
    def test_tracking_follows_the_target(self):
        params = FilterConfig(num_particles=300, recovery=False)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        truth = np.array([0.0, 1.0, 1.0, 1.5])
        pf.init_tracking(truth)
        for _ in range(20):
            delta = np.array([0.05, 0.0, 0.0, 0.02])
            pose = pose_from_xyzyaw(truth[None])[0]
            new = move(np.random.default_rng(1), truth[None], delta, (0, 0, 0), (0, 0))[0]
            pf.predict(odometry_increment(pose, pose_from_xyzyaw(new[None])[0]))
            truth = new
            info = pf.update(bowl(truth))
        assert np.linalg.norm(info.estimate[:3] - truth[:3]) < 0.05
        assert len(pf.particles) == 300

    def test_global_set_is_thinned(self):
        params = FilterConfig(num_particles=100, global_particles=1000, global_frames=2)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_global()
        assert len(pf.particles) == 1000 and pf.in_global_phase
        pf.update(bowl(np.array([0, 5, 1, 0])))
        assert len(pf.particles) == 1000
        pf.update(bowl(np.array([0, 5, 1, 0])))
        assert len(pf.particles) == 100 and not pf.in_global_phase

    def test_recovery_injects_on_collapse(self):
        params = FilterConfig(num_particles=200, recovery_patience=2, recovery_threshold=0.5)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_tracking(np.array([0, 2, 1, 0]))
        good = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.9))  # noqa: E731
        bad = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.35))  # noqa: E731
        for _ in range(10):
            assert pf.update(good).injected == 0
        infos = [pf.update(bad) for _ in range(12)]  # below the threshold, above the gate
        assert sum(i.injected for i in infos) > 0 and {i.status for i in infos} == {"tracking"}
        assert np.isfinite(pf.logw).all() and len(pf.particles) == 200

    def test_poor_fit_coasts_then_relocalizes(self):
        params = FilterConfig(num_particles=200, global_particles=1000, lost_frames=4)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_tracking(np.array([0, 2, 1, 0]))
        truth = np.array([0.0, 2.0, 1.0, 0.0])
        for _ in range(10):
            good = pf.update(bowl(truth))
        assert good.status == "tracking" and good.confidence > 0.5

        def poor(states, tilt):  # sharply peaked elsewhere, but fits badly everywhere
            return bowl(np.array([0.0, 5.0, 1.0, 0.0]))(states)[0], np.full(len(states), 0.01)

        logw = pf.logw.copy()
        coast = [pf.update(poor) for _ in range(3)]
        assert [i.status for i in coast] == ["coasting"] * 3
        np.testing.assert_array_equal(pf.logw, logw)  # the poor frames weighed nothing
        assert coast[-1].confidence < good.confidence
        assert np.linalg.norm(coast[-1].estimate[:3] - truth[:3]) < 0.05
        lost = pf.update(poor)
        assert lost.status == "lost" and lost.confidence == 0.0
        assert len(pf.particles) == 200  # the caller re-localizes
        pf.relocalize_uniform(lost.estimate)
        assert pf.in_global_phase and len(pf.particles) == 1000 + 200
        # while the global set is kept, the lost track's pose moved by the odometry is
        # reported, not the middle of the free space
        delta = np.array([0.1, 0.0, 0.0, 0.05])
        pf.predict(delta)
        reckoned = apply_increment(lost.estimate[None], delta)[0]
        flat = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.5))  # noqa: E731
        again = pf.update(flat)  # a frame that tells nothing
        assert again.status == "ambiguous"
        np.testing.assert_allclose(again.estimate, reckoned, atol=1e-12)
        assert np.linalg.norm(pf.estimate()[:3] - reckoned[:3]) > 1.0  # the set's own mean
        while pf.in_global_phase:
            last = pf.update(bowl(truth))
        assert pf.update(bowl(truth)).status == "tracking"
        assert np.linalg.norm(last.estimate[:3] - truth[:3]) < 0.3  # the gathered set's

    def test_apply_increment(self):
        poses = np.array([[1.0, 2.0, 1.0, np.pi / 2], [0.0, 0.0, 0.5, np.pi - 0.05]])
        out = apply_increment(poses, np.array([1.0, 0.5, 0.1, 0.1]))
        np.testing.assert_allclose(out[0], [0.5, 3.0, 1.1, np.pi / 2 + 0.1], atol=1e-12)
        assert -np.pi <= out[1, 3] < np.pi and out[1, 3] < 0  # wrapped

    def test_tilt_corrections_find_the_imu_error(self):
        # a likelihood peaked at the true pose and at an IMU roll / pitch error: the particles'
        # corrections gather there; with tilt_std 0 they stay zero and no draw is made
        error = np.deg2rad([0.6, -0.9])
        truth = np.array([0.0, 1.0, 1.0, 1.5])

        def lik(states, tilt):
            d2 = ((states[:, :3] - truth[:3]) ** 2).sum(1)
            e2 = ((tilt - error) ** 2).sum(1) / np.deg2rad(0.2) ** 2
            return -50.0 * d2 - 0.5 * e2, np.ones(len(states))

        pf = ParticleFilter(FilterConfig(num_particles=300, tilt_std=[1.0, 0.1]), FREE,
                            np.random.default_rng(0))
        pf.init_tracking(truth)
        for _ in range(15):
            pf.predict(np.zeros(4))
            info = pf.update(lik)
        assert np.rad2deg(np.abs(info.tilt - error)).max() < 0.15
        off = ParticleFilter(FilterConfig(num_particles=300, tilt_std=[0.0, 0.0]), FREE,
                             np.random.default_rng(0))
        off.init_tracking(truth)
        off.predict(np.zeros(4))
        assert off.tilt.shape == (300, 2) and not off.tilt.any()

    @pytest.mark.parametrize("case", ["nan_quality", "flat", "huge"])
    def test_degenerate_likelihood_keeps_the_filter_alive(self, case):
        pf = ParticleFilter(FilterConfig(num_particles=100), FREE, np.random.default_rng(0))
        pf.init_tracking(np.array([0, 2, 1, 0]))
        for _ in range(5):
            def f(s, t):
                n = len(s)
                if case == "nan_quality":
                    return np.zeros(n), np.full(n, np.nan)
                if case == "flat":
                    return np.full(n, 3.0), np.zeros(n)
                return np.full(n, 1e6), np.ones(n)
            pf.predict(np.zeros(4))
            info = pf.update(f)
            assert np.isfinite(info.estimate).all() and np.isfinite(pf.logw).all()
        assert len(pf.particles) == 100


class TestMetrics:
    def test_error_stats(self):
        s = error_stats(np.array([0.1, 0.2, 0.3, 0.4]), np.array([1.0, 3.0]))
        assert s["mean_position_error_m"] == pytest.approx(0.25)
        assert s["rmse_m"] == pytest.approx(np.sqrt(0.075))
        assert s["mean_yaw_error_deg"] == pytest.approx(2.0)
        with pytest.raises(ValueError):
            error_stats(np.array([]))

    def test_convergence(self):
        e = np.array([3, 2, 0.2, 0.5, 0.1, 0.1, 0.2])
        assert convergence_frame(e, 0.3) == 4
        assert convergence_frame(np.array([0.1, 0.1]), 0.3) == 0
        assert convergence_frame(np.array([0.1, 0.5]), 0.3) is None

    def test_yaw_and_timing(self):
        est = np.array([[0, 0, 0, np.pi - 0.01]])
        tru = np.array([[0, 0, 0, -np.pi + 0.01]])
        np.testing.assert_allclose(yaw_errors_deg(est, tru), np.degrees(0.02))
        assert timing_stats([1.0, 2.0, 6.0]) == {"min": 1.0, "avg": 3.0, "max": 6.0}


def test_lost_track_needs_a_long_stretch():
    from localize.offline.metrics import lost_track

    t = np.arange(30) * 0.1
    e = np.zeros(30)
    e[5:15] = 2.0  # 0.9 s above 1 m
    assert not lost_track(e, t, 1.0, 1.0)
    e[15] = 2.0  # 1.0 s: not longer than
    assert not lost_track(e, t, 1.0, 1.0)
    e[16] = 2.0
    assert lost_track(e, t, 1.0, 1.0)
    e = np.full(30, 2.0)
    assert lost_track(e, t, 1.0, 1.0) and not lost_track(np.zeros(30), t, 1.0, 1.0)
    with pytest.raises(ValueError, match="timestamps"):
        lost_track(e, t[:-1], 1.0, 1.0)


def test_log_sum_exp_matches_scipy():
    """pose_stats.log_sum_exp: scipy's logsumexp on log-weights, no overflow, -inf when none."""
    from scipy.special import logsumexp

    from localize.filter.pose_stats import log_sum_exp

    rng = np.random.default_rng(0)
    for n in (1, 7, 500, 40000):
        a = rng.normal(0, 50, n) + 800.0  # exp would overflow without the shift
        assert abs(log_sum_exp(a) - logsumexp(a)) <= 1e-12 * abs(logsumexp(a))
    assert log_sum_exp(np.array([-np.inf, 0.0])) == 0.0
    assert log_sum_exp(np.full(3, -np.inf)) == -np.inf and log_sum_exp(np.zeros(0)) == -np.inf
