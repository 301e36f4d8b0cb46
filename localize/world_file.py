"""``world=FILE``: a building model file as the localizer's map, with no dataset rendered.

**The import** is datagen's: ``python -m datagen.worlds.file_map FILE DIR`` (the import, the
model edges and the free space of ``python -m datagen world=file``, written as a dataset's
``world/``; ``core.dataset.load_world`` reads it), run in a process of its own. localize imports
no datagen (the stages import only downward: tests/test_imports.py), and a localizer on a drone
needs none of the importer's libraries; the import's memory (a hospital's textures) is freed
when that process ends. Its log comes through this process's, its user errors (``error: ...``)
become a ``ValueError`` naming ``world=FILE``.

**The cache** holds one map per content: ``<world.cache>/<key>/<inputs>/``.

- ``key``: sha256 of the file's bytes, its extension (the format is chosen by it), the import
  keys given (``world.*``, canonical JSON) and the importer's code (the .py files of the
  ``datagen`` and ``core`` packages). Never the file's path or name: the same building under
  another name or in another folder finds the same map.
- ``inputs``: sha256 of the other files the import read (a Gazebo world's models, their meshes
  and images; the import's ``inputs.json``) and their contents. Each is named relative to the
  building file's folder where it lies under that folder's parent (Gazebo's resource root: a
  world's ``../models``), else by its absolute path. A map is reused only where every one of
  them still has the bytes it had: a copy of a world beside other models is imported again.
- Written atomically: the import writes into ``<key>/.tmp-<pid>-<random>/``, which is renamed
  to ``<key>/<inputs>/`` when complete; a failed import leaves nothing, a killed one a
  ``.tmp-*`` folder that lookups ignore. Of two runs importing the same content at once, the
  first rename wins and the other's copy is dropped.

Where: ``world.cache`` (default: ``$XDG_CACHE_HOME/edgeloc/worlds``, else
``~/.cache/edgeloc/worlds``), a user cache folder rather than the output root, because an entry
depends on content alone: the offline app's runs of any ``name``, ``out_root`` or working
folder and the live node share it (the node is often started from elsewhere, by a launch
file), and removing old reports does not cost a large building's import again (the AWS
bookstore: about a minute on 2 cores).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import secrets
import shutil
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib.util import find_spec
from pathlib import Path

import numpy as np

from core.atomic import file_sha256
from core.dataset import Camera, World, load_world
from localize.config import WorldFileConfig

log = logging.getLogger(__name__)

#: The datagen command that imports a file and writes its map (datagen/worlds/file_map.py).
IMPORTER = "datagen.worlds.file_map"
#: The import's list of the files it read, in the map folder.
INPUTS = "inputs.json"
#: Bumped when the cache's layout changes.
CACHE_VERSION = b"edgeloc-world-cache-1"
#: The packages whose code makes the map (their .py files are in the key).
IMPORTER_PACKAGES = ("datagen", "core")


def cache_root(cache: str | None) -> Path:
    """The cache folder: ``cache`` (``world.cache``), else ``$XDG_CACHE_HOME/edgeloc/worlds``, else
    ``~/.cache/edgeloc/worlds``."""
    if cache:
        return Path(cache).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "edgeloc" / "worlds"


@cache
def importer_digest() -> str:
    """sha256 of the importer's code: every .py file of ``IMPORTER_PACKAGES``, by relative
    path. A change to it (a new edge rule, another free-space margin) makes new maps."""
    h = hashlib.sha256()
    for name in IMPORTER_PACKAGES:
        spec = find_spec(name)  # finds the package without importing it
        if spec is None or not spec.submodule_search_locations:
            raise RuntimeError(f"the {name} package is not installed: world=FILE needs the "
                               "importer (pip install -e . in the repository)")
        root = Path(next(iter(spec.submodule_search_locations)))
        for f in sorted(root.rglob("*.py")):
            h.update(f"{name}/{f.relative_to(root).as_posix()}\0".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def content_key(path: str | Path, settings: Mapping) -> str:
    """The cache key of a building file: sha256 of its bytes, its extension, the import
    settings and ``importer_digest`` (module docstring)."""
    path = Path(path)
    h = hashlib.sha256(CACHE_VERSION)
    h.update(path.suffix.lower().encode() + b"\0")
    h.update(file_sha256(path).encode())
    h.update(json.dumps(dict(settings), sort_keys=True, default=str).encode() + b"\0")
    h.update(importer_digest().encode())
    return h.hexdigest()


def _input_name(dep: Path, file: Path) -> str:
    """How ``inputs.json`` names a file the import read: relative to the building file's
    folder where it lies under that folder's parent, else absolute."""
    folder = file.parent.resolve()
    try:
        dep.resolve().relative_to(folder.parent)
    except ValueError:
        return str(dep.resolve())
    return os.path.relpath(dep.resolve(), folder)


