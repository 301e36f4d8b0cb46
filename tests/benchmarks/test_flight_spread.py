"""benchmarks/flight_spread.py: new flights of a dataset's presets, and the pooled table."""

from __future__ import annotations

import json
import shutil

import pytest

from benchmarks.flight_spread import flights_config, merge_flights, summarize
from datagen.generate import run as render


def _metrics(errs: dict[str, dict[str, float]]) -> dict:
    return {"flights": {f: {m: {"mean_position_error_m": e} for m, e in d.items()}
                        for f, d in errs.items()}}


class TestSummarize:
    def test_ratios_and_pooling(self):
        rows = summarize(_metrics({
            "cluttered_1": {"cnn": 0.02, "oracle": 0.01, "none": 0.08},
            "cluttered_2": {"cnn": 0.04, "oracle": 0.01, "none": 0.08},
            "paper_1": {"cnn": 0.03, "oracle": 0.02, "none": 0.06},
        }))
        assert rows[0].startswith("| flight | cnn (m) | oracle (m) | none (m) |")
        one = next(r for r in rows if r.startswith("| cluttered_1 "))
        assert "| 0.0200 | 0.0100 | 0.0800 | 2.00 | 4.00 |" in one
        pooled = next(r for r in rows if "cluttered, 2 flights pooled" in r)
        assert "| 0.0300 | 0.0100 | 0.0800 | 3.00 | 2.67 |" in pooled
        assert any("paper, 1 flights pooled" in r and "| 1.50 | 2.00 |" in r for r in rows)

    def test_missing_mode_leaves_a_dash(self):
        rows = summarize(_metrics({"paper_1": {"cnn": 0.03, "oracle": 0.02}}))
        assert rows[0].count("(m)") == 2
        assert "| 1.50 | - |" in rows[2]


class TestMergeFlights:
    def test_pools_the_own_flights_with_the_new(self):
        own = _metrics({"cluttered": {"cnn": 0.01, "oracle": 0.01}})
        new = _metrics({"cluttered_1": {"cnn": 0.03, "oracle": 0.01}})
        rows = summarize(merge_flights(new, own))
        pooled = next(r for r in rows if "cluttered, 2 flights pooled" in r)
        assert "| 0.0200 | 0.0100 | 2.00 |" in pooled

    def test_a_preset_name_with_an_underscore(self):
        own = _metrics({"cluttered_long": {"cnn": 0.01}, "cluttered": {"cnn": 0.05}})
        new = _metrics({"cluttered_long_1": {"cnn": 0.03}, "cluttered_1": {"cnn": 0.07}})
        rows = summarize(merge_flights(new, own))
        long = next(r for r in rows if "cluttered_long, 2 flights pooled" in r)
        assert "| 0.0200 |" in long
        plain = next(r for r in rows if "**cluttered, 2 flights pooled" in r)
        assert "| 0.0600 |" in plain

    def test_a_flight_in_two_reports(self):
        m = _metrics({"paper": {"cnn": 0.01}})
        with pytest.raises(ValueError, match="paper"):
            merge_flights(m, m)


class TestFlightsConfig:
    def test_new_flights_of_each_preset(self, tiny_dataset, tmp_path):
        cfg = flights_config(tiny_dataset, 2, tmp_path / "tiny_flights")
        gen = json.loads((tiny_dataset / "dataset.json").read_text())["generator"]
        assert cfg["render_flights"] == ["paper_1", "paper_2", "cluttered_1", "cluttered_2"]
        assert cfg["flights"]["cluttered_2"] == gen["flights"]["cluttered"]
        assert all(n == 0 for n in cfg["splits"].values())
        assert cfg["world"] == gen["world"] and cfg["seed"] == gen["seed"]
        assert cfg["out_dir"] == str(tmp_path / "tiny_flights")

    def test_renders_only_the_new_flights(self, tiny_dataset, tmp_path):
        gen = json.loads((tiny_dataset / "dataset.json").read_text())["generator"]
        cfg = flights_config(tiny_dataset, 1, tmp_path / "f")
        cfg["flights"] = {k: v for k, v in cfg["flights"].items() if k == "paper_1"}
        cfg["flights"]["paper_1"]["num_frames"] = 3
        cfg["render_flights"] = ["paper_1"]
        out = render(cfg, progress=False)
        assert sorted(p.name for p in (out / "flights").iterdir()) == ["paper_1"]
        assert not (out / "train" / "rgb").exists() or not any((out / "train" / "rgb").iterdir())
        for f in ("model.npz", "edges.npz"):  # the same world, so the same model to localize in
            assert (out / "world" / f).read_bytes() == (tiny_dataset / "world" / f).read_bytes()
        assert gen["flights"]["paper"]["num_frames"] == 30  # the source is left as it was

    def test_bad_dataset(self, tmp_path):
        with pytest.raises(FileNotFoundError, match="dataset.json"):
            flights_config(tmp_path, 3, tmp_path / "x")
        d = tmp_path / "noflights"
        d.mkdir()
        (d / "dataset.json").write_text(json.dumps({"generator": {"render_flights": []}}))
        with pytest.raises(ValueError, match="rendered no flights"):
            flights_config(d, 3, tmp_path / "y")
        shutil.rmtree(d)
