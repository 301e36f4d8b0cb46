"""COLLADA (.dae) files through pycollada (trimesh's own COLLADA reader drops the material
names that the name rules need).

The file's ``<unit meter=...>`` is applied; its ``<up_axis>`` is not (Gazebo does not apply it
either: files declared Y_UP often carry node matrices that already give Z-up geometry).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datagen.importers.building import Part


def _colour(material) -> np.ndarray:
    """Diffuse RGB of a pycollada material, NaN for a texture or none."""
    diffuse = getattr(getattr(material, "effect", None), "diffuse", None)
    if isinstance(diffuse, (tuple, list, np.ndarray)) and len(diffuse) >= 3:
        return np.asarray(diffuse[:3], np.float64)
    return np.full(3, np.nan)


def load_dae(path: Path) -> tuple[list[Part], float]:
    """The triangles of a COLLADA file in its scene's frame, in metres.

    Returns:
        parts: one per primitive, named ``geometry/material``; face_class UNSET.
        unit: metres per file unit (``<unit meter=...>``, 1 if absent).
    """
    import collada

    ignore = [collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError,
              collada.common.DaeIncompleteError]
    try:
        doc = collada.Collada(str(path), ignore=ignore)
    except Exception as err:  # pycollada raises many kinds for broken XML / COLLADA
        raise ValueError(f"{path}: not a readable COLLADA file ({type(err).__name__}: "
                         f"{err})") from None
    unit = float(doc.assetInfo.unitmeter or 1.0)
    parts: list[Part] = []
    if doc.scene is None:
        return parts, unit
    for geom in doc.scene.objects("geometry"):
        gname = geom.original.name or geom.original.id or "geometry"
        for prim in geom.primitives():
            material = getattr(prim, "material", None)
            if hasattr(prim, "triangleset"):
                prim = prim.triangleset()
            if not hasattr(prim, "triangles") or prim.vertex is None:
                continue  # lines
            idx = np.asarray(prim.vertex_index, np.int64).reshape(-1, 3)
            if not len(idx):
                continue
            mname = (material.name or material.id) if material is not None else "default"
            parts.append(Part(vertices=np.asarray(prim.vertex, np.float64) * unit, faces=idx,
                              name=f"{gname}/{mname}", colour=_colour(material)))
    return parts, unit
