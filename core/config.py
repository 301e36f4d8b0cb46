"""Typed configs shared by the three stages.

Each stage's settings are dataclasses (``datagen/config.py``, ``train/config.py``,
``localize/config.py``): their field defaults are the only defaults, and Hydra composes the
YAML presets of ``conf/`` onto them (``register_schema``), so a typo or a wrong type in a YAML
file or on the command line fails at start-up, naming the key. ``typed`` does the same check
for a plain mapping (library use, tests, settings read back from a model folder);
``compose_config`` composes a conf/ file as a stage's command line would (benchmarks, tests).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

T = TypeVar("T")
#: The repository's Hydra config folder.
CONF = Path(__file__).resolve().parents[1] / "conf"
#: Overrides that shrink conf/datagen.yaml to seconds of rendering (128x96, 20 images, three
#: 30-frame flights): the tests' and benchmarks' tiny dataset.
TINY_DATAGEN = [
    "camera.width=128", "camera.height=96",
    "splits.train=12", "splits.val=4", "splits.test=4",
    "render.spp=2", "training.chunk=6",
    "flights.paper.num_frames=30", "flights.cluttered.num_frames=30",
    "render_flights=[paper,cluttered]", "val_flights=[paper]",
]


def _cycle(index: int, values: list) -> Any:
    """``${cycle:${world.seed},[60,80,100]}``: ``values[index % len(values)]`` (a setting that
    varies along a sweep, e.g. each procedural floor's camera)."""
    return values[int(index) % len(values)]


if not OmegaConf.has_resolver("cycle"):
    OmegaConf.register_new_resolver("cycle", _cycle)


def register_schema(name: str, node: type, group: str | None = None) -> None:
    """Store dataclass ``node`` in Hydra's ConfigStore as ``name`` (in config group ``group``),
    for a defaults list (``defaults: [name, ...]``): every key then has its type and
    default."""
    ConfigStore.instance().store(name=name, node=node, group=group)


def typed(cls: type[T], cfg: Mapping | None, where: str) -> T:
    """An instance of dataclass ``cls``: its defaults updated by ``cfg`` (a mapping or a
    DictConfig, possibly partial), checked by OmegaConf against the field types.

    Args:
        cls: a dataclass whose fields have OmegaConf-compatible annotations.
        cfg: the values to set (None: the defaults).
        where: the config key the values come from, for messages (e.g. ``"filter"``).

    Raises:
        ValueError: an unknown key or a value of the wrong type, naming ``where.key``, the
            value and (for a typo) the known keys; or a check of ``cls`` failing, prefixed
            with ``where`` unless its message starts with it.
    """
    base = OmegaConf.structured(cls)
    try:
        merged = OmegaConf.merge(base, cfg or {})
    except OmegaConfBaseException as err:
        key = f"{where}.{err.full_key}" if getattr(err, "full_key", None) else where
        known = ", ".join(base.keys())
        raise ValueError(f"{key}: {err.msg.splitlines()[0]} (known keys of {where}: {known})"
                         ) from None
    try:
        return OmegaConf.to_object(merged)
    except ValueError as err:  # a check of the dataclass's own (``__post_init__``)
        if str(err).startswith(where):  # names the key already
            raise
        raise ValueError(f"{where}: {err}") from None


def as_config(cls: type[T], cfg: Any, where: str) -> T:
    """``cfg`` if it is a ``cls`` already, else ``typed(cls, cfg, where)`` (a mapping or a
    DictConfig, possibly partial; None: the defaults)."""
    return cfg if isinstance(cfg, cls) else typed(cls, cfg, where)


def compose_config(name: str, overrides: list[str] | None = None) -> dict:
    """Compose ``conf/<name>.yaml`` with ``overrides`` (Hydra's command-line syntax), resolved
    to plain containers."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name=name, overrides=overrides or [])
    return OmegaConf.to_container(cfg, resolve=True)
