"""ONNX export of a SegNet (or LR-ASPP) with metadata, checked against torch with onnxruntime.

The graph takes ``image`` (N, 3, H, W) float32 in [0, 1] and gives ``logits`` (N, C, H, W)
and ``labels`` (N, H, W) uint8, their argmax (``add_label_output``); the batch
size is dynamic, H and W are fixed to the size given at export (the dataset's camera size).
Normalization and the padding to a multiple of ``2 ** stages`` happen inside the graph, so a
consumer feeds plain [0, 1] images of the exported size. Metadata (``metadata_props``,
every value a JSON string): classes, input_height, input_width, normalization, padding,
model, config_hash.

Pooling in the graph: the encoder's max-pooling indices are kept as window-local codes
(``train.net.window_pool.WindowMaxPool``) and unpooled with masks and DepthToSpace, which computes
exactly what ``nn.MaxPool2d(return_indices=True)`` + ``nn.MaxUnpool2d`` compute (the torch
network's pooling) and runs about twice as fast in onnxruntime. ``external_data=False`` keeps
the weights inside the one file.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import onnx
import torch
from torch import nn

from core.atomic import atomic_write
from core.segmenter import INPUT_NAME, LABELS_NAME, OUTPUT_NAME, ort_session
from train.config import ExportConfig
from train.net.segnet import SegNet

OPSET = ExportConfig.opset
#: How the exported graph pools (``train.net.window_pool.WindowMaxPool``).
GRAPH_POOLING = "window"


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


class ParityError(RuntimeError):
    """onnxruntime and torch disagree by more than the tolerance; ``report`` has the figures."""

    def __init__(self, message: str, report: ParityReport) -> None:
        super().__init__(message)
        self.report = report


@dataclass
class ParityReport:
    """How closely onnxruntime reproduces torch on a set of images.

    Attributes:
        max_abs_diff: max |logits_onnx - logits_torch| over all images, classes and pixels,
            with both runtimes using the same max-pooling choices (see ``pool_index_flips``).
        raw_max_abs_diff: the same without aligning pooling choices.
        pool_index_flips: pooling windows where onnxruntime picked another maximum than torch.
            Such a flip happens only where two window values differ by float rounding
            (``max_flip_gap``); it moves one decoder value by a pixel, so the raw difference can
            exceed the tolerance although the graph is right.
        max_flip_gap: largest |a - b| in torch between the two values a flipped window chose.
        label_agreement: fraction of pixels with the same argmax class.
        labels_output_mismatch: pixels where the graph's ``labels`` output differs from the
            argmax of its own logits (0 for a correct graph; -1: no such output).
        images: number of images compared.
    """

    max_abs_diff: float
    raw_max_abs_diff: float
    pool_index_flips: int = 0
    max_flip_gap: float = 0.0
    label_agreement: float = 1.0
    labels_output_mismatch: int = -1
    images: int = 0
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {
            "max_abs_diff": self.max_abs_diff,
            "raw_max_abs_diff": self.raw_max_abs_diff,
            "pool_index_flips": self.pool_index_flips,
            "max_flip_gap": self.max_flip_gap,
            "label_agreement": self.label_agreement,
            "labels_output_mismatch": self.labels_output_mismatch,
            "images": self.images,
            "notes": self.notes,
        }


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[None]:
    """Silence the exporter's chatter (onnx_ir warnings about empty attributes, etc.)."""
    names = ("onnx_ir", "onnxscript", "torch.onnx", "torch.export", "torch._dynamo")
    loggers = [logging.getLogger(n) for n in names]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        for lg, lvl in zip(loggers, levels, strict=True):
            lg.setLevel(lvl)


class _WithIndices(nn.Module):
    """Graph that also outputs the pooling indices (used only by the parity check)."""

    def __init__(self, model: SegNet) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        logits, idx = self.model.forward_with_indices(x)
        return (logits, *idx)


