"""The ``device`` key (train/loop/distributed.py ``training_device``): ``auto`` takes a GPU where
torch sees one, else the CPU, and trains the same weights as ``device=cpu`` there."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

import train.run as tt
from train.config_checks import resolve_precision
from train.loop.distributed import SINGLE, DistWorld, backend_for, training_device
from train.run_identity import train_settings, training_config


def test_auto_is_the_cpu_without_a_gpu(monkeypatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert training_device("auto") == torch.device("cpu")
    assert training_device("cpu") == torch.device("cpu")
    with pytest.raises(ValueError, match="device=cuda.*no GPU.*device=auto"):
        training_device("cuda")
    with pytest.raises(ValueError, match="device='gpu': use auto, cpu or cuda"):
        training_device("gpu")


def test_auto_is_the_local_gpu_where_there_is_one(monkeypatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setenv("LOCAL_RANK", "1")  # the second process torchrun starts on a node
    assert training_device("auto") == torch.device("cuda", 1)
    assert backend_for(training_device("cuda")) == "nccl"
    assert backend_for(training_device("cpu")) == "gloo"
    assert resolve_precision("auto", "cuda") is False  # float32 on a GPU


def test_auto_is_the_cpu_here() -> None:
    """This machine: no GPU (the training tests run on the CPU)."""
    if torch.cuda.is_available():
        pytest.skip("a GPU is present")
    assert training_device("auto").type == "cpu"


def test_collectives_keep_the_device_when_alone() -> None:
    t = torch.ones(3)
    assert DistWorld(0, 1, torch.device("cpu")).sum(t) is t


def test_device_is_not_in_the_config_hash(synthetic_dataset: Path, compose_train,
                                          tmp_path: Path) -> None:
    """A run started on the CPU resumes on a GPU: the device does not change what is
    trained."""
    cpu = training_config(compose_train(synthetic_dataset, tmp_path, "device=cpu"))
    assert cpu == training_config(compose_train(synthetic_dataset, tmp_path, "device=auto"))


def trained_weights(dataset: Path, out_root: Path, compose_train, device: str) -> dict:
    """One epoch of ``python -m train``'s training (prepare and fit, no export) with
    ``device``; the weights."""
    settings = train_settings(compose_train(dataset, out_root, "epochs=1", f"device={device}"))
    job = tt.prepare(settings, SINGLE, training_device(settings.device))
    tt.fit(job)
    return {k: v.detach().cpu() for k, v in job.net.state_dict().items()}


def test_cpu_and_auto_train_the_same_weights(synthetic_dataset: Path, compose_train,
                                             tmp_path: Path) -> None:
    if torch.cuda.is_available():
        pytest.skip("a GPU is present: auto trains there (float rounding differs)")
    cpu = trained_weights(synthetic_dataset, tmp_path / "cpu", compose_train, "cpu")
    auto = trained_weights(synthetic_dataset, tmp_path / "auto", compose_train, "auto")
    assert cpu.keys() == auto.keys()
    for k in cpu:
        torch.testing.assert_close(auto[k], cpu[k], rtol=0, atol=0, msg=k)
