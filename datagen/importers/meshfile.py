"""Single mesh files: glTF/GLB, OBJ, PLY, STL through trimesh, COLLADA through ``dae``.

Units: glTF is metres by its spec, COLLADA says its ``<unit>``; OBJ/PLY/STL take ``units``
(metres per file unit). Up axis: glTF is Y-up by its spec; the others take ``up_axis`` (one
of ``orient.AXES``, or ``auto``: found from the mesh, ``orient.find_up_axis``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datagen.importers.dae import load_dae
from datagen.importers.images import linear_image
from datagen.importers.orient import axis_name, find_up_axis, to_z_up
from datagen.mesh.building import Part, check_finite

#: Y-up to Z-up: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], np.float64)


def _trimesh_colour(mesh) -> np.ndarray:
    """(3,) or (m, 3) linear-ish RGB in [0, 1] of a trimesh mesh's visual, NaN if it has
    only a texture or nothing."""
    visual = mesh.visual
    if visual.kind == "face" or visual.kind == "vertex":
        return np.asarray(visual.face_colors[:, :3], np.float64) / 255.0
    material = getattr(visual, "material", None)
    if material is not None and getattr(material, "baseColorTexture", None) is None \
            and getattr(material, "image", None) is None:
        rgba = getattr(material, "baseColorFactor", None)
        if rgba is None:
            rgba = getattr(material, "main_color", None)
        if rgba is not None:
            rgba = np.asarray(rgba, np.float64)
            return rgba[:3] / (255.0 if rgba.dtype.kind in "ui" or rgba.max() > 1 else 1.0)
    return np.full(3, np.nan)


def _trimesh_texture(mesh, images: dict[int, np.ndarray]
                     ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The base colour image of a textured trimesh mesh (``images.linear_image``; ``images``
    caches them by PIL image) and (m, 3, 2) corner UVs; (None, None) without."""
    visual = mesh.visual
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    pil = getattr(material, "baseColorTexture", None)
    if pil is None:
        pil = getattr(material, "image", None)
    if visual.kind != "texture" or uv is None or pil is None or len(uv) != len(mesh.vertices):
        return None, None
    if id(pil) not in images:
        images[id(pil)] = linear_image(np.asarray(pil.convert("RGB")))
    return images[id(pil)], np.asarray(uv, np.float32)[np.asarray(mesh.faces)]


def _load_trimesh(path: Path) -> list[Part]:
    """Parts of a file trimesh reads, in the file's frame and units (scene graph applied);
    ValueError for a vertex that is NaN or infinite (``check_finite``)."""
    import trimesh

    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as err:  # trimesh raises many kinds for broken files
        raise ValueError(f"{path}: not a readable mesh file ({type(err).__name__}: {err})"
                         ) from None
    parts, matrices, images = [], [], {}
    for node in scene.graph.nodes_geometry:
        matrix, gname = scene.graph[node]
        mesh = scene.geometry[gname]
        if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
            continue
        material = getattr(getattr(mesh.visual, "material", None), "name", None)
        texture, uv = _trimesh_texture(mesh, images)
        parts.append(Part(mesh.vertices, mesh.faces, f"{node}/{material or gname}",
                          _trimesh_colour(mesh), texture=texture, uv=uv))
        matrices.append(np.asarray(matrix, np.float64))
    check_finite(parts, path)
    return [p.moved(m) for p, m in zip(parts, matrices, strict=True)]


def load_mesh_file(path: Path, units: float = 1.0, up_axis: str = "z"
                   ) -> tuple[list[Part], dict]:
    """The triangles of a mesh file in metres, Z up.

    Args:
        path: a .glb/.gltf/.obj/.ply/.dae/.stl file.
        units: metres per file unit for OBJ/PLY/STL.
        up_axis: the file's up axis for OBJ/PLY/STL/DAE: one of ``orient.AXES`` (``x``,
            ``y``, ``z`` mean +x, +y, +z) or ``auto`` (found from the mesh).

    Returns:
        parts (face_class UNSET) and info: ``units`` (metres per file unit applied),
        ``up_axis`` (the axis turned to +Z), ``up_axis_from`` (``format``, ``setting`` or
        ``auto``) and, for ``auto``, ``up_axis_found`` (``orient.UpAxis.as_info``).

    Raises:
        ValueError: an unreadable file, or vertices that are NaN or infinite (naming the file
            and their number).
    """
    ext = path.suffix.lower()
    info: dict = {}
    if ext == ".dae":
        parts, scale = load_dae(path)
        check_finite(parts, path)
    else:
        parts = _load_trimesh(path)
        gltf = ext in (".glb", ".gltf")
        scale = 1.0 if gltf else units
        for p in parts:
            p.vertices = p.vertices * scale
    if ext in (".glb", ".gltf"):
        up, source = "+y", "format"
    elif up_axis == "auto":
        found = _find_up(parts)
        up, source = found["axis"], "auto"
        info["up_axis_found"] = found
    else:
        up, source = axis_name(up_axis), "setting"
    if up != "+z":
        m = to_z_up(up)
        parts = [p.moved(m) for p in parts]
    return parts, {"units": scale, "up_axis": up, "up_axis_from": source, **info}


def _find_up(parts: list[Part]) -> dict:
    """``orient.find_up_axis`` of the parts together (``+z`` for no triangles)."""
    parts = [p for p in parts if len(p.faces)]
    if not parts:
        return {"axis": "+z", "sureness": 0.0}
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])[:-1]
    vertices = np.concatenate([p.vertices for p in parts])
    faces = np.concatenate([np.asarray(p.faces, np.int64) + o
                            for p, o in zip(parts, offsets, strict=True)])
    return find_up_axis(vertices, faces).as_info()
