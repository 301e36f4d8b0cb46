"""benchmarks/class_cost.py: the metres each class's segmentation errors cost, per building."""

from __future__ import annotations

import json

import pytest

from benchmarks.class_cost import costs, main, mean_errors, table
from tests.localize.conftest import QUICK


def test_costs_are_the_cnn_error_minus_the_swapped():
    e = {"cnn": 0.30, "oracle": 0.05, "all": 0.06, "window": 0.10, "door": 0.32}
    assert costs(e) == pytest.approx({"all": 0.24, "window": 0.20, "door": -0.02})
    md = table({"hospital": e}, ["window", "door", "clutter"])
    row = md.splitlines()[2].split(" | ")
    assert row[1:4] == ["0.050", "0.300", "0.060"]
    assert row[4:] == ["+0.200", "-0.020", "- |"]


def test_mean_errors_average_the_flights_per_mode():
    run = lambda m: {"mean_position_error_m": m, "per_seed_mean_m": [m], "lost_rate": 0.0}  # noqa: E731
    m = {"flights": {"a": {"cnn": run(0.2), "oracle": {}},
                     "b": {"cnn": run(0.4), "oracle": run(0.1)}}}
    assert mean_errors(m) == pytest.approx({"cnn": 0.3, "oracle": 0.1})


def test_an_exact_segnet_loses_nothing_to_any_class(flat_dataset, flat_segnet, tmp_path, capsys):
    """With a SegNet that labels every pixel right, taking a class from the truth changes no
    label, so every variant's cnn error is the plain one's, to the bit."""
    root = tmp_path / "tp"
    (root / "datasets").mkdir(parents=True)
    (root / "datasets" / "floor101").symlink_to(flat_dataset, target_is_directory=True)
    assert main(["--buildings", "floor101", "bookstore", "--classes", "floor", "door",
                 "--onnx", str(flat_segnet), "--root", str(root), "max_frames=6",
                 *QUICK]) == 0
    assert "bookstore: no dataset" in capsys.readouterr().out
    got = json.loads((root / "class_cost" / "class_cost.json").read_text())["errors_m"]
    assert set(got) == {"floor101"}
    e = got["floor101"]
    assert set(e) == {"cnn", "oracle", "all", "floor", "door"}
    assert all(v == e["cnn"] for k, v in e.items() if k != "oracle"), e
    assert (root / "class_cost" / "floor101" / "swap_door" / "cache").is_symlink()
    assert "| floor101 |" in (root / "class_cost" / "class_cost.md").read_text()
