"""Scores on a split: the torch network's (validation) and the exported graph's (the test).

Validation keeps each image's confusion matrix and boundary counts (``ImageScores``): the
keep rule of a fine-tune (train/keep.py) resamples the images to judge a difference against
the split's noise. The test score is that of the labels the localizer reads: the ``labels``
output of ``segnet.onnx`` run by onnxruntime through ``core.segmenter.OnnxSegmenter``, the
class reader of ``localize.frontend.segmenter.load_segmenter``. Validation, run after every
epoch, scores the torch network's argmax (the export's parity check holds the two to the same
labels).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from train.data import SplitData, batches, num_batches, to_float
from train.metrics import (
    boundary_counts,
    boundary_f,
    confusion_matrix,
    pair_boundary_counts,
    scores,
)
from train.net.segnet import SegNet


@dataclass(frozen=True)
class ImageScores:
    """A network's scores on a split, image by image.

    Attributes:
        confusion: (N, C, C) int64 confusion matrices, rows = truth.
        boundary: (N, 4) int64 ``train.metrics.boundary_counts`` at 2 px.
    """

    confusion: np.ndarray
    boundary: np.ndarray

    def __len__(self) -> int:
        return int(self.confusion.shape[0])

    def summary(self) -> dict:
        """``train.metrics.scores`` of the summed confusion matrix (pixel_accuracy,
        class_accuracy, mean_iou, ...) and ``boundary_f`` of the summed counts
        (boundary_precision, boundary_recall, boundary_f)."""
        return scores(self.confusion.sum(0)) | boundary_f(self.boundary.sum(0))


def _bar(data: SplitData, batch_size: int, progress: bool, desc: str):
    return tqdm(batches(len(data), batch_size), total=num_batches(len(data), batch_size),
                desc=desc, disable=not progress, leave=False)


@torch.inference_mode()
def score_images(
    model: SegNet,
    data: SplitData,
    num_classes: int,
    batch_size: int = 8,
    progress: bool = False,
    desc: str = "eval",
) -> ImageScores:
    """Each image's confusion matrix and boundary counts (2 px) of the torch network's argmax
    on a split (full images, no augmentation).

    Args:
        model: the network (put in eval mode; the images go to its device).
        data: the split, (N, 3, H, W) uint8 images and (N, H, W) labels.
        num_classes: C.
        batch_size: images per forward pass.
        progress: show a progress bar labelled ``desc``.
    """
    model.eval()
    device = next(model.parameters()).device
    cms, counts = [], []
    for idx in _bar(data, batch_size, progress, desc):
        pred = model(to_float(data.images[idx]).to(device)).argmax(1).cpu()
        truth = data.labels[idx]
        for p, t in zip(pred, truth, strict=True):
            cms.append(confusion_matrix(p, t, num_classes).numpy())
            counts.append(boundary_counts(p.numpy(), t.numpy()))
    if not cms:
        return ImageScores(np.zeros((0, num_classes, num_classes), np.int64),
                           np.zeros((0, 4), np.int64))
    return ImageScores(np.stack(cms), np.stack(counts))


@dataclass(frozen=True)
class GraphScores:
    """An exported graph's scores on a split, summed over its images.

    Attributes:
        confusion: (C, C) int64, rows = truth.
        boundary: (4,) int64 ``train.metrics.boundary_counts`` at 2 px.
        pairs: {pair_code: (4,) int64 ``train.metrics.pair_boundary_counts``} at 2 px.
    """

    confusion: torch.Tensor
    boundary: np.ndarray
    pairs: dict[int, np.ndarray]


def score_onnx(
    onnx_path: str | Path,
    data: SplitData,
    num_classes: int,
    batch_size: int = 8,
    threads: int = 2,
    progress: bool = False,
    desc: str = "test",
) -> GraphScores:
    """The confusion matrix and the boundary counts, overall and per class pair, of an
    exported graph's labels on a split, as the localizer reads them (the test block of
    metrics.json).

    Args:
        onnx_path: a ``segnet.onnx`` (or its int8 copy) written by ``python -m train``.
        data: the split, (N, 3, H, W) uint8 images of the graph's input size.
        num_classes: C (the graph's class count).
        batch_size: images per onnxruntime run.
        threads: onnxruntime intra-op threads.
        progress: show a progress bar labelled ``desc``.
    """
    from core.segmenter import OnnxSegmenter

    seg = OnnxSegmenter(onnx_path, threads=threads)
    if seg.num_classes != num_classes:
        raise ValueError(f"{onnx_path} has {seg.num_classes} classes, the split {num_classes}")
    cm = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    boundary = np.zeros(4, np.int64)
    pairs: dict[int, np.ndarray] = {}
    for idx in _bar(data, batch_size, progress, desc):
        rgb = np.ascontiguousarray(data.images[idx].permute(0, 2, 3, 1).numpy())
        labels = torch.from_numpy(seg.labels(rgb))
        cm += confusion_matrix(labels, data.labels[idx], num_classes)
        for p, t in zip(labels.numpy(), data.labels[idx].numpy(), strict=True):
            boundary = boundary + boundary_counts(p, t)
            for code, c in pair_boundary_counts(p, t).items():
                pairs[code] = pairs.get(code, 0) + c
    return GraphScores(cm, boundary, pairs)
