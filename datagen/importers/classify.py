"""Classes for every face of an imported building, and the open-top ceiling.

Order: the format's class (IFC type, set by the reader); then the name rules on the most
specific part of the face's name that any rule matches (the material before the node,
visual, link and model: ``name_evidence``); geometry overrules a name where a large horizontal
surface is plainly floor or ceiling (``overruled``); the faces still without a class by
geometry: the model's own furniture (pieces standing on the floor that do not reach the
storey's top: ``own_furniture``, ``datagen.mesh.furniture``) is clutter; of the rest, a
horizontal up-facing face within ``floor_tolerance`` of the storey floor is floor, a
horizontal down-facing one ceiling, the rest wall.
"""

from __future__ import annotations

import re

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from core import classes as C
from datagen.importers.config import NameRule
from datagen.mesh.building import UNSET, Building, face_areas_normals, weighted_quantile
from datagen.mesh.furniture import furniture_faces

HORIZONTAL = 0.9  # |normal z| from which a face is horizontal (within ~25 deg)
LARGE_M2 = 1.0  # m^2, a connected horizontal surface from which geometry overrules a name
MIN_STOREY = 1.8  # m, the least floor-to-top height for a ceiling by geometry


def compile_rules(rules: list[NameRule]) -> list[tuple[re.Pattern, int]]:
    """(regex, class id) per rule; a bad regex or class name raises naming the rule."""
    out = []
    for i, rule in enumerate(rules):
        if rule.cls not in C.ID:
            raise ValueError(f"name_rules[{i}].cls: unknown class {rule.cls!r}; use one of "
                             f"{', '.join(C.NAMES)}")
        try:
            out.append((re.compile(rule.pattern, re.IGNORECASE), C.ID[rule.cls]))
        except re.error as err:
            raise ValueError(f"name_rules[{i}].pattern: {rule.pattern!r} is not a regex "
                             f"({err})") from None
    return out


def name_evidence(names: list[str], rules: list[NameRule]) -> tuple[np.ndarray, np.ndarray]:
    """The class each name gives and how specific the deciding part is.

    A name is split at ``/`` into parts (SDF ``model/.../link/visual/geometry/material``, a
    mesh file's ``node/material``); the parts are tried from the last (the material, the
    most specific) to the first (the model), and the first part in which a rule's pattern
    occurs decides, by the first such rule (so a material ``Carpet_...`` decides before a
    link ``walls``, and ``..._floor_01_walls`` is still wall).

    Returns:
        (len(names),) uint8 classes, UNSET where no rule occurs in any part; (len(names),)
        int16 depth of the deciding part (0: the last part, 1: the one before, ...; -1
        where none).
    """
    compiled = compile_rules(rules)
    cls = np.full(len(names), UNSET, np.uint8)
    depth = np.full(len(names), -1, np.int16)
    for i, name in enumerate(names):
        for d, part in enumerate(reversed(name.split("/"))):
            hit = next((c for rx, c in compiled if rx.search(part)), None)
            if hit is not None:
                cls[i], depth[i] = hit, d
                break
    return cls, depth


def name_classes(names: list[str], rules: list[NameRule]) -> np.ndarray:
    """(len(names),) uint8: the class each name gives (``name_evidence``), UNSET where no
    rule matches."""
    return name_evidence(names, rules)[0]


def floor_height(z: np.ndarray, area: np.ndarray, normal: np.ndarray,
                 face_class: np.ndarray, bin_m: float = 0.1) -> float | None:
    """The storey floor's height (m): the area-weighted median height of the up-facing
    horizontal faces classed floor if any, else of the lowest 0.1 m band holding at least
    half the area of the largest band of up-facing horizontal faces; None without either."""
    up = normal[:, 2] >= HORIZONTAL
    floor = up & (face_class == C.FLOOR)
    if floor.any():
        return weighted_quantile(z[floor], area[floor], 0.5)
    if not up.any():
        return None
    band = np.floor(z[up] / bin_m).astype(np.int64)
    bands, inv = np.unique(band, return_inverse=True)
    band_area = np.bincount(inv.ravel(), weights=area[up])
    lowest = bands[np.flatnonzero(band_area >= 0.5 * band_area.max())[0]]
    sel = band == lowest
    return weighted_quantile(z[up][sel], area[up][sel], 0.5)


