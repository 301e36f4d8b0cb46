"""SegNet accuracy on flight frames as the localizer reads them: one table of models x datasets.

Usage::

    python benchmarks/segnet_flights.py --onnx outputs/models/demo/segnet.onnx \\
        --datasets outputs/datasets/demo outputs/datasets/demo_real [--set test|val]

The test split of ``python -m train`` holds ideal renders. A realistic camera's frames
(``realism=real``: sensor noise, exposure changes, JPEG, lens distortion undone by the
localizer, motion blur, rolling shutter) are what the cnn mode meets; this scores each model on
every delivered frame of a dataset's flights of one set, undistorted to the pinhole K with their
true labels (``Flight.image`` / ``Flight.labels``), skipping frames inside a camera dropout (the
image shows nothing) and pixels the lens does not see. Prints pixel accuracy and mean IoU (over
the classes present) per model and dataset, and writes them with each class's IoU as JSON
with ``--out``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.atomic import atomic_write_json  # noqa: E402
from core.dataset import Dataset  # noqa: E402
from localize.frontend.segmenter import load_segmenter  # noqa: E402
from train.metrics import confusion_matrix, metrics_json  # noqa: E402

BATCH = 16


def flight_frames(flight) -> np.ndarray:
    """(T,) bool: the delivered frames outside the flight's camera dropouts."""
    frames = np.arange(len(flight.rgb)) if flight.frames is None else flight.frames
    keep = np.ones(len(frames), dtype=bool)
    for d in flight.info.get("dropout") or []:
        first, stop = d["frames"]
        keep &= ~((frames >= first) & (frames < stop))
    return keep


def labelled_batches(segmenter, dataset: Dataset, flight_set: str, progress: bool = True
                     ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(predicted, true) (B, H, W) labels of every usable frame of the dataset's flights of
    ``flight_set``, ``BATCH`` frames at a time."""
    for name in dataset.flight_names(flight_set):
        flight = dataset.flight(name)
        index = np.flatnonzero(flight_frames(flight))
        for start in tqdm(range(0, len(index), BATCH), desc=f"{dataset.root.name}/{name}",
                          disable=not progress, leave=False):
            batch = index[start:start + BATCH]
            rgb = np.stack([flight.image(int(t)) for t in batch])
            yield segmenter.labels(rgb), np.stack([flight.labels(int(t)) for t in batch])


def confusion(segmenter, dataset: Dataset, flight_set: str, num_classes: int,
              progress: bool = True) -> torch.Tensor:
    """(C, C) int64 confusion (rows = truth) of the segmenter's labels on every usable frame of
    the dataset's flights of ``flight_set``; label 255 (unseen) is ignored."""
    cm = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    for pred, truth in labelled_batches(segmenter, dataset, flight_set, progress):
        cm += confusion_matrix(torch.from_numpy(pred.astype(np.int64)),
                               torch.from_numpy(truth.astype(np.int64)), num_classes)
    return cm


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--onnx", nargs="+", type=Path, required=True, help="segnet.onnx files")
    ap.add_argument("--datasets", nargs="+", type=Path, required=True)
    ap.add_argument("--set", default="test", choices=["test", "val"], dest="flight_set")
    ap.add_argument("--out", type=Path, help="write the figures here as JSON")
    args = ap.parse_args()
    results: dict = {}
    for ds_path in args.datasets:
        dataset = Dataset(ds_path)
        if not dataset.flight_names(args.flight_set):
            print(f"{ds_path}: no {args.flight_set} flights; skipped", file=sys.stderr)
            continue
        for onnx in args.onnx:
            seg = load_segmenter(onnx, dataset.classes)
            cm = confusion(seg, dataset, args.flight_set, seg.num_classes)
            m = metrics_json(cm, [c["name"] for c in dataset.classes])
            results.setdefault(str(onnx), {})[ds_path.name] = {
                k: m[k] for k in ("pixel_accuracy", "mean_iou", "per_class_iou")
            } | {"pixels": int(cm.sum())}
    names = [p.name for p in args.datasets if any(p.name in r for r in results.values())]
    print(f"pixel accuracy / mean IoU on the {args.flight_set} flights' frames")
    print("| model | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for onnx, by_ds in results.items():
        cells = [f"{by_ds[n]['pixel_accuracy']:.3f} / {by_ds[n]['mean_iou']:.3f}"
                 if n in by_ds else "-" for n in names]
        print(f"| {onnx} | " + " | ".join(cells) + " |")
    if args.out:
        atomic_write_json(args.out, {"flight_set": args.flight_set, "results": results})
        print(f"written: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
