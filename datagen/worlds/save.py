"""Write a built world to ``<dataset>/world/`` (see core.dataset for the layout)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import trimesh

from core import classes as C
from core.atomic import atomic_write_bytes, atomic_write_json
from core.dataset import World


def _npz_bytes(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def save_world(d: str | Path, w: World) -> None:
    """model.npz, edges.npz (not for a world built without edges: ``num_edges`` None),
    free.npz, world.json, model.ply (face colour = class colour) and, for an imported
    building, import_summary.json."""
    d = Path(d)
    atomic_write_bytes(d / "model.npz", _npz_bytes(
        vertices=w.vertices, faces=w.faces.astype(np.int64), face_class=w.face_class))
    normals = {} if w.normals is None else {"normals": w.normals}
    if w.info.get("num_edges", 0) is None:  # built without edges: none, as world.json says
        (d / "edges.npz").unlink(missing_ok=True)
    else:
        atomic_write_bytes(d / "edges.npz", _npz_bytes(
            segments=w.segments, classes=w.segment_classes, crease_deg=w.crease_deg,
            **normals))
    w.free.save(d / "free.npz")
    atomic_write_json(d / "world.json", w.info)
    if "import_summary" in w.info:
        atomic_write_json(d / "import_summary.json", w.info["import_summary"])
    colors = np.concatenate([C.palette()[w.face_class],
                             np.full((len(w.faces), 1), 255, np.uint8)], axis=1)
    mesh = trimesh.Trimesh(w.vertices, w.faces, face_colors=colors, process=False)
    atomic_write_bytes(d / "model.ply", trimesh.exchange.ply.export_ply(mesh, encoding="ascii"))
