"""The entry points on a user's error: one line ``error: <message>`` on stderr and exit status
2, no traceback; ``HYDRA_FULL_ERROR=1`` keeps the traceback. A key the schema does not know is
refused, also when added with ``+`` (``core.config.hydra_app``, ``typed``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from core.config import CONF, TINY_DATAGEN, error_message, typed
from localize.config import LocalizeConfig

REPO = Path(__file__).resolve().parents[2]
MISSING = "/nonexistent/dataset"
#: Per entry point, a setting that fails at start-up (a file that is not there): the run stops
#: there, whether or not an earlier check stops it first.
FAILS = {"datagen": ["world=file", "world.path=/nonexistent/building.world"],
         "train": [f"dataset={MISSING}"], "localize": [f"dataset={MISSING}"],
         "localize.ros2": [f"dataset={MISSING}"]}


def cli(tmp_path: Path, module: str, *args: str, full_error: bool = False
        ) -> subprocess.CompletedProcess:
    """``python -m <module> <args>`` run from ``tmp_path`` (its outputs/ there)."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["PYTHONPATH"] = str(REPO)
    if full_error:
        env["HYDRA_FULL_ERROR"] = "1"
    return subprocess.run([sys.executable, "-m", module, *args], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)


def assert_user_error(res: subprocess.CompletedProcess, *words: str) -> None:
    """Exit status 2, one line ``error: ...`` naming ``words`` on stderr, no traceback."""
    err = res.stderr
    assert res.returncode == 2, (res.returncode, err[-3000:])
    assert "Traceback" not in err and "HYDRA_FULL_ERROR" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, err
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.parametrize("module", list(FAILS))
def test_unknown_key_added_with_plus(tmp_path: Path, module: str) -> None:
    """``+filtr.k=3`` (what Hydra suggests for a typo) is refused before anything runs, naming
    the key."""
    assert_user_error(cli(tmp_path, module, "+filtr.k=3", *FAILS[module]), "filtr", "not in")


@pytest.mark.parametrize("module", list(FAILS))
def test_missing_file(tmp_path: Path, module: str) -> None:
    assert_user_error(cli(tmp_path, module, *FAILS[module]), "/nonexistent/")


@pytest.mark.parametrize("args, words", [
    (["filtr.k=3"], ["filtr", "not in 'LocalizeConfig'"]),  # Hydra's composition
    (["+filter.kk=3"], ["filter.kk", "known keys of filter", "num_particles"]),
    (["max_frames=abc"], ["max_frames", "abc"]),
    (["filter=nonexistent"], ["filter/nonexistent", "default, paper"]),
    ([f"dataset={MISSING}", "seeds=[]"], ["seeds"]),
])
def test_localize_user_errors(tmp_path: Path, args: list[str], words: list[str]) -> None:
    assert_user_error(cli(tmp_path, "localize", *args), *words)


def test_datagen_bad_value(tmp_path: Path) -> None:
    assert_user_error(cli(tmp_path, "datagen", "progress=maybe"), "progress", "maybe")


@pytest.mark.parametrize("args", [[f"dataset={MISSING}"], ["+filtr.k=3"], ["filtr.k=3"]])
def test_full_error_keeps_the_traceback(tmp_path: Path, args: list[str]) -> None:
    res = cli(tmp_path, "localize", *args, full_error=True)
    assert res.returncode != 0 and "Traceback" in res.stderr, res.stderr[-3000:]


def test_a_multirun_goes_on_after_a_failing_job(tmp_path: Path) -> None:
    """``-m``: the job with an unknown flight is reported as ``error: ...`` and the next job
    still writes its dataset; the multirun exits 1 with the failure's message."""
    tiny = [o for o in TINY_DATAGEN if not o.startswith("render_flights=")]
    res = cli(tmp_path, "datagen", "-m", "name=mr", "render_flights=[nope],[paper]",
              "progress=false", *tiny)
    assert res.returncode == 1, res.stderr[-3000:]
    errors = [line for line in res.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "nope" in errors[0], res.stderr[-3000:]
    assert "Traceback" not in res.stderr, res.stderr[-3000:]
    assert (tmp_path / "outputs/datasets/mr/dataset.json").is_file(), res.stderr[-3000:]


def test_argparse_tool(tmp_path: Path) -> None:
    res = cli(tmp_path, "localize.recordings.export", MISSING, "paper", str(tmp_path / "o"))
    assert_user_error(res, f"dataset not found: {MISSING}")
    res = cli(tmp_path, "localize.recordings.export", MISSING, "paper", str(tmp_path / "o"),
              full_error=True)
    assert res.returncode != 0 and "Traceback" in res.stderr, res.stderr[-3000:]


def test_typed_refuses_keys_hydra_added() -> None:
    """A composed DictConfig (the schema's object type) with a key added by ``+``: ``typed``
    refuses it as it does in a plain mapping."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("localize", overrides=["+filtr.k=3"])
    with pytest.raises(ValueError, match=r"^filtr: .*known keys: filter, edges"):
        typed(LocalizeConfig, cfg, "")
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("localize", overrides=["+filter.kk=3"])
    with pytest.raises(ValueError, match=r"^localize\.filter\.kk: .*known keys of "
                                         r"localize\.filter: num_particles"):
        typed(LocalizeConfig, cfg, "localize")


def test_error_message_of_os_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError) as err:
        open(tmp_path / "none.txt")
    assert error_message(err.value) == f"{tmp_path / 'none.txt'}: No such file or directory"
    assert error_message(FileNotFoundError("dataset not found: x")) == "dataset not found: x"
