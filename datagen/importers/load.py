"""``load_building``: any supported building model file to one classed triangle mesh."""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from core import classes as C
from core.config import as_config
from datagen.importers.classify import add_ceiling, ceiling_height, class_shares, classify
from datagen.importers.config import ImportConfig
from datagen.importers.orient import axis_name
from datagen.importers.summary import check_size, file_units
from datagen.mesh.building import (
    Building,
    Part,
    assemble,
    check_finite,
    face_areas_normals,
    weighted_quantile,
)

log = logging.getLogger(__name__)
SDF_EXTENSIONS = (".world", ".sdf")
MESH_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply", ".dae", ".stl")
IFC_EXTENSIONS = (".ifc",)
UNIT_FORMATS = ("obj", "ply", "stl")  # the formats whose units are world.units
EXTENSIONS = SDF_EXTENSIONS + MESH_EXTENSIONS + IFC_EXTENSIONS
FAR_FACTOR, FAR_M = 10.0, 100.0  # a part this many times the model's size away, and at
# least these metres, is left out (far_parts)
CHOICES = {"doors": ("open", "closed"), "ceiling": ("auto", "none")}


def check_settings(s: ImportConfig) -> None:
    """Raise ValueError naming the setting for a value out of its range."""
    for key, allowed in CHOICES.items():
        if getattr(s, key) not in allowed:
            raise ValueError(f"{key}: {getattr(s, key)!r} is not one of {', '.join(allowed)}")
    if s.up_axis != "auto":
        axis_name(s.up_axis)
    if not s.units > 0:
        raise ValueError(f"units: {s.units} must be > 0 (metres per file unit)")
    if not s.floor_tolerance >= 0:
        raise ValueError(f"floor_tolerance: {s.floor_tolerance} must be >= 0")


def has_ceiling(b: Building, floor_z: float, top: float) -> bool:
    """Whether ceiling faces above the walls' mid-height cover at least half the floor's
    area (down-facing faces lower down, e.g. table undersides, do not count)."""
    area, _ = face_areas_normals(b.vertices, b.faces)
    z = b.vertices[b.faces][:, :, 2].mean(axis=1)
    high = (b.face_class == C.CEILING) & (z > (floor_z + top) / 2)
    return bool(area[high].sum() >= 0.5 * area[b.face_class == C.FLOOR].sum())


def far_parts(parts: list[Part], factor: float = FAR_FACTOR, least: float = FAR_M
               ) -> dict[int, float]:
    """Parts lying far from the rest (a model left at z = 343 km): index into ``parts`` ->
    distance (m) of its nearest vertex from the box of the middle 96 % of the surface area
    (per axis), for those farther than ``factor`` times that box's diagonal and at least
    ``least`` metres."""
    full = [i for i, p in enumerate(parts) if len(p.faces)]
    if len(full) < 2:
        return {}
    tri = [np.asarray(parts[i].vertices, np.float64)[parts[i].faces] for i in full]
    centre = np.concatenate([t.mean(axis=1) for t in tri])
    area = np.concatenate([np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]),
                                          axis=1) / 2 for t in tri]) + 1e-12
    lo = np.array([weighted_quantile(centre[:, a], area, 0.02) for a in range(3)])
    hi = np.array([weighted_quantile(centre[:, a], area, 0.98) for a in range(3)])
    limit = max(least, factor * float(np.linalg.norm(hi - lo)))
    out: dict[int, float] = {}
    for i in full:
        v = parts[i].vertices
        d = float(np.linalg.norm(np.maximum(np.maximum(lo - v, v - hi), 0.0), axis=1).min())
        if d > limit:
            out[i] = round(d, 1)
    return out


