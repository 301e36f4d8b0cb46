"""Fixtures for the train tests: a tiny synthetic dataset in datagen's layout, tiny configs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from core import classes as C
from core.atomic import atomic_write_json, write_png
from core.imaging.camera import intrinsics

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"
HEIGHT, WIDTH = 48, 64  # not a multiple of 32: exercises the padding


def synthetic_frame(
    rng: np.random.Generator, height: int = HEIGHT, width: int = WIDTH
) -> tuple[np.ndarray, np.ndarray]:
    """A corridor-like cartoon: ceiling, wall, floor, a door, a window, a box and a person.

    Returns:
        rgb (H, W, 3) uint8 and label (H, W) uint8 (a few pixels are 255 = ignore).
    """
    label = np.full((height, width), C.WALL, dtype=np.uint8)
    horizon_top = int(rng.integers(height // 6, height // 3))
    horizon_bot = int(rng.integers(2 * height // 3, 5 * height // 6))
    label[:horizon_top] = C.CEILING
    label[horizon_bot:] = C.FLOOR

    def rect(cls: int, y0: int, y1: int, wmin: int, wmax: int) -> None:
        w = int(rng.integers(wmin, wmax))
        x0 = int(rng.integers(0, width - w))
        label[y0:y1, x0 : x0 + w] = cls

    rect(C.DOOR, horizon_top + 2, horizon_bot, width // 8, width // 4)
    rect(C.WINDOW, horizon_top + 3, (horizon_top + horizon_bot) // 2, width // 8, width // 5)
    rect(C.CLUTTER, horizon_bot - 4, height - 2, width // 10, width // 5)
    if rng.random() < 0.7:
        rect(C.PERSON, horizon_top + 4, height - 4, width // 16, width // 10)
    label[:2, :2] = C.VOID
    colours = C.palette()[: C.NUM_CLASSES].astype(np.float32)
    gain = rng.uniform(0.7, 1.2)
    rgb = colours[label] * gain + rng.normal(0.0, 8.0, (height, width, 3))
    label[rng.random((height, width)) < 0.002] = 255
    return np.clip(rgb, 0, 255).astype(np.uint8), label


def write_synthetic_dataset(
    root: Path, counts: dict[str, int], seed: int = 0, height: int = HEIGHT, width: int = WIDTH
) -> Path:
    """Write a dataset in datagen's layout (dataset.json and split images) under root."""
    rng = np.random.default_rng(seed)
    for split, n in counts.items():
        for i in range(n):
            rgb, label = synthetic_frame(rng, height, width)
            write_png(root / split / "rgb" / f"{i:06d}.png", rgb)
            write_png(root / split / "label" / f"{i:06d}.png", label)
    atomic_write_json(
        root / "dataset.json",
        {
            "schema_version": 1,
            "classes": C.as_json(),
            "camera": {
                "K": intrinsics(width, height, 90.0).tolist(),
                "width": width,
                "height": height,
                "body_from_cam": np.eye(4).tolist(),
            },
            "counts": counts,
            "seed": seed,
        },
    )
    return root


@pytest.fixture(scope="session")
def synthetic_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Tiny dataset: 24 train, 6 val, 6 test frames of 64x48."""
    root = tmp_path_factory.mktemp("synthetic") / "dataset"
    return write_synthetic_dataset(root, {"train": 24, "val": 6, "test": 6})


TINY_OVERRIDES = [
    "model.width=0.125",
    "model.stages=3",
    "model.convs_per_stage=[1,1,1]",
    "epochs=2",
    "batch_size=4",
    "threads=2",
    "progress=false",
    "max_minutes=5",
    "export.parity_images=3",
    "export.batch_size=2",
    "optim.lr=0.01",
]


def train_config(dataset: Path, out_root: Path, *overrides: str) -> DictConfig:
    """conf/train.yaml composed with Hydra and shrunk for tests."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(
            "train",
            overrides=[f"dataset={dataset}", f"out_root={out_root}", *TINY_OVERRIDES, *overrides],
        )


def read_metrics(out_dir: Path) -> dict:
    return json.loads((out_dir / "metrics.json").read_text())


@pytest.fixture(scope="session")
def make_dataset():
    """Factory: ``make_dataset(root, counts, seed=0, height=48, width=64) -> root``."""
    return write_synthetic_dataset


@pytest.fixture(scope="session")
def compose_train():
    """Factory: ``compose_train(dataset, out_root, *overrides) -> DictConfig`` (tiny model)."""
    return train_config
