"""benchmarks/global_start.py: starts spread over the flights, kidnappings, the table, and a
whole small call on the tiny dataset."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks.global_start import (
    kidnaps_of,
    main,
    markdown,
    start_frames,
    starts_of,
    summarize,
)
from tests.localize.conftest import QUICK


class FakeFlight(list):
    """A flight of ``n`` frames flying +x at 0.1 m a frame (the kidnappings read its truth)."""

    def __init__(self, n: int):
        super().__init__([0] * n)
        self.groundtruth = np.tile(np.eye(4), (n, 1, 1))
        self.groundtruth[:, 0, 3] = 0.1 * np.arange(n)


def fake_dataset(lengths: dict[str, int]):
    flights = {name: FakeFlight(n) for name, n in lengths.items()}
    return SimpleNamespace(flight_names=lambda which: list(lengths),
                           flight=lambda name: flights[name])


def test_start_frames_spread_and_leave_room():
    assert start_frames(1150, 200, 4) == [0, 317, 633, 950]
    assert start_frames(40, 60, 3) == [0]  # a short flight: one start, all its frames
    ds = fake_dataset({"paper": 1150, "cluttered": 1150})
    starts = starts_of(ds, 200, 5)
    assert [s for s in starts if s[0] == "paper"] == [("paper", 0), ("paper", 475),
                                                      ("paper", 950)]
    assert len(starts) == 5
    pairs = kidnaps_of(ds, 30, 200, 3)
    assert len(pairs) == 3 and all(a != b for a, b in pairs)
    # teleported to the start farthest from where the tracked stretch ends
    assert pairs[0] == (("paper", 0), ("paper", 920))
    assert pairs[2] == (("paper", 920), ("paper", 0))


def _row(kind="global", **kw):
    base = {"floor": "f", "mode": "oracle", "kind": kind, "frames": 220,
            "false_convergence": False, "global_update_ms": [100.0, 120.0],
            "peak_particles": 200000, "final_error_m": 0.1,
            "quality": [0.05, 0.95, 0.95, np.nan], "within": [0, 1, 0, 1]}
    if kind == "global":
        base.update(converged_frame=50, converged_m=2.0)
    else:
        base.update(lost_declared=True, lost_after_frames=12, back_frames=40)
    return {**base, **kw}


def test_summary_and_table():
    rows = [_row(), _row(converged_frame=150, converged_m=6.0),
            _row(converged_frame=None, converged_m=None, false_convergence=True),
            _row(frames=60, converged_frame=20, converged_m=1.0),
            _row("kidnapped"), _row("kidnapped", lost_declared=False, lost_after_frames=None,
                                    back_frames=None),
            _row("kidnapped", lost_after_frames=31, back_frames=90)]
    e = summarize(rows)["f"]["oracle"]
    assert e["starts"] == 4
    assert e["within_0.3m_by_30"] == 0.25
    assert e["within_0.3m_by_100"] == pytest.approx(1 / 3)  # the 60-frame run cannot tell
    assert e["within_0.3m_by_200"] == pytest.approx(2 / 3)
    assert e["median_frames_to_converge"] == 50 and e["median_m_to_converge"] == 2.0
    assert e["false_convergence_rate"] == 0.25
    assert e["global_update_ms"] == {"median": 110.0, "max": 120.0}
    assert e["kidnaps"] == 3 and e["kidnap_lost_declared"] == pytest.approx(2 / 3)
    assert e["kidnap_lost_by_30"] == pytest.approx(1 / 3)  # one declared too late (31)
    assert e["kidnap_back_by_100"] == pytest.approx(2 / 3)
    q = e["quality_reliability"]  # every run's frames; a NaN quality left out
    assert q[0]["frames"] == 7 and q[0]["observed"] == 0.0
    assert q[9]["frames"] == 14 and q[9]["observed"] == 0.5
    assert q[9]["predicted"] == pytest.approx(0.95)
    md = markdown({"load": [1.0, 1.0, 1.0], "peak_rss_gb": 1.5, "table": {"f": {"oracle": e}}})
    assert "| f | oracle | 4 | 25% | 33% | 67% | 50 / 2.0 | 25% | 110 / 120 | 200000 | " \
           "67% / 33% / 67% | 0% |" in md
    assert "| f | oracle | 0.45 | 0.00 / 0.05 (7) | - |" in md


@pytest.mark.slow
def test_a_small_call_writes_the_table_and_resumes(flat_dataset, tmp_path):
    argv = ["--floors", f"tiny={flat_dataset}", "--modes", "oracle", "--starts", "2",
            "--frames", "12", "--kidnaps", "1", "--kidnap-after", "6", "--kidnap-frames", "12",
            "--out-root", str(tmp_path), "--", *QUICK[2:], "filter.lost_frames=3"]
    assert main(argv) == 0
    out = tmp_path / "global_start"
    result = json.loads((out / "global_start.json").read_text())
    e = result["table"]["tiny"]["oracle"]
    assert e["starts"] == 2 and e["kidnaps"] == 1
    assert (out / "global_start.md").read_text().startswith("# Global start")
    assert (out / "global_start.png").stat().st_size > 1000
    records = sorted((out / "reports" / "tiny" / "runs").glob("*/*.json"))
    assert len(records) == 3
    rec = json.loads(records[0].read_text())
    assert len(rec["hypotheses"]) == rec["num_frames"] and rec["hypotheses"][0][0][4] > 0
    stamps = [p.stat().st_mtime_ns for p in records]
    assert main(argv) == 0  # finished runs are kept
    assert [p.stat().st_mtime_ns for p in records] == stamps
