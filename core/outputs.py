"""One policy for output folders: a folder belongs to the settings its results depend on.

A stage's output folder (a dataset, a model folder, a localization report) holds a record
(``config.json``, or the stage's own file such as a dataset's ``dataset.json``) with the
settings its results depend on. ``claim_output`` is called before anything is written:

- no results there yet (none of the stage's ``results`` paths exists): a fresh folder,
  unless a live run holds it: then its record is compared as below (a run that has written
  its record but no result yet owns the folder);
- the same settings: the run resumes (the stage skips what is done);
- other settings only in keys the stage lets grow (a count that rises, a list that gains
  entries, an unset value that is set): the folder grows;
- other settings: refused with an ``OutputFolderError`` naming each differing key and its two
  values, and the two fixes (``overwrite=true`` empties the folder, or another ``name=``);
- settings a stage declares speed-only (threads, block sizes) are never compared.

Locking. A run holds ``fcntl.flock`` on ``<folder>/.lock`` for as long as it writes: an
exclusive lock, or a shared one for stages whose runs of one config may write side by side
(datagen's shards render disjoint frames). A second short lock, ``.lock-setup``, is held
while a run reads and writes the record, so two runs never both find an empty folder.

Wait or refuse: a run that finds the folder held waits ``wait_s`` (10 s) and then refuses
(``FolderBusy``: "another run is writing <folder> (pid N); wait for it or pick another
name="). Runs last minutes to hours, so waiting for one to end would leave a job hanging
with no word, or start it hours later against a config it never saw; the short wait only
absorbs a run that is just ending (a sweep's jobs back to back). The setup lock is waited
for longer (``SETUP_WAIT_S``): it is held for the seconds a record takes to write.

flock locks are advisory, held per open file, and released by the kernel when the process
ends however it ends (no stale lock files). They do not work across machines on NFS.
"""

from __future__ import annotations

import contextvars
import copy
import fcntl
import functools
import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

from core.atomic import atomic_write_json

log = logging.getLogger(__name__)

LOCK_NAME = ".lock"
SETUP_LOCK_NAME = ".lock-setup"
#: Seconds a run waits for another run holding the folder before refusing.
RUN_WAIT_S = 10.0
#: Seconds a run waits for another run's setup (reading and writing the record).
SETUP_WAIT_S = 60.0
_POLL_S = 0.05
_MISSING = object()


class OutputFolderError(RuntimeError):
    """An output folder holds results of other settings (or results without a record)."""


class FolderBusy(OutputFolderError):
    """Another run holds the folder's lock."""


@dataclass(frozen=True)
class FolderPolicy:
    """How a stage keys its output folders by their settings.

    Attributes:
        record: file in the folder holding the settings (JSON).
        section: the record's key holding the settings (None: the whole record).
        keys: dotted keys (``fnmatch`` patterns) compared; None: all.
        grow: dotted keys (patterns) that may grow: numbers may rise, lists gain entries,
            unset (missing or null) values be set.
        speed_only: dotted keys (patterns) never compared: they change how fast, not what.
        results: paths (glob patterns) in the folder whose presence means it holds results.
        concurrent: runs of the same settings may hold the folder at once (shared lock).
    """

    record: str = "config.json"
    section: str | None = None
    keys: tuple[str, ...] | None = None
    grow: tuple[str, ...] = ()
    speed_only: tuple[str, ...] = ()
    results: tuple[str, ...] = ()
    concurrent: bool = False

    def settings(self, record: Mapping) -> dict[str, Any]:
        """The compared settings of a record, flattened to dotted keys (JSON values)."""
        node = record.get(self.section) if self.section else record
        flat = flatten(json.loads(json.dumps(node or {})))
        if self.keys is not None:
            flat = {k: v for k, v in flat.items() if _matches(k, self.keys)}
        return {k: v for k, v in flat.items() if not _matches(k, self.speed_only)}

    def has_results(self, folder: Path) -> bool:
        return any(next(folder.glob(p), None) is not None for p in self.results)


def flatten(d: Mapping, prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}`` (lists and scalars are leaves)."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping) and v:
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def without(d: Mapping, patterns: tuple[str, ...]) -> dict:
    """A nested copy of ``d`` without the dotted keys in ``patterns`` (or under them)."""
    out = {}
    for k, v in d.items():
        if _matches(str(k), patterns):
            continue
        inner = tuple(p.split(".", 1)[1] for p in patterns if "." in p
                      and fnmatchcase(str(k), p.split(".", 1)[0]))
        out[k] = without(v, inner) if isinstance(v, Mapping) else copy.deepcopy(v)
    return out