def to_onnx_proto(
    module: nn.Module,
    height: int,
    width: int,
    output_names: Sequence[str] = (OUTPUT_NAME,),
    opset: int = OPSET,
) -> onnx.ModelProto:
    """Export a module taking (N, 3, H, W) images with the dynamo exporter, dynamic batch.

    Args:
        module: the network, put in eval mode here.
        height, width: the fixed input size H, W.
        output_names: names of the graph outputs.
        opset: ONNX opset.

    Returns:
        The ONNX model (weights embedded).
    """
    module = module.eval()
    example = torch.rand(2, 3, height, width, generator=torch.Generator().manual_seed(0))
    batch = torch.export.Dim("batch", min=1, max=4096)
    with _quiet_exporter():
        program = torch.onnx.export(
            module,
            (example,),
            dynamo=True,
            external_data=False,
            input_names=[INPUT_NAME],
            output_names=list(output_names),
            dynamic_shapes=({0: batch},),
            opset_version=opset,
            optimize=True,
            verbose=False,
        )
    return program.model_proto


def onnx_metadata(
    model: SegNet,
    classes: Sequence[dict],
    height: int,
    width: int,
    config_hash: str,
    extra: dict | None = None,
) -> dict[str, str]:
    """The metadata_props of segnet.onnx; every value is a JSON string.

    Args:
        model: the exported network (for normalization, padding, its ``describe()``).
        classes: dataset.json's class list (id, name, color, structural).
        height, width: the graph's input size.
        config_hash: hash of the training config and dataset (see train.run_identity.config_hash).
        extra: more keys to record (values are JSON-encoded).
    """
    meta = {
        "classes": list(classes),
        "input_height": int(height),
        "input_width": int(width),
        "input_name": INPUT_NAME,
        "output_name": OUTPUT_NAME,
        "normalization": {
            "input_range": [0.0, 1.0],
            "mean": model.mean.flatten().tolist(),
            "std": model.std.flatten().tolist(),
            "applied_in_graph": True,
            "note": "feed RGB float32 in [0, 1]; the graph computes (x - mean) / std",
        },
        "padding": {
            "multiple": model.multiple,
            "mode": "reflect",
            "where": "bottom/right",
            "applied_in_graph": True,
            "note": "the graph pads to a multiple and crops the logits back to the input size",
        },
        "model": model.describe(),
        "config_hash": config_hash,
    }
    meta.update(extra or {})
    return {k: json.dumps(v) for k, v in meta.items()}


def _chunks(n: int, size: int) -> Iterator[slice]:
    for i in range(0, n, size):
        yield slice(i, min(i + size, n))


@torch.inference_mode()
def check_parity(
    model: SegNet,
    onnx_model: onnx.ModelProto,
    images: torch.Tensor,
    threads: int = 2,
    batch_size: int = 4,
    exported: SegNet | None = None,
) -> ParityReport:
    """Compare onnxruntime with torch on images, in batches of varying size.

    First the raw logits are compared. Where they differ by more than 1e-4, a second graph
    that also outputs the pooling indices is exported and run, torch is re-run with
    onnxruntime's indices, and the difference is measured again with the pooling choices
    aligned; the flipped windows are counted and their value gap measured, so a genuine
    export error (large gap or large aligned difference) is told apart from float rounding.

    Args:
        model: the torch network.
        onnx_model: its export (input ``image``, output ``logits``).
        images: (N, 3, H, W) float32 in [0, 1], H and W the exported size.
        threads: onnxruntime intra-op threads.
        batch_size: largest batch; the last batch may be smaller (checks the dynamic batch).
        exported: the module that was exported, if not ``model`` itself (e.g. ``model`` with
            window pooling); used for the graph with pooling indices.

    Returns:
        The parity figures.
    """
    model = model.eval()
    sess = ort_session(onnx_model.SerializeToString(), threads)
    names = [OUTPUT_NAME] + [o.name for o in sess.get_outputs() if o.name == LABELS_NAME]
    n = images.shape[0]
    raw = 0.0
    agree = 0
    mismatch = 0 if len(names) > 1 else -1
    for sl in _chunks(n, batch_size):
        x = images[sl].contiguous()
        ref = model(x)
        out, *labels = sess.run(names, {INPUT_NAME: x.numpy()})
        raw = max(raw, float(np.abs(out - ref.numpy()).max()))
        agree += int((out.argmax(1) == ref.argmax(1).numpy()).sum())
        if labels:
            mismatch += int((labels[0] != out.argmax(1)).sum())
    report = ParityReport(
        max_abs_diff=raw,
        raw_max_abs_diff=raw,
        images=n,
        label_agreement=agree / float(images[:, 0].numel()),
        labels_output_mismatch=mismatch,
    )
    if raw <= 1e-4 or not isinstance(model, SegNet):  # only a SegNet has pooling choices
        return report
    return _align_pooling(model, sess, images, report, threads, batch_size, exported)


