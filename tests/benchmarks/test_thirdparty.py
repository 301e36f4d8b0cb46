"""benchmarks/thirdparty.py: the per-mode figures of a localize report and the table."""

from __future__ import annotations

import pytest

from benchmarks.thirdparty import table, tracking


def metrics(errors: dict[str, list[float]], lost: dict[str, float]) -> dict:
    """A metrics.json of two flights: mode -> per-flight mean error, two seeds each."""
    flights = {}
    for i, name in enumerate(("paper", "cluttered")):
        flights[name] = {m: {"mean_position_error_m": e[i], "per_seed_mean_m": [e[i]] * 2,
                             "lost_rate": lost[m] if i == 1 else 0.0}
                         for m, e in errors.items()}
    return {"flights": flights, "timing_ms_by_mode": {"cnn": {"total": {"avg": 41.7}}}}


def test_tracking_means_flights_and_counts_lost_runs():
    got = tracking(metrics({"cnn": [0.05, 0.15], "none": [0.5, 1.5]},
                           {"cnn": 0.0, "none": 0.5}))
    assert got["cnn"]["mean_m"] == pytest.approx(0.10) and got["cnn"]["runs"] == 4
    assert got["cnn"]["lost"] == 0 and got["cnn"]["frame_ms"] == pytest.approx(41.7)
    assert got["none"]["lost"] == 1 and got["none"]["frame_ms"] is None


def test_table_has_the_fine_tune_columns_only_when_run():
    tr = tracking(metrics({"cnn": [0.05, 0.15]}, {"cnn": 0.0}))
    seg = {"pixel_accuracy": 0.9, "mean_iou": 0.6, "boundary_f": 0.4}
    plain = table({"floor101": {"import": None, "segnet": seg, "tracking": tr}}, ["cnn"])
    assert "fine-tuned" not in plain and "0.900 / 0.600 / 0.400" in plain
    ft = {"segnet": {"mean_iou": 0.7, "boundary_f": 0.5},
          "tracking": tracking(metrics({"cnn": [0.04, 0.06]}, {"cnn": 0.0}))}
    rows = table({"floor101": {"import": None, "segnet": seg, "tracking": tr},
                  "hospital": {"import": None, "tracking": tr, "finetuned": ft}},
                 ["cnn"]).splitlines()
    head = [c.strip() for c in rows[0].strip("|").split("|")]
    cells = [c.strip() for c in rows[3].strip("|").split("|")]
    assert cells[head.index("cnn fine-tuned m (lost)")] == "0.050 (0/4)"
    assert cells[head.index("fine-tuned mIoU / bF")] == "0.700 / 0.500"
    assert rows[2].count("|") == rows[0].count("|")  # a row without a fine-tune: "-" cells
