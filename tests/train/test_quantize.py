"""train.deploy.quantize: an int8 copy of a trained segnet.onnx that segments like the float one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnx
import pytest

import train.run as tt
from core.atomic import read_png
from core.dataset import Dataset
from core.outputs import LOCK_NAME, SETUP_LOCK_NAME
from core.segmenter import OnnxSegmenter, read_metadata
from train.deploy.quantize import (
    INT8_NAME,
    REPORT_NAME,
    float_nodes,
    main,
    quantize_segnet,
    spread_indices,
)


def test_spread_indices() -> None:
    assert spread_indices(10, 3).tolist() == [0, 4, 9]  # 4.5 rounds to even
    assert spread_indices(3, 10).tolist() == [0, 1, 2]
    assert spread_indices(5, 1).tolist() == [0]
    assert spread_indices(0, 4).size == 0


@pytest.fixture(scope="module")
def quantized(synthetic_dataset: Path, compose_train, tmp_path_factory) -> tuple[Path, dict]:
    """A tiny model trained 4 epochs, then ``python -m train.deploy.quantize`` on its folder."""
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
    assert not [p for p in model_dir.iterdir() if p.name not in (LOCK_NAME, SETUP_LOCK_NAME)
                and (p.name.startswith(".") or p.is_dir())]
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


#: Quantizes argv[1] into argv[2] and dies (SIGKILL) inside onnxruntime's quantize_static.
KILLED = """
import os, signal, sys
import numpy as np
import train.deploy.quantize as q
from core.segmenter import read_metadata
import onnx
meta = read_metadata(onnx.load(sys.argv[1], load_external_data=False))
frames = np.zeros((1, int(meta["input_height"]), int(meta["input_width"]), 3), np.uint8)
q.quantize_static = lambda *a, **k: os.kill(os.getpid(), signal.SIGKILL)
q.quantize_segnet(sys.argv[1], sys.argv[2], frames)
"""


@pytest.mark.slow
def test_killed_quantization_leaves_no_work_folder(tmp_path: Path, quantized) -> None:
    """A quantization killed mid-way cannot clean up; the next one in that folder does, and
    keeps the work folder of a quantization still running."""
    model_dir, _ = quantized
    src = tmp_path / "segnet.onnx"
    src.write_bytes((model_dir / "segnet.onnx").read_bytes())
    killed = subprocess.run([sys.executable, "-c", KILLED, str(src), str(tmp_path / "a.onnx")],
                            cwd=Path(__file__).resolve().parents[2], capture_output=True)
    assert killed.returncode == -9, killed.stderr[-2000:]
    left = [p.name for p in tmp_path.iterdir() if p.is_dir()]
    assert len(left) == 1 and "quantize" in left[0], left  # what the kill left
    live = tmp_path / f".quantize.{os.getpid()}.running"
    live.mkdir()
    meta = read_metadata(onnx.load(str(src), load_external_data=False))
    h, w = int(meta["input_height"]), int(meta["input_width"])
    quantize_segnet(src, tmp_path / "b.onnx", np.zeros((2, h, w, 3), np.uint8))
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_dir()) == [live.name]
    assert (tmp_path / "b.onnx").is_file()
