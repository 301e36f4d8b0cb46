"""An int8 copy of a segnet.onnx: onnxruntime's static quantization, checked on the test split.

onnxruntime quantizes the graph (QDQ format): the convolutions' weights to int8 per output
channel, their inputs and outputs to uint8 with ranges calibrated on training images (the
largest and smallest value each activation takes on them). onnxruntime then runs the
convolutions as int8 kernels, which a CPU with AVX512-VNNI (or AVX-VNNI, ARM's dot product)
runs several times faster than float ones; the graph's input and output stay float32, so
the file is a drop-in replacement for ``segnet.onnx`` (``core.segmenter.OnnxSegmenter``,
``python -m localize onnx_model=...``). The metadata is copied, with ``quantization`` added.

What it costs is measured, not assumed: both graphs segment the test split and the file's
``quantize.json`` gives their pixel accuracy and mean IoU, and how many pixels change label.

Command line::

    python -m train.deploy.quantize outputs/models/demo [--calibration 64] [--dataset DIR]

writes ``outputs/models/demo/segnet_int8.onnx`` and ``quantize.json`` (docs/train.md).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import onnx
import torch
from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process
from tqdm import tqdm

from core.atomic import atomic_write, atomic_write_json, file_sha256, read_png
from core.config import user_errors
from core.dataset import open_datasets
from core.segmenter import (
    INPUT_NAME,
    INT8_NAME,
    QUANTIZE_REPORT,
    OnnxSegmenter,
    network_input,
    read_metadata,
)
from train.config import ExportConfig
from train.metrics import confusion_matrix, metrics_json

REPORT_NAME = QUANTIZE_REPORT
#: Prefix of the work folder a quantization makes in the model folder (``.quantize.<pid>.*``).
WORK_PREFIX = ".quantize."
#: ops quantized by default: every one onnxruntime can (None); the convolutions alone change
#: more labels (docs/notes/experiments.md)
OP_TYPES: tuple[str, ...] | None = None


#: training images whose activation ranges set the int8 scales (``export.int8_calibration``)
CALIBRATION = ExportConfig.int8_calibration


def spread_indices(total: int, n: int) -> np.ndarray:
    """``n`` indices spread evenly over ``range(total)`` (all of them when n >= total).

    Returns:
        (min(n, total),) int64, increasing.
    """
    if total <= 0:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.linspace(0, total - 1, max(1, min(int(n), total))).round().astype(np.int64))


def read_images(paths: list[Path]) -> np.ndarray:
    """(N, H, W, 3) uint8 RGB images."""
    return np.stack([read_png(p) for p in paths])


class _Frames(CalibrationDataReader):
    """onnxruntime's CalibrationDataReader over (N, H, W, 3) uint8 frames, one at a time."""

    def __init__(self, images: np.ndarray) -> None:
        self.images = images
        self.i = 0

    def get_next(self) -> dict | None:
        if self.i >= len(self.images):
            return None
        x = network_input(self.images[self.i : self.i + 1])
        self.i += 1
        return {INPUT_NAME: x}

    def rewind(self) -> None:
        self.i = 0


#: exporter scopes (node ``namespace`` metadata) left in float: the pooling codes compare a
#: window's values with its maximum exactly, which quantized copies of the two would not
FLOAT_SCOPES = ("WindowMaxPool", "WindowMaxUnpool")


def float_nodes(proto: onnx.ModelProto, scopes: tuple[str, ...] = FLOAT_SCOPES) -> list[str]:
    """Names of the nodes exported from inside the modules ``scopes`` (class names)."""
    return [n.name for n in proto.graph.node
            if any(p.key == "namespace" and any(s in p.value for s in scopes)
                   for p in n.metadata_props)]


