"""train.quantize: an int8 copy of a trained segnet.onnx that segments like the float one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnx
import pytest

import train.train as tt
from core.atomic import read_png
from core.dataset import Dataset
from train.predict import OnnxSegmenter
from train.quantize import (
    INT8_NAME,
    REPORT_NAME,
    float_nodes,
    main,
    quantize_segnet,
    spread_indices,
)
from train.runtime import read_metadata


def test_spread_indices() -> None:
    assert spread_indices(10, 3).tolist() == [0, 4, 9]  # 4.5 rounds to even
    assert spread_indices(3, 10).tolist() == [0, 1, 2]
    assert spread_indices(5, 1).tolist() == [0]
    assert spread_indices(0, 4).size == 0


@pytest.fixture(scope="module")
def quantized(synthetic_dataset: Path, compose_train, tmp_path_factory) -> tuple[Path, dict]:
    """A tiny model trained 4 epochs, then ``python -m train.quantize`` on its folder."""
    out_root = tmp_path_factory.mktemp("models")
    tt.run(compose_train(synthetic_dataset, out_root, "epochs=4"))
    model_dir = out_root / "demo"
    assert main([str(model_dir), "--calibration", "8"]) == 0
    return model_dir, json.loads((model_dir / REPORT_NAME).read_text())


@pytest.mark.slow
def test_int8_segments_like_the_float_model(quantized, synthetic_dataset: Path) -> None:
    model_dir, report = quantized
    int8 = model_dir / INT8_NAME
    assert int8.is_file()
    # no temporary files left beside the outputs
    assert not [p for p in model_dir.iterdir() if p.name.startswith(".") or p.is_dir()]
    meta, meta32 = read_metadata(int8), read_metadata(model_dir / "segnet.onnx")
    assert meta["quantization"]["calibration_images"] == 8
    assert {k: v for k, v in meta.items() if k != "quantization"} == meta32
    # the pooling bookkeeping stays float: its one-hot convolutions read float weights
    proto8 = onnx.load(str(int8))
    keep = set(float_nodes(proto8))
    inits = {t.name for t in proto8.graph.initializer}
    pool_convs = [n for n in proto8.graph.node if n.op_type == "Conv" and n.name in keep]
    assert pool_convs and all(n.input[1] in inits for n in pool_convs)
    assert [o.name for o in proto8.graph.output] == ["logits", "labels"]
    # the same frames through both graphs: nearly the same logits and labels (a tiny network
    # trained for seconds has small margins between classes: the shipped ones agree on more)
    rgb_paths, _ = Dataset(synthetic_dataset).split("test")
    rgb = np.stack([read_png(p) for p in rgb_paths])
    z32 = OnnxSegmenter(model_dir / "segnet.onnx").logits(rgb)
    z8 = OnnxSegmenter(int8).logits(rgb)
    assert z8.shape == z32.shape and z8.dtype == np.float32
    spread = float(z32.max() - z32.min())
    assert np.abs(z8 - z32).mean() < 0.02 * spread
    assert (z8.argmax(1) == z32.argmax(1)).mean() > 0.85
    assert report["images"] == len(rgb_paths)
    assert report["label_agreement"] == pytest.approx((z8.argmax(1) == z32.argmax(1)).mean())
    for key in ("pixel_accuracy", "mean_iou"):
        assert abs(report["int8"][key] - report["fp32"][key]) < 0.05
    # the report's float scores are the trained model's own test scores (segnet.onnx's labels)
    metrics = json.loads((model_dir / "metrics.json").read_text())
    assert report["fp32"]["pixel_accuracy"] == pytest.approx(
        metrics["test"]["pixel_accuracy"], abs=1e-6)


def test_bad_input(tmp_path: Path, quantized) -> None:
    with pytest.raises(FileNotFoundError, match="segnet.onnx"):
        main([str(tmp_path)])
    model_dir, _ = quantized
    with pytest.raises(ValueError, match="calibration frames"):
        quantize_segnet(model_dir / "segnet.onnx", tmp_path / "x.onnx",
                        np.zeros((2, 10, 10, 3), np.uint8))
    assert not (tmp_path / "x.onnx").exists()