def _matches(key: str, patterns: tuple[str, ...]) -> bool:
    """Whether a dotted key is one of the patterns or lies under one."""
    return any(fnmatchcase(key, p) or key.startswith(p + ".") for p in patterns)


def _grows(old: Any, new: Any) -> bool:
    if old is _MISSING or old is None:
        return True
    if isinstance(old, bool) or isinstance(new, bool):
        return False
    if isinstance(old, int | float) and isinstance(new, int | float):
        return new >= old
    if isinstance(old, list) and isinstance(new, list):
        return all(x in new for x in old)
    return False


@dataclass(frozen=True)
class Comparison:
    """Differences between a folder's settings and a run's: ``differ`` (key, old, new) that
    refuse the folder, ``grown`` (key, old, new) that a grow allows."""

    differ: list[tuple[str, Any, Any]]
    grown: list[tuple[str, Any, Any]]

    @property
    def same(self) -> bool:
        return not self.differ and not self.grown


def compare(old: Mapping, new: Mapping, policy: FolderPolicy) -> Comparison:
    """Compare two records' settings under ``policy``."""
    a, b = policy.settings(old), policy.settings(new)
    differ, grown = [], []
    for k in sorted(set(a) | set(b)):
        va, vb = a.get(k, _MISSING), b.get(k, _MISSING)
        if va == vb:
            continue
        item = (k, None if va is _MISSING else va, None if vb is _MISSING else vb)
        (grown if _matches(k, policy.grow) and _grows(va, vb) else differ).append(item)
    return Comparison(differ, grown)


def describe(items: list[tuple[str, Any, Any]], limit: int = 8) -> str:
    """``"seed (0 -> 3), splits.train (4 -> 2)"``, at most ``limit`` keys."""
    text = ", ".join(f"{k} ({_short(a)} -> {_short(b)})" for k, a, b in items[:limit])
    return text + (f" and {len(items) - limit} more" if len(items) > limit else "")


def _short(v: Any) -> str:
    s = json.dumps(v)
    return s if len(s) <= 40 else s[:37] + "..."


class Claim:
    """A run's hold on its output folder; ``release()`` (or leaving ``with``) lets it go.

    Attributes:
        folder: the output folder.
        status: "new", "resume", "grow" or "overwrite".
        alone: no other run held the folder at the claim (temp files there are stale).
        comparison: the settings compared with the folder's record (None if new).
    """

    def __init__(self, folder: Path, fd: int, status: str, alone: bool,
                 comparison: Comparison | None):
        self.folder, self._fd, self.status = folder, fd, status
        self.alone, self.comparison = alone, comparison

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the file releases its flock
            self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self) -> None:
        self.release()


_SCOPE: contextvars.ContextVar[list[Claim] | None] = contextvars.ContextVar(
    "output_claims", default=None)


def releases_claims(fn: Callable) -> Callable:
    """Decorate a stage's ``run``: every claim made while it runs is released when it returns
    or raises (a traceback kept by a caller does not keep the folder locked)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        token = _SCOPE.set([])
        try:
            return fn(*args, **kwargs)
        finally:
            for claim in _SCOPE.get() or []:
                claim.release()
            _SCOPE.reset(token)

    return wrapper


def claim_output(folder: str | Path, record: Mapping, policy: FolderPolicy, *,
                 overwrite: bool = False, write: Callable[[], None] | None = None,
                 wait_s: float | None = None) -> Claim:
    """Check ``folder`` against this run's settings, lock it, and write its record.

    Args:
        folder: the output folder (made if missing).
        record: this run's record; its settings (``policy.settings``) are compared with the
            folder's ``policy.record``.
        policy: the stage's policy.
        overwrite: a folder of other settings is emptied (lock files kept) instead of refused.
        write: writes the record (and whatever must be written with it); default: ``record``
            as JSON to ``folder/policy.record``. Called under the setup lock on every claim.
        wait_s: seconds to wait for another run holding the folder (default ``RUN_WAIT_S``).

    Returns:
        The claim; the folder stays locked until it is released.

    Raises:
        OutputFolderError: the folder holds results of other settings (naming the keys), or
            results but no record, and ``overwrite`` is false.
        FolderBusy: another run holds the folder (after ``wait_s``).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    wait_s = RUN_WAIT_S if wait_s is None else float(wait_s)
    setup = _open(folder / SETUP_LOCK_NAME)
    try:
        if not _lock(setup, fcntl.LOCK_EX, max(wait_s, SETUP_WAIT_S)):
            raise FolderBusy(_busy(folder, "is setting up"))
        run_fd = _open(folder / LOCK_NAME)
        try:
            claim = _claim_locked(folder, run_fd, record, policy, overwrite, write, wait_s)
        except BaseException:
            os.close(run_fd)
            raise
    finally:
        os.close(setup)
    scope = _SCOPE.get()
    if scope is not None:
        scope.append(claim)
    return claim