def quantize_segnet(src: str | Path, dst: str | Path, calibration: np.ndarray,
                    op_types: tuple[str, ...] | None = OP_TYPES) -> dict:
    """Write an int8 copy of ``src`` to ``dst`` (atomically; the metadata copied).

    Args:
        src: a segnet.onnx (float32) written by ``python -m train``.
        dst: the int8 file to write.
        calibration: (N, H, W, 3) uint8 RGB frames of the graph's input size whose activation
            ranges set the uint8 scales (training images: not the test split).
        op_types: ONNX op types to quantize (None: all that onnxruntime can).

    Returns:
        The ``quantization`` metadata entry written into ``dst``.
    """
    src, dst = Path(src), Path(dst)
    src_proto = onnx.load(str(src), load_external_data=False)
    meta = read_metadata(src_proto)
    h, w = int(meta["input_height"]), int(meta["input_width"])
    if calibration.ndim != 4 or calibration.shape[1:] != (h, w, 3) or len(calibration) == 0:
        raise ValueError(f"calibration frames must be (N >= 1, {h}, {w}, 3) uint8 for {src}, got "
                         f"{calibration.shape}")
    reader = _Frames(calibration)
    info = {"format": "QDQ", "weights": "int8 per channel", "activations": "uint8",
            "calibration": "minmax", "calibration_images": int(len(calibration)),
            "op_types": "all" if op_types is None else list(op_types),
            "float_scopes": list(FLOAT_SCOPES)}
    remove_stale_work_dirs(dst.parent)
    with tempfile.TemporaryDirectory(prefix=f"{WORK_PREFIX}{os.getpid()}.", dir=dst.parent) as tmp:
        pre = Path(tmp) / "pre.onnx"
        out = Path(tmp) / "int8.onnx"
        quant_pre_process(str(src), str(pre), skip_symbolic_shape=True)
        keep_float = float_nodes(onnx.load(str(pre), load_external_data=False))
        quantize_static(str(pre), str(out), reader, quant_format=QuantFormat.QDQ,
                        op_types_to_quantize=None if op_types is None else list(op_types),
                        nodes_to_exclude=keep_float,
                        per_channel=True,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8)
        proto = onnx.load(str(out))
    props = {p.key: p.value for p in src_proto.metadata_props}
    props["quantization"] = json.dumps(info)
    onnx.helper.set_model_props(proto, props)
    atomic_write(dst, lambda p: onnx.save(proto, str(p)))
    return info


def remove_stale_work_dirs(folder: str | Path) -> list[Path]:
    """Delete the work folders (``.quantize.<pid>.*``) in ``folder`` whose process is gone: a
    killed quantization cannot remove its own. Those of live processes are kept.

    Returns:
        The folders removed.
    """
    stale = [d for d in Path(folder).glob(f"{WORK_PREFIX}*")
             if d.is_dir() and not _alive(d.name[len(WORK_PREFIX):].split(".")[0])]
    for d in stale:
        shutil.rmtree(d, ignore_errors=True)
    return stale


def _alive(pid: str) -> bool:
    """Whether process ``pid`` (text) runs; a name that is no pid counts as dead."""
    if not pid.isdigit():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def compare_on_split(fp32: str | Path, int8: str | Path, rgb_paths: list[Path],
                     label_paths: list[Path], threads: int = 2, batch_size: int = 8,
                     progress: bool = False) -> dict:
    """Test scores of the float and the int8 graph on the same frames (networks alone).

    Returns:
        ``{"fp32": metrics_json, "int8": metrics_json, "label_agreement": fraction of pixels
        both give the same label, "images": N}``.
    """
    a = OnnxSegmenter(fp32, threads=threads)
    b = OnnxSegmenter(int8, threads=threads)
    c = a.num_classes
    cms = [torch.zeros((c, c), dtype=torch.int64), torch.zeros((c, c), dtype=torch.int64)]
    same = total = 0
    for i in tqdm(range(0, len(rgb_paths), batch_size), desc="compare", disable=not progress):
        rgb = read_images(rgb_paths[i : i + batch_size])
        truth = torch.from_numpy(
            np.stack([read_png(p, rgb=False) for p in label_paths[i : i + batch_size]]))
        preds = (a.labels(rgb), b.labels(rgb))
        for cm, pred in zip(cms, preds, strict=True):
            cm += confusion_matrix(torch.from_numpy(pred), truth, c)
        same += int((preds[0] == preds[1]).sum())
        total += preds[0].size
    names = [cl["name"] for cl in a.classes]
    return {"fp32": metrics_json(cms[0], names), "int8": metrics_json(cms[1], names),
            "label_agreement": same / max(total, 1), "images": len(rgb_paths)}


