"""Test helpers: compose the real Hydra configs, shrunk."""

from __future__ import annotations

from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

CONF = Path(__file__).resolve().parents[1] / "conf"

#: Overrides that shrink the default datagen config to seconds of rendering.
TINY_DATAGEN = [
    "camera.width=128", "camera.height=96",
    "splits.train=12", "splits.val=4", "splits.test=4",
    "render.spp=2", "training.chunk=6",
    "flights.paper.num_frames=30", "flights.cluttered.num_frames=30",
    "render_flights=[paper,cluttered]", "val_flights=[paper]",
]


def compose_config(name: str, overrides: list[str] | None = None) -> dict:
    """Compose ``conf/<name>.yaml`` with overrides, resolved to plain containers."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name=name, overrides=overrides or [])
    return OmegaConf.to_container(cfg, resolve=True)
