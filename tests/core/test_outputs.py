"""core.outputs: an output folder belongs to its settings; one writer at a time (or shards)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core.outputs import (
    LOCK_NAME,
    FolderBusy,
    FolderPolicy,
    OutputFolderError,
    claim_output,
    compare,
    flatten,
    holder_pid,
    releases_claims,
    without,
)

POLICY = FolderPolicy(record="config.json", grow=("splits", "flights"),
                      speed_only=("threads", "filter.workers"), results=("out/*",))
BASE = {"seed": 0, "splits": {"train": 4, "val": 1}, "threads": 2,
        "filter": {"k": 7.0, "workers": 1}, "flights": ["paper"], "note": None}


def record(**changes) -> dict:
    r = json.loads(json.dumps(BASE))
    for key, value in changes.items():
        node, *path = [r, *key.split("__")]
        for part in path[:-1]:
            node = node[part]
        node[path[-1]] = value
    return r


def made(folder: Path, rec: dict, **kw) -> None:
    """A run that claims the folder, writes one result and ends."""
    with claim_output(folder, rec, POLICY, **kw) as claim:
        (folder / "out").mkdir(exist_ok=True)
        (folder / "out" / "a.txt").write_text(str(rec["seed"]))
    assert not claim.held


class TestCompare:
    def test_flatten_and_without(self) -> None:
        assert flatten({"a": {"b": 1, "c": [1, 2]}, "d": {}}) == {"a.b": 1, "a.c": [1, 2],
                                                                  "d": {}}
        assert without({"a": {"b": 1, "c": 2}, "e": 3}, ("a.b", "e")) == {"a": {"c": 2}}

    def test_same(self) -> None:
        assert compare(BASE, record(), POLICY).same

    def test_speed_only_ignored(self) -> None:
        assert compare(BASE, record(threads=8, filter__workers=4), POLICY).same

    def test_differ_names_keys_and_values(self) -> None:
        c = compare(BASE, record(seed=3, filter__k=5.0), POLICY)
        assert c.differ == [("filter.k", 7.0, 5.0), ("seed", 0, 3)] and not c.grown

    @pytest.mark.parametrize("change", [{"splits__train": 8}, {"flights": ["paper", "x"]},
                                        {"splits__test": 2}])
    def test_grow(self, change: dict) -> None:
        c = compare(BASE, record(**change), POLICY)
        assert c.grown and not c.differ

    @pytest.mark.parametrize("change", [{"splits__train": 3}, {"flights": []},
                                        {"splits__train": True}])
    def test_shrink_differs(self, change: dict) -> None:
        assert compare(BASE, record(**change), POLICY).differ

    def test_a_non_grow_key_that_rises_differs(self) -> None:
        assert compare(BASE, record(seed=1), POLICY).differ

    def test_keys_and_section(self) -> None:
        p = FolderPolicy(section="gen", keys=("seed",))
        assert compare({"gen": BASE}, {"gen": record(filter__k=1.0), "x": 1}, p).same
        assert compare({"gen": BASE}, {"gen": record(seed=2)}, p).differ


class TestClaim:
    def test_new_then_resume(self, tmp_path: Path) -> None:
        made(tmp_path, record())
        assert json.loads((tmp_path / "config.json").read_text()) == record()
        with claim_output(tmp_path, record(threads=16), POLICY) as claim:
            assert claim.status == "resume" and claim.alone
        assert json.loads((tmp_path / "config.json").read_text())["threads"] == 16

    def test_refuse_names_the_keys_and_the_fixes(self, tmp_path: Path) -> None:
        made(tmp_path, record())
        with pytest.raises(OutputFolderError) as err:
            claim_output(tmp_path, record(seed=3, filter__k=1.0), POLICY)
        msg = str(err.value)
        assert "seed (0 -> 3)" in msg and "filter.k (7.0 -> 1.0)" in msg
        assert "overwrite=true" in msg and "name=" in msg and str(tmp_path) in msg
        assert json.loads((tmp_path / "config.json").read_text()) == record(), "unchanged"
        with claim_output(tmp_path, record(), POLICY, wait_s=0):  # the lock was let go
            pass

    def test_overwrite_empties_but_keeps_the_lock(self, tmp_path: Path) -> None:
        made(tmp_path, record())
        (tmp_path / "other.txt").write_text("x")
        with claim_output(tmp_path, record(seed=3), POLICY, overwrite=True) as claim:
            assert claim.status == "overwrite"
            assert sorted(p.name for p in tmp_path.iterdir()) == [
                ".lock", ".lock-setup", "config.json"]

    def test_grow_keeps_results(self, tmp_path: Path) -> None:
        made(tmp_path, record())
        with claim_output(tmp_path, record(splits__train=8), POLICY) as claim:
            assert claim.status == "grow"
            assert (tmp_path / "out" / "a.txt").is_file()
        assert json.loads((tmp_path / "config.json").read_text())["splits"]["train"] == 8

    def test_no_results_any_config(self, tmp_path: Path) -> None:
        claim_output(tmp_path, record(), POLICY).release()  # a record, no results
        with claim_output(tmp_path, record(seed=5), POLICY) as claim:
            assert claim.status == "new"

    def test_results_without_record(self, tmp_path: Path) -> None:
        (tmp_path / "out").mkdir()
        (tmp_path / "out" / "a.txt").write_text("?")
        with pytest.raises(OutputFolderError, match="no config.json.*overwrite=true"):
            claim_output(tmp_path, record(), POLICY)
        claim_output(tmp_path, record(), POLICY, overwrite=True).release()
        assert not (tmp_path / "out").exists()

    def test_bad_record(self, tmp_path: Path) -> None:
        (tmp_path / "out").mkdir()
        (tmp_path / "out" / "a.txt").write_text("?")
        (tmp_path / "config.json").write_text("{")
        with pytest.raises(OutputFolderError, match="not valid JSON"):
            claim_output(tmp_path, record(), POLICY)

    def test_failed_write_releases(self, tmp_path: Path) -> None:
        def boom() -> None:
            raise OSError("disk full")

        with pytest.raises(OSError, match="disk full"):
            claim_output(tmp_path, record(), POLICY, write=boom)
        claim_output(tmp_path, record(), POLICY, wait_s=0).release()


class TestLock:
    def test_second_holder_waits_then_refuses(self, tmp_path: Path) -> None:
        first = claim_output(tmp_path, record(), POLICY)
        t0 = time.monotonic()
        with pytest.raises(FolderBusy, match=r"another run is writing .* \(pid \d+\); wait for "
                                             r"it or pick another name="):
            claim_output(tmp_path, record(), POLICY, wait_s=0.3)
        assert 0.3 <= time.monotonic() - t0 < 5
        first.release()
        claim_output(tmp_path, record(), POLICY, wait_s=0).release()

    def test_concurrent_policy_shares_one_config_only(self, tmp_path: Path) -> None:
        shared = FolderPolicy(results=("out/*",), grow=("splits",), concurrent=True)
        made(tmp_path, record(), overwrite=False)
        a = claim_output(tmp_path, record(), shared)
        b = claim_output(tmp_path, record(), shared, wait_s=0)  # a second shard
        assert a.alone and not b.alone
        for other in (record(splits__train=9), record(seed=2)):  # a grow or an overwrite
            with pytest.raises(FolderBusy):
                claim_output(tmp_path, other, shared, overwrite=True, wait_s=0.1)
        a.release()
        b.release()

    def test_live_run_without_results_refuses_another_config(self, tmp_path: Path) -> None:
        """Two runs of one folder started together: the first has written its record, not
        yet a result; the second, of another seed, is refused and never shares the lock."""
        shared = FolderPolicy(results=("out/*",), grow=("splits",), concurrent=True)
        first = claim_output(tmp_path, record(), shared)
        with pytest.raises(OutputFolderError, match=r"being written by another run \(pid \d+\)"
                                                    r" with another config: seed \(0 -> 1\)"):
            claim_output(tmp_path, record(seed=1), shared, wait_s=0)
        with pytest.raises(FolderBusy):  # a grow waits for the folder alone
            claim_output(tmp_path, record(splits__train=9), shared, wait_s=0.1)
        with claim_output(tmp_path, record(), shared, wait_s=0) as shard:  # its own config
            assert shard.status == "new" and not shard.alone
        assert json.loads((tmp_path / "config.json").read_text())["seed"] == 0
        first.release()
        with claim_output(tmp_path, record(seed=1), shared, wait_s=0) as claim:  # ended
            assert claim.status == "new"

    def test_other_process_named_by_pid(self, tmp_path: Path) -> None:
        code = ("import sys, time; from core.outputs import FolderPolicy, claim_output; "
                "c = claim_output(sys.argv[1], {}, FolderPolicy()); print('held', flush=True); "
                "time.sleep(60)")
        proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)],
                                stdout=subprocess.PIPE, text=True,
                                cwd=Path(__file__).resolve().parents[2])
        try:
            assert proc.stdout.readline().strip() == "held"
            assert holder_pid(tmp_path) == proc.pid
            with pytest.raises(FolderBusy, match=f"pid {proc.pid}"):
                claim_output(tmp_path, {}, FolderPolicy(), wait_s=0.2)
        finally:
            proc.kill()
            proc.wait()
        claim_output(tmp_path, {}, FolderPolicy(), wait_s=2).release()  # the kernel let go
        assert (tmp_path / LOCK_NAME).is_file()

    def test_releases_claims(self, tmp_path: Path) -> None:
        @releases_claims
        def run(fail: bool) -> None:
            claim_output(tmp_path, record(), POLICY)
            if fail:
                raise KeyError("mid-run")

        with pytest.raises(KeyError) as kept:  # the traceback keeps the frame alive
            run(True)
        run(False)  # the lock was released all the same
        assert kept.value is not None
