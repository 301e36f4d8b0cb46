"""Segmentation scores as the SegNet paper reports them, from one confusion matrix, and the
boundary F-score (what the edge likelihood needs: class boundaries where the truth has them).

Rows of the confusion matrix are the true class, columns the predicted class. Pixels whose
label is 255 (ignore) are not counted.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import torch

from core.atomic import atomic_write
from core.classes import pair_classes, pair_code

IGNORE = 255


def confusion_matrix(pred: torch.Tensor, target: torch.Tensor, num_classes: int) -> torch.Tensor:
    """Confusion matrix by one bincount.

    Args:
        pred: (...) integer predicted class ids in [0, C).
        target: (...) integer true class ids in [0, C) or 255 (ignored), same shape.
        num_classes: C.

    Returns:
        (C, C) int64, entry [t, p] = number of pixels of true class t predicted as p.
    """
    if pred.shape != target.shape:
        raise ValueError(f"pred {tuple(pred.shape)} and target {tuple(target.shape)} differ")
    t = target.reshape(-1).long()
    p = pred.reshape(-1).long()
    keep = t != IGNORE
    t, p = t[keep], p[keep]
    if t.numel() and (
        int(t.max()) >= num_classes
        or int(p.max()) >= num_classes
        or int(t.min()) < 0
        or int(p.min()) < 0
    ):
        raise ValueError(f"class ids outside [0, {num_classes}) in pred or target")
    return torch.bincount(t * num_classes + p, minlength=num_classes**2).view(
        num_classes, num_classes
    )


def scores(cm: np.ndarray | torch.Tensor) -> dict:
    """Global accuracy, class-average accuracy, per-class and mean IoU.

    Averages run over the classes present in the ground truth (row sum > 0); absent classes
    get NaN in the per-class arrays.

    Args:
        cm: (C, C) confusion matrix, rows = truth.

    Returns:
        dict with pixel_accuracy, class_accuracy, mean_iou (floats in [0, 1]),
        per_class_accuracy (C,), iou (C,) float64 arrays, present (C,) bool.
    """
    cm = np.asarray(cm, dtype=np.float64)
    if cm.ndim != 2 or cm.shape[0] != cm.shape[1]:
        raise ValueError(f"confusion matrix must be (C, C), got {cm.shape}")
    tp = np.diag(cm)
    gt = cm.sum(1)
    pred = cm.sum(0)
    total = cm.sum()
    present = gt > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        acc = np.where(present, tp / gt, np.nan)
        iou = np.where(present, tp / (gt + pred - tp), np.nan)
    return {
        "pixel_accuracy": float(tp.sum() / total) if total else float("nan"),
        "class_accuracy": float(np.nanmean(acc)) if present.any() else float("nan"),
        "mean_iou": float(np.nanmean(iou)) if present.any() else float("nan"),
        "per_class_accuracy": acc,
        "iou": iou,
        "present": present,
    }


def metrics_json(cm: np.ndarray | torch.Tensor, class_names: Sequence[str],
                 boundary: np.ndarray | None = None,
                 pairs: dict[int, np.ndarray] | None = None) -> dict:
    """The ``test`` block of metrics.json: fractions, per-class IoU by name (null if absent);
    with ``boundary`` (summed ``boundary_counts``) the boundary precision, recall and F at
    2 px, with ``pairs`` (summed ``pair_boundary_counts``) ``per_pair_boundary``."""
    s = scores(cm)
    extra = {}
    if boundary is not None:
        extra = {k: (None if np.isnan(v) else v) for k, v in boundary_f(boundary).items()}
    if pairs is not None:
        extra["per_pair_boundary"] = pair_boundary_json(pairs, class_names)
    return {
        "pixel_accuracy": s["pixel_accuracy"],
        "class_accuracy": s["class_accuracy"],
        "mean_iou": s["mean_iou"],
        "per_class_iou": {
            n: (None if np.isnan(v) else float(v))
            for n, v in zip(class_names, s["iou"], strict=True)
        },
        "per_class_accuracy": {
            n: (None if np.isnan(v) else float(v))
            for n, v in zip(class_names, s["per_class_accuracy"], strict=True)
        },
        "confusion_matrix": np.asarray(cm, dtype=np.int64).tolist(),
    } | extra


def plot_confusion(
    cm: np.ndarray | torch.Tensor, class_names: Sequence[str], path: str | Path, title: str = ""
) -> None:
    """Write a row-normalized confusion matrix as PNG (atomically).

    Args:
        cm: (C, C) confusion matrix, rows = truth.
        class_names: C names.
        path: output PNG path.
        title: plot title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cm = np.asarray(cm, dtype=np.float64)
    rows = cm.sum(1, keepdims=True)
    norm = np.divide(cm, rows, out=np.zeros_like(cm), where=rows > 0)
    c = len(class_names)
    fig, ax = plt.subplots(figsize=(1.0 + 0.75 * c, 0.8 + 0.7 * c), dpi=100)
    ax.imshow(norm, cmap="Blues", vmin=0.0, vmax=1.0)
    for i in range(c):
        for j in range(c):
            if rows[i, 0] > 0:
                ax.text(
                    j,
                    i,
                    f"{100 * norm[i, j]:.0f}",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="white" if norm[i, j] > 0.5 else "black",
                )
    ax.set_xticks(range(c), class_names, rotation=45, ha="right")
    ax.set_yticks(range(c), class_names)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true (row %)")
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, format="png"))
    plt.close(fig)