def _input_path(name: str, file: Path) -> Path:
    p = Path(name)
    return p if p.is_absolute() else file.parent.resolve() / p


def _inputs_hold(entry: Path, file: Path) -> bool:
    """Whether every file ``entry``'s import read, found from ``file``, has the bytes it had."""
    try:
        inputs = json.loads((entry / INPUTS).read_text())["inputs"]
    except (OSError, ValueError, KeyError):
        return False
    for item in inputs:
        p = _input_path(item["path"], file)
        if not p.is_file() or file_sha256(p) != item["sha256"]:
            log.info("world: %s changed since the map in %s was made", p, entry)
            return False
    return True


@dataclass(frozen=True)
class FileMap:
    """A building file's map in the cache.

    Attributes:
        file: the building file given.
        folder: the map (a dataset's ``world/`` files, ``inputs.json``).
        digest: ``<key>/<inputs>``, the content it was made from (what a report records).
        reused: it was in the cache (False: imported by this call).
    """

    file: Path
    folder: Path
    digest: str
    reused: bool

    def world(self) -> World:
        """The map as the localizer reads it."""
        return load_world(self.folder)


def file_map(path: str | Path, settings: Mapping | None = None,
             cache: str | None = None) -> FileMap:
    """The map of a building file: from the cache, else imported into it (module docstring).

    Args:
        path: the building file (whatever ``python -m datagen.importers`` reads).
        settings: ``world=file``'s import keys (``WorldFileConfig.import_settings``); {}: the
            importer's defaults.
        cache: the cache folder (``cache_root``).

    Raises:
        FileNotFoundError: the file is missing (names ``world=``).
        ValueError: the import refused the file or a setting (its error, naming ``world=``).
        RuntimeError: the importer failed otherwise (its last output).
    """
    file = Path(path).expanduser()
    if not file.is_file():
        what = "a folder" if file.is_dir() else "not found"
        raise FileNotFoundError(f"world={path}: {what}; name a building model file (a Gazebo "
                                ".world or .sdf, a mesh .glb .gltf .obj .ply .dae .stl, or an "
                                ".ifc; docs/importers.md)")
    settings = dict(settings or {})
    key = content_key(file, settings)
    root = cache_root(cache) / key[:32]
    if root.is_dir():
        for entry in sorted(root.iterdir()):
            if not entry.name.startswith(".") and _inputs_hold(entry, file):
                log.info("world: %s: reusing its map %s (same content: no import)", file, entry)
                return FileMap(file, entry, f"{key[:32]}/{entry.name}", True)
    root.mkdir(parents=True, exist_ok=True)
    tmp = root / f".tmp-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        log.info("world: %s: importing (python -m %s; cached in %s)", file, IMPORTER, root)
        run_importer(file, settings, tmp)
        read = json.loads((tmp / INPUTS).read_text())["inputs"]
        own = str(file.resolve())
        inputs = [{"path": _input_name(Path(p), file), "sha256": file_sha256(Path(p))}
                  for p in read if p != own]
        variant = hashlib.sha256(json.dumps(sorted(i["sha256"] for i in inputs)).encode())
        (tmp / INPUTS).write_text(json.dumps({"inputs": inputs}, indent=1))
        final = root / variant.hexdigest()[:16]
        try:
            tmp.rename(final)
        except OSError:
            if not (final / INPUTS).is_file():
                raise
            log.info("world: %s: another run made the same map first; using it", file)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if not any(root.iterdir()):  # a failed first import leaves no empty key folder
            root.rmdir()
    log.info("world: %s: map written to %s", file, final)
    return FileMap(file, final, f"{key[:32]}/{final.name}", False)


