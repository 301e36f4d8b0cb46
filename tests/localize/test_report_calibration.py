"""The confidence calibration (localize.offline.metrics.calibration) and where the report shows
it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from omegaconf import OmegaConf

from localize.config import LocalizeConfig
from localize.offline.metrics import calibration
from localize.offline.report import _calibration_table, calibrations, summarize
from localize.offline.report_plots import plot_calibration


def test_accurate_high_confidence_scores_one() -> None:
    conf = np.r_[np.full(90, 0.95), np.full(10, 0.3)]
    err = np.r_[np.full(90, 0.05), np.full(10, 2.0)]  # the unsure frames are the wrong ones
    h = calibration(err, conf, 0.3)["high_confidence"]
    assert h == {"min_confidence": 0.9, "frame_share": 0.9, "within_share": 1.0}


def test_confidently_wrong_scores_low() -> None:
    conf = np.full(100, 0.95)
    err = np.r_[np.full(20, 0.05), np.full(80, 3.0)]
    c = calibration(err, conf, 0.3)
    assert c["high_confidence"]["within_share"] == pytest.approx(0.2)
    assert c["bins"][-1]["within_share"] == pytest.approx(0.2)
    assert c["bins"][-1]["frame_share"] == 1.0


def test_bins_and_empty_bins() -> None:
    """Each bin is [lo, hi), the last [lo, 1]; a bin without frames has no share (None, valid
    JSON), not NaN."""
    conf = np.array([0.0, 0.5, 0.69, 0.9, 1.0])
    err = np.array([0.1, 0.5, 0.1, 0.1, 0.4])
    c = calibration(err, conf, 0.3, bins=(0.0, 0.5, 0.7, 0.8, 0.9, 1.0))
    assert [b["frame_share"] for b in c["bins"]] == [0.2, 0.4, 0.0, 0.0, 0.4]
    assert [b["within_share"] for b in c["bins"]] == [1.0, 0.5, None, None, 0.5]
    assert c["bins"][0]["confidence"] == [0.0, 0.5]
    json.dumps(c, allow_nan=False)
    none_high = calibration(np.array([0.1]), np.array([0.2]), 0.3)["high_confidence"]
    assert none_high["within_share"] is None and none_high["frame_share"] == 0.0


def test_lengths_must_match() -> None:
    with pytest.raises(ValueError, match="3 errors for 2 confidences"):
        calibration(np.zeros(3), np.zeros(2), 0.3)


def _record(flight, mode, init, seed, err, conf, truth=True) -> dict:
    n = len(err)
    r = {"flight": flight, "mode": mode, "init": init, "seed": seed, "likelihood": "vectorized",
         "num_frames": n, "filter_particles": 100, "timestamps": list(np.arange(n) * 0.1),
         "timing_ms": {s: [1.0] * n for s in ("acquisition", "segmentation", "preprocessing",
                                                "filter", "total")},
         "status": ["tracking"] * n, "confidence": list(conf)}
    if truth:
        r.update(position_error_m=list(err), yaw_error_deg=[0.1] * n)
    return r


def test_summary_and_report_show_the_calibration(tmp_path) -> None:
    """metrics.json holds the calibration of the tracking and the global runs per flight and
    mode; the report's table flags a confidently wrong mode; no truth, no calibration."""
    cfg = OmegaConf.structured(LocalizeConfig)
    good, wrong = np.full(20, 0.05), np.full(20, 2.0)
    sure = np.full(20, 0.95)
    records = [_record("f", "cnn", "tracking", 0, good, sure),
               _record("f", "cnn", "global", 0, wrong, sure),
               _record("f", "none", "tracking", 0, good, np.full(20, 0.4)),
               _record("g", "cnn", "tracking", 0, good, sure, truth=False)]
    m = summarize(records, cfg)
    json.dumps(m, allow_nan=False)
    f = m["flights"]["f"]
    assert f["cnn"]["calibration"]["high_confidence"]["within_share"] == 1.0
    assert f["cnn"]["calibration"]["within_m"] == cfg.metrics.calibration_within_m
    assert f["cnn"]["global"]["calibration"]["high_confidence"]["within_share"] == 0.0
    assert f["none"]["calibration"]["high_confidence"]["within_share"] is None
    assert "calibration" not in m["flights"]["g"]["cnn"]
    table = "\n".join(_calibration_table(m))
    assert "| f | global | cnn | 100.0% | 0.0% | **no** |" in table
    assert "| f | tracking | cnn | 100.0% | 100.0% | yes |" in table
    assert "| f | tracking | none | 0.0% | - | - |" in table
    path = tmp_path / "f_calibration.png"
    plot_calibration(calibrations(f), "f", path)
    assert path.stat().st_size > 0


def test_summary_and_report_show_the_quality_reliability() -> None:
    """Records with a quality: metrics.json holds its reliability per decile beside the
    calibration, report.md its table; records whose quality is NaN (a mode without
    calibration) have none."""
    from localize.offline.report import _quality_table

    cfg = OmegaConf.structured(LocalizeConfig)
    err = np.r_[np.full(10, 0.05), np.full(10, 2.0)]
    rated = _record("f", "oracle", "global", 0, err, np.zeros(20))
    rated["quality"] = [0.95] * 10 + [0.05] * 5 + [0.95] * 5  # 5 confidently wrong frames
    unrated = _record("f", "cnn", "global", 0, err, np.zeros(20))
    unrated["quality"] = [float("nan")] * 20
    m = summarize([rated, unrated], cfg)
    q = m["flights"]["f"]["oracle"]["global"]["quality"]
    assert q[0]["frames"] == 5 and q[0]["observed"] == 0.0
    assert q[9]["frames"] == 15 and q[9]["observed"] == pytest.approx(10 / 15)
    assert q[9]["predicted"] == pytest.approx(0.95)
    assert "quality" not in m["flights"]["f"]["cnn"]["global"]
    table = "\n".join(_quality_table(m))
    assert "| f | global | oracle | 0.28 | 0.00 / 0.05 (5) |" in table
    assert "0.67 / 0.95 (15) |" in table and "| f | global | cnn |" not in table