def class_boundaries(labels: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose right or lower neighbour has another class, neither of the
    two ignored (255)."""
    lab = np.asarray(labels)
    out = np.zeros(lab.shape, dtype=bool)
    for a, b, at in ((lab[:, :-1], lab[:, 1:], out[:, :-1]), (lab[:-1], lab[1:], out[:-1])):
        at |= (a != b) & (a != IGNORE) & (b != IGNORE)
    return out


def boundary_counts(pred: np.ndarray, truth: np.ndarray, tolerance_px: float = 2.0
                    ) -> np.ndarray:
    """(4,) int64 counts for ``boundary_f``: predicted boundary pixels within
    ``tolerance_px`` of a true one, predicted boundary pixels, true boundary pixels within
    ``tolerance_px`` of a predicted one, true boundary pixels (``class_boundaries``; pixels
    where the truth is ignored count for neither).

    Args:
        pred, truth: (H, W) class ids of one image.
    """
    valid = np.asarray(truth) != IGNORE
    return _match_counts(class_boundaries(pred) & valid, class_boundaries(truth), tolerance_px)


def boundary_f(counts: np.ndarray) -> dict:
    """Boundary precision, recall and F-score from summed ``boundary_counts``: precision NaN
    without predicted boundaries, recall NaN without true ones, F NaN without either (0
    where one of them is missing or none is matched)."""
    hit_p, n_p, hit_t, n_t = (float(c) for c in counts)
    p = hit_p / n_p if n_p else float("nan")
    r = hit_t / n_t if n_t else float("nan")
    pp, rr = (p if n_p else 0.0), (r if n_t else 0.0)
    f = float("nan") if not (n_p or n_t) else (2 * pp * rr / (pp + rr) if pp + rr else 0.0)
    return {"boundary_precision": p, "boundary_recall": r, "boundary_f": f}


def pair_boundary_codes(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The class pair of each class change: (H, W - 1) and (H - 1, W) uint8 ``pair_code`` of
    each pixel and its right, and its lower, neighbour; 0 where the two are one class or either
    is ignored (255). Class ids must be below 16."""
    lab = np.asarray(labels)
    out = []
    for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1], lab[1:])):
        change = (a != b) & (a != IGNORE) & (b != IGNORE)
        out.append(np.where(change, pair_code(np.where(change, a, 0), np.where(change, b, 0)), 0)
                   .astype(np.uint8))
    return out[0], out[1]


def _pair_mask(codes: tuple[np.ndarray, np.ndarray], code: int, shape: tuple[int, int]
               ) -> np.ndarray:
    """(H, W) bool: the pixels of ``class_boundaries`` whose change (right or below) is the
    pair ``code``."""
    out = np.zeros(shape, dtype=bool)
    out[:, :-1] |= codes[0] == code
    out[:-1] |= codes[1] == code
    return out


def pair_boundary_counts(pred: np.ndarray, truth: np.ndarray, tolerance_px: float = 2.0
                         ) -> dict[int, np.ndarray]:
    """``boundary_counts`` of each class pair: a predicted a|b boundary pixel is matched by a
    true a|b boundary pixel within ``tolerance_px``, and the other way round (a wall|door
    boundary put where the truth has wall|floor counts as a miss of both pairs).

    Args:
        pred, truth: (H, W) class ids (< 16) of one image; pixels where the truth is 255
            count for neither.

    Returns:
        {pair_code: (4,) int64 counts} for every pair present in ``pred`` or ``truth``.
    """
    truth = np.asarray(truth)
    valid = truth != IGNORE
    pred = np.where(valid, np.asarray(pred), IGNORE)
    pc, tc = pair_boundary_codes(pred), pair_boundary_codes(truth)
    codes = set(np.unique(np.concatenate([c.ravel() for c in (*pc, *tc)])).tolist()) - {0}
    out = {}
    for code in sorted(codes):
        bp, bt = _pair_mask(pc, code, truth.shape), _pair_mask(tc, code, truth.shape)
        out[int(code)] = _match_counts(bp, bt, tolerance_px)
    return out


def _match_counts(bp: np.ndarray, bt: np.ndarray, tolerance_px: float) -> np.ndarray:
    """(4,) counts of ``boundary_counts`` for predicted and true boundary masks."""
    def near(b: np.ndarray) -> np.ndarray:  # distance (px) to the nearest pixel of b
        if not b.any():
            return np.full(b.shape, np.inf)
        return cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)

    return np.array([(near(bt)[bp] <= tolerance_px).sum(), bp.sum(),
                     (near(bp)[bt] <= tolerance_px).sum(), bt.sum()], dtype=np.int64)


def pair_boundary_json(counts: dict[int, np.ndarray], class_names: Sequence[str]) -> dict:
    """The ``per_pair_boundary`` block of metrics.json: for each class pair with boundaries
    (``"floor | wall"``, lower class id first), its ``boundary_f`` and the true and predicted
    boundary pixels, most true pixels first (NaN as null).

    Args:
        counts: {pair_code: (4,) summed ``pair_boundary_counts``}.
        class_names: the names by class id.
    """
    rows = []
    for code, c in counts.items():
        a, b = pair_classes(int(code))
        f = boundary_f(c)
        rows.append((int(c[3]), f"{class_names[a]} | {class_names[b]}", {
            **{k: (None if np.isnan(v) else round(v, 6)) for k, v in f.items()},
            "true_px": int(c[3]), "predicted_px": int(c[1])}))
    return {name: row for _, name, row in sorted(rows, key=lambda r: (-r[0], r[1]))}
