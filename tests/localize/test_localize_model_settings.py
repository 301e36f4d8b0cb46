"""``python -m localize`` takes the localize settings a model carries (its folder's
localize.yaml or its ONNX metadata) under the command line's overrides and records which layer
set each value that differs from its default; a file that is not an ONNX model is named as
such."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

import localize.__main__ as lm
from core.config import CONF
from core.segmenter import OnnxSegmenter
from localize import resolve as ls
from localize.frontend.segmenter import SHIPPED_MODEL, load_segmenter, model_path
from tests.localize.conftest import palette_segnet

#: What conf/experiment/best5_context.yaml carries.
HR3C = {"filter": {"mode_likelihood": {"cnn": {"k": 50.0}}},
        "edges": {"cnn": {"prior_correction": 0.0, "snap_nearest": True, "refine": "none",
                          "snap_px": 1}}}


def composed(overrides: list[str]):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose("localize", overrides=overrides)


@pytest.fixture
def carrying(tmp_path: Path) -> Path:
    """A model folder whose segnet.onnx carries best5_context's settings in its metadata only."""
    (tmp_path / "m").mkdir()
    return palette_segnet(tmp_path / "m" / "segnet.onnx", 12, 16,
                          extra_metadata={"localize": HR3C})


class TestApplyModelSettings:
    def test_from_metadata(self, carrying: Path, caplog) -> None:
        overrides = [f"onnx_model={carrying}"]
        cfg = composed(overrides)
        with caplog.at_level(logging.INFO, logger="localize.resolve"):
            taken = ls.apply_model_settings(cfg, overrides)
        assert cfg.filter.mode_likelihood.cnn.k == 50.0
        assert cfg.filter.mode_likelihood.cnn.orientation_bins == 12  # merged, not replaced
        assert cfg.edges.cnn.snap_px == 1 and cfg.edges.cnn.snap_nearest is True
        assert cfg.edges.cnn.refine == "none" and cfg.edges.cnn.prior_correction == 0.0
        assert taken["edges.cnn.snap_px"] == 1 and len(taken) == 5
        assert "settings from the model" in caplog.text and "edges.cnn.snap_px=1" in caplog.text
        assert "metadata key 'localize'" in caplog.text

    def test_command_line_wins(self, carrying: Path, caplog) -> None:
        """A key the command line gives keeps its value; a group choice (filter=paper) covers
        every key under it; the other settings still come from the model."""
        overrides = [f"onnx_model={carrying}", "edges.cnn.snap_px=3", "filter=paper"]
        cfg = composed(overrides)
        assert cfg.filter.mode_likelihood is None  # the paper: one likelihood for every mode
        with caplog.at_level(logging.INFO, logger="localize.resolve"):
            taken = ls.apply_model_settings(cfg, overrides)
        assert cfg.edges.cnn.snap_px == 3
        assert cfg.filter.mode_likelihood is None
        assert cfg.edges.cnn.refine == "none"  # from the model
        assert set(taken) == {"edges.cnn.prior_correction", "edges.cnn.snap_nearest",
                              "edges.cnn.refine"}
        assert "kept over the model's for: filter.mode_likelihood.cnn.k edges.cnn.snap_px" \
            in caplog.text

    def test_folder_file_before_metadata(self, carrying: Path) -> None:
        """localize.yaml beside the graph (shared with its int8 copy) is read first."""
        (carrying.parent / "localize.yaml").write_text("edges:\n  cnn:\n    snap_px: 4\n")
        overrides = [f"onnx_model={carrying}"]
        cfg = composed(overrides)
        assert ls.apply_model_settings(cfg, overrides) == {"edges.cnn.snap_px": 4}
        assert cfg.edges.cnn.snap_px == 4
        assert cfg.filter.mode_likelihood.cnn.k == 40.0  # conf/filter/default.yaml's

    def test_model_without_settings(self, tmp_path: Path) -> None:
        plain = palette_segnet(tmp_path / "segnet.onnx", 12, 16)
        for path in (plain, tmp_path / "absent" / "segnet.onnx"):
            overrides = [f"onnx_model={path}"]
            cfg = composed(overrides)
            assert ls.apply_model_settings(cfg, overrides) == {}
            assert cfg == composed(overrides)

    def test_unknown_section_names_the_file(self, carrying: Path) -> None:
        (carrying.parent / "localize.yaml").write_text("edgez:\n  cnn:\n    snap_px: 4\n")
        overrides = [f"onnx_model={carrying}"]
        with pytest.raises(ValueError, match=r"localize.yaml: edgez.cnn.snap_px is not a "
                                             r"localize setting"):
            ls.apply_model_settings(composed(overrides), overrides)

    def test_unknown_key_names_the_file(self, carrying: Path) -> None:
        """A key localize/config.py does not take (a typo, or a setting since removed) fails
        naming the file, the key and the class it is not in."""
        (carrying.parent / "localize.yaml").write_text("edges:\n  cnn:\n    snap_band: true\n")
        overrides = [f"onnx_model={carrying}"]
        with pytest.raises(ValueError, match=r"localize.yaml: edges.cnn.snap_band=True: Key "
                                             r"'snap_band' not in 'CnnConfig'"):
            ls.apply_model_settings(composed(overrides), overrides)

    def test_not_a_mapping(self, carrying: Path) -> None:
        (carrying.parent / "localize.yaml").write_text("- 1\n")
        overrides = [f"onnx_model={carrying}"]
        with pytest.raises(ValueError, match="localize.yaml: the localize settings must be a "
                                             "mapping"):
            ls.apply_model_settings(composed(overrides), overrides)


