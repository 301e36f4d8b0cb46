"""core.segmenter reads a model and its metadata through onnxruntime: the live node's start
pays no ``onnx`` import (1.5 s), and the metadata agree with the onnx package's reading."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from core.segmenter import OnnxSegmenter, load_onnx, read_metadata

ROOT = Path(__file__).resolve().parents[2]
GENERALIST = ROOT / "models" / "generalist" / "segnet.onnx"


def test_no_onnx_import() -> None:
    code = ("import sys; from core.segmenter import OnnxSegmenter, read_metadata; "
            f"s = OnnxSegmenter({str(GENERALIST)!r}); read_metadata({str(GENERALIST)!r}); "
            "print('onnx' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, check=True)
    assert out.stdout.strip() == "False"


def test_metadata_same_as_the_onnx_package() -> None:
    via_ort = read_metadata(GENERALIST)
    assert via_ort == read_metadata(load_onnx(GENERALIST))
    assert OnnxSegmenter(GENERALIST).metadata == via_ort
    assert {"classes", "input_height", "input_width", "localize"} <= set(via_ort)


def test_not_a_model_named(tmp_path: Path) -> None:
    bad = tmp_path / "segnet.onnx"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    with pytest.raises(ValueError, match=rf"{bad} is not an ONNX model"):
        read_metadata(bad)
    with pytest.raises(FileNotFoundError, match="not found"):
        read_metadata(tmp_path / "none.onnx")
