"""Rebuild a dataset's model edges: ``python -m datagen.mesh.rebuild_edges DATASET [...]``.

Reads ``world/model.npz`` (and ``world_truth/model.npz`` where the dataset has one), extracts
its model edges with the current ``datagen.mesh.edges.extract_edges`` and replaces ``edges.npz``
(and ``num_edges`` in ``world.json``), each written to a temporary file then renamed. Nothing
is rendered: the frames, labels and free space stay as they are, so a dataset rendered
earlier can be localized against the current edges. The crease threshold is the one the
dataset was generated with (``dataset.json`` ``generator.world.crease_deg``), unless
``--crease-deg`` is given.
"""

from __future__ import annotations

import argparse
import io
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from core.atomic import atomic_write_bytes, atomic_write_json
from core.config import user_errors
from core.dataset import read_json
from datagen.config import WorldConfig
from datagen.mesh.edges import EdgeExtractionConfig, extract_edges

#: the folders of a dataset that hold a world model.
WORLD_DIRS = ("world", "world_truth")


def dataset_crease_deg(root: Path) -> float:
    """The crease threshold ``root/dataset.json`` was generated with (the default when the
    file or the key is missing)."""
    f = root / "dataset.json"
    world = read_json(f).get("generator", {}).get("world", {}) if f.is_file() else {}
    return float(world.get("crease_deg", WorldConfig.crease_deg))


def rebuild_world_edges(world_dir: Path, crease_deg: float,
                        settings: EdgeExtractionConfig | None = None) -> tuple[int, int]:
    """Replace ``world_dir/edges.npz`` with the edges of ``world_dir/model.npz``
    (``extract_edges`` with ``crease_deg`` and ``settings``, None: the defaults).

    Returns:
        (segments before, segments after); before is -1 when there was no edges.npz.

    Raises:
        FileNotFoundError: no model.npz, naming it. ValueError: model.npz lacks a key.
    """
    model = world_dir / "model.npz"
    if not model.is_file():
        raise FileNotFoundError(f"{model}: no world model; is {world_dir.parent} a dataset "
                                "(datagen's output folder)?")
    m = np.load(model)
    for key in ("vertices", "faces", "face_class"):
        if key not in m:
            raise ValueError(f"{model}: key {key!r} missing; re-run datagen for this dataset")
    old = world_dir / "edges.npz"
    before = len(np.load(old)["segments"]) if old.is_file() else -1
    seg, cls, crease, normals = extract_edges(m["vertices"], m["faces"], m["face_class"],
                                               crease_deg, settings=settings)
    buf = io.BytesIO()
    np.savez_compressed(buf, segments=seg, classes=cls, crease_deg=crease, normals=normals)
    atomic_write_bytes(old, buf.getvalue())
    info_file = world_dir / "world.json"
    if info_file.is_file():
        info = {k: v for k, v in read_json(info_file).items() if k != "edges"}
        atomic_write_json(info_file, {**info, "num_edges": int(len(seg))})
    return before, len(seg)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m datagen.mesh.rebuild_edges",
                                description="Rebuild a dataset's world/edges.npz from its "
                                            "world/model.npz with the current code.")
    p.add_argument("dataset", type=Path, nargs="+", help="dataset folder(s)")
    p.add_argument("--crease-deg", type=float, default=None,
                   help="crease threshold, degrees (default: the dataset's own)")
    p.add_argument("--simplify-m", type=float, default=EdgeExtractionConfig.simplify_m,
                   help="metres, tolerance of straightening chained pieces (default "
                   f"{EdgeExtractionConfig.simplify_m})")
    p.add_argument("--min-length", type=float, default=EdgeExtractionConfig.min_length,
                   help="metres, shortest segment kept (default "
                        f"{EdgeExtractionConfig.min_length})")
    args = p.parse_args(argv)
    settings = replace(EdgeExtractionConfig(), simplify_m=args.simplify_m,
                       min_length=args.min_length)
    for root in args.dataset:
        crease = args.crease_deg if args.crease_deg is not None else dataset_crease_deg(root)
        dirs = [root / d for d in WORLD_DIRS if (root / d / "model.npz").is_file()]
        if not dirs:
            print(f"error: {root / 'world' / 'model.npz'}: not found; give a dataset folder",
                  file=sys.stderr)
            return 2
        for d in dirs:
            try:
                before, after = rebuild_world_edges(d, crease, settings)
            except (FileNotFoundError, ValueError) as err:
                print(f"error: {err}", file=sys.stderr)
                return 2
            print(f"{d}: {before} -> {after} model edge segments (crease {crease:g} deg)")
    return 0


if __name__ == "__main__":
    with user_errors():
        sys.exit(main())
