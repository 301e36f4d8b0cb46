"""Semantic classes shared by every stage (ids are fixed; docs/conventions.md)."""

from __future__ import annotations

import numpy as np

#: (id, name, RGB colour) for every class, in id order.
CLASSES: tuple[tuple[int, str, tuple[int, int, int]], ...] = (
    (0, "void", (0, 0, 0)),
    (1, "floor", (128, 64, 128)),
    (2, "wall", (70, 130, 180)),
    (3, "ceiling", (250, 250, 210)),
    (4, "door", (190, 110, 40)),
    (5, "window", (0, 220, 220)),
    (6, "clutter", (230, 200, 0)),
    (7, "person", (220, 20, 60)),
)
NAMES: tuple[str, ...] = tuple(name for _, name, _ in CLASSES)
ID: dict[str, int] = {name: i for i, name, _ in CLASSES}
NUM_CLASSES = len(CLASSES)
VOID, FLOOR, WALL, CEILING, DOOR, WINDOW, CLUTTER, PERSON = range(NUM_CLASSES)
STRUCTURAL: tuple[int, ...] = (FLOOR, WALL, CEILING, DOOR, WINDOW)
IGNORE = 255


def palette() -> np.ndarray:
    """Colour table indexed by class id, IGNORE mapped to white.

    Returns:
        (256, 3) uint8 array.
    """
    table = np.full((256, 3), 255, dtype=np.uint8)
    for i, _, colour in CLASSES:
        table[i] = colour
    return table


def colorize(label: np.ndarray) -> np.ndarray:
    """Colour a label map.

    Args:
        label: (H, W) uint8 class ids.

    Returns:
        (H, W, 3) uint8 RGB image.
    """
    return palette()[label]


def as_json() -> list[dict]:
    """Class list as written to dataset.json and ONNX metadata."""
    return [
        {"id": i, "name": n, "color": list(c), "structural": i in STRUCTURAL}
        for i, n, c in CLASSES
    ]
