"""onnxruntime helpers shared by export and prediction (no torch import here)."""

from __future__ import annotations

import json
from pathlib import Path

import onnx
import onnxruntime as ort

INPUT_NAME = "image"
OUTPUT_NAME = "logits"
LABELS_NAME = "labels"
#: The model folder's file of the localize settings its model is tuned for (beside segnet.onnx).
LOCALIZE_SETTINGS_NAME = "localize.yaml"
#: The metadata key of the same settings in the ONNX file (a JSON object).
LOCALIZE_METADATA_KEY = "localize"


def load_onnx(path: str | Path) -> onnx.ModelProto:
    """Read an ONNX model file (its external data not loaded), refusing other files.

    Raises:
        FileNotFoundError: there is no such file.
        ValueError: the file is not an ONNX model (names it and what to pass instead).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"ONNX model not found: {path}. Train and export one with "
                                "`python -m train`.")
    try:
        proto = onnx.load(str(path), load_external_data=False)
        reason = "" if len(proto.graph.node) else "no graph in it"
    except Exception as err:  # protobuf's DecodeError and friends: not a serialized ModelProto
        reason = f"{type(err).__name__}: {err}"
    if reason:
        raise ValueError(
            f"{path} is not an ONNX model ({reason}). Give the segnet.onnx (or segnet_int8.onnx) "
            "of a model folder written by `python -m train`, e.g. "
            "onnx_model=outputs/models/demo/segnet.onnx")
    return proto


def add_label_output(proto: onnx.ModelProto) -> onnx.ModelProto:
    """Append a ``labels`` output, the argmax class of ``logits`` per pixel, to a SegNet graph.

    (N, C, H, W) float32 logits -> (N, H, W) uint8 labels (ArgMax over C, the first class
    winning a tie, as ``numpy.argmax``; then Cast). onnxruntime's ArgMax takes 0.35 ms on a
    320x240 frame of 8 classes where ``numpy.argmax(axis=0)`` takes 2.1 ms (a strided
    reduction), and the localizer reads labels only. Modifies and returns ``proto``.
    """
    graph = proto.graph
    if any(o.name == LABELS_NAME for o in graph.output):
        return proto
    logits = next((o for o in graph.output if o.name == OUTPUT_NAME), None)
    if logits is None:
        raise ValueError(f"the graph has no {OUTPUT_NAME!r} output to take labels from")
    dims = logits.type.tensor_type.shape.dim
    shape = [d.dim_param or d.dim_value for i, d in enumerate(dims) if i != 1]
    graph.node.extend([
        onnx.helper.make_node("ArgMax", [OUTPUT_NAME], ["labels_int64"], axis=1, keepdims=0,
                              select_last_index=0),
        onnx.helper.make_node("Cast", ["labels_int64"], [LABELS_NAME],
                              to=onnx.TensorProto.UINT8),
    ])
    graph.output.append(
        onnx.helper.make_tensor_value_info(LABELS_NAME, onnx.TensorProto.UINT8, shape))
    return proto


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
        model = load_onnx(model)
    out = {}
    for p in model.metadata_props:
        try:
            out[p.key] = json.loads(p.value)
        except json.JSONDecodeError:
            out[p.key] = p.value
    return out


def model_localize_settings(onnx_path: str | Path) -> tuple[dict, str | None]:
    """The localize settings a model carries (``python -m train``'s ``localize`` key).

    From the model folder's ``localize.yaml`` beside the file (shared by segnet.onnx and its
    int8 copy), else from the file's metadata key ``localize``.

    Args:
        onnx_path: a segnet.onnx (or its int8 copy).

    Returns:
        The settings, nested as in conf/localize.yaml ({} when the model carries none, or the
        file does not exist), and where they were read (None when nowhere).
    """
    import yaml

    onnx_path = Path(onnx_path)
    folder_file = onnx_path.parent / LOCALIZE_SETTINGS_NAME
    if folder_file.is_file():
        settings = yaml.safe_load(folder_file.read_text()) or {}
        source = str(folder_file)
    elif onnx_path.is_file():
        settings = read_metadata(onnx_path).get(LOCALIZE_METADATA_KEY) or {}
        source = f"{onnx_path} (metadata key {LOCALIZE_METADATA_KEY!r})"
    else:
        return {}, None
    if not isinstance(settings, dict):
        raise ValueError(f"{source}: the localize settings must be a mapping of "
                         f"conf/localize.yaml keys, got {settings!r}; re-train or fix the file")
    return settings, source