def _claim_locked(folder: Path, fd: int, record: Mapping, policy: FolderPolicy,
                  overwrite: bool, write: Callable[[], None] | None, wait_s: float) -> Claim:
    """The claim, under the setup lock: compare, lock the run lock, clear, write."""
    path = folder / policy.record
    comparison, status = None, "new"
    if policy.has_results(folder):
        if not path.is_file():
            if not overwrite:
                raise OutputFolderError(
                    f"{folder} holds results but no {policy.record}: it was not made by this "
                    "stage, or its record was deleted. Pass overwrite=true to empty it, or pick "
                    "another name=...")
            status = "overwrite"
        else:
            comparison = compare(_read_record(path), record, policy)
            status = ("resume" if comparison.same else "grow" if not comparison.differ
                      else "overwrite")
            if comparison.differ and not overwrite:
                raise OutputFolderError(
                    f"{folder} holds results made with another config: "
                    f"{describe(comparison.differ)} (folder -> this run; from {path}). Pass "
                    "overwrite=true to replace them, or pick another name=... for this run.")
    alone = _lock(fd, fcntl.LOCK_EX, 0.0)
    if not alone and status == "new" and path.is_file():
        # a live run's record, before its first result: the folder is that run's already
        comparison = compare(_read_record(path), record, policy)
        if comparison.differ and not overwrite:
            raise OutputFolderError(
                f"{folder} is being written by another run (pid {holder_pid(folder)}) with "
                f"another config: {describe(comparison.differ)} (folder -> this run; from "
                f"{path}). Wait for it and pass overwrite=true to replace its results, or "
                "pick another name=... for this run.")
        if not comparison.same:
            status = "grow" if not comparison.differ else "overwrite"
    if not alone:
        if policy.concurrent and status in ("resume", "new"):
            if not _lock(fd, fcntl.LOCK_SH, wait_s):
                raise FolderBusy(_busy(folder, "is writing"))
        elif not _lock(fd, fcntl.LOCK_EX, wait_s):
            raise FolderBusy(_busy(folder, "is writing"))
        else:
            alone = True
    if status == "overwrite":
        log.warning("overwrite=true: emptying %s (%s)", folder,
                    describe(comparison.differ) if comparison else f"no {policy.record}")
        _empty(folder)
    elif status == "grow":
        log.info("%s grows: %s; its results are kept", folder, describe(comparison.grown))
    (write or (lambda: atomic_write_json(path, record)))()
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    if alone and policy.concurrent:
        fcntl.flock(fd, fcntl.LOCK_SH)  # setup lock held: no run can slip in between
    return Claim(folder, fd, status, alone, comparison)


def _read_record(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise OutputFolderError(f"{path} is not valid JSON ({err}); pass overwrite=true to empty "
                                "the folder, or pick another name=...") from err


def _open(path: Path) -> int:
    return os.open(path, os.O_RDWR | os.O_CREAT, 0o666)


def _lock(fd: int, mode: int, wait_s: float) -> bool:
    """Take flock ``mode`` on fd, polling up to ``wait_s`` seconds; whether it was taken."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fd, mode | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(_POLL_S)


def holder_pid(folder: str | Path) -> int | None:
    """The pid written by the last run that claimed ``folder`` (None if none)."""
    try:
        return int((Path(folder) / LOCK_NAME).read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _busy(folder: Path, doing: str) -> str:
    return (f"another run {doing} {folder} (pid {holder_pid(folder)}); wait for it or pick "
            "another name=...")


def _empty(folder: Path) -> None:
    """Remove everything in folder but its lock files."""
    for p in _entries(folder):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()


def _entries(folder: Path) -> Iterator[Path]:
    return (p for p in folder.iterdir() if p.name not in (LOCK_NAME, SETUP_LOCK_NAME))
