"""An adaptive particle count while tracking: KLD sampling (Fox 2003), as nav2 AMCL and Beluga.

A resampled set needs as many particles as it takes for the distribution they draw to stay
within a Kullback-Leibler divergence ``err`` of the true posterior with probability
``1 - delta``: with the posterior spread over k bins of a histogram of the poses,

    n = (k - 1) / (2 err) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z)^3

(z the upper ``1 - delta`` quantile of the standard normal; Fox 2003, eq. 13). A converged
track occupies few bins and needs few particles; a spread set (an ambiguous view, a
recovery's injected particles) occupies many and gets more, up to the configured count.

The bins are those of x, y (``kld_bin[0]`` metres) and yaw (``kld_bin[1]`` degrees); a bin
counts when it holds at least ``1 / n_max`` of the weight, the bins a systematic draw of
``n_max`` particles surely hits (so the count needs no extra random draw).
"""

from __future__ import annotations

import numpy as np

#: KLD sampling's bound on the divergence (nav2 AMCL's ``pf_err``).
KLD_ERR = 0.05
#: Upper standard normal quantile of KLD sampling: delta = 0.01 (nav2 AMCL's ``pf_z`` 0.99).
KLD_Z = 2.326


def kld_count(k: int, err: float = KLD_ERR, z: float = KLD_Z) -> int:
    """Particles KLD sampling asks for a posterior over ``k`` occupied bins (module
    docstring); 1 for k <= 1."""
    if k <= 1:
        return 1
    a = 2.0 / (9.0 * (k - 1))
    return int(np.ceil((k - 1) / (2.0 * err) * (1.0 - a + np.sqrt(a) * z) ** 3))


def occupied_bins(particles: np.ndarray, logw: np.ndarray, bin_m: float, bin_deg: float,
                  min_mass: float) -> int:
    """Bins of the (x, y, yaw) histogram holding at least ``min_mass`` of the weight.

    Args:
        particles: (N, 4) x, y, z (metres), yaw (radians).
        logw: (N,) normalized log-weights.
        bin_m, bin_deg: bin size in x and y (metres) and in yaw (degrees).
        min_mass: weight a bin needs to count.
    """
    cell = np.floor(particles[:, :2] / bin_m).astype(np.int64)
    turn = np.floor(np.mod(particles[:, 3], 2 * np.pi) / np.deg2rad(bin_deg)).astype(np.int64)
    keys = np.stack([cell[:, 0], cell[:, 1], turn], axis=1)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    mass = np.bincount(inverse.ravel(), weights=np.exp(logw))
    return int(np.count_nonzero(mass >= min_mass))


def adaptive_count(particles: np.ndarray, logw: np.ndarray, n_min: int, n_max: int,
                   bin_m: float, bin_deg: float) -> int:
    """The particle count of a resampled tracking set: ``kld_count`` of its occupied bins,
    clipped to [``n_min``, ``n_max``]; ``n_max`` when ``n_min`` is 0 or >= ``n_max`` (a fixed
    count)."""
    if n_min <= 0 or n_min >= n_max:
        return n_max
    k = occupied_bins(particles, logw, bin_m, bin_deg, 1.0 / n_max)
    return int(np.clip(kld_count(k), n_min, n_max))