def storey_top(vertices: np.ndarray, faces: np.ndarray, normal: np.ndarray,
               keep: np.ndarray) -> float | None:
    """Height (m) of the storey's top: the 98th area-weighted percentile of the highest
    vertices of the vertical faces (|normal z| < 0.3) in ``keep`` (F,) bool; None without."""
    vertical = keep & (np.abs(normal[:, 2]) < 0.3)
    if not vertical.any():
        return None
    area, _ = face_areas_normals(vertices, faces[vertical])
    return weighted_quantile(vertices[faces[vertical]][:, :, 2].max(axis=1), area, 0.98)


def surface_areas(faces: np.ndarray, face_name: np.ndarray, area: np.ndarray,
                  sel: np.ndarray) -> np.ndarray:
    """(F,) the area (m^2) of the connected surface (faces of one name sharing a vertex) of
    the faces in ``sel`` (F,) bool that each face belongs to; 0 outside ``sel``."""
    out = np.zeros(len(faces))
    if not sel.any():
        return out
    pairs = np.stack([faces[sel].ravel(), np.repeat(face_name[sel], 3)], axis=1)
    _, node = np.unique(pairs, axis=0, return_inverse=True)
    f = node.reshape(-1, 3)
    n = int(node.max()) + 1
    graph = coo_matrix((np.ones(2 * len(f)), (np.concatenate([f[:, 0], f[:, 1]]),
                                              np.concatenate([f[:, 1], f[:, 2]]))),
                       shape=(n, n))
    _, label = connected_components(graph, directed=False)
    per = np.bincount(label[f[:, 0]], weights=area[sel], minlength=label.max() + 1)
    out[sel] = per[label[f[:, 0]]]
    return out


def geometry_classes(z: np.ndarray, normal: np.ndarray, floor_z: float,
                     tolerance: float) -> np.ndarray:
    """(F,) uint8 class by geometry: up-facing horizontal near the floor -> floor,
    down-facing horizontal -> ceiling, the rest -> wall."""
    out = np.full(len(z), C.WALL, np.uint8)
    out[(normal[:, 2] >= HORIZONTAL) & (np.abs(z - floor_z) <= tolerance)] = C.FLOOR
    out[normal[:, 2] <= -HORIZONTAL] = C.CEILING
    return out


def overruled(b: Building, z: np.ndarray, area: np.ndarray, normal: np.ndarray,
              named: np.ndarray, depth: np.ndarray, floor_z: float,
              tolerance: float) -> np.ndarray:
    """(F,) uint8 the class geometry gives over a name, UNSET where it gives none.

    A large (``LARGE_M2``, one connected surface of one name) up-facing horizontal surface within
    ``tolerance`` of the floor is floor, a large down-facing one within ``tolerance`` of the
    storey's top (``storey_top`` of the faces not named door, window or clutter, at least
    ``MIN_STOREY`` above the floor) is ceiling; either overrules a name unless the name is
    the material's (the last part) and says door, window or clutter.

    Args:
        named: (F,) bool, faces classed by a name; depth: (F,) the deciding part's depth.
    """
    out = np.full(len(z), UNSET, np.uint8)
    kept = named & ~((depth == 0) & np.isin(b.face_class, (C.DOOR, C.WINDOW, C.CLUTTER)))
    up = (normal[:, 2] >= HORIZONTAL) & (np.abs(z - floor_z) <= tolerance)
    out[kept & up & (b.face_class != C.FLOOR)
        & (surface_areas(b.faces, b.face_name, area, up) >= LARGE_M2)] = C.FLOOR
    structure = ~np.isin(b.face_class, (C.DOOR, C.WINDOW, C.CLUTTER))
    top = storey_top(b.vertices, b.faces, normal, structure)
    if top is None or top - floor_z < MIN_STOREY:
        return out
    down = (normal[:, 2] <= -HORIZONTAL) & (np.abs(z - top) <= tolerance)
    out[kept & down & (b.face_class != C.CEILING)
        & (surface_areas(b.faces, b.face_name, area, down) >= LARGE_M2)] = C.CEILING
    return out


def own_furniture(b: Building, normal: np.ndarray, unset: np.ndarray, floor_z: float,
                  tolerance: float) -> np.ndarray:
    """(F,) bool: the faces of ``unset`` (F,) bool that are the model's own furniture
    (``datagen.mesh.furniture``: standing on the floor, not reaching the storey's top);
    none where the storey is lower than ``MIN_STOREY`` (no top to measure against)."""
    top = storey_top(b.vertices, b.faces, normal,
                     ~np.isin(b.face_class, (C.DOOR, C.WINDOW, C.CLUTTER)))
    if top is None or top - floor_z < MIN_STOREY or not unset.any():
        return np.zeros(len(b.faces), bool)
    return furniture_faces(b.vertices, b.faces, normal, unset, floor_z, top, tolerance)