def test_override_keys() -> None:
    assert ls.override_keys(["a.b=1", "+c.d=[1,2]", "++e=x", "~f.g", "filter=paper",
                             "hydra.run.dir=/x", "db@pkg=mysql"]) == \
        ["a.b", "c.d", "e", "f.g", "filter", "db"]


def test_main_reads_the_command_line(carrying: Path, tmp_path: Path, monkeypatch) -> None:
    """The entry point takes the overrides from HydraConfig (as ``python -m localize`` sets
    it) and hands the merged config to run."""
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import open_dict

    seen = {}

    def fake_run(cfg):
        seen["cfg"] = cfg
        return tmp_path / "report.md"

    monkeypatch.setattr(lm, "run", fake_run)
    overrides = [f"onnx_model={carrying}", "edges.cnn.snap_px=2"]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("localize", overrides=overrides, return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)
    with open_dict(cfg):
        del cfg["hydra"]
    try:
        lm.main.__wrapped__(cfg)
    finally:
        HydraConfig.instance().cfg = None
    cfg = seen["cfg"]
    assert cfg.edges.cnn.snap_px == 2 and cfg.filter.mode_likelihood.cnn.k == 50.0
    assert cfg.edges.cnn.refine == "none"
    assert cfg.set_by["onnx_model"] == "command line"
    assert "edges.cnn.snap_px" not in cfg.set_by  # the command line gave its default
    assert cfg.set_by["edges.cnn.refine"].startswith(f"model {carrying}")


class TestSettingLayers:
    """``resolve`` records, for each value that differs from its default, the layer that set
    it; ``settings_table`` gives the rows metrics.json and report.md show."""

    def test_each_layer_named(self, carrying: Path, tmp_path: Path, monkeypatch) -> None:
        monkeypatch.chdir(tmp_path)  # no outputs/models/<dataset>: auto is the shipped model
        overrides = ["filter=paper", "edges.cnn.snap_px=3", "name=layers"]
        cfg = composed(overrides)
        set_by = ls.resolve(cfg, overrides, {"filter": "paper", "hydra/launcher": "basic"})
        assert cfg.onnx_model == str(SHIPPED_MODEL) and set_by["onnx_model"] == ls.AUTO
        assert set_by["filter.num_particles"] == "conf/filter/paper.yaml"
        assert set_by["filter.likelihood.k"] == "conf/filter/paper.yaml"
        assert set_by["edges.cnn.snap_px"] == set_by["name"] == "command line"
        assert "dataset" not in set_by and "seeds" not in set_by  # defaults
        assert dict(cfg.set_by) == set_by

        overrides = [f"onnx_model={carrying}", "filter=paper", "edges.cnn.snap_px=3"]
        cfg = composed(overrides)
        set_by = ls.resolve(cfg, overrides, {"filter": "paper"})
        model = f"model {carrying} (metadata key 'localize')"
        assert set_by["edges.cnn.refine"] == set_by["edges.cnn.snap_nearest"] == model
        assert set_by["edges.cnn.prior_correction"] == model
        assert set_by["filter.mode_likelihood"] == "conf/filter/paper.yaml"  # kept: null
        assert set_by["edges.cnn.snap_px"] == set_by["onnx_model"] == "command line"

    def test_table(self, carrying: Path) -> None:
        from localize.offline.report import _settings

        overrides = [f"onnx_model={carrying}", "filter.num_particles=300"]
        cfg = composed(overrides)
        assert {"key": "filter.num_particles", "value": 300, "default": 500,
                "set_by": ls.UNRECORDED} in ls.settings_table(cfg)  # not resolved
        ls.resolve(cfg, overrides, {"filter": "default"})
        rows = {r["key"]: r for r in ls.settings_table(cfg)}
        assert rows["filter.num_particles"] == {"key": "filter.num_particles", "value": 300,
                                                "default": 500, "set_by": "command line"}
        assert rows["edges.cnn.snap_px"]["default"] == 2
        assert rows["edges.cnn.snap_px"]["value"] == 1
        assert "set_by" not in rows
        lines = _settings({"settings": list(rows.values())})
        assert "| filter.num_particles | `300` | `500` | command line |" in lines
        assert _settings({}) == []

    def test_defaults_have_no_rows(self) -> None:
        assert ls.settings_table(composed([])) == []


class TestNotAnOnnxFile:
    @pytest.mark.parametrize("content", [b"name: demo\nseed: 0\n", b"\x89PNG\r\n\x1a\n" + bytes(64),
                                         b""])
    def test_named(self, tmp_path: Path, content: bytes) -> None:
        path = tmp_path / "segnet.onnx"
        path.write_bytes(content)
        with pytest.raises(ValueError, match=rf"{path} is not an ONNX model .*onnx_model="):
            OnnxSegmenter(path)
        with pytest.raises(ValueError, match=rf"{path} is not an ONNX model"):
            load_segmenter(path, [])

    def test_missing(self, tmp_path: Path) -> None:
        with pytest.raises(FileNotFoundError, match="not found"):
            OnnxSegmenter(tmp_path / "none.onnx")


class TestModelPath:
    """onnx_model=auto: the dataset's own SegNet where `python -m train` wrote one, else the
    shipped generalist; any other value is a path."""

    def test_auto(self, tmp_path, monkeypatch):
        monkeypatch.chdir(tmp_path)
        assert model_path("auto", "outputs/datasets/office") == SHIPPED_MODEL
        own = tmp_path / "outputs" / "models" / "office" / "segnet.onnx"
        own.parent.mkdir(parents=True)
        own.write_bytes(b"onnx")
        assert model_path("auto", "outputs/datasets/office").resolve() == own
        assert model_path("auto", "outputs/datasets/other") == SHIPPED_MODEL
        assert model_path("m/segnet.onnx", "outputs/datasets/office") == Path("m/segnet.onnx")
