"""COLLADA (.dae) files through pycollada (trimesh's own COLLADA reader drops the material
names that the name rules need).

The file's ``<unit meter=...>`` is applied; its ``<up_axis>`` is not (Gazebo does not apply it
either: files declared Y_UP often carry node matrices that already give Z-up geometry).
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote

import numpy as np

from datagen.importers.images import load_image
from datagen.mesh.building import Part


def _colour(material) -> np.ndarray:
    """Diffuse RGB of a pycollada material, NaN for a texture or none."""
    diffuse = getattr(getattr(material, "effect", None), "diffuse", None)
    if isinstance(diffuse, (tuple, list, np.ndarray)) and len(diffuse) >= 3:
        return np.asarray(diffuse[:3], np.float64)
    return np.full(3, np.nan)


def _texture(prim, material, folder: Path) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The diffuse image of a triangle primitive's material (``images.load_image``) and
    (T, 3, 2) corner UVs of its first texture coordinate set; (None, None) without."""
    diffuse = getattr(getattr(material, "effect", None), "diffuse", None)
    image = getattr(getattr(getattr(diffuse, "sampler", None), "surface", None), "image", None)
    sets, index = getattr(prim, "texcoordset", ()), getattr(prim, "texcoord_indexset", ())
    if image is None or not getattr(image, "path", None) or not len(sets) or not len(index):
        return None, None
    name = unquote(image.path.removeprefix("file://"))
    img = load_image(str((folder / name).resolve()))
    if img is None:
        return None, None
    return img, np.asarray(sets[0], np.float32)[np.asarray(index[0]).reshape(-1, 3)]


def load_dae(path: Path) -> tuple[list[Part], float]:
    """The triangles of a COLLADA file in its scene's frame, in metres.

    Returns:
        parts: one per primitive, named ``geometry/material``, with the material's diffuse
            colour or image texture (and corner UVs); face_class UNSET.
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
            texture, uv = _texture(prim, material, path.parent)
            parts.append(Part(vertices=np.asarray(prim.vertex, np.float64) * unit, faces=idx,
                              name=f"{gname}/{mname}", colour=_colour(material),
                              texture=texture, uv=uv))
    return parts, unit
