"""The calibrated quality (``localize.filter.quality``): a fit on frames whose chance of being
within 0.3 m is known recovers it; the reliability table; a malformed calibration file is
refused naming it; the Localizer rates each estimate and reports ``tracking`` only where the
quality reaches ``filter.tracking_quality``."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from core import classes as C
from localize.edge_model import EdgeModel
from localize.filter import quality as Q
from localize.filter.projection import cam_from_world
from localize.localizer import Localizer
from tests.localize.test_localize_localizer import SETTINGS, TRUE


def synthetic(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(inputs (n, F), within (n,), true probability (n,)): frames of the search and of the
    filter whose chance of being right rises with the top mass and falls with the spread,
    differently in the two phases."""
    search = rng.random(n) < 0.5
    mass = rng.random(n)
    spread = np.exp(rng.normal(-1.0, 1.0, n))
    x = np.stack([Q.inputs(bool(s), "ambiguous" if s else "tracking", [m, (1 - m) / 2], sp, sp,
                           0.3, 0.0 if s else m, np.nan if s else 0.8, np.nan if s else 50.0,
                           200) for s, m, sp in zip(search, mass, spread, strict=True)])
    z = np.where(search, 6 * mass - 5, 3 * mass - 2 * np.log(spread + Q.SPREAD_FLOOR_M) - 1)
    p = 1 / (1 + np.exp(-z))
    return x, rng.random(n) < p, p


def test_a_fit_recovers_known_probabilities():
    rng = np.random.default_rng(0)
    x, y, _ = synthetic(rng, 6000)
    xt, yt, pt = synthetic(rng, 6000)
    for method in Q.MAPS:
        q = Q.fit(x, y, groups=np.arange(len(y)) // 50, method=method)(xt)
        assert np.all((q >= Q.QMIN) & (q <= 1 - Q.QMIN))
        assert np.mean(np.abs(q - pt)) < 0.04, method
    q = Q.fit(x, y, l2=1.0)(xt)  # little ridge: the true model's coefficients
    assert np.mean(np.abs(q - pt)) < 0.01
    table = Q.reliability(q, yt)
    assert [b["lo"] for b in table] == pytest.approx(np.arange(10) / 10)
    assert sum(b["frames"] for b in table) == len(yt)
    # per decile, the mean quality is the mean true probability (the observed share is that
    # up to the draw's noise, ~0.03 for 300 frames)
    idx = np.minimum((q * 10).astype(int), 9)
    assert max(abs(q[idx == b].mean() - pt[idx == b].mean()) for b in range(10)) < 0.02
    assert Q.worst_gap(table, min_frames=200) < 0.1
    # a constant guess is not calibrated in its deciles: the check can fail
    flat = Q.reliability(np.where(rng.random(len(yt)) < 0.5, 0.05, 0.95), yt)
    assert Q.worst_gap(flat) > 0.2


def test_reliability_leaves_out_nan_and_counts_the_bins():
    table = Q.reliability([0.05, 0.05, 0.95, np.nan, 1.0], [True, False, True, False, True])
    assert table[0] == {"lo": 0.0, "hi": 0.1, "frames": 2, "predicted": 0.05, "observed": 0.5}
    assert table[9]["frames"] == 2 and table[9]["observed"] == 1.0
    assert table[5]["frames"] == 0 and table[5]["observed"] is None
    with pytest.raises(ValueError, match="3 qualities for 2 outcomes"):
        Q.reliability([0.1, 0.2, 0.3], [True, False])


def test_a_calibration_file_round_trips_and_a_bad_one_is_named(tmp_path):
    rng = np.random.default_rng(1)
    x, y, _ = synthetic(rng, 2000)
    model = Q.fit(x, y)
    path = tmp_path / "q.json"
    Q.save({"oracle": model}, path, 0.3)
    loaded = Q.load(path, "oracle")
    np.testing.assert_allclose(loaded(x), model(x))
    assert Q.load(path, "cnn") is None  # a mode without calibration: no quality
    with pytest.raises(ValueError, match="not found"):
        Q.load(tmp_path / "missing.json", "oracle")
    d = json.loads(path.read_text())
    d["inputs"] = d["inputs"][:-1]
    (tmp_path / "old.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="old.json was fitted on the inputs"):
        Q.load(tmp_path / "old.json", "oracle")
    d = json.loads(path.read_text())
    d["modes"]["oracle"]["coef"] = [1.0]
    (tmp_path / "short.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match=r"short.json modes.oracle: coef must be"):
        Q.load(tmp_path / "short.json", "oracle")


def test_the_localizer_rates_its_estimates_and_gates_tracking(small_world, camera, renderer,
                                                             tmp_path):
    """Tracking from near the truth: the quality is the calibration's of the estimate's
    inputs; the status is ``tracking`` with a gate of 0 and ``ambiguous`` with a gate above
    every quality."""
    rng = np.random.default_rng(2)
    x, y, _ = synthetic(rng, 3000)
    path = tmp_path / "q.json"
    Q.save({"oracle": Q.fit(x, y)}, path, 0.3)
    labels, _ = renderer.render(np.linalg.inv(cam_from_world(TRUE[None],
                                                             camera.body_from_cam)[0]))
    model = EdgeModel.build(small_world, SETTINGS).for_mode(small_world, "oracle")
    out = {}
    for gate in (0.0, 1.0):
        settings = replace(SETTINGS, filter=replace(SETTINGS.filter, quality_model=str(path),
                                                    tracking_quality=gate))
        loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                        model=model)
        loc.reset(TRUE)
        for t in range(3):
            est = loc.step(None, None if t == 0 else np.zeros(4), None, 0.1 * t, labels=labels)
        out[gate] = est
    a, b = out[0.0], out[1.0]
    assert a.status == "tracking" and b.status == "ambiguous"
    assert 0 < a.quality < 1 and a.quality == b.quality
    assert len(a.quality_inputs) == len(Q.INPUTS)
    assert a.quality == pytest.approx(float(Q.load(path, "oracle")(np.array(a.quality_inputs))[0]))
    # mode none has no calibration in the file: no quality, no gate
    none = Localizer(small_world, camera, "none", replace(SETTINGS, filter=replace(
        SETTINGS.filter, quality_model=str(path), tracking_quality=1.0)),
        np.random.default_rng(0), model=model)
    none.reset(TRUE)
    est = none.step(C.colorize(labels), None, None, 0.0)
    assert np.isnan(est.quality) and est.status == "tracking"


def test_the_shipped_calibration_covers_oracle_and_cnn_fitted_on_validation_floors():
    """The shipped file rates the estimates of modes oracle and cnn (the SegNet's edges), each
    fitted on the validation floors only (201-203; 101-103 are the test floors), with
    qualities that rise from a lost search's frame to a converged track's."""
    x = np.stack([Q.inputs(True, "ambiguous", [0.05, 0.04], 8.0, 3.0, 2.5, 0.0, np.nan, np.nan,
                           60000),
                  Q.inputs(False, "tracking", [1.0], 0.02, 0.02, 0.003, 0.98, 0.66, 32.0, 500)])
    for mode in ("oracle", "cnn"):
        model = Q.load(None, mode)
        assert model is not None, mode
        assert model.fitted_on["floors"] == ["floor201", "floor202", "floor203"]
        low, high = model(x)
        assert low < 0.2 < 0.8 < high, (mode, low, high)