def run_importer(file: Path, settings: Mapping, out: Path) -> None:
    """Run ``python -m datagen.worlds.file_map FILE OUT --settings JSON`` in this interpreter,
    the project this module belongs to first on its path, its log passed to this process's.

    Raises:
        ValueError: the importer's user error (its ``error:`` line), naming ``world=``.
        RuntimeError: it failed otherwise (its last lines).
    """
    project = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([project, *filter(None, [env.get("PYTHONPATH")])])
    env.pop("HYDRA_FULL_ERROR", None)
    cmd = [sys.executable, "-m", IMPORTER, str(file), str(out), "--settings",
           json.dumps(dict(settings))]
    lines: list[str] = []
    with subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=env) as proc:
        assert proc.stderr is not None
        level = logging.INFO
        for line in proc.stderr:
            line = line.rstrip("\n")
            lines.append(line)
            head, _, rest = line.partition(":")
            if head in ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"):
                level, line = getattr(logging, head), rest
            if not line.startswith("error: "):
                log.log(level, "import: %s", line)
    errors = [ln[len("error: "):] for ln in lines if ln.startswith("error: ")]
    if proc.returncode == 2 and errors:
        raise ValueError(f"world={file}: {errors[-1]} (docs/importers.md)")
    if proc.returncode != 0:
        tail = "\n".join(lines[-15:])
        raise RuntimeError(f"world={file}: the import (python -m {IMPORTER}) failed with exit "
                           f"status {proc.returncode}:\n{tail}")


def check_world_keys(cfg: Mapping, command_line_keys: Sequence[str],
                     recording: bool | None) -> None:
    """Refuse ``world=`` with ``dataset=`` on the command line (both name the building model:
    one would be ignored) and, in the offline app, ``world=`` without a recording (a building
    file has no flights to run).

    Args:
        cfg: the composed config (``world.path``, ``dataset``).
        command_line_keys: the keys the command line sets (``resolve.override_keys``).
        recording: whether a recording is given; None where the app has none (the node).
    """
    path = cfg["world"]["path"]
    if not path:
        return
    if "dataset" in command_line_keys:
        raise ValueError(f"world={path} and dataset={cfg['dataset']} both name the building "
                         "model: give one. world=FILE imports the file (the camera from the "
                         "recording or the CameraInfo, the shipped SegNet); dataset=DATASET "
                         "reads the model, camera and SegNet of a dataset python -m datagen made")
    if recording is False:
        raise ValueError(f"world={path}: a building file has no flights to localize; give a "
                         "recording in it (recording=PATH), or localize a dataset's flights "
                         "with dataset=DATASET instead of world=")


def map_of(world: WorldFileConfig) -> FileMap:
    """The map of the ``world`` settings (``file_map`` of ``world.path``, its import keys and
    ``world.cache``)."""
    return file_map(world.path, world.import_settings(), world.cache)


def frames_target(size: tuple[int, int], body_from_cam: np.ndarray | None = None) -> Camera:
    """What a recording's or a live camera's frames are delivered as when the map is a file:
    ``size`` (W, H) px, the SegNet's input, and the camera mount (None: the recording's own,
    else ``core.imaging.camera.forward_mount``'s, with a warning:
    ``recordings.recording.delivered_camera``). Its K is NaN: the intrinsics come with the
    frames (camera.yaml, a bag's or the node's CameraInfo)."""
    w, h = (int(v) for v in size)
    return Camera(np.full((3, 3), np.nan), w, h, body_from_cam)


def segnet_size(onnx_path: str | Path) -> tuple[int, int]:
    """(W, H) px, the input of a segnet.onnx (its metadata ``input_width``, ``input_height``)."""
    from core.segmenter import read_metadata

    meta = read_metadata(onnx_path)
    try:
        return int(meta["input_width"]), int(meta["input_height"])
    except KeyError as err:
        raise ValueError(f"{onnx_path}: metadata key {err} missing; give onnx_model= a "
                         "segnet.onnx written by python -m train") from None