def int8_summary(report: dict) -> dict:
    """The ``int8`` entry of a model's metrics.json from a quantize.json report: the share of
    labels equal to the float graph's and the int8 graph's test pixel accuracy and mean IoU."""
    return {"label_agreement": report["label_agreement"],
            **{k: report["int8"][k] for k in ("pixel_accuracy", "mean_iou")}}


def quantize_model_dir(model_dir: str | Path, dataset: str | Path | None = None,
                       calibration: int = CALIBRATION, test_limit: int | None = None,
                       threads: int = 2, progress: bool = True) -> dict:
    """``segnet_int8.onnx`` and ``quantize.json`` in a model folder of ``python -m train``.

    Args:
        model_dir: holds segnet.onnx and config.json.
        dataset: the dataset (or a glob pattern of datasets) to calibrate on (training
            split) and test on (test split); None: the model's own (config.json).
        calibration: training images for the activation ranges, spread over the split.
        test_limit: compare on the first N test images only (None: all).

    Returns:
        The quantize.json contents.
    """
    model_dir = Path(model_dir)
    src = model_dir / "segnet.onnx"
    if not src.is_file():
        raise FileNotFoundError(f"{src} not found; train and export a model first "
                                "(`python -m train name=...`)")
    if dataset is None:
        cfg_path = model_dir / "config.json"
        if not cfg_path.is_file():
            raise FileNotFoundError(f"{cfg_path} not found; pass the dataset with --dataset")
        dataset = json.loads(cfg_path.read_text())["dataset"]
    datasets = open_datasets(dataset)
    train_rgb = [p for d in datasets for p in d.split("train")[0]]
    if not train_rgb:
        raise FileNotFoundError(f"{dataset} has no training images to calibrate on; finish "
                                "the dataset with `python -m datagen`")
    chosen = [train_rgb[i] for i in spread_indices(len(train_rgb), calibration)]
    dst = model_dir / INT8_NAME
    info = quantize_segnet(src, dst, read_images(chosen))
    tests = [d.split("test") for d in datasets]  # (rgb paths, label paths) of each
    test_rgb = [p for rgb, _ in tests for p in rgb][:test_limit]
    test_label = [p for _, labels in tests for p in labels][:test_limit]
    report = {"model": src.name, "model_sha256": file_sha256(src), "int8_model": dst.name,
              "dataset": str(dataset), "quantization": info}
    report.update(compare_on_split(src, dst, test_rgb, test_label, threads, progress=progress))
    atomic_write_json(model_dir / REPORT_NAME, report)
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model_dir", help="a model folder of `python -m train` (outputs/models/NAME)")
    ap.add_argument("--dataset", default=None, help="default: the model's training dataset")
    ap.add_argument("--calibration", type=int, default=CALIBRATION,
                    help="training images to calibrate on")
    ap.add_argument("--test-limit", type=int, default=None, help="test images to compare on")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    r = quantize_model_dir(args.model_dir, args.dataset, args.calibration, args.test_limit,
                           args.threads)
    for k in ("fp32", "int8"):
        print(f"{k}: test pixel acc {r[k]['pixel_accuracy']:.4f}, mIoU {r[k]['mean_iou']:.4f}")
    print(f"labels equal on {100 * r['label_agreement']:.2f} % of pixels ({r['images']} images)")
    print(f"int8 model: {Path(args.model_dir) / r['int8_model']}")
    return 0


if __name__ == "__main__":
    with user_errors():
        raise SystemExit(main())
