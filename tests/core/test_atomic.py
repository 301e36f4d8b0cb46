"""Tests of core.atomic: a full disk is named, and leaves nothing behind."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from core import atomic
from core.atomic import DiskFullError, atomic_write_json, write_png


def full_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every rename fails as on a full disk (no real disk filling)."""
    def replace(src, dst):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic.os, "replace", replace)


def test_full_disk_names_the_file_the_folder_and_the_fix(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    full_disk(monkeypatch)
    folder = tmp_path / "demo" / "train" / "rgb"
    message = rf"writing 000001.png into {folder} failed: the disk is full \([\d.]+ MB free"
    with pytest.raises(DiskFullError, match=message + r" there\)\. Free space") as info:
        write_png(folder / "000001.png", np.zeros((4, 4, 3), np.uint8))
    assert info.value.errno == errno.ENOSPC and isinstance(info.value, OSError)
    assert list(folder.iterdir()) == []  # no temporary file left


def test_other_errors_pass_through(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def replace(src, dst):
        raise PermissionError(errno.EACCES, "denied")

    monkeypatch.setattr(atomic.os, "replace", replace)
    with pytest.raises(PermissionError) as info:
        atomic_write_json(tmp_path / "a.json", {})
    assert not isinstance(info.value, DiskFullError)


def test_guard_takes_a_stage_fix(tmp_path: Path) -> None:
    with pytest.raises(DiskFullError, match=r"writing x into .* MB free there\)\. Do this\.$"):
        with atomic.disk_full_guard(tmp_path, "x", fix="Do this."):
            raise OSError(errno.ENOSPC, "No space left on device")


def test_a_stage_guard_gives_its_advice_over_the_writer_s(tmp_path, monkeypatch):
    """A DiskFullError of an inner writer keeps where it failed and takes the outer fix; it
    survives pickling (a worker process's error)."""
    import pickle

    from core import atomic

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.tempfile, "mkstemp", full)
    with pytest.raises(DiskFullError) as info, atomic.disk_full_guard(tmp_path, "x", "Do Y"):
        atomic_write_json(tmp_path / "a.json", {})
    assert f"writing a.json into {tmp_path} failed" in str(info.value)
    assert str(info.value).endswith("Do Y") and info.value.errno == errno.ENOSPC
    back = pickle.loads(pickle.dumps(info.value))
    assert str(back) == str(info.value) and back.fix == "Do Y"
