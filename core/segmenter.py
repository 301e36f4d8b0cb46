"""The ONNX SegNet runtime every stage shares: reading a ``segnet.onnx`` and its metadata, an
onnxruntime session, and ``OnnxSegmenter``, per-pixel classes of RGB frames (no torch import;
the ``onnx`` package, 1.5 s of imports, only where a caller asks for the ``ModelProto``).

API::

    seg = OnnxSegmenter("outputs/models/demo/segnet.onnx", threads=2)
    labels, probs = seg.predict(rgb)        # rgb (H, W, 3) uint8 -> (H, W) uint8, (C, H, W)
    labels, probs = seg.predict(batch)      # (N, H, W, 3) uint8 -> (N, H, W), (N, C, H, W)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import onnxruntime as ort

if TYPE_CHECKING:
    import onnx

#: The int8 copy of a segnet.onnx and its report, beside it (``train.deploy.quantize``).
INT8_NAME = "segnet_int8.onnx"
QUANTIZE_REPORT = "quantize.json"
INPUT_NAME = "image"
OUTPUT_NAME = "logits"
LABELS_NAME = "labels"


def _not_onnx(path: Path, reason: str) -> ValueError:
    return ValueError(
        f"{path} is not an ONNX model ({reason}). Give the segnet.onnx (or segnet_int8.onnx) "
        "of a model folder written by `python -m train`, e.g. "
        "onnx_model=outputs/models/demo/segnet.onnx")


def _require_file(path: Path) -> None:
    if not path.is_file():
        raise FileNotFoundError(f"ONNX model not found: {path}. Train and export one with "
                                "`python -m train`.")


def load_onnx(path: str | Path) -> onnx.ModelProto:
    """Read an ONNX model file (its external data not loaded), refusing other files.

    Raises:
        FileNotFoundError: there is no such file.
        ValueError: the file is not an ONNX model (names it and what to pass instead).
    """
    import onnx

    path = Path(path)
    _require_file(path)
    try:
        proto = onnx.load(str(path), load_external_data=False)
        reason = "" if len(proto.graph.node) else "no graph in it"
    except Exception as err:  # protobuf's DecodeError and friends: not a serialized ModelProto
        reason = f"{type(err).__name__}: {err}"
    if reason:
        raise _not_onnx(path, reason)
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
    return _session(model, so)


def _session(model: str | Path | bytes, so: ort.SessionOptions) -> ort.InferenceSession:
    """``ort.InferenceSession``; a path that is not a file or not an ONNX model raises
    FileNotFoundError or ValueError naming it."""
    if isinstance(model, bytes):
        return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])
    path = Path(model)
    _require_file(path)
    try:
        return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])
    except Exception as err:  # onnxruntime's InvalidProtobuf, Fail, InvalidGraph
        raise _not_onnx(path, f"{type(err).__name__}: {err}".strip()) from None


def read_metadata(model: onnx.ModelProto | str | Path) -> dict:
    """Decoded metadata_props of an ONNX file or model (JSON values parsed).

    A file is read by onnxruntime with no graph optimization (~0.1 s), not the onnx package.
    """
    if hasattr(model, "metadata_props"):
        props = {p.key: p.value for p in model.metadata_props}
    else:
        so = ort.SessionOptions()
        so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
        so.log_severity_level = 3
        props = _session(model, so).get_modelmeta().custom_metadata_map
    return _decoded(props)


def _decoded(props: dict[str, str]) -> dict:
    out = {}
    for key, value in props.items():
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def network_input(batch: np.ndarray) -> np.ndarray:
    """The graph's ``image`` input of RGB frames: (N, H, W, 3) uint8 -> (N, 3, H, W) float32 in
    [0, 1], contiguous (shape and dtype are the caller's to check)."""
    x = np.ascontiguousarray(batch.transpose(0, 3, 1, 2), dtype=np.float32)
    x *= np.float32(1.0 / 255.0)
    return x


class OnnxSegmenter:
    """Per-pixel classes from segnet.onnx.

    The graph normalizes and pads internally, so this class only converts uint8 (H, W, 3)
    images to float32 (N, 3, H, W) in [0, 1]. Images must have the size recorded in the
    file's metadata (``input_height`` x ``input_width``, the dataset camera's size); other
    sizes raise ValueError (resize them first, e.g. ``cv2.resize(..., INTER_AREA)``).

    Args:
        path: segnet.onnx written by ``python -m train``.
        threads: onnxruntime intra-op threads.

    Attributes:
        classes: the class list (dicts with id, name, color, structural).
        num_classes: C.
        structural_ids: (S,) int ids of the structural classes.
        input_size: (H, W) the graph expects.
        metadata: all decoded metadata.
    """

    def __init__(self, path: str | Path, threads: int = 2) -> None:
        path = Path(path)
        # a missing or non-ONNX file: an error that names it
        self.session = ort_session(path, threads)
        self.metadata = _decoded(self.session.get_modelmeta().custom_metadata_map)
        for key in ("classes", "input_height", "input_width"):
            if key not in self.metadata:
                raise ValueError(
                    f"{path}: metadata key {key!r} missing; re-export the model "
                    f"with `python -m train`"
                )
        self.path = path
        self.classes: list[dict] = list(self.metadata["classes"])
        self.num_classes = len(self.classes)
        self.structural_ids = np.array(
            [c["id"] for c in self.classes if c.get("structural")], dtype=np.int64
        )
        self.input_size = (int(self.metadata["input_height"]), int(self.metadata["input_width"]))
        outputs = {o.name: o for o in self.session.get_outputs()}
        if OUTPUT_NAME not in outputs:
            raise ValueError(f"{path}: the graph has no {OUTPUT_NAME!r} output; re-export the "
                             "model with `python -m train`")
        # graphs exported since e9222ac (2026-11-27) also give the argmax, faster than numpy's
        self.has_labels_output = LABELS_NAME in outputs
        out_shape = outputs[OUTPUT_NAME].shape
        if isinstance(out_shape[1], int) and out_shape[1] != self.num_classes:
            raise ValueError(
                f"{path}: graph outputs {out_shape[1]} classes but the metadata "
                f"lists {self.num_classes}; re-export the model"
            )
        self._palette = np.full((256, 3), 255, dtype=np.uint8)
        for c in self.classes:
            self._palette[int(c["id"])] = c["color"]

    def _to_input(self, rgb: np.ndarray) -> tuple[np.ndarray, bool]:
        single = rgb.ndim == 3
        batch = rgb[None] if single else rgb
        if batch.ndim != 4 or batch.shape[-1] != 3:
            raise ValueError(
                f"expected an (H, W, 3) image or (N, H, W, 3) batch, got shape {rgb.shape}"
            )
        if batch.dtype != np.uint8:
            raise ValueError(f"expected uint8 RGB, got {batch.dtype}")
        if batch.shape[1:3] != self.input_size:
            h, w = self.input_size
            raise ValueError(
                f"image size {batch.shape[2]}x{batch.shape[1]} (WxH) differs from the model's "
                f"input {w}x{h} ({self.path}); resize the image to {w}x{h} first."
            )
        return network_input(batch), single

    def logits(self, rgb: np.ndarray) -> np.ndarray:
        """The network's logits.

        Args:
            rgb: (H, W, 3) or (N, H, W, 3) uint8 RGB.

        Returns:
            (C, H, W) or (N, C, H, W) float32.
        """
        x, single = self._to_input(rgb)
        out = self.session.run([OUTPUT_NAME], {INPUT_NAME: x})[0]
        return out[0] if single else out

    def logits_and_labels(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``logits(rgb)`` and ``labels(rgb)`` from one run of the graph.

        Returns:
            (C, H, W) or (N, C, H, W) float32 and (H, W) or (N, H, W) uint8.
        """
        if not self.has_labels_output:
            z = self.logits(rgb)
            return z, z.argmax(0 if z.ndim == 3 else 1).astype(np.uint8)
        x, single = self._to_input(rgb)
        z, labels = self.session.run([OUTPUT_NAME, LABELS_NAME], {INPUT_NAME: x})
        return (z[0], labels[0]) if single else (z, labels)

    def labels(self, rgb: np.ndarray) -> np.ndarray:
        """Class labels only (no softmax): (H, W, 3) or (N, H, W, 3) uint8 RGB ->
        (H, W) or (N, H, W) uint8. The graph's own ``labels`` output where it has one, else
        the argmax of ``logits``."""
        if not self.has_labels_output:
            return self.logits_and_labels(rgb)[1]
        x, single = self._to_input(rgb)
        out = self.session.run([LABELS_NAME], {INPUT_NAME: x})[0]  # the logits not copied out
        return out[0] if single else out

    def predict(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Class labels and softmax probabilities.

        Args:
            rgb: (H, W, 3) or (N, H, W, 3) uint8 RGB.

        Returns:
            labels (H, W) or (N, H, W) uint8 and probs (C, H, W) or (N, C, H, W) float32.
        """
        z = self.logits(rgb)
        axis = 0 if z.ndim == 3 else 1
        labels = z.argmax(axis).astype(np.uint8)
        z = z - z.max(axis, keepdims=True)
        np.exp(z, out=z)
        z /= z.sum(axis, keepdims=True)
        return labels, z

    def colorize(self, labels: np.ndarray) -> np.ndarray:
        """(..., H, W) uint8 labels -> (..., H, W, 3) uint8 colours of the metadata's classes."""
        return self._palette[labels]

    def overlay(self, rgb: np.ndarray, labels: np.ndarray, alpha: float = 0.5) -> np.ndarray:
        """Blend class colours over an image: (H, W, 3) uint8."""
        blend = (1.0 - alpha) * rgb.astype(np.float32) + alpha * self.colorize(labels)
        return np.clip(blend + 0.5, 0, 255).astype(np.uint8)