def _align_pooling(model: SegNet, sess, images: torch.Tensor, report: ParityReport,
                   threads: int, batch_size: int, exported: SegNet | None) -> ParityReport:
    """``check_parity``'s second pass: torch re-run with onnxruntime's pooling choices, the
    flipped windows counted and their value gap measured; ``report`` updated and returned."""
    n, raw = images.shape[0], report.raw_max_abs_diff
    h, w = images.shape[-2:]
    aux = to_onnx_proto(
        _WithIndices(exported or model),
        h,
        w,
        output_names=[OUTPUT_NAME] + [f"pool{k}" for k in range(model.stages)],
    )
    aux_sess = ort_session(aux.SerializeToString(), threads)
    aligned, flips, gap = 0.0, 0, 0.0
    for sl in _chunks(n, batch_size):
        x = images[sl].contiguous()
        outs = aux_sess.run(None, {INPUT_NAME: x.numpy()})
        main = sess.run([OUTPUT_NAME], {INPUT_NAME: x.numpy()})[0]
        ort_idx = [torch.from_numpy(o) for o in outs[1:]]
        ref_logits, _ = model.forward_with_indices(x, ort_idx)
        aligned = max(
            aligned,
            float(np.abs(outs[0] - ref_logits.numpy()).max()),
            float(np.abs(main - outs[0]).max()),
        )
        flips_b, gap_b = _flip_gaps(model, x, ort_idx)
        flips += flips_b
        gap = max(gap, gap_b)
    report.max_abs_diff = aligned
    report.pool_index_flips = flips
    report.max_flip_gap = gap
    report.notes.append(
        f"raw difference {raw:.2e} > 1e-4 explained by {flips} pooling windows where the two "
        f"runtimes picked different maxima (values within {gap:.1e}); with aligned pooling "
        f"choices the difference is {aligned:.2e}"
    )
    return report


def _flip_gaps(model: SegNet, x: torch.Tensor, ort_idx: list[torch.Tensor]) -> tuple[int, float]:
    """Count windows whose pooling index differs and the value gap there (torch, ORT indices).

    Stage k's features are recomputed in torch with onnxruntime's indices imposed on stages
    before k, so both indices refer to the same feature map.
    """
    flips, gap = 0, 0.0
    for k in range(model.stages):
        feats = _stage_features(model, x, ort_idx[:k], k)
        a = feats.flatten(2).gather(2, ort_idx[k].flatten(2))
        _, idx_k = nn.functional.max_pool2d(feats, 2, 2, return_indices=True)
        b = feats.flatten(2).gather(2, idx_k.flatten(2))
        diff = idx_k.flatten(2) != ort_idx[k].flatten(2)
        flips += int(diff.sum())
        if diff.any():
            gap = max(gap, float((a - b).abs()[diff].max()))
    return flips, gap


