"""Datagen shards through Hydra's launcher plugins give the dataset of one process: Ray (a local
cluster the launcher starts, and an existing cluster given by its address) and submitit (its
local executor; SLURM's preset is checked as composed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from core.atomic import read_png
from core.config import CONF, TINY_DATAGEN
from core.outputs import LOCK_NAME, SETUP_LOCK_NAME

ROOT = Path(__file__).resolve().parents[2]
#: No usage reports from Ray (no network in tests).
RAY_ENV = {"RAY_USAGE_STATS_ENABLED": "0"}
RAY_LOCAL = ["+hydra.launcher.ray.init.num_cpus=2",
             "+hydra.launcher.ray.init.include_dashboard=false"]  # a 2-CPU local cluster


def dataset_files(root: Path) -> dict[str, bytes]:
    """Every file's bytes but dataset.json (compared as JSON), the per-run timing statistics
    and the lock files."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and not str(p.relative_to(root)).startswith("stats")
            and p.name not in (LOCK_NAME, SETUP_LOCK_NAME, "dataset.json")}


def multirun(tmp: Path, launcher: list[str], env: dict[str, str] | None = None) -> Path:
    """``python -m datagen -m shard=0,1 num_shards=2 <launcher>`` of the tiny dataset, run as a
    user runs it (from the repository's root); returns the dataset folder."""
    out = tmp / "tiny"
    args = [sys.executable, "-m", "datagen", "-m", "shard=0,1", "num_shards=2", *launcher,
            *TINY_DATAGEN, "name=tiny", f"out_dir={out}", "progress=false",
            f"hydra.sweep.dir={tmp / 'sweep'}"]
    res = subprocess.run(args, cwd=ROOT, env={**os.environ, **(env or {})},
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return out


def assert_same_dataset(sharded: Path, single: Path) -> None:
    """The same labels, poses, world files and images, byte for byte, but where Mitsuba's
    llvm_ad_rgb itself is not bit-exact from run to run (its multithreaded kernels: a
    colour value here and there one 8-bit level off, docs/datagen.md "Resume, grow, shard";
    scalar_rgb: every byte); dataset.json the same but for the recorded command, which is the
    user's without the shard keys."""
    a, b = dataset_files(sharded), dataset_files(single)
    assert sorted(a) == sorted(b)
    differ = [k for k in a if a[k] != b[k]]
    variant = json.loads((single / "stats.json").read_text())["render"]["variant"]
    if variant == "llvm_ad_rgb":
        assert all("/rgb/" in k for k in differ), differ
        assert len(differ) <= sum("/rgb/" in k for k in a) // 10, differ  # seen: 0-3 of 110
        for k in differ:
            d = np.abs(read_png(sharded / k).astype(int) - read_png(single / k).astype(int))
            assert d.max() <= 1 and np.count_nonzero(d) <= 10, (k, d.max(), np.count_nonzero(d))
    else:
        assert differ == []
    assert any(k.startswith("train/rgb/") for k in a) and any(k.startswith("flights/") for k in a)
    meta_a = json.loads((sharded / "dataset.json").read_text())
    meta_b = json.loads((single / "dataset.json").read_text())
    command = meta_a.pop("command")
    meta_b.pop("command")
    assert meta_a == meta_b
    assert command.startswith("python -m datagen camera.width=128")
    assert f"out_dir={sharded}" in command and "shard=" not in command
    runs = sorted(p.name for p in (sharded / "stats").glob("shard-*.json"))
    assert runs == ["shard-0-of-2.json", "shard-1-of-2.json"]
    stats = json.loads((sharded / "stats.json").read_text())  # each shard rendered its half
    assert all(sum(r["rendered"].values()) > 0 for r in stats["shards"])
    assert {k: sum(r["rendered"][k] for r in stats["shards"]) for k in stats["counts"]} \
        == stats["counts"]


@pytest.fixture(scope="module")
def ray_cluster():
    """A local 2-CPU Ray cluster started by this process for the module, shut down after;
    yields its address."""
    ray = pytest.importorskip("ray")
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    with pytest.MonkeyPatch.context() as mp:
        for k, v in RAY_ENV.items():
            mp.setenv(k, v)
        ray.init(num_cpus=2, include_dashboard=False, object_store_memory=78_643_200,
                 log_to_driver=False)
        try:
            yield ray.get_runtime_context().gcs_address
        finally:
            ray.shutdown()


@pytest.mark.slow
class TestRay:
    def test_local_cluster_of_the_launcher(self, tmp_path, tiny_dataset):
        """``hydra/launcher=ray``: the launcher starts a local cluster, ends with the run."""
        pytest.importorskip("hydra_plugins.hydra_ray_launcher")
        out = multirun(tmp_path, ["hydra/launcher=ray", *RAY_LOCAL], RAY_ENV)
        assert_same_dataset(out, tiny_dataset)

    def test_existing_cluster(self, tmp_path, tiny_dataset, ray_cluster):
        """``hydra/launcher=ray_cluster hydra.launcher.ray.init.address=HOST:PORT``: the
        shards run as tasks of a running cluster."""
        out = multirun(tmp_path, ["hydra/launcher=ray_cluster",
                                  f"hydra.launcher.ray.init.address={ray_cluster}"], RAY_ENV)
        assert_same_dataset(out, tiny_dataset)


@pytest.mark.slow
def test_submitit_local(tmp_path, tiny_dataset):
    """``hydra/launcher=submitit_local``: each shard a submitit job (a local process)."""
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    out = multirun(tmp_path, ["hydra/launcher=submitit_local"])
    assert_same_dataset(out, tiny_dataset)
    assert len(list((tmp_path / "sweep" / ".submitit").glob("*/*_result.pkl"))) == 2


def test_slurm_preset():
    """``hydra/launcher=slurm`` is the plugin's submitit_slurm with datagen's defaults; every
    key of the plugin is still there and set from the command line."""
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("datagen", ["hydra/launcher=slurm", "hydra.launcher.partition=cpu",
                                  "hydra.launcher.cpus_per_task=8"], return_hydra_config=True)
    launcher = OmegaConf.to_container(cfg.hydra.launcher)
    assert launcher["_target_"].endswith("submitit_launcher.SlurmLauncher")
    assert launcher["partition"] == "cpu" and launcher["cpus_per_task"] == 8
    assert launcher["max_num_timeout"] == 3 and launcher["timeout_min"] == 240
    assert launcher["mem_gb"] == 8 and "account" in launcher and "qos" in launcher