def read_parts(path: Path, s: ImportConfig) -> tuple[list[Part], dict]:
    """The reader for the file's extension: parts and the reader's info."""
    ext = path.suffix.lower()
    if ext in SDF_EXTENSIONS:
        from datagen.importers.sdf import load_sdf

        parts, info = load_sdf(path, list(s.model_path))
        return parts, {"format": "sdf", **info}
    if ext in MESH_EXTENSIONS:
        from datagen.importers.meshfile import load_mesh_file

        parts, info = load_mesh_file(path, s.units, s.up_axis)
        return parts, {"format": ext.lstrip("."), **info}
    if ext in IFC_EXTENSIONS:
        from datagen.importers.ifc import load_ifc

        parts, info = load_ifc(path, s.storey, s.doors)
        return parts, {"format": "ifc", **info}
    raise ValueError(f"{path}: unknown extension {ext or '(none)'!r}; a building model is one "
                     f"of {', '.join(EXTENSIONS)}")


def load_building(path: str | Path | None = None,
                  settings: ImportConfig | Mapping | None = None) -> Building:
    """Import a building model as one triangle mesh with a class per face.

    Args:
        path: the model file, chosen by extension: .world/.sdf (Gazebo), .glb/.gltf/.obj/
            .ply/.dae/.stl (a mesh), .ifc; None: ``settings.path``.
        settings: ``ImportConfig`` or a mapping of the keys that differ (None: defaults).

    Returns:
        the Building (metres, Z up); ``info`` holds format, counts, missing models and
        meshes, parts left out as far from the rest (``far_parts``), class area shares, the
        faces classed by format / name / geometry over a name / geometry (``classed_by``),
        floor and ceiling heights, units, the up axis and the import time (s).

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: an unknown extension, a bad setting, an unreadable file, vertices that are
            NaN or infinite, a model larger than a building (``summary.check_size``: read in
            the wrong units), a model with no floor or no walls, a storey that does not
            exist; each naming the file or key.
    """
    t0 = time.perf_counter()
    s = as_config(ImportConfig, settings, "world")
    check_settings(s)
    raw = str(path if path is not None else s.path)
    if not raw:
        raise ValueError("world.path: no building model file given; name one: "
                         f"world.path=FILE ({', '.join(EXTENSIONS)})")
    path = Path(raw)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file (path / world.path must name a "
                                f"building model file: {', '.join(EXTENSIONS)})")
    parts, info = read_parts(path, s)
    check_finite(parts, path)
    far = far_parts(parts)
    info["far_parts"] = {parts[i].name: d for i, d in far.items()}
    if far:
        log.warning("%s: %d parts lie far from the rest and are left out: %s", path,
                    len(far), ", ".join(f"{n} ({d:.0f} m)" for n, d in
                                        info["far_parts"].items()))
        parts = [p for i, p in enumerate(parts) if i not in far]
    if not any(len(p.faces) for p in parts):
        raise ValueError(f"{path}: no triangles found (nothing to import)")
    points = np.concatenate([p.vertices for p in parts if len(p.faces)])
    check_size(path, points.min(axis=0), points.max(axis=0), file_units(info),
               info["format"] in UNIT_FORMATS)
    b = assemble(parts)
    floor_z = classify(b, s.name_rules, s.floor_tolerance, str(path))
    added = 0
    top = ceiling_height(b)
    if s.ceiling == "auto" and not has_ceiling(b, floor_z, top):
        added = add_ceiling(b, top)
    lo, hi = b.vertices.min(axis=0), b.vertices.max(axis=0)
    counts = np.bincount(b.face_class, minlength=C.NUM_CLASSES)
    b.info = {
        "source": str(path), **info,
        "vertices": int(len(b.vertices)), "faces": int(len(b.faces)),
        "faces_per_class": {C.NAMES[i]: int(counts[i]) for i in range(C.NUM_CLASSES)
                            if counts[i]},
        "class_shares": class_shares(b), "classed_by": b.info["classed_by"],
        "floor_z": round(floor_z, 4),
        "wall_top_z": round(top, 4), "ceiling_added": added,
        "bounds": [lo.round(4).tolist(), hi.round(4).tolist()],
        "seconds": round(time.perf_counter() - t0, 3),
    }
    return b