def _stage_features(
    model: SegNet, x: torch.Tensor, imposed: list[torch.Tensor], k: int
) -> torch.Tensor:
    """Encoder features of stage k before pooling, with given indices for stages < k."""
    x, _ = model.preprocess(x)
    for j, stage in enumerate(model.encoder):
        x = stage(x)
        if j == k:
            return x
        idx = imposed[j]
        x = x.flatten(2).gather(2, idx.flatten(2)).view(idx.shape)
    raise IndexError(k)


def graph_module(model: nn.Module) -> nn.Module:
    """What is exported of a network: a SegNet pooling by window codes (``GRAPH_POOLING``, a
    copy), LR-ASPP as it is."""
    if isinstance(model, SegNet):
        return copy.deepcopy(model).set_pooling(GRAPH_POOLING)
    return model


def export_checked(
    model: SegNet,
    path: str | Path,
    images: torch.Tensor,
    metadata: dict[str, str],
    tolerance: float = ExportConfig.tolerance,
    threads: int = 2,
    batch_size: int = ExportConfig.batch_size,
    opset: int = OPSET,
) -> ParityReport:
    """Export ``model`` to ``path`` (one file), then check it with onnxruntime.

    The file is written only if the parity check passes (max_abs_diff <= tolerance and every
    pooling flip is a rounding-level tie); otherwise ParityError is raised and no file is left.
    The graph pools by window codes (``GRAPH_POOLING``); the check compares it with ``model``
    as it is (usually pooling with indices, the same function).

    Args:
        model: the network in eval mode.
        path: output .onnx path.
        images: (N, 3, H, W) float32 in [0, 1] test images; H, W become the graph's input size.
        metadata: metadata_props (see ``onnx_metadata``).
        tolerance: largest accepted |onnx - torch| on logits.
        threads: onnxruntime threads for the check.
        batch_size: batch size of the check (the last batch may be smaller).
        opset: ONNX opset.

    Returns:
        The parity report.
    """
    if images.ndim != 4 or images.shape[1] != 3 or images.shape[0] < 1:
        raise ValueError(f"parity images must be (N >= 1, 3, H, W), got {tuple(images.shape)}")
    model = model.eval()
    h, w = int(images.shape[2]), int(images.shape[3])
    exported = graph_module(model)
    proto = add_label_output(to_onnx_proto(exported, h, w, opset=opset))
    onnx.helper.set_model_props(proto, metadata)
    onnx.checker.check_model(proto)
    report = check_parity(
        model, proto, images, threads=threads, batch_size=batch_size, exported=exported
    )
    # A flip is float rounding only if the two candidate values are (nearly) equal.
    flip_ok = report.max_flip_gap <= max(tolerance, 1e-5)
    if report.labels_output_mismatch != 0:
        raise ParityError(
            f"ONNX export of {path}: its {LABELS_NAME!r} output differs from the argmax of its "
            f"logits on {report.labels_output_mismatch} pixels. The file was not written.",
            report,
        )
    if report.max_abs_diff > tolerance or not flip_ok:
        raise ParityError(
            f"ONNX export of {path} does not match torch: max |onnx - torch| = "
            f"{report.max_abs_diff:.3e} (raw {report.raw_max_abs_diff:.3e}, tolerance "
            f"{tolerance:.0e}), {report.pool_index_flips} pooling flips with gap up to "
            f"{report.max_flip_gap:.2e}. The file was not written.",
            report,
        )
    data = proto.SerializeToString()
    atomic_write(path, lambda p: p.write_bytes(data))
    return report


def update_metadata(path: str | Path, extra: dict) -> None:
    """Add or replace metadata_props of an ONNX file (values JSON-encoded), atomically; the
    graph is left as it is.

    Args:
        path: the .onnx file.
        extra: keys and values to record (``onnx_metadata``'s convention).
    """
    proto = onnx.load(str(path), load_external_data=False)
    props = {p.key: p.value for p in proto.metadata_props}
    props.update({k: json.dumps(v) for k, v in extra.items()})
    onnx.helper.set_model_props(proto, props)
    data = proto.SerializeToString()
    atomic_write(path, lambda p: p.write_bytes(data))
