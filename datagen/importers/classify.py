"""Classes for every face of an imported building, and the open-top ceiling.

Order: the format's class (IFC type, set by the reader), then the name rules (regex on the
face's name), then geometry: a horizontal up-facing face within ``floor_tolerance`` of the
storey floor is floor, a horizontal down-facing one ceiling, the rest wall.
"""

from __future__ import annotations

import re

import numpy as np

from core import classes as C
from datagen.importers.building import UNSET, Building, face_areas_normals
from datagen.importers.settings import NameRule

HORIZONTAL = 0.9  # |normal z| from which a face is horizontal (within ~25 deg)


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


def name_classes(names: list[str], rules: list[NameRule]) -> np.ndarray:
    """(len(names),) uint8: the class of the first rule whose pattern occurs in each name,
    UNSET where none does."""
    compiled = compile_rules(rules)
    out = np.full(len(names), UNSET, np.uint8)
    for i, name in enumerate(names):
        out[i] = next((cls for rx, cls in compiled if rx.search(name)), UNSET)
    return out


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` quantile (0..1) of ``values`` weighted by ``weights``."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, q * cum[-1])])


def floor_height(z: np.ndarray, area: np.ndarray, normal: np.ndarray,
                 face_class: np.ndarray, bin_m: float = 0.1) -> float | None:
    """The storey floor's height (m): the area-weighted median height of floor faces if any
    are classed already, else of the lowest 0.1 m band holding at least half the area of the
    largest band of up-facing horizontal faces; None without either."""
    floor = face_class == C.FLOOR
    if floor.any():
        return weighted_quantile(z[floor], area[floor], 0.5)
    up = normal[:, 2] >= HORIZONTAL
    if not up.any():
        return None
    band = np.floor(z[up] / bin_m).astype(np.int64)
    bands, inv = np.unique(band, return_inverse=True)
    band_area = np.bincount(inv.ravel(), weights=area[up])
    lowest = bands[np.flatnonzero(band_area >= 0.5 * band_area.max())[0]]
    sel = band == lowest
    return weighted_quantile(z[up][sel], area[up][sel], 0.5)


def geometry_classes(z: np.ndarray, normal: np.ndarray, floor_z: float,
                     tolerance: float) -> np.ndarray:
    """(F,) uint8 class by geometry: up-facing horizontal near the floor -> floor,
    down-facing horizontal -> ceiling, the rest -> wall."""
    out = np.full(len(z), C.WALL, np.uint8)
    out[(normal[:, 2] >= HORIZONTAL) & (np.abs(z - floor_z) <= tolerance)] = C.FLOOR
    out[normal[:, 2] <= -HORIZONTAL] = C.CEILING
    return out


def classify(b: Building, rules: list[NameRule], tolerance: float, source: str) -> float:
    """Fill the UNSET classes of ``b`` in place (name rules, then geometry) and check that
    the result has a floor below walls. Returns the floor height (m)."""
    area, normal = face_areas_normals(b.vertices, b.faces)
    z = b.vertices[b.faces][:, :, 2].mean(axis=1)
    unset = b.face_class == UNSET
    b.face_class[unset] = name_classes(b.names, rules)[b.face_name[unset]]
    floor_z = floor_height(z, area, normal, b.face_class)
    fix = ("add a floor model, a name rule `pattern -> floor` for its name, or check "
           "up_axis / units")
    if floor_z is None:
        raise ValueError(f"{source}: no floor found (no face classed floor and no up-facing "
                         f"horizontal face); {fix}")
    unset = b.face_class == UNSET
    b.face_class[unset] = geometry_classes(z[unset], normal[unset], floor_z, tolerance)
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
