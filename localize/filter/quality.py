"""The calibrated quality of an estimate: the probability that it lies within 0.3 m of the truth.

Each frame's estimate (``localizer.Estimate``) carries ``quality``, in [0, 1]: a calibration
fitted on validation floors (``benchmarks/quality.py``) maps what the filter knows of itself
to the share of such frames that were within ``within_m`` (0.3 m) of the truth. What it knows
(``inputs``, ``INPUTS``): whether the frame is the global search's, the filter's own status
(a hypothesis has dominated; coasting; lost), the heaviest hypothesis's mass and its margin
over the next one, the spread of the set and of the heaviest hypothesis, the filter's
confidence, the best particle's fit and the effective sample size's share.

The map: the inputs standardized, a logistic regression (with each input's product with the
search flag, so the search's frames and the filter's weigh them apart), its score mapped to
the quality by knots, interpolated (``QualityModel``): the sigmoid, or an isotonic (monotone)
regression of the validation frames' outcomes on the score (``fit``; which one, and the
ridge penalty, chosen by leaving one validation floor out: benchmarks/quality.py). One
calibration per edge mode (the labels differ: the SegNet's blur the floor boundary), in one
JSON file; the shipped one is
``localize/filter/quality.json`` (``filter.quality_model``: null). A mode it has no
calibration for gets NaN (and no status gate).

``reliability`` is the check: per decile of predicted quality, the frames in it, their mean
quality and the share within ``within_m``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import isotonic_regression, minimize

from core.atomic import atomic_write_json

#: The shipped calibration (``filter.quality_model: null``).
SHIPPED = Path(__file__).with_name("quality.json")
#: The inputs of the quality, in the order ``inputs`` gives them.
INPUTS = ("search", "dominated", "coasting", "lost", "top_mass", "margin", "log_spread",
          "log_top_spread", "yaw_spread", "confidence", "best_score", "scored", "ess_share")
#: The inputs whose product with ``search`` is an input of the regression too.
BY_SEARCH = ("top_mass", "margin", "log_spread", "log_top_spread", "yaw_spread")
#: Metres added to a spread before its log (a spread of 0 is finite).
SPREAD_FLOOR_M = 0.05
#: The quality stays inside [QMIN, 1 - QMIN]: a finite validation set tells no certainty.
QMIN = 0.002
_LOADED: dict = {}


def inputs(search: bool, status: str, masses, position_std: float, top_std: float,
           yaw_std: float, confidence: float, best_score: float, ess: float,
           num_particles: int) -> np.ndarray:
    """(len(INPUTS),) float64 inputs of one frame's quality.

    Args:
        search: the frame is the global search's (before its handover).
        status: the filter's own status (``particle_filter.StepInfo.status``; the search's
            frames: ``ambiguous``).
        masses: the hypotheses' masses, heaviest first (``hypotheses.Hypothesis.mass``).
        position_std: the set's horizontal spread, m.
        top_std: the heaviest hypothesis's horizontal spread, m (NaN: none).
        yaw_std: the set's yaw spread, rad.
        confidence: the filter's confidence (NaN or 0 while ambiguous).
        best_score: the best particle's fit (NaN: not scored, or the search's frame).
        ess: effective sample size (NaN: the search's frame).
        num_particles: the set's size.
    """
    m = [float(v) for v in masses] + [0.0, 0.0]

    def finite(v: float, default: float) -> float:
        v = float(v)
        return v if np.isfinite(v) else default

    spread = finite(position_std, 10.0)
    return np.array([
        float(search), float(status in ("tracking", "coasting")), float(status == "coasting"),
        float(status == "lost"), m[0], m[0] - m[1],
        np.log(spread + SPREAD_FLOOR_M), np.log(finite(top_std, spread) + SPREAD_FLOOR_M),
        finite(yaw_std, np.pi), finite(confidence, 0.0), finite(best_score, 0.0),
        float(np.isfinite(best_score)),
        finite(ess, 0.0) / max(int(num_particles), 1)])


def _design(x: np.ndarray) -> np.ndarray:
    """(N, F') the regression's columns: the inputs (N, len(INPUTS)) and each ``BY_SEARCH``
    input times the search flag."""
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    s = x[:, INPUTS.index("search")][:, None]
    return np.hstack([x, x[:, [INPUTS.index(k) for k in BY_SEARCH]] * s])


@dataclass(frozen=True)
class QualityModel:
    """One edge mode's calibration (module docstring).

    Attributes:
        mean, scale: (F',) standardization of the regression's columns.
        coef: (F',) logistic coefficients; intercept: its constant.
        knots_x: (K,) increasing logistic scores; knots_y: (K,) non-decreasing quality at them
            (interpolated, held flat outside).
        fitted_on: what it was fitted on (floors, frames), for the record.
    """

    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    knots_x: np.ndarray
    knots_y: np.ndarray
    fitted_on: dict

    def score(self, x: np.ndarray) -> np.ndarray:
        """(N,) logistic scores of inputs (N, len(INPUTS))."""
        return ((_design(x) - self.mean) / self.scale) @ self.coef + self.intercept

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """(N,) quality in [QMIN, 1 - QMIN] of inputs (N, len(INPUTS)) (or one frame's
        (len(INPUTS),))."""
        q = np.interp(self.score(x), self.knots_x, self.knots_y)
        return np.clip(q, QMIN, 1.0 - QMIN)

    def as_json(self) -> dict:
        return {"mean": self.mean.tolist(), "scale": self.scale.tolist(),
                "coef": self.coef.tolist(), "intercept": float(self.intercept),
                "knots_x": self.knots_x.tolist(), "knots_y": self.knots_y.tolist(),
                "fitted_on": self.fitted_on}

    @classmethod
    def from_json(cls, d: dict, where: str) -> QualityModel:
        """From ``as_json``'s dict; ValueError naming ``where`` and the key for a malformed
        one."""
        n = len(INPUTS) + len(BY_SEARCH)
        try:
            arrays = {k: np.asarray(d[k], dtype=np.float64)
                      for k in ("mean", "scale", "coef", "knots_x", "knots_y")}
            intercept = float(d["intercept"])
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"{where}: a quality calibration needs mean, scale, coef, "
                             f"intercept, knots_x, knots_y ({err}); refit it with "
                             "benchmarks/quality.py") from None
        for k in ("mean", "scale", "coef"):
            if arrays[k].shape != (n,) or not np.isfinite(arrays[k]).all():
                raise ValueError(f"{where}: {k} must be {n} finite numbers (the inputs "
                                 f"{', '.join(INPUTS)} and {len(BY_SEARCH)} products), got "
                                 f"shape {arrays[k].shape}; refit it with benchmarks/quality.py")
        kx, ky = arrays["knots_x"], arrays["knots_y"]
        if (kx.ndim != 1 or kx.shape != ky.shape or len(kx) < 1 or np.any(np.diff(kx) < 0)
                or np.any(np.diff(ky) < 0) or (arrays["scale"] <= 0).any()):
            raise ValueError(f"{where}: knots_x and knots_y must be equally long and "
                             "non-decreasing, scale positive; refit it with "
                             "benchmarks/quality.py")
        return cls(arrays["mean"], arrays["scale"], arrays["coef"], intercept, kx, ky,
                   dict(d.get("fitted_on", {})))


#: ``fit``'s maps from the logistic score to the quality.
MAPS = ("logistic", "isotonic")
#: The logistic map's knots: scores from -SCORE_SPAN to SCORE_SPAN (the sigmoid, off by
#: < 1e-3 between knots; flat outside, where it is within 1e-5 of 0 or 1).
SCORE_SPAN, SCORE_STEP = 12.0, 0.1


def fit(x: np.ndarray, within: np.ndarray, groups: np.ndarray | None = None,
        l2: float = 10.0, method: str = "logistic",
        fitted_on: dict | None = None) -> QualityModel:
    """A calibration from validation frames.

    Args:
        x: (N, len(INPUTS)) the frames' inputs.
        within: (N,) bool, the frame's error was below ``within_m``.
        groups: (N,) a run id per frame: each run weighs as much in the logistic fit as any
            other (a run of 300 frames does not count 10x one of 30); None: every frame alike.
        l2: ridge penalty of the standardized coefficients, x 1e-3 (per unit of total weight).
        method: the map from the logistic score to the quality: ``logistic`` (its sigmoid,
            as knots) or ``isotonic`` (``scipy.optimize.isotonic_regression`` of ``within``
            on the score, its blocks' mean scores as knots).
        fitted_on: stored with it.

    Returns:
        The ``QualityModel``: the logistic regression (L-BFGS) and the map.
    """
    if method not in MAPS:
        raise ValueError(f"quality fit: method must be one of {MAPS}, got {method!r}")
    X = _design(x)
    y = np.asarray(within, dtype=np.float64)
    if len(X) != len(y) or len(y) < 2 or y.min() == y.max():
        raise ValueError(f"quality fit: needs frames both within and not ({len(y)} frames, "
                         f"{int(y.sum())} within)")
    if groups is None:
        w = np.ones(len(y))
    else:
        _, inv, counts = np.unique(groups, return_inverse=True, return_counts=True)
        w = 1.0 / counts[inv]
    w = w / w.sum()
    mean = (w @ X)
    scale = np.sqrt(w @ (X - mean) ** 2)
    scale[scale < 1e-9] = 1.0
    Z = (X - mean) / scale

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        z = Z @ theta[1:] + theta[0]
        p = 1.0 / (1.0 + np.exp(-z))
        nll = w @ (np.logaddexp(0.0, z) - y * z)
        g = w * (p - y)
        grad = np.concatenate([[g.sum()], Z.T @ g + 2 * l2 * 1e-3 * theta[1:]])
        return float(nll + l2 * 1e-3 * theta[1:] @ theta[1:]), grad

    theta = minimize(loss, np.zeros(Z.shape[1] + 1), jac=True, method="L-BFGS-B").x
    if method == "logistic":
        kx = np.arange(-SCORE_SPAN, SCORE_SPAN + SCORE_STEP / 2, SCORE_STEP)
        return QualityModel(mean, scale, theta[1:], float(theta[0]), kx, 1 / (1 + np.exp(-kx)),
                            dict(fitted_on or {}))
    s = Z @ theta[1:] + theta[0]
    order = np.argsort(s, kind="stable")
    iso = isotonic_regression(y[order], weights=np.ones(len(y))).x
    # knots: each block of equal fitted value at its mean score
    starts = np.flatnonzero(np.r_[True, np.diff(iso) != 0])
    ends = np.r_[starts[1:], len(iso)]
    kx = np.array([s[order[a:b]].mean() for a, b in zip(starts, ends, strict=True)])
    ky = iso[starts]
    return QualityModel(mean, scale, theta[1:], float(theta[0]), kx, ky, dict(fitted_on or {}))


def save(models: dict[str, QualityModel], path: Path, within_m: float, note: str = "") -> None:
    """Write the calibrations of the edge modes (``{mode: model}``) to ``path`` (JSON,
    atomic)."""
    atomic_write_json(Path(path), {"within_m": float(within_m), "inputs": list(INPUTS),
                                   "by_search": list(BY_SEARCH), "note": note,
                                   "modes": {m: q.as_json() for m, q in models.items()}})


def load(path: str | Path | None, mode: str) -> QualityModel | None:
    """The calibration of edge ``mode`` in the file ``path`` (None: ``SHIPPED``), read once
    per file; None when the file holds none for the mode. ValueError naming the file when it
    is missing or malformed, or fitted on other inputs."""
    p = SHIPPED if path in (None, "") else Path(path)
    key = str(p.resolve())
    if key not in _LOADED:
        if not p.is_file():
            raise ValueError(f"filter.quality_model: {p} not found; give a calibration file "
                             "of benchmarks/quality.py, or null for the shipped one")
        try:
            d = json.loads(p.read_text())
        except json.JSONDecodeError as err:
            raise ValueError(f"filter.quality_model: {p} is not JSON ({err})") from None
        if list(d.get("inputs", [])) != list(INPUTS) or list(d.get("by_search", [])) != list(
                BY_SEARCH):
            raise ValueError(f"filter.quality_model: {p} was fitted on the inputs "
                             f"{d.get('inputs')}, this code computes {list(INPUTS)}; refit it "
                             "with benchmarks/quality.py")
        _LOADED[key] = {m: QualityModel.from_json(v, f"{p} modes.{m}")
                        for m, v in d.get("modes", {}).items()}
    return _LOADED[key].get(mode)


def reliability(quality: np.ndarray, within: np.ndarray, bins: int = 10) -> list[dict]:
    """Per decile of predicted quality ([0, 0.1), ..., [0.9, 1]): ``lo``, ``hi``, ``frames``,
    ``predicted`` (their mean quality) and ``observed`` (the share within), None where the
    bin has no frame; frames with a NaN quality are left out."""
    q = np.asarray(quality, dtype=np.float64).ravel()
    y = np.asarray(within, dtype=bool).ravel()
    if q.shape != y.shape:
        raise ValueError(f"reliability: {q.size} qualities for {y.size} outcomes")
    keep = np.isfinite(q)
    q, y = q[keep], y[keep]
    idx = np.clip((q * bins).astype(int), 0, bins - 1)
    out = []
    for b in range(bins):
        sel = idx == b
        n = int(sel.sum())
        out.append({"lo": b / bins, "hi": (b + 1) / bins, "frames": n,
                    "predicted": float(q[sel].mean()) if n else None,
                    "observed": float(y[sel].mean()) if n else None})
    return out


def worst_gap(table: list[dict], min_frames: int = 1) -> float | None:
    """The largest |observed - predicted| of a ``reliability`` table over the bins with at
    least ``min_frames`` frames (None: no such bin)."""
    gaps = [abs(b["observed"] - b["predicted"]) for b in table if b["frames"] >= min_frames]
    return max(gaps) if gaps else None
