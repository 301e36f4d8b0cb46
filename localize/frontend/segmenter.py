"""The cnn mode's segmenter: loading ``segnet.onnx`` with a class check, and its labels with
the training's class-weight prior taken out (``structural_prior_labels``)."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from core.atomic import file_sha256
from core.model_folder import MODELS_ROOT
from core.segmenter import INT8_NAME, QUANTIZE_REPORT
from localize.frontend.edge_image import check_rgb

log = logging.getLogger(__name__)

#: The generalist SegNet that ships with the code, for buildings it never saw: trained on
#: procedural floors (models/generalist/README.md).
SHIPPED_MODEL = Path(__file__).resolve().parents[2] / "models" / "generalist" / "segnet.onnx"


def model_path(onnx_model: str, dataset: str) -> Path:
    """The segnet.onnx that localize's ``onnx_model`` names.

    ``auto`` (the default) is the dataset's own SegNet,
    ``outputs/models/<the dataset folder's name>/segnet.onnx`` (what ``python -m train
    name=<name>`` writes for ``dataset=outputs/datasets/<name>``) where it exists, else the
    shipped generalist (``SHIPPED_MODEL``). Any other value is the path itself.
    """
    if onnx_model != "auto":
        return Path(onnx_model)
    own = MODELS_ROOT / Path(dataset).name / "segnet.onnx"
    return own if own.is_file() else SHIPPED_MODEL


def int8_copy(path: str | Path) -> Path | None:
    """The int8 copy of the SegNet ``path`` (``core.segmenter.INT8_NAME`` beside it, written by
    ``python -m train.deploy.quantize``), where one exists that was made of this file: the
    folder's ``quantize.json`` names a model of ``path``'s file name, and its ``model_sha256``
    is that of ``path``'s bytes. None otherwise (no copy, a stale one of an earlier training,
    or a report without the digest: quantize again)."""
    path = Path(path)
    copy = path.with_name(INT8_NAME)
    report = path.with_name(QUANTIZE_REPORT)
    if path.name == INT8_NAME or not copy.is_file() or not report.is_file():
        return None
    try:
        made = json.loads(report.read_text())
        made_of, digest = Path(str(made.get("model", ""))).name, made.get("model_sha256")
    except (json.JSONDecodeError, AttributeError):
        return None
    if made_of != path.name or digest is None:
        return None
    return copy if digest == file_sha256(path) else None


def runtime_model(onnx_model: str, dataset: str, int8: bool = True) -> Path:
    """The file cnn mode runs: ``model_path(onnx_model, dataset)``, or with ``int8`` (the
    ``segnet_int8`` setting) its int8 copy where one exists (``int8_copy``)."""
    path = model_path(onnx_model, dataset)
    return (int8_copy(path) if int8 and path.is_file() else None) or path


def check_classes(model_classes: list[dict], dataset_classes: list[dict], where: str) -> None:
    """Raise if the segmenter's classes differ from the dataset's (ids and names).

    Args:
        model_classes: the ONNX file's ``classes`` metadata.
        dataset_classes: ``dataset.json`` classes.
        where: the ONNX path, for the message.
    """
    def key(cs: list[dict]) -> list[tuple[int, str]]:
        return [(int(c["id"]), str(c["name"])) for c in cs]

    if key(model_classes) != key(dataset_classes):
        raise ValueError(
            f"{where}: the model's classes {key(model_classes)} do not match the dataset's "
            f"{key(dataset_classes)}; train the model on a dataset with the same class list "
            "(python -m train dataset=...) or localize with the dataset it was trained on.")


def load_segmenter(path: str | Path, dataset_classes: list[dict], threads: int = 2):
    """Open ``segnet.onnx`` with ``core.segmenter.OnnxSegmenter`` and check its class list.

    Raises:
        FileNotFoundError: the model file is missing (says how to make it).
        ValueError: it is not an ONNX model, or its classes do not match the dataset's.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"segmentation model not found: {path}. Train and export one with `python -m train` "
            "(or set localize's `onnx_model=` to an existing segnet.onnx, or drop `cnn` from "
            "modes).")
    from core.segmenter import OnnxSegmenter

    seg = OnnxSegmenter(str(path), threads=threads)
    classes = seg.classes
    if isinstance(classes, str):
        classes = json.loads(classes)
    check_classes(list(classes), dataset_classes, str(path))
    return seg


