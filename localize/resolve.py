"""A localize run's settings, resolved in one place, and the layer that set each value.

Four layers, each over the ones before it:

1. the defaults: localize/config.py (``LocalizeConfig``);
2. the presets: conf/localize.yaml and the group files chosen by it or by the command line
   (``conf/filter/<name>.yaml``);
3. the model: the localize settings the SegNet's folder carries (``localize.yaml`` beside
   ``segnet.onnx``, else the graph's metadata key ``localize``; ``python -m train`` writes
   them), for every key the command line does not give (a key it gives, or a parent of it,
   e.g. ``filter=paper``, keeps the command line's value);
4. the command line.

Hydra composes 1, 2 and 4; ``resolve`` turns ``onnx_model=auto`` into its path, merges 3 in
under 4 and records in ``set_by`` the layer of each value that differs from its default
(``settings_table`` gives the rows metrics.json and report.md show).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict
from omegaconf.errors import OmegaConfBaseException

from core.model_folder import model_localize_settings
from core.outputs import flatten
from localize.config import AppConfig, LocalizeConfig
from localize.frontend.segmenter import SHIPPED_MODEL, model_path
from localize.world_file import check_world_keys

log = logging.getLogger(__name__)

#: ``set_by`` of ``onnx_model`` when ``auto`` chose it (``segmenter.model_path``).
AUTO = "onnx_model=auto"
#: ``set_by`` of a value the command line gives.
COMMAND_LINE = "command line"
#: ``settings_table``'s layer of a value no ``resolve`` recorded (a config composed by a
#: caller, a test or a benchmark, and run without ``python -m localize``).
UNRECORDED = "-"


def override_keys(overrides: Sequence[str]) -> list[str]:
    """The config keys a command line's overrides set.

    ``a.b=1`` -> ``a.b``; ``+a.b=1``, ``++a.b=1`` and ``~a.b`` -> ``a.b``; a group choice
    ``filter=paper`` -> ``filter`` (it sets every key under it).
    """
    keys = []
    for item in overrides:
        key = str(item).split("=", 1)[0].lstrip("+~").strip()
        if key and not key.startswith("hydra."):
            keys.append(key.split("@", 1)[0])  # group@package=choice: the group
    return keys


def _overlaps(key: str, given: str) -> bool:
    """Whether the command line's ``given`` key covers ``key`` (the same, a parent or a child)."""
    return key == given or key.startswith(given + ".") or given.startswith(key + ".")


def _covers(key: str, given: str) -> bool:
    """Whether ``given`` sets ``key`` (the same key or a parent of it)."""
    return key == given or key.startswith(given + ".")


def apply_model_settings(cfg: DictConfig, overrides: Sequence[str]) -> dict:
    """Merge the localize settings ``cfg.onnx_model`` carries into ``cfg``, under ``overrides``.

    Args:
        cfg: the composed conf/localize.yaml; changed in place.
        overrides: the command line's overrides (``HydraConfig.get().overrides.task``).

    Returns:
        The settings taken from the model, ``{"dotted.key": value}`` ({} when none).

    Raises:
        ValueError: a setting of the model names no section of conf/localize.yaml, or a key or
            a value localize/config.py does not take (names the file it came from).
    """
    taken, _ = _apply_model_settings(cfg, overrides)
    return taken


def _apply_model_settings(cfg: DictConfig, overrides: Sequence[str]) -> tuple[dict, str | None]:
    """``apply_model_settings``, and where the model's settings were read (None: nowhere)."""
    settings, source = model_localize_settings(cfg.onnx_model)
    if not settings:
        return {}, source
    given = override_keys(overrides)
    taken, kept = {}, []
    for key, value in flatten(settings).items():
        if any(_overlaps(key, g) for g in given):
            kept.append(key)
            continue
        parent = key.rpartition(".")[0]
        if parent and not isinstance(OmegaConf.select(cfg, parent), DictConfig):
            raise ValueError(f"{source}: {key} is not a localize setting (conf/localize.yaml "
                             f"has no section {parent}); fix the model's localize settings")
        taken[key] = value
    with open_dict(cfg):
        for key, value in taken.items():
            try:
                OmegaConf.update(cfg, key, value, merge=True)
            except OmegaConfBaseException as err:
                raise ValueError(f"{source}: {key}={value!r}: {err.msg.splitlines()[0]}; fix "
                                 "the model's localize settings") from None
    if taken:
        log.info("settings from the model (%s): %s", source,
                 " ".join(f"{k}={v}" for k, v in taken.items()))
    if kept:
        log.info("the command line's values kept over the model's for: %s", " ".join(kept))
    return taken, source


def defaults(schema: type[AppConfig] = LocalizeConfig) -> dict[str, Any]:
    """Every setting's default of an app's schema, ``{"dotted.key": value}``."""
    return flatten(OmegaConf.to_container(OmegaConf.structured(schema)))


