"""The network of the ``model`` settings: SegNet (``model.arch: segnet``, train/net/segnet.py)
or LR-ASPP on MobileNetV3-Small (``model.arch: lraspp``, train/net/lraspp.py), built, described
in a checkpoint (``model_kwargs``) and rebuilt from it (``from_kwargs``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict

import torch
from torch import nn

from train.config import ModelConfig
from train.net import segnet
from train.net.lraspp import LRASPPNet

#: The ``model.arch`` values.
ARCHS = ("segnet", "lraspp")
#: The ``model`` settings that are LRASPPNet constructor arguments.
LRASPP_KWARGS = ("width", "downsample", "inter_channels", "mean", "std")
#: ``model`` settings only LR-ASPP reads: left out of a SegNet's config hash, so that the
#: SegNet folders written before LR-ASPP existed keep their identity.
LRASPP_ONLY = ("arch", "inter_channels")
#: SegNet options LR-ASPP has no counterpart of, with the values that leave them off.
SEGNET_ONLY_OFF = {"stem": "average", "head": "bilinear", "context_layers": 0}


def _as_dict(model_cfg: ModelConfig | Mapping) -> dict:
    return asdict(model_cfg) if isinstance(model_cfg, ModelConfig) else dict(model_cfg)


def arch_of(model_cfg: ModelConfig | Mapping) -> str:
    """The ``model.arch`` of a config or checkpoint kwargs (``segnet`` where it is absent)."""
    arch = _as_dict(model_cfg).get("arch") or "segnet"
    if arch not in ARCHS:
        raise ValueError(f"model.arch={arch!r}: use {' or '.join(ARCHS)}")
    return arch


def model_kwargs(model_cfg: ModelConfig | Mapping) -> dict:
    """The constructor arguments of the ``model`` settings, as a checkpoint keeps them
    (``from_kwargs`` rebuilds the network): SegNet's ``segnet.model_kwargs`` (no ``arch``
    key, as before LR-ASPP), LR-ASPP's with ``arch: lraspp``."""
    cfg = _as_dict(model_cfg)
    if arch_of(cfg) == "segnet":
        return segnet.model_kwargs(cfg)
    for key, off in SEGNET_ONLY_OFF.items():
        if key in cfg and cfg[key] != off:
            raise ValueError(f"model.{key}={cfg[key]!r} is a SegNet option: model.arch=lraspp "
                             f"takes {key}={off!r}")
    out = {k: cfg[k] for k in LRASPP_KWARGS if k in cfg and cfg[k] is not None}
    for k in ("mean", "std"):
        if k in out:
            out[k] = list(out[k])
    return {"arch": "lraspp", **out}


def from_kwargs(num_classes: int, kwargs: Mapping,
                generator: torch.Generator | None = None) -> nn.Module:
    """The network of ``model_kwargs`` (a checkpoint's ``model_kwargs``)."""
    kw = dict(kwargs)
    if arch_of(kw) == "lraspp":
        kw.pop("arch")
        return LRASPPNet(num_classes=num_classes, generator=generator, **kw)
    kw.pop("arch", None)
    return segnet.SegNet(num_classes=num_classes, generator=generator, **kw)


def build_model(model_cfg: ModelConfig | Mapping, num_classes: int,
                generator: torch.Generator | None = None) -> nn.Module:
    """The network of the ``model`` settings (``train.config.ModelConfig``), its initial
    weights drawn from ``generator``.

    Args:
        model_cfg: the settings, or a mapping of some of them (the others: the network's
            defaults).
        num_classes: number of classes of the dataset.
        generator: draws the initial weights.
    """
    return from_kwargs(num_classes, model_kwargs(model_cfg), generator)


def hash_view(model: dict) -> dict:
    """The ``model`` settings as the config hash and the folder record see them: a SegNet's
    without the LR-ASPP-only keys (``LRASPP_ONLY``)."""
    if arch_of(model) == "segnet":
        return {k: v for k, v in model.items() if k not in LRASPP_ONLY}
    return model
