"""Re-export a trained model folder's ``segnet.onnx`` with this version's graph, no training.

The exported graph changes between versions while the weights do not (2026-11-27: the faster
window pooling and the ``labels`` output, docs/train.md). This writes the folder's
``checkpoint_best.pt`` out again with the current exporter, keeps the old file's metadata (classes,
size, test metrics, refine settings, class weights), checks onnxruntime against torch on the
first test images of the model's dataset as ``python -m train`` does, and replaces
``segnet.onnx`` only if the check passes. ``metrics.json``'s parity entries are updated; an
int8 copy beside it is made again from the new graph (``train.quantize``).

Command line::

    python -m train.reexport outputs/models/hr3 [--dataset DIR] [--tolerance 3e-4]

Re-running the folder's own ``python -m train ...`` line does the same (it resumes after the
last epoch and exports), but needs that line's exact overrides; this needs only the folder.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import onnx
import torch

from core.atomic import atomic_write_json
from core.dataset import Dataset
from train.data import to_float
from train.export import ParityReport, export_checked
from train.quantize import (
    CALIBRATION,
    INT8_NAME,
    REPORT_NAME,
    int8_summary,
    quantize_model_dir,
    read_images,
)
from train.runtime import read_metadata
from train.train import load_checkpoint

log = logging.getLogger(__name__)

#: test images of the parity check (``export.parity_images`` of conf/train.yaml)
PARITY_IMAGES = 8


def default_tolerance(metrics: dict) -> float:
    """1e-4 (``export.tolerance``'s default), or twice the difference the folder's first export
    measured if that was larger (a fine-tuning exported with a looser ``export.tolerance``):
    the same weights through an equivalent graph differ from torch by the same amount."""
    return max(1e-4, 2.0 * float(metrics.get("onnx_max_abs_diff") or 0.0))


def parity_images(dataset: Dataset, n: int = PARITY_IMAGES) -> torch.Tensor:
    """The first ``n`` test images, (n, 3, H, W) float32 in [0, 1]."""
    rgb_paths, _ = dataset.split("test")
    if not rgb_paths:
        raise FileNotFoundError(f"{dataset.root / 'test'} has no images for the parity check; "
                                "pass another dataset with --dataset")
    images = torch.from_numpy(read_images(rgb_paths[:n])).permute(0, 3, 1, 2)
    return to_float(images)  # as ``python -m train`` makes its parity images


def reexport(model_dir: str | Path, dataset: str | Path | None = None,
             tolerance: float | None = None, threads: int = 2) -> ParityReport:
    """Re-export ``model_dir/segnet.onnx`` from its best checkpoint (see the module docstring).

    Args:
        model_dir: a folder of ``python -m train`` (checkpoint_best.pt, segnet.onnx,
            metrics.json, config.json).
        dataset: where the parity images come from; None: the model's training dataset.
        tolerance: largest accepted |onnx - torch|; None: ``default_tolerance``.
        threads: onnxruntime threads.

    Returns:
        The parity report of the new graph.

    Raises:
        FileNotFoundError: a file the folder should have is missing (says what to run).
        train.export.ParityError: the new graph does not match torch (the old file is kept).
    """
    model_dir = Path(model_dir)
    files = {name: model_dir / name for name in
             ("checkpoint_best.pt", "segnet.onnx", "metrics.json", "config.json")}
    for path in files.values():
        if not path.is_file():
            raise FileNotFoundError(f"{path} not found: {model_dir} is not a finished model "
                                    f"folder; train it with `python -m train name=...`")
    old = onnx.load(str(files["segnet.onnx"]), load_external_data=False)
    metadata = {p.key: p.value for p in old.metadata_props}
    meta = read_metadata(old)
    metrics = json.loads(files["metrics.json"].read_text())
    if dataset is None:
        dataset = json.loads(files["config.json"].read_text())["dataset"]
    images = parity_images(Dataset(dataset))
    size = (int(meta["input_height"]), int(meta["input_width"]))
    if tuple(images.shape[2:]) != size:
        raise ValueError(f"the test images of {dataset} are {images.shape[3]}x{images.shape[2]}, "
                         f"the model's input {size[1]}x{size[0]}: pass its dataset with --dataset")
    model = load_checkpoint(files["checkpoint_best.pt"])
    model.set_flip_average(bool(meta.get("flip_average", False)))
    tol = default_tolerance(metrics) if tolerance is None else float(tolerance)
    pooling = str(meta.get("model", {}).get("pooling", "window"))
    report = export_checked(model, files["segnet.onnx"], images, metadata, tolerance=tol,
                            threads=threads, pooling=pooling)
    metrics["onnx_max_abs_diff"] = report.max_abs_diff
    metrics["onnx_parity"] = report.as_dict()
    atomic_write_json(files["metrics.json"], metrics)
    log.info("%s: re-exported, max |onnx - torch| %.2e", files["segnet.onnx"], report.max_abs_diff)
    if (model_dir / INT8_NAME).is_file():  # made from the old graph: make it again
        q_path = model_dir / REPORT_NAME
        calibration = CALIBRATION
        if q_path.is_file():
            calibration = int(json.loads(q_path.read_text())["quantization"]["calibration_images"])
        q = quantize_model_dir(model_dir, dataset, calibration, threads=threads, progress=False)
        metrics["int8"] = int8_summary(q)
        atomic_write_json(files["metrics.json"], metrics)
        log.info("%s: made again, labels equal to the float graph's on %.2f %% of pixels",
                 model_dir / INT8_NAME, 100 * q["label_agreement"])
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model_dir", help="a model folder of `python -m train` (outputs/models/NAME)")
    ap.add_argument("--dataset", default=None, help="default: the model's training dataset")
    ap.add_argument("--tolerance", type=float, default=None,
                    help="largest accepted |onnx - torch| (default: 1e-4, or twice the first "
                         "export's difference if larger)")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    report = reexport(args.model_dir, args.dataset, args.tolerance, args.threads)
    print(f"onnx: {Path(args.model_dir) / 'segnet.onnx'} (max |onnx - torch| "
          f"{report.max_abs_diff:.2e}, labels output checked)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
