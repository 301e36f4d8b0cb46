"""A training run's identity: its typed settings, the part of them that determines the weights,
the config hash over that part and dataset.json, and the model folder's claim by that hash
(core.outputs; docs/outputs.md)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from core.config import as_config
from core.outputs import Claim, FolderPolicy, claim_output, without
from train.config import TrainConfig
from train.net.build import hash_view

#: Config keys that do not change what is trained (left out of the config hash).
HASH_EXCLUDE = (
    "name",
    "out_root",
    "threads",
    "device",
    "max_minutes",
    "finish_by",
    "budget_clock",
    "overwrite",
    "progress",
    "eval.batch_size",
    "localize",
    "export",
    "keep",
)
#: A model folder belongs to its training config and dataset.json (core.outputs): config.json
#: holds them; one run at a time.
MODEL_POLICY = FolderPolicy(record="config.json", keys=("config", "dataset_digest"),
                            results=("checkpoint_*.pt", "segnet.onnx", "metrics.json"))


# ----------------------------------------------------------------------------- config


def train_settings(cfg: DictConfig | Mapping | TrainConfig) -> TrainConfig:
    """The typed settings of a composed conf/train.yaml (or of a mapping of some of its keys,
    the others at their defaults); an unknown key or a wrong type raises ValueError."""
    return as_config(TrainConfig, cfg, "train")


def training_config(cfg: DictConfig | TrainConfig) -> dict:
    """The part of the config that determines the trained weights (resolved, plain dict)."""
    d = OmegaConf.to_container(cfg if OmegaConf.is_config(cfg) else OmegaConf.structured(cfg),
                               resolve=True)
    d.pop("hydra", None)
    d = without(d, HASH_EXCLUDE)
    if "model" in d:
        d["model"] = hash_view(d["model"])
    return d


def config_hash(train_cfg: dict, dataset_json: bytes) -> str:
    """16 hex digits of sha256 over the training config and the dataset's dataset.json."""
    h = hashlib.sha256(json.dumps(train_cfg, sort_keys=True).encode())
    h.update(hashlib.sha256(dataset_json).digest())
    return h.hexdigest()[:16]




def prepare_output(out_dir: Path, info: dict, overwrite: bool) -> Claim:
    """Claim ``out_dir`` for this config (``MODEL_POLICY``) and write its config.json.

    Args:
        out_dir: the model folder.
        info: {"config_hash", "config", "dataset_digest"} of this run.
        overwrite: empty a folder made with another config instead of failing.

    Returns:
        The claim: the folder stays locked until ``run`` returns.

    Raises:
        core.outputs.OutputFolderError: the folder holds another config's model (naming the
            differing keys) and not ``overwrite``.
        core.outputs.FolderBusy: another run writes the folder.
    """
    return claim_output(out_dir, info, MODEL_POLICY, overwrite=overwrite)
