"""``python -m localize``: the edge particle filter on a dataset's flights (conf/localize.yaml).

A model folder made by ``python -m train`` records the localize settings its SegNet is tuned
for (``localize.yaml`` beside ``segnet.onnx``, and the graph's metadata key ``localize``). After
Hydra composes the config, those settings are merged in under the command line: a key the
command line gives (or a parent of it, e.g. ``filter=paper``) keeps the command line's value;
the others take the model's. The log names each setting taken from the model.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf, open_dict
from omegaconf.errors import OmegaConfBaseException

from core.model_folder import model_localize_settings
from core.outputs import flatten
from localize.runner import run
from localize.segmenter import model_path

log = logging.getLogger(__name__)


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
    settings, source = model_localize_settings(cfg.onnx_model)
    if not settings:
        return {}
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
    return taken


@hydra.main(version_base="1.3", config_path="../conf", config_name="localize")
def main(cfg: DictConfig) -> None:
    if cfg.onnx_model == "auto":
        cfg.onnx_model = str(model_path("auto", cfg.dataset))
        log.info("onnx_model=auto: %s", cfg.onnx_model)
    apply_model_settings(cfg, HydraConfig.get().overrides.task)
    if cfg.recording is None:
        report = run(cfg)
    else:
        from localize.recorded import run_recording

        report = run_recording(cfg)
    print(f"report: {report}")


if __name__ == "__main__":
    main()
