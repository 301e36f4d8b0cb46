"""A fine-tune that never hurts: ship the fine-tuned network only where the building's own
validation images show a gain over the network it started from (``init_from``).

Both networks segment the validation split (``train.loop.evaluate.score_images``) and are
compared on two scores:

- boundary F at 2 px: class boundaries where the truth has them, what the edge likelihood
  reads;
- mean IoU: whether the regions carry the right class. The localizer keeps only the
  boundaries between two structural classes (clutter and people removed), so a boundary in the
  right place between the wrong classes is still a wrong edge; and at the network's quarter
  resolution boundary F at 2 px hardly moves: in the demo's corridor, on its 40 validation
  images, the generalist, a fine-tune of it and the SegNet trained there score boundary F
  0.437, 0.415 and 0.448 (within the noise) and mean IoU 0.496, 0.592 and 0.708; the
  fine-tune tracks 0.019 m against the generalist's 0.022 (docs/notes/finetune_keep.md).

Boundary F decides; where it shows no difference beyond its noise, mean IoU decides; a loss
beyond the noise in either keeps the starting network. That is: the fine-tune ships when one
score gains more than its margin and neither loses more than its margin, else the starting
network ships (ties included: the burden of proof is on the fine-tune). Each margin is the
larger of ``keep.min_gain`` (0.01) and ``keep.sigmas`` (2) standard errors of that score's
difference, from a paired bootstrap over the validation images (both networks scored on the
same resampled images). With the 40 validation images of a datagen dataset the standard
error is 0.017-0.024 for either score (the corridor's three SegNets), so a gain must exceed
0.03-0.05; the floor keeps a gain below 0.01 from counting on a large split, where the
renders' difference from the building's real frames outweighs it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from train.config import KeepConfig
from train.loop.evaluate import ImageScores
from train.metrics import boundary_f

log = logging.getLogger(__name__)

#: The scores the rule reads, in metrics.json's ``keep`` block, and their names in messages.
SCORES = ("boundary_f", "mean_iou")
NAMES = {"boundary_f": "boundary F", "mean_iou": "mIoU"}


def mean_iou_of(cms: np.ndarray) -> np.ndarray:
    """Mean IoU over the classes present in the truth, of each of a stack of confusion matrices.

    Args:
        cms: (B, C, C) confusion matrices, rows = truth.

    Returns:
        (B,) float64 (NaN where no class is present).
    """
    cms = np.asarray(cms, dtype=np.float64)
    tp = np.diagonal(cms, axis1=1, axis2=2)
    gt, pred = cms.sum(2), cms.sum(1)
    present = gt > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(present, tp / (gt + pred - tp), 0.0)
    n = present.sum(1)
    return np.where(n > 0, iou.sum(1) / np.maximum(n, 1), np.nan)


def boundary_f_of(counts: np.ndarray) -> np.ndarray:
    """Boundary F of each of a stack of summed ``boundary_counts``: (B, 4) -> (B,)."""
    return np.array([boundary_f(c)["boundary_f"] for c in np.asarray(counts)])


def paired_bootstrap(a: ImageScores, b: ImageScores, rng: np.random.Generator,
                     resamples: int) -> dict[str, float]:
    """Standard error of ``b``'s score minus ``a``'s over draws of the images (the same draw
    for both networks), for each score of ``SCORES``.

    Args:
        a, b: two networks' scores on the same N images.
        rng: draws the resamples.
        resamples: bootstrap draws (each N images with replacement).

    Returns:
        {score name: standard error}; 0 for fewer than 2 images.
    """
    n = len(a)
    if len(b) != n:
        raise ValueError(f"the two networks were scored on {n} and {len(b)} images")
    if n < 2 or resamples < 2:
        return dict.fromkeys(SCORES, 0.0)
    draws = rng.integers(0, n, size=(resamples, n))
    weights = np.stack([np.bincount(d, minlength=n) for d in draws]).astype(np.float64)  # (R, N)

    def resampled(x: np.ndarray) -> np.ndarray:  # (N, ...) per image -> (R, ...) summed
        return (weights @ x.reshape(n, -1).astype(np.float64)).reshape(-1, *x.shape[1:])

    diffs = {"boundary_f": boundary_f_of(resampled(b.boundary))
             - boundary_f_of(resampled(a.boundary)),
             "mean_iou": mean_iou_of(resampled(b.confusion)) - mean_iou_of(resampled(a.confusion))}
    return {k: float(np.nanstd(v, ddof=1)) for k, v in diffs.items()}


@dataclass(frozen=True)
class KeepDecision:
    """Which network ships, and why.

    Attributes:
        kept: ``finetuned`` or ``init`` (``init_from``'s network).
        init_from: the starting network's folder or checkpoint.
        images: validation images both networks were scored on.
        init, finetuned: their validation scores ({score: value} for ``SCORES``, plus
            boundary precision and recall).
        gain: finetuned minus init, per score of ``SCORES``.
        margin: the margin per score (``KeepConfig``).
        std_error: the paired bootstrap's standard error per score.
    """

    kept: str
    init_from: str
    images: int
    init: dict
    finetuned: dict
    gain: dict
    margin: dict
    std_error: dict

    @property
    def kept_init(self) -> bool:
        return self.kept == "init"

    def kept_what(self) -> str:
        """What ships, in a few words: "the fine-tuned network" or "init_from's network
        (models/generalist)"."""
        return (f"init_from's network ({self.init_from})" if self.kept_init
                else "the fine-tuned network")

    def message(self) -> str:
        """One line: what ships, both boundary F and mean IoU, the gain against the margin."""
        name = Path(self.init_from).name
        if name == "checkpoint_best.pt":
            name = Path(self.init_from).parent.name
        a, b, g, m = self.init, self.finetuned, self.gain, self.margin
        figures = (f"val boundary F {_fmt(a['boundary_f'])} vs fine-tuned "
                   f"{_fmt(b['boundary_f'])} ({_fmt(g['boundary_f'], '+.3f')}, margin "
                   f"{m['boundary_f']:.3f}), mIoU {_fmt(a['mean_iou'])} vs "
                   f"{_fmt(b['mean_iou'])} ({_fmt(g['mean_iou'], '+.3f')}, margin "
                   f"{m['mean_iou']:.3f}); {self.images} images")
        if self.kept_init:
            return f"kept {name} (init_from={self.init_from}): {figures}: {self.reason()}"
        return f"kept the fine-tuned network over {name}: {figures}"

    def reason(self) -> str:
        """Why the starting network ships ("" when the fine-tune does)."""
        if not self.kept_init:
            return ""
        lost = [k for k in SCORES if self.gain[k] is not None and self.gain[k] < -self.margin[k]]
        if any(self.gain[k] is None for k in SCORES):
            return "a score is undefined (no class boundaries)"
        if lost:
            return f"the fine-tune loses {' and '.join(NAMES[k] for k in lost)} beyond the margin"
        return "no gain beyond the margin"

    def as_dict(self) -> dict:
        """metrics.json's ``keep`` block (JSON types)."""
        return {"kept": self.kept, "init_from": self.init_from, "images": self.images,
                "init": self.init, "finetuned": self.finetuned, "gain": self.gain,
                "margin": self.margin, "std_error": self.std_error,
                "rule": "the fine-tune ships when val boundary F or mean IoU gains more than "
                        "its margin and neither loses more than its margin (train/keep.py)",
                "message": self.message()}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _fmt(x: float | None, spec: str = ".3f") -> str:
    return "n/a" if x is None else format(x, spec)


def decide(init: ImageScores, finetuned: ImageScores, cfg: KeepConfig, init_from: str,
           rng: np.random.Generator) -> KeepDecision:
    """The keep rule (module docstring) on two networks' scores on the same validation images.

    Args:
        init: the starting network's scores; finetuned: the fine-tuned network's.
        cfg: the ``keep`` settings (margins, resamples).
        init_from: the starting network's source (for the record).
        rng: draws the bootstrap's resamples.
    """
    if len(init) == 0:
        raise ValueError("the keep rule needs validation images: the dataset's val split is "
                         "empty; render some (datagen splits.val=) or set "
                         "keep.init_unless_gain=false")
    a, b = init.summary(), finetuned.summary()
    keys = (*SCORES, "boundary_precision", "boundary_recall")
    before = {k: _finite(a[k]) for k in keys}
    after = {k: _finite(b[k]) for k in keys}
    se = paired_bootstrap(init, finetuned, rng, cfg.resamples)
    margin = {k: max(cfg.min_gain, cfg.sigmas * se[k]) for k in SCORES}
    gain = {k: b[k] - a[k] for k in SCORES}
    defined = all(math.isfinite(g) for g in gain.values())  # NaN: a score without boundaries
    gains = any(gain[k] > margin[k] for k in SCORES)
    loses = any(gain[k] < -margin[k] for k in SCORES)
    ships = defined and gains and not loses
    return KeepDecision(
        kept="finetuned" if ships else "init", init_from=init_from, images=len(init),
        init=before, finetuned=after, gain={k: _finite(v) for k, v in gain.items()},
        margin={k: round(v, 6) for k, v in margin.items()},
        std_error={k: round(v, 6) for k, v in se.items()})
