"""onnxruntime helpers shared by export and prediction (no torch import here)."""

from __future__ import annotations

import json
from pathlib import Path

import onnx
import onnxruntime as ort

INPUT_NAME = "image"
OUTPUT_NAME = "logits"


def ort_session(model: str | Path | bytes, threads: int = 2) -> ort.InferenceSession:
    """An onnxruntime CPU session with all graph optimizations and ``threads`` intra-op threads.

    Args:
        model: path of an .onnx file or its serialized bytes.
        threads: intra-op threads (inter-op is 1: the graph is a chain).
    """
    so = ort.SessionOptions()
    so.intra_op_num_threads = int(threads)
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.log_severity_level = 3
    # Idle worker threads would otherwise spin for a while after each run, taking the cores from
    # the caller's next step (the localizer's edge maps and filter).
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    src = model if isinstance(model, bytes) else str(model)
    return ort.InferenceSession(src, so, providers=["CPUExecutionProvider"])


def read_metadata(model: onnx.ModelProto | str | Path) -> dict:
    """Decoded metadata_props of an ONNX file or model (JSON values parsed)."""
    if not isinstance(model, onnx.ModelProto):
        model = onnx.load(str(model), load_external_data=False)
    out = {}
    for p in model.metadata_props:
        try:
            out[p.key] = json.loads(p.value)
        except json.JSONDecodeError:
            out[p.key] = p.value
    return out
