"""Which class's segmentation errors cost the cnn mode its accuracy: the SegNet's labels with one
set of classes taken from the truth.

Usage::

    python benchmarks/class_swap.py --swap floor \\
        onnx_model=outputs/models/best1_fullres/segnet.onnx name=hw6 "modes=[cnn]" \\
        progress=false     # reports hw6_swap_floor, hw6_swap_floor_own
    python benchmarks/class_swap.py --swap door,window ...   # several classes at once

This is ``benchmarks/flight_spread.py`` (same arguments after ``--swap``; its flights) with one
change to the cnn mode: every pixel that the true label image or the SegNet puts in one of the
``--swap`` classes takes its true label, so every boundary of those classes is where the
truth has it, and every other boundary is the SegNet's. The drop in the cnn error against a
plain ``flight_spread`` run with the same overrides and seeds is what perfect segmentation of
those classes would be worth; the classes whose swap closes most of the gap to ``oracle`` are
where a better SegNet pays (docs/localize.md, "which class costs the gap"). A diagnostic: the
localizer itself never reads true labels in cnn mode. The report's name gets the suffix
``_swap_<classes>``, so a swapped run never resumes from a plain one's runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import classes as C  # noqa: E402
from localize.frontend.sources import EdgeSource, LabelFunction  # noqa: E402


def swap_labels(predicted: np.ndarray, truth: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """The predicted labels with the true label wherever either map has one of ``classes``.

    Args:
        predicted, truth: (H, W) uint8 class ids.
        classes: (K,) class ids to take from the truth.
    Returns:
        (H, W) uint8.
    """
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted {predicted.shape} and true {truth.shape} labels differ")
    take = np.isin(truth, classes) | np.isin(predicted, classes)
    return np.where(take, truth, predicted).astype(np.uint8)


def swapped_source(own: EdgeSource, classes: np.ndarray) -> LabelFunction:
    """The cnn mode's edge source with ``classes`` taken from the truth: a label function of
    the frame and its true labels, ``swap_labels`` of the SegNet's (``own``) and the true
    ones."""

    def labels(rgb: np.ndarray, truth: np.ndarray) -> np.ndarray:
        return swap_labels(own.labels(rgb, None), truth, classes)

    return LabelFunction(labels, mode=own.mode, needs_truth=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 epilog="Every other argument is benchmarks/flight_spread.py's "
                                        "(--dataset, --flights, localize overrides).")
    ap.add_argument("--swap", required=True,
                    help="comma-separated class names whose true labels replace the SegNet's")
    a, rest = ap.parse_known_args()
    names = [n for n in a.swap.split(",") if n]
    unknown = sorted(set(names) - set(C.NAMES))
    if unknown or not names:
        ap.error(f"--swap {a.swap!r}: unknown class {unknown}; use names from {list(C.NAMES)}")
    classes = np.array([C.ID[n] for n in names])
    import flight_spread  # noqa: E402  (benchmarks/ is on sys.path as the script's folder)

    sys.argv = [sys.argv[0], *report_name(rest, names)]
    flight_spread.main(source_wrappers={"cnn": lambda own: swapped_source(own, classes)})


def report_name(args: list[str], names: list[str]) -> list[str]:
    """``args`` with the report's ``name=`` override suffixed by ``_swap_<classes>`` (no
    override: ``swap_<classes>``), so a swapped run never resumes from, or into, a plain run's
    report."""
    swap = "swap_" + "_".join(names)
    given = [a.split("=", 1)[1] for a in args if a.startswith("name=")]
    name = f"{given[-1]}_{swap}" if given else swap
    return [a for a in args if not a.startswith("name=")] + [f"name={name}"]


if __name__ == "__main__":
    main()
