"""Semantic classes shared by every stage (ids are fixed; docs/conventions.md)."""

from __future__ import annotations

from collections.abc import Mapping

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


def pair_code(a, b) -> np.ndarray:
    """Code of the unordered class pair {a, b}: ``16 * min + max`` as uint8 (class ids < 16;
    never 0 for two different classes).

    Args:
        a, b: class ids, scalars or arrays of one shape.
    """
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    if (np.maximum(a, b) >= 16).any():
        raise ValueError("class pair codes need class ids below 16")
    return (16 * np.minimum(a, b) + np.maximum(a, b)).astype(np.uint8)


def pair_classes(code):
    """The two class ids (lower, higher) of a ``pair_code``; scalars or arrays of one shape."""
    return code // 16, code % 16


def pair_name(code: int, names: Mapping[int, str]) -> str:
    """``"wall | door"`` for a ``pair_code``, from class names by id (an unnamed id as itself)."""
    a, b = pair_classes(int(code))
    return f"{names.get(a, a)} | {names.get(b, b)}"


def structural_mask(labels: np.ndarray, structural: tuple[int, ...] = STRUCTURAL
                    ) -> np.ndarray:
    """(H, W) bool: the pixels of ``labels`` (uint8 class ids) whose class is structural."""
    lut = np.zeros(256, dtype=bool)
    lut[list(structural)] = True
    return lut[labels]


def class_changes(labels: np.ndarray, struct: np.ndarray
                  ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """The 4-neighbour pixel pairs p, q whose classes are two different structural classes.

    Args:
        labels: (H, W) class ids.
        struct: (H, W) bool, the structural pixels (``structural_mask``).

    Returns:
        For axis 0 (q below p) and axis 1 (q right of p): ``(diff, a, b)``, each (H - 1, W)
        or (H, W - 1): ``diff`` true at the p of each such pair, ``a`` and ``b`` the classes
        of p and q.
    """
    out = []
    for axis in (0, 1):
        a = np.take(labels, range(labels.shape[axis] - 1), axis=axis)
        b = np.take(labels, range(1, labels.shape[axis]), axis=axis)
        sa = np.take(struct, range(labels.shape[axis] - 1), axis=axis)
        sb = np.take(struct, range(1, labels.shape[axis]), axis=axis)
        out.append(((a != b) & sa & sb, a, b))
    return tuple(out)
