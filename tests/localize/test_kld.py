"""The adaptive particle count (KLD sampling): its formula, its bins, and a filter whose count
goes down once converged and back up when the set spreads or recovery injects."""

from __future__ import annotations

import numpy as np

from core.occupancy import OccupancyMap
from localize.filter.kld import adaptive_count, kld_count, occupied_bins
from localize.filter.particle_filter import FilterConfig, ParticleFilter

BOXES = np.array([[-0.7, 0.3, 0.7, 9.7]])
FREE = OccupancyMap.from_boxes(BOXES, np.array([0.5, 2.2]), 0.05, margin=0.3)


def test_kld_count_formula():
    """Fox 2003, eq. 13, against its chi-square form: n = chi2_{k-1, 1-delta} / (2 err)."""
    from scipy.stats import chi2

    for k in (2, 10, 50, 400):
        exact = chi2.ppf(0.99, k - 1) / (2 * 0.05)
        assert abs(kld_count(k) - exact) <= 0.02 * exact + 1
    assert kld_count(1) == 1 and kld_count(0) == 1
    assert kld_count(200) > kld_count(20) > kld_count(3)


def test_occupied_bins_count_mass():
    """Only bins holding >= min_mass count; a yaw and the same yaw a turn later share one."""
    p = np.array([[0.01, 0.01, 1, 0.5], [0.02, 0.02, 1, 0.51 - 2 * np.pi],
                  [1.0, 0.0, 1, 0.0], [2.0, 0.0, 1, 0.0]])
    logw = np.log([0.45, 0.45, 0.099, 0.001])
    assert occupied_bins(p, logw, 0.05, 2.0, 0.01) == 2  # the last holds 0.001 < 0.01
    assert occupied_bins(p, logw, 0.05, 2.0, 0.0) == 3
    tight = np.zeros((500, 4))
    assert adaptive_count(tight, np.full(500, -np.log(500)), 100, 500, 0.05, 2.0) == 100
    wide = np.random.default_rng(0).uniform(-3, 3, (500, 4))
    assert adaptive_count(wide, np.full(500, -np.log(500)), 100, 500, 0.05, 2.0) == 500
    assert adaptive_count(tight, np.full(500, -np.log(500)), 500, 500, 0.05, 2.0) == 500
    assert adaptive_count(tight, np.full(500, -np.log(500)), 0, 500, 0.05, 2.0) == 500  # off


def _peaked(truth: np.ndarray, width: float):
    """A log-likelihood peaked at ``truth`` (x, y, yaw) with ``width`` metres."""
    def ll(states, tilt):
        d2 = ((states[:, :2] - truth[:2]) ** 2).sum(1) + (states[:, 3] - truth[3]) ** 2
        return -d2 / (2 * width ** 2), np.full(len(states), 0.8)
    return ll


def test_count_goes_down_when_converged_and_up_on_spread():
    params = FilterConfig(num_particles=600, min_particles=150, recovery=False, resample_ess=1.0,
                          tilt_std=[0.0, 0.0], motion_std=[0.005, 0.0, 0.1])
    pf = ParticleFilter(params, FREE, np.random.default_rng(1))
    truth = np.array([0.0, 5.0, 1.0, 0.0])
    pf.init_tracking(truth)
    counts = []
    for _ in range(15):
        pf.predict(np.zeros(4))
        counts.append(pf.update(_peaked(truth, 0.02)).num_particles)
    assert counts[-1] < 300 and min(counts) >= 150  # converged: fewer, not below the floor
    # the set spreads over many bins (a flat likelihood after a wide scatter): back up
    rng = np.random.default_rng(2)
    pf.particles[:, :2] += rng.normal(0, 0.3, (len(pf.particles), 2))
    pf.particles[:, 3] += rng.normal(0, 0.3, len(pf.particles))
    info = pf.update(_peaked(truth, 0.5))
    assert info.resampled and info.num_particles > 2 * counts[-1]


def test_off_by_default_keeps_the_count():
    pf = ParticleFilter(FilterConfig(num_particles=300, tilt_std=[0.0, 0.0]), FREE,
                        np.random.default_rng(1))
    truth = np.array([0.0, 5.0, 1.0, 0.0])
    pf.init_tracking(truth)
    for _ in range(5):
        pf.predict(np.zeros(4))
        assert pf.update(_peaked(truth, 0.02)).num_particles == 300


def test_recovery_injection_draws_the_full_count():
    params = FilterConfig(num_particles=400, min_particles=100, tilt_std=[0.0, 0.0],
                          recovery_patience=1, gate=0.0)
    pf = ParticleFilter(params, FREE, np.random.default_rng(3))
    truth = np.array([0.0, 5.0, 1.0, 0.0])
    pf.init_tracking(truth)
    for _ in range(10):
        pf.predict(np.zeros(4))
        pf.update(_peaked(truth, 0.02))
    assert len(pf.particles) < 400

    def collapsed(states, tilt):  # the fit falls far below its long-run level
        return np.zeros(len(states)), np.full(len(states), 0.01)
    for _ in range(5):
        info = pf.update(collapsed)
        if info.injected:
            break
    assert info.injected > 0 and len(pf.particles) == 400