def logits_and_labels(segmenter, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C, H, W) logits and (H, W) argmax labels of a frame: from one run of the graph where the
    segmenter gives both (``OnnxSegmenter.logits_and_labels``), else the argmax of its logits."""
    both = getattr(segmenter, "logits_and_labels", None)
    if both is not None:
        z, labels = both(rgb)
        return np.asarray(z), np.asarray(labels)
    z = np.asarray(segmenter.logits(rgb))
    return z, z.argmax(0)


def structural_prior_labels(logits: np.ndarray, structural_ids: np.ndarray,
                            log_prior: np.ndarray, labels: np.ndarray | None = None
                            ) -> np.ndarray:
    """Class labels with the training's class-weight prior taken out of the structural choice.

    A network trained with class-weighted cross-entropy (weight w_c) learns softmax scores
    proportional to w_c p(c | x), not p(c | x): where the image is ambiguous it picks the
    higher-weight class. The demo's SegNet weighs wall 0.36 and floor, ceiling, door and window
    0.65-1.05, so those classes spread into the wall and their boundaries with it move (doors
    and windows over their wall-coloured jambs and reveals, for one). Subtracting log w_c from
    the logits gives back the decision by p(c | x); a fraction of it
    (``edges.cnn.prior_correction`` < 1) goes part of the way.

    Only the choice among structural classes is corrected: a pixel whose plain argmax is
    structural takes the structural class with the largest ``z_c - log w_c``; other pixels
    (clutter, person, void) keep their class, so the masks of unknown pixels do not change.

    Args:
        logits: (C, H, W) float class scores.
        structural_ids: (S,) int ids of the structural classes.
        log_prior: (C,) float log w_c (0 for a class without a weight), or a multiple of it.
        labels: (H, W) the plain argmax of ``logits`` if the caller has it (the graph's
            ``labels`` output); None computes it.

    Returns:
        (H, W) uint8 labels.
    """
    ids = np.asarray(structural_ids, dtype=np.int64)
    labels = logits.argmax(0) if labels is None else labels
    # argmax over the S structural classes of z_c - log w_c, one class at a time (S passes
    # over (H, W), not an (S, H, W) copy); ties go to the first, as ``argmax``
    prior = np.asarray(log_prior, dtype=np.float64)  # as (S, H, W) logits - prior did
    best = logits[ids[0]] - prior[ids[0]]
    corrected = np.full(labels.shape, ids[0], dtype=np.uint8)
    for c in ids[1:]:
        z = logits[c] - prior[c]
        higher = z > best
        np.copyto(best, z, where=higher)
        corrected[higher] = c
    structural = np.zeros(logits.shape[0], dtype=bool)
    structural[ids] = True
    return np.where(structural[labels], corrected, labels).astype(np.uint8)


def class_log_prior(segmenter) -> np.ndarray | None:
    """log w_c (C,) of the class weights the segmenter was trained with (its ONNX metadata
    ``class_weights``, by class name); None, with a warning, for a model without them (trained
    before they were recorded, or without class weighting: nothing to correct). Classes with
    weight 0 (absent from the training labels) get 0."""
    if "class_weights" not in segmenter.metadata:
        log.warning("%s has no class_weights metadata (re-train with `python -m train` to "
                    "record them); edges.cnn.prior_correction is off", segmenter.path)
        return None
    weights = segmenter.metadata["class_weights"]
    if weights is None:  # trained without class weighting: no prior to take out
        return None
    missing = [c["name"] for c in segmenter.classes if c["name"] not in weights]
    if missing:
        raise ValueError(f"{segmenter.path}: metadata class_weights lacks the classes {missing}; "
                         "re-export the model with `python -m train`")
    w = np.array([float(weights[c["name"]]) for c in segmenter.classes])
    return np.log(np.where(w > 0, w, 1.0))



class LabelPredictor:
    """Labels of RGB frames from a segmenter, as the cnn mode reads them.

    With ``prior_correction`` s > 0 the structural labels come from ``structural_prior_labels``
    with s * log w_c (the model's ``class_weights`` metadata; none recorded: plain argmax).

    Args:
        segmenter: an ``OnnxSegmenter`` (``load_segmenter``), or any object with
            ``labels(rgb) -> (H, W)`` and, for the prior correction, ``logits(rgb) -> (C, H,
            W)``, ``structural_ids``, ``metadata``, ``classes``.
        prior_correction: strength s (``edges.cnn.prior_correction``; 0: plain argmax).
    """

    def __init__(self, segmenter, prior_correction: float = 0.0):
        self.segmenter = segmenter
        self.log_prior = None
        if prior_correction > 0:
            log_w = class_log_prior(segmenter)
            self.log_prior = None if log_w is None else prior_correction * log_w

    def __call__(self, rgb: np.ndarray) -> np.ndarray:
        """Predicted labels (H, W) uint8 of an (H, W, 3) uint8 RGB frame."""
        check_rgb(rgb)
        if self.log_prior is None:
            labels = self.segmenter.labels(rgb)  # argmax only
        else:
            z, plain = logits_and_labels(self.segmenter, rgb)
            labels = structural_prior_labels(z, self.segmenter.structural_ids, self.log_prior,
                                             plain)
        labels = np.asarray(labels)
        if labels.shape != rgb.shape[:2]:
            raise ValueError(f"segmenter returned labels {labels.shape} for an image "
                             f"{rgb.shape[:2]}")
        return labels.astype(np.uint8, copy=False)
