"""Contact sheet of a dataset: RGB, label colours and edges (Canny on RGB in white, label
boundaries between structural classes in green) for a few frames.

``python -m datagen.contact_sheet <dataset> <out.png> [--frames 6] [--split train]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from core import classes as C
from core.atomic import read_png, write_png
from core.config import user_errors
from core.dataset import Dataset


def structural_boundaries(label: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose right or lower neighbour has another structural class."""
    s = np.isin(label, C.STRUCTURAL)
    edge = np.zeros(label.shape, dtype=bool)
    dx = (label[:, 1:] != label[:, :-1]) & s[:, 1:] & s[:, :-1]
    dy = (label[1:] != label[:-1]) & s[1:] & s[:-1]
    edge[:, 1:] |= dx
    edge[1:] |= dy
    return edge


def edge_panel(rgb: np.ndarray, label: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: Canny edges of the image (white) and model-class boundaries (green)."""
    canny = cv2.Canny(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), 50, 150) > 0
    out = np.zeros_like(rgb)
    out[canny] = 255
    out[structural_boundaries(label)] = (0, 255, 0)
    return out


def contact_sheet(dataset: str | Path, frames: int = 6, split: str = "train") -> np.ndarray:
    """Rows of [RGB | label | edges] for evenly spaced frames of a split and of each flight."""
    ds = Dataset(dataset)
    pairs = []
    rgb, lab = ds.split(split)
    if rgb:
        for i in np.linspace(0, len(rgb) - 1, min(frames, len(rgb))).astype(int):
            pairs.append((rgb[i], lab[i]))
    for name in ds.flight_names():
        f = ds.flight(name)
        pairs.append((f.rgb[len(f.rgb) // 2], f.label[len(f.rgb) // 2]))
    if not pairs:
        raise FileNotFoundError(f"{dataset}: no frames to show; render a dataset first")
    rows = []
    for p_rgb, p_lab in pairs:
        im, lb = read_png(p_rgb), read_png(p_lab, rgb=False)
        rows.append(np.concatenate([im, C.colorize(lb), edge_panel(im, lb)], axis=1))
    return np.concatenate(rows, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset")
    ap.add_argument("out")
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--split", default="train")
    a = ap.parse_args()
    write_png(a.out, contact_sheet(a.dataset, a.frames, a.split))
    print(f"contact sheet written to {a.out}")


if __name__ == "__main__":
    with user_errors():
        main()