def non_defaults(cfg: DictConfig, schema: type[AppConfig] = LocalizeConfig) -> dict[str, Any]:
    """The settings of ``cfg`` whose value differs from the default of ``schema`` (a key the
    defaults do not have, e.g. a mode of ``filter.mode_likelihood``, counts),
    ``{"dotted.key": value}``; ``set_by`` itself is not a setting."""
    base = defaults(schema)
    cfg = OmegaConf.to_container(cfg, resolve=True)
    cfg.pop("set_by", None)
    cfg.pop("hydra", None)
    return {k: v for k, v in flatten(cfg).items() if k not in base or base[k] != v}


def layers(cfg: DictConfig, overrides: Sequence[str], choices: Mapping[str, str | None],
           model_keys: Sequence[str] = (), model_source: str | None = None,
           auto_model: bool = False, schema: type[AppConfig] = LocalizeConfig,
           app_yaml: str = "conf/localize.yaml") -> dict[str, str]:
    """The layer that set each value of ``cfg`` that differs from its default.

    Args:
        cfg: the resolved config.
        overrides: the command line's overrides.
        choices: the config groups' choices (``HydraConfig.get().runtime.choices``), e.g.
            ``{"filter": "paper"}``.
        model_keys: the dotted keys taken from the model (``apply_model_settings``).
        model_source: where the model's settings were read.
        auto_model: ``onnx_model`` was ``auto`` and ``model_path`` chose it.
        schema, app_yaml: the app's schema and its config file.

    Returns:
        ``{"dotted.key": layer}``: ``command line``, ``model <where>``, ``onnx_model=auto``,
        ``conf/<group>/<choice>.yaml`` (a key under a group's node) or ``app_yaml``.
    """
    groups = {g: c for g, c in choices.items() if c is not None and not g.startswith("hydra")}
    given = [k for k in override_keys(overrides) if k not in groups]
    model = list(model_keys)
    out = {}
    for key in non_defaults(cfg, schema):
        group = key.split(".", 1)[0]
        if key == "onnx_model" and auto_model:
            out[key] = AUTO
        elif any(_covers(key, g) for g in given):
            out[key] = COMMAND_LINE
        elif any(_covers(key, m) for m in model):
            out[key] = f"model {model_source}"
        elif group in groups:
            out[key] = f"conf/{group}/{groups[group]}.yaml"
        else:
            out[key] = app_yaml
    return out


def resolve(cfg: DictConfig, overrides: Sequence[str],
            choices: Mapping[str, str | None] | None = None,
            schema: type[AppConfig] = LocalizeConfig,
            app_yaml: str = "conf/localize.yaml") -> dict[str, str]:
    """Resolve a composed localize config in place: ``world=`` is checked against ``dataset=``
    and ``recording=`` (``world_file.check_world_keys``), ``onnx_model=auto`` becomes its path
    (with ``world=``: the shipped generalist), the model's settings merge in under the command
    line, and ``cfg.set_by`` records the layer of
    each value that differs from its default (``layers``).

    Args:
        cfg: conf/localize.yaml as Hydra composed it (defaults, presets, command line).
        overrides: the command line's overrides (``HydraConfig.get().overrides.task``).
        choices: the config groups' choices (``HydraConfig.get().runtime.choices``; None:
            none recorded).
        schema, app_yaml: the app's schema and config file (the live node's:
            ``Ros2Config``, ``conf/ros2.yaml``).

    Returns:
        ``cfg.set_by``.
    """
    world = cfg.world.path
    check_world_keys(cfg, override_keys(overrides),
                     None if "recording" not in cfg else cfg.recording is not None)
    auto = cfg.onnx_model == "auto"
    if auto:
        # a building file has no SegNet of its own: the shipped generalist
        cfg.onnx_model = str(SHIPPED_MODEL if world else model_path("auto", cfg.dataset))
        log.info("onnx_model=auto: %s", cfg.onnx_model)
    taken, source = _apply_model_settings(cfg, overrides)
    set_by = layers(cfg, overrides, choices or {}, list(taken), source, auto, schema, app_yaml)
    with open_dict(cfg):
        cfg.set_by = set_by
    return set_by


def settings_table(cfg: DictConfig) -> list[dict]:
    """The rows of the settings that differ from their defaults, by key: ``key``, ``value``,
    ``default`` (None where the defaults have no such key) and ``set_by`` (``cfg.set_by``;
    ``-`` where no ``resolve`` recorded it)."""
    base = defaults()
    set_by = dict(cfg.get("set_by") or {})
    return [{"key": k, "value": v, "default": base.get(k), "set_by": set_by.get(k, UNRECORDED)}
            for k, v in sorted(non_defaults(cfg).items())]
