"""benchmarks/paper_faithful.py: the paper's render-per-particle likelihood against the
vectorized one, on the same frames and particles, through the runner's pass."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.paper_faithful import comparison_summary, main, run_specs
from tests.localize.conftest import QUICK
from tests.localize.test_localize_localizer import checksum

#: Per run: the estimate (3, 4) summed over frames, then weighted by frame number 1..3 (3
#: frames of 8 particles, mode cnn), recorded on the flat-shaded tiny dataset.
REFERENCE = {
    "paper/cnn_paper_faithful_n8_seed0": [-0.4887618586548706, 27.978434297830667, 4.056921140034035, -3.431648227294949, -0.9301666876425729, 55.90471778561468, 8.131571547114426, -6.879212534143395],  # noqa: E501
    "paper/cnn_vectorized_n8_seed0": [-0.5517562258991249, 28.659981715119766, 4.17582249208259, -3.4298095339509636, -1.0830663276346817, 57.28764303060676, 8.350806446513902, -6.881792294421868],  # noqa: E501
}


def record(likelihood: str, errors: list[float], filter_ms: list[float]) -> dict:
    return {"likelihood": likelihood, "flight": "paper", "mode": "oracle", "num_frames": 2,
            "filter_particles": 8, "position_error_m": errors,
            "timing_ms": {"filter": filter_ms}}


def test_run_names_seed_the_two_likelihoods_apart():
    specs = run_specs("paper", "cnn", [0, 1], 8)
    assert [r.likelihood for r in specs["vectorized"]] == ["vectorized_n8"] * 2
    assert [r.seed for r in specs["paper_faithful"]] == [0, 1]
    assert specs["paper_faithful"][0].likelihood == "paper_faithful_n8"


def test_summary_pairs_the_likelihoods_and_skips_the_main_runs():
    s = comparison_summary([record("vectorized", [9.0], [1.0]),
                            record("vectorized_n8", [0.1, 0.3], [2.0, 2.0]),
                            record("paper_faithful_n8", [0.2, 0.2], [100.0, 300.0])])
    assert s["vectorized"]["mean_position_error_m"] == pytest.approx(0.2)
    assert s["paper_faithful"]["filter_ms"]["avg"] == pytest.approx(200.0)
    assert s["speed_ratio"] == pytest.approx(100.0)
    assert "speed_ratio" not in comparison_summary([record("vectorized_n8", [0.1], [1.0])])


def test_missing_dataset_says_so(tmp_path, capsys):
    assert main(["--dataset", str(tmp_path / "none"), "--out-root", str(tmp_path)]) == 0
    assert "not found" in capsys.readouterr().out


@pytest.mark.slow
def test_comparison_gives_the_recorded_trajectories(flat_dataset, flat_segnet, tmp_path,
                                                    capsys):
    quick = [o for o in QUICK if not o.startswith(("progress=", "seeds="))]
    assert main(["--dataset", str(flat_dataset), "--onnx-model", str(flat_segnet),
                 "--out-root", str(tmp_path), "--name", "pf", "--mode", "cnn", "--frames", "3",
                 "--particles", "8", "--seeds", "0", "--hough", "20", "8", "3", *quick]) == 0
    out = tmp_path / "pf"
    got = {f"{p.parent.name}/{p.stem}": json.loads(p.read_text())
           for p in sorted((out / "runs").glob("*/*.json"))}
    assert set(got) == set(REFERENCE)
    for key, want in REFERENCE.items():
        # cnn labels come from onnxruntime, whose kernels differ by CPU in the last bits
        np.testing.assert_allclose(checksum(got[key]["estimate"]), want, rtol=0, atol=1e-4,
                                   err_msg=key)
    s = json.loads((out / "paper_faithful.json").read_text())
    assert s["paper_faithful"]["num_particles"] == s["vectorized"]["num_particles"] == 8
    assert s["speed_ratio"] > 1.0
    assert np.isfinite(s["paper_faithful"]["mean_position_error_m"])
    assert "speed-up of the vectorized likelihood" in capsys.readouterr().out
