"""Scores on a split: the torch network's (validation) and the exported graph's (the test).

The test score is that of the labels the localizer reads: the ``labels`` output of
``segnet.onnx`` run by onnxruntime through ``core.segmenter.OnnxSegmenter``, the class reader of
``localize.frontend.segmenter.load_segmenter``. Validation, run after every epoch, scores the torch
network's argmax (the export's parity check holds the two to the same labels).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from train.data import SplitData, batches, num_batches, to_float
from train.metrics import confusion_matrix
from train.net.segnet import SegNet


def _bar(data: SplitData, batch_size: int, progress: bool, desc: str):
    return tqdm(batches(len(data), batch_size), total=num_batches(len(data), batch_size),
                desc=desc, disable=not progress, leave=False)


@torch.inference_mode()
def evaluate(
    model: SegNet,
    data: SplitData,
    num_classes: int,
    batch_size: int = 8,
    progress: bool = False,
    desc: str = "eval",
) -> torch.Tensor:
    """Confusion matrix of the torch network's argmax on a split (full images, no augmentation).

    Args:
        model: the network (put in eval mode; the images go to its device).
        data: the split, (N, 3, H, W) uint8 images and (N, H, W) labels.
        num_classes: C.
        batch_size: images per forward pass.
        progress: show a progress bar labelled ``desc``.

    Returns:
        (C, C) int64, rows = truth.
    """
    model.eval()
    device = next(model.parameters()).device
    cm = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    for idx in _bar(data, batch_size, progress, desc):
        logits = model(to_float(data.images[idx]).to(device))
        cm += confusion_matrix(logits.argmax(1).cpu(), data.labels[idx], num_classes)
    return cm


def evaluate_onnx(
    onnx_path: str | Path,
    data: SplitData,
    num_classes: int,
    batch_size: int = 8,
    threads: int = 2,
    progress: bool = False,
    desc: str = "test",
) -> torch.Tensor:
    """Confusion matrix of an exported graph's labels on a split, as the localizer reads them.

    Args:
        onnx_path: a ``segnet.onnx`` (or its int8 copy) written by ``python -m train``.
        data: the split, (N, 3, H, W) uint8 images of the graph's input size.
        num_classes: C (the graph's class count).
        batch_size: images per onnxruntime run.
        threads: onnxruntime intra-op threads.
        progress: show a progress bar labelled ``desc``.

    Returns:
        (C, C) int64, rows = truth.
    """
    from core.segmenter import OnnxSegmenter

    seg = OnnxSegmenter(onnx_path, threads=threads)
    if seg.num_classes != num_classes:
        raise ValueError(f"{onnx_path} has {seg.num_classes} classes, the split {num_classes}")
    cm = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    for idx in _bar(data, batch_size, progress, desc):
        rgb = np.ascontiguousarray(data.images[idx].permute(0, 2, 3, 1).numpy())
        labels = torch.from_numpy(seg.labels(rgb))
        cm += confusion_matrix(labels, data.labels[idx], num_classes)
    return cm
