"""A building file's map for the localizer, with no dataset rendered:
``python -m datagen.worlds.file_map FILE OUT [--settings JSON]``.

Imports FILE as ``python -m datagen world=file world.path=FILE`` does (``site.file_site``: the
import, its summary logged, the model edges, the free space) and writes what a dataset's
``world/`` holds (``save.save_world``: model.npz, edges.npz, free.npz, world.json, model.ply,
import_summary.json) into the folder OUT, plus ``inputs.json``: every file the import opened
for reading (the building file, the models it includes, their meshes and images), absolute
paths, found by an audit hook on ``open`` (Python's own files and the installed packages' left
out). ``python -m localize world=FILE`` and ``python -m localize.ros2 world=FILE`` run it in a
process of its own (localize imports no datagen: tests/test_imports.py) and cache OUT by the
content of those files (localize/world_file.py).

``--settings`` is a JSON mapping of ``world=file``'s keys (``FileWorldConfig``: ``units``,
``up_axis``, ``model_path``, ``crease_deg``, ``camera_margin``, ...); errors name them
``world.<key>``, as localize's ``world.*`` keys are. A user error prints ``error: <message>``
and exits with status 2 (``core.config.user_errors``).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import sysconfig
from pathlib import Path

from core.atomic import atomic_write_json
from core.config import user_errors

log = logging.getLogger(__name__)

#: Where the settings are in a config (their errors name ``world.<key>``).
SETTINGS_KEY = "world"
#: What ``inputs.json`` is called in OUT.
INPUTS = "inputs.json"


def _library_roots() -> tuple[str, ...]:
    """Folders whose files are code, not building inputs: the interpreter's and the installed
    packages', and this project's packages."""
    roots = {sys.prefix, sys.base_prefix, sys.exec_prefix}
    roots |= {p for p in sysconfig.get_paths().values() if p}
    here = Path(__file__).resolve().parents[2]
    roots |= {str(here / pkg) for pkg in ("core", "datagen", "train", "localize")}
    return tuple(str(Path(r).resolve()) for r in roots)


class OpenedFiles:
    """The regular files opened for reading while it is installed (``sys.addaudithook``: an
    audit hook cannot be removed, so ``stop`` ends the recording)."""

    def __init__(self) -> None:
        self.paths: set[str] = set()
        self.on = False
        sys.addaudithook(self._hook)

    def _hook(self, event: str, args: tuple) -> None:
        if not self.on or event != "open" or not isinstance(args[0], str | Path):
            return
        mode = args[1]
        if mode is None or (isinstance(mode, str) and "r" in mode and "+" not in mode):
            self.paths.add(str(args[0]))

    def inputs(self, out: Path) -> list[str]:
        """The regular files read, absolute and sorted, outside the library folders and
        ``out``."""
        skip = (*_library_roots(), str(out.resolve()))
        found = set()
        for p in self.paths:
            path = Path(p).resolve()
            text = str(path)
            if path.is_file() and not text.startswith(skip) and not text.startswith(
                    ("/proc/", "/sys/", "/dev/")):
                found.add(text)
        return sorted(found)


def write_file_map(path: str, out: str | Path, settings: dict | None = None) -> Path:
    """Import the building file ``path`` with ``world=file``'s ``settings`` and write its map
    and ``inputs.json`` into ``out`` (made; it must not hold a map yet).

    Returns:
        ``out``.

    Raises:
        FileNotFoundError, ValueError: from the import (a missing file, an unknown extension,
            a bad setting, no floor, no free space, ...), naming the file or key.
    """
    from datagen.config import world_config
    from datagen.worlds.save import save_world
    from datagen.worlds.site import file_site

    out = Path(out)
    if (out / "world.json").exists():
        raise ValueError(f"{out} already holds a map; give an empty folder")
    spec = world_config({**(settings or {}), "kind": "file", "path": str(path)}, SETTINGS_KEY)
    opened = OpenedFiles()
    opened.on = True
    try:
        site = file_site(spec)
    finally:
        opened.on = False
    save_world(out, site.world)
    atomic_write_json(out / INPUTS, {"file": str(Path(path).resolve()),
                                     "inputs": opened.inputs(out)})
    return out


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(
        prog="python -m datagen.worlds.file_map",
        description="Import a building model file and write the localizer's map of it "
                    "(model, edges, free space) into OUT, with no dataset rendered.")
    p.add_argument("file", help="the building model file (as python -m datagen.importers)")
    p.add_argument("out", help="the folder to write (made)")
    p.add_argument("--settings", default="{}", help="JSON mapping of world=file keys, e.g. "
                   "'{\"units\": 0.001, \"up_axis\": \"-y\"}'")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="[%(asctime)s][%(name)s][%(levelname)s] - %(message)s")
    with user_errors():
        try:
            settings = json.loads(args.settings)
        except json.JSONDecodeError as err:
            raise ValueError(f"--settings is not JSON: {err}") from None
        if not isinstance(settings, dict):
            raise ValueError(f"--settings must be a JSON mapping of world=file keys, got "
                             f"{args.settings}")
        write_file_map(args.file, args.out, settings)
    print(args.out)


if __name__ == "__main__":
    main()
