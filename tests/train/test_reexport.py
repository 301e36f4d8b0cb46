"""train.reexport: a model folder's graph written again from its checkpoint, no training."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest

import train.train as tt
from core.atomic import is_temp, read_png
from core.dataset import Dataset
from train.export import ParityError, to_onnx_proto
from train.predict import OnnxSegmenter
from train.reexport import default_tolerance, main, reexport
from train.train import load_checkpoint


@pytest.fixture(scope="module")
def folder(synthetic_dataset: Path, compose_train, tmp_path_factory) -> Path:
    """A tiny model trained one epoch (segnet.onnx, segnet_int8.onnx, metrics.json, ...)."""
    out_root = tmp_path_factory.mktemp("models")
    tt.run(compose_train(synthetic_dataset, out_root, "epochs=1"))
    return out_root / "demo"


def _old_style_copy(folder: Path, dest: Path) -> Path:
    """The folder with its graph exported as before the ``labels`` output (same metadata)."""
    shutil.copytree(folder, dest)
    current = onnx.load(str(dest / "segnet.onnx"))
    h, w = (d.dim_value for d in current.graph.input[0].type.tensor_type.shape.dim[2:])
    model = load_checkpoint(dest / "checkpoint_best.pt").set_pooling("window")
    old = to_onnx_proto(model, h, w)
    old.metadata_props.extend(current.metadata_props)
    onnx.save(old, str(dest / "segnet.onnx"))
    (dest / "segnet_int8.onnx").write_bytes(b"an int8 copy of the old graph")
    return dest


@pytest.mark.slow
def test_reexport_upgrades_an_old_graph(folder: Path, synthetic_dataset: Path,
                                        tmp_path: Path) -> None:
    d = _old_style_copy(folder, tmp_path / "m")
    assert not OnnxSegmenter(d / "segnet.onnx").has_labels_output
    assert main([str(d)]) == 0
    new = onnx.load(str(d / "segnet.onnx"))
    assert [o.name for o in new.graph.output] == ["logits", "labels"]
    shipped = onnx.load(str(folder / "segnet.onnx"))
    assert {p.key: p.value for p in new.metadata_props} == {
        p.key: p.value for p in shipped.metadata_props}
    # the same function as the folder's own export, now with the graph's argmax
    rgb_paths, _ = Dataset(synthetic_dataset).split("test")
    rgb = np.stack([read_png(p) for p in rgb_paths])
    a, b = OnnxSegmenter(d / "segnet.onnx"), OnnxSegmenter(folder / "segnet.onnx")
    assert a.has_labels_output
    np.testing.assert_allclose(a.logits(rgb), b.logits(rgb), atol=1e-5)
    metrics = json.loads((d / "metrics.json").read_text())
    assert metrics["onnx_parity"]["labels_output_mismatch"] == 0
    # the stale int8 copy is made again from the new graph
    int8 = OnnxSegmenter(d / "segnet_int8.onnx")
    assert int8.has_labels_output and int8.labels(rgb).shape == rgb.shape[:3]
    assert 0.5 < metrics["int8"]["label_agreement"] <= 1.0


@pytest.mark.slow
def test_failed_check_keeps_the_old_file(folder: Path, tmp_path: Path) -> None:
    d = _old_style_copy(folder, tmp_path / "m")
    before = (d / "segnet.onnx").read_bytes()
    with pytest.raises(ParityError, match="not written"):
        reexport(d, tolerance=-1.0)  # no graph can pass
    assert (d / "segnet.onnx").read_bytes() == before
    assert not [p for p in d.iterdir() if is_temp(p)]  # no temporary file left


def test_bad_input(folder: Path, make_dataset, tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="python -m train"):
        reexport(tmp_path)
    other = make_dataset(tmp_path / "other", {"train": 2, "val": 1, "test": 2}, height=40,
                         width=56)
    with pytest.raises(ValueError, match="--dataset"):
        reexport(folder, dataset=other)
    assert default_tolerance({}) == 1e-4
    assert default_tolerance({"onnx_max_abs_diff": 2.3e-4}) == pytest.approx(4.6e-4)