def classify(b: Building, rules: list[NameRule], tolerance: float, source: str) -> float:
    """Fill the UNSET classes of ``b`` in place (names, geometry over names, then geometry
    for the rest: furniture, floor, ceiling, wall) and check that the result has a floor
    below walls. Sets ``b.info["classed_by"]``: faces classed by the format, by a name, by
    geometry over a name, by geometry alone as floor, ceiling or wall, and as furniture
    (clutter). Returns the floor height (m)."""
    area, normal = face_areas_normals(b.vertices, b.faces)
    z = b.vertices[b.faces][:, :, 2].mean(axis=1)
    unset = b.face_class == UNSET
    by_format = int((~unset).sum())
    cls, depth = name_evidence(b.names, rules)
    b.face_class[unset] = cls[b.face_name[unset]]
    named = unset & (b.face_class != UNSET)
    depth = np.where(named, depth[b.face_name], -1)
    floor_z = floor_height(z, area, normal, b.face_class)
    fix = ("add a floor model, a name rule `pattern -> floor` for its name, or check "
           "up_axis / units")
    if floor_z is None:
        raise ValueError(f"{source}: no floor found (no face classed floor and no up-facing "
                         f"horizontal face); {fix}")
    over = overruled(b, z, area, normal, named, depth, floor_z, tolerance)
    b.face_class[over != UNSET] = over[over != UNSET]
    if (over == C.FLOOR).any():
        floor_z = floor_height(z, area, normal, b.face_class)
    unset = b.face_class == UNSET
    furniture = own_furniture(b, normal, unset, floor_z, tolerance)
    b.face_class[unset] = geometry_classes(z[unset], normal[unset], floor_z, tolerance)
    b.face_class[furniture] = C.CLUTTER
    n_over, n_furniture = int((over != UNSET).sum()), int(furniture.sum())
    b.info["classed_by"] = {"format": by_format, "name": int(named.sum()) - n_over,
                            "geometry_over_name": n_over,
                            "geometry": int(unset.sum()) - n_furniture,
                            "furniture": n_furniture}
    walls = b.face_class == C.WALL
    if not walls.any():
        raise ValueError(f"{source}: no wall faces found; add a name rule `pattern -> wall` "
                         f"or check up_axis")
    if not (b.face_class == C.FLOOR).any():
        raise ValueError(f"{source}: no floor: no face is classed floor (name rules gave the "
                         f"horizontal faces other classes); {fix}")
    if floor_z >= weighted_quantile(z[walls], area[walls], 0.5):
        raise ValueError(f"{source}: no floor found below the walls (the lowest large "
                         f"horizontal surface is at z = {floor_z:.2f} m); {fix}")
    return floor_z


def ceiling_height(b: Building) -> float:
    """Height (m) of the walls' tops: the 98th area-weighted percentile of the wall faces'
    highest vertices."""
    walls = b.face_class == C.WALL
    area, _ = face_areas_normals(b.vertices, b.faces[walls])
    top = b.vertices[b.faces[walls]][:, :, 2].max(axis=1)
    return weighted_quantile(top, area, 0.98)


def add_ceiling(b: Building, height: float, name: str = "auto_ceiling") -> int:
    """Add a ceiling (class ceiling, facing down) at ``height`` over the floor faces' exact
    footprint. Returns the number of faces added."""
    floor = b.faces[b.face_class == C.FLOOR]
    used, inv = np.unique(floor, return_inverse=True)
    top = b.vertices[used].copy()
    top[:, 2] = height
    return b.add_faces(top, inv.reshape(-1, 3)[:, ::-1], C.CEILING, name)


def class_shares(b: Building) -> dict[str, float]:
    """Share of the total surface area per class name (classes with faces only)."""
    area, _ = face_areas_normals(b.vertices, b.faces)
    per = np.bincount(b.face_class, weights=area, minlength=256)
    total = max(per.sum(), 1e-12)
    return {C.NAMES[i]: round(float(per[i] / total), 4) for i in range(C.NUM_CLASSES)
            if per[i] > 0}
