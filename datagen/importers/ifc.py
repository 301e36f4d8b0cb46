"""IFC building models through ifcopenshell: one storey, classes from the IFC types.

Geometry per element in world coordinates, metres (``ifcopenshell.geom``). The storey's own
elements are read; the slabs, coverings and roofs of the storey above (or, for the top storey,
the roofs) give only their down-facing faces, as the ceiling. Door leaves are left out with
``doors: open``; the openings they fill stay cut in the walls, and the reveal faces of door and
window openings take the door / window class (as the corridor's recesses do).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from core import classes as C
from datagen.importers.classify import HORIZONTAL
from datagen.mesh.building import UNSET, Part, face_areas_normals

#: IFC type -> class, the first that the element is (``is_a``) decides; None: by the name
#: rules and geometry. IfcSlab and IfcCovering are classed per face / predefined type.
TYPE_CLASS: tuple[tuple[str, int | None], ...] = (
    ("IfcWall", C.WALL), ("IfcColumn", C.WALL), ("IfcStair", C.WALL),
    ("IfcStairFlight", C.WALL), ("IfcRailing", C.WALL), ("IfcBeam", C.WALL),
    ("IfcRamp", C.WALL), ("IfcRampFlight", C.WALL), ("IfcMember", C.WALL),
    ("IfcCurtainWall", C.WINDOW), ("IfcPlate", C.WINDOW), ("IfcDoor", C.DOOR),
    ("IfcWindow", C.WINDOW), ("IfcRoof", C.CEILING), ("IfcFurnishingElement", C.CLUTTER),
    ("IfcDistributionElement", C.CLUTTER), ("IfcBuildingElementProxy", None),
)
SKIP = ("IfcOpeningElement", "IfcFeatureElement", "IfcSpace", "IfcVirtualElement",
        "IfcAnnotation", "IfcGrid")
CEILING_SOURCES = ("IfcSlab", "IfcCovering", "IfcRoof")


def _open(path: Path):
    import ifcopenshell

    try:
        return ifcopenshell.open(str(path))
    except Exception as err:  # ifcopenshell raises its own kinds for a broken file
        raise ValueError(f"{path}: not a readable IFC file ({type(err).__name__}: {err})"
                         ) from None


def storey_elevations(model) -> list[tuple[object, float]]:
    """(storey, elevation in metres) by elevation: the placement's height, else
    ``Elevation``."""
    import ifcopenshell.util.placement
    import ifcopenshell.util.unit

    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    out = []
    for s in model.by_type("IfcBuildingStorey"):
        if s.ObjectPlacement is not None:
            z = float(ifcopenshell.util.placement.get_local_placement(s.ObjectPlacement)[2, 3])
        else:
            z = float(s.Elevation or 0.0)
        out.append((s, z * scale))
    return sorted(out, key=lambda se: (se[1], se[0].id()))


def choose_storey(storeys: list[tuple[object, float]], name: str | None, source: Path) -> int:
    """Index into ``storeys`` of the storey named ``name`` (case-insensitive), or for None
    the ground storey: the lowest elevation >= -0.5 m, else the lowest."""
    if name is None:
        ground = [i for i, (_, z) in enumerate(storeys) if z >= -0.5]
        return ground[0] if ground else 0
    for i, (s, _) in enumerate(storeys):
        if (s.Name or "").strip().lower() == name.strip().lower():
            return i
    known = ", ".join(f"{s.Name!r} ({z:.2f} m)" for s, z in storeys) or "none"
    raise ValueError(f"{source}: no storey named {name!r} (storey setting); the file's "
                     f"storeys: {known}")


def _elements(model, storeys, index: int, doors: str) -> tuple[list, list]:
    """(the storey's elements, the ceiling sources above it), sorted by id."""
    import ifcopenshell.util.element as ue

    def products(objs) -> list:
        return sorted((e for e in objs if e.is_a("IfcElement") and e.Representation
                       and not any(e.is_a(t) for t in SKIP)), key=lambda e: e.id())

    if not storeys:
        return products(model.by_type("IfcElement")), []
    own = products(ue.get_decomposition(storeys[index][0]))
    if doors == "open":
        own = [e for e in own if not e.is_a("IfcDoor")]
    if index + 1 < len(storeys):
        above = products(ue.get_decomposition(storeys[index + 1][0]))
    else:
        in_storeys = {e.id() for s, _ in storeys[: index + 1]
                      for e in ue.get_decomposition(s)}
        above = [e for e in products(model.by_type("IfcRoof") + model.by_type("IfcSlab"))
                 if e.id() not in in_storeys
                 and (e.is_a("IfcRoof") or e.PredefinedType == "ROOF")]
    return own, [e for e in above if any(e.is_a(t) for t in CEILING_SOURCES)]


def element_classes(element, normal: np.ndarray) -> np.ndarray:
    """(m,) uint8 class per face of an element from its IFC type (UNSET where the type does
    not say): a slab's top is floor, its underside ceiling, its edges wall; a roof slab is
    ceiling; a covering is ceiling, floor (FLOORING) or wall."""
    m = len(normal)
    ptype = getattr(element, "PredefinedType", None)
    if element.is_a("IfcSlab") and ptype != "ROOF":
        out = np.full(m, C.WALL, np.uint8)
        out[normal[:, 2] >= HORIZONTAL] = C.FLOOR
        out[normal[:, 2] <= -HORIZONTAL] = C.CEILING
        return out
    if element.is_a("IfcSlab") or element.is_a("IfcCovering"):
        cls = {"FLOORING": C.FLOOR, "CEILING": C.CEILING, "ROOF": C.CEILING}.get(ptype, C.WALL)
        return np.full(m, cls, np.uint8)
    cls = next((c for t, c in TYPE_CLASS if element.is_a(t)), None)
    return np.full(m, UNSET if cls is None else cls, np.uint8)


def _shapes(model, elements: list, settings) -> list[tuple[object, np.ndarray, np.ndarray,
                                                            list, np.ndarray]]:
    """(element, vertices (n, 3) m, faces (m, 3), material names, per-face material index)
    for each element with geometry."""
    import ifcopenshell.geom

    if not elements:
        return []
    it = ifcopenshell.geom.iterator(settings, model, max(1, os.cpu_count() or 1),
                                    include=elements)
    out = []
    if not it.initialize():
        return out
    while True:
        shape = it.get()
        g = shape.geometry
        faces = np.asarray(g.faces, np.int64).reshape(-1, 3)
        if len(faces):
            mats = [(m.name, m.diffuse.components if m.diffuse is not None else None)
                    for m in g.materials]
            out.append((model.by_id(shape.id), np.asarray(g.verts, np.float64).reshape(-1, 3),
                        faces, mats, np.asarray(g.material_ids, np.int64)))
        if not it.next():
            break
    return sorted(out, key=lambda s: s[0].id())


def _parts(shapes, ceiling_only: bool, floor_z: float = -np.inf) -> list[Part]:
    """A part per (element, material); for ceiling sources only the down-facing faces; the
    undersides of floor slabs below ``floor_z`` (m; never seen from the storey) left out."""
    parts = []
    for element, v, f, mats, mat_id in shapes:
        _, normal = face_areas_normals(v, f)
        cls = element_classes(element, normal)
        keep = ~((normal[:, 2] <= -HORIZONTAL) & (v[f][:, :, 2].max(axis=1) < floor_z)
                 & (cls != UNSET))
        if ceiling_only:
            keep = normal[:, 2] <= -HORIZONTAL
            cls = np.full(len(f), C.CEILING, np.uint8)
        mat_id = np.where(mat_id < 0, 0, mat_id) if len(mats) else np.zeros(len(f), np.int64)
        for k in np.unique(mat_id[keep]):
            sel = keep & (mat_id == k)
            mname, rgb = mats[k] if k < len(mats) else ("", None)
            colour = np.asarray(rgb, np.float64)[:3] if rgb is not None else np.full(3, np.nan)
            parts.append(Part(v, f[sel], f"{element.is_a()}/{element.Name or ''}/{mname}",
                              colour, cls[sel]))
    return parts


def _reveals(model, settings, parts: list[Part]) -> None:
    """Wall faces inside the opening a door or window fills take its class."""
    import ifcopenshell.geom

    boxes = []
    for e in model.by_type("IfcDoor") + model.by_type("IfcWindow"):
        for rel in e.FillsVoids or ():
            shape = ifcopenshell.geom.create_shape(settings, rel.RelatingOpeningElement)
            v = np.asarray(shape.geometry.verts, np.float64).reshape(-1, 3)
            if len(v):
                cls = C.DOOR if e.is_a("IfcDoor") else C.WINDOW
                boxes.append((v.min(axis=0) - 0.01, v.max(axis=0) + 0.01, cls))
    for p in parts:
        cls = np.broadcast_to(np.asarray(p.face_class, np.uint8), (len(p.faces),)).copy()
        centre = p.vertices[p.faces].mean(axis=1)
        for lo, hi, c in boxes:
            cls[(cls == C.WALL) & np.all((centre >= lo) & (centre <= hi), axis=1)] = c
        p.face_class = cls


def space_footprints(model, storey, settings) -> dict[str, list[list[float]]]:
    """The footprints of a storey's rooms (its ``IfcSpace``; all of the file's without
    storeys): name (``LongName``, else ``Name``, else ``#id``) -> polygon corners [[x, y],
    ...] in metres, the outline of the space's triangles seen from above (shapely, which
    ifcopenshell requires); a space in pieces keeps its largest. ``hint.space=NAME`` starts a
    global search in one (world.json ``spaces``)."""
    import ifcopenshell.util.element as ue
    from shapely import Polygon, union_all

    objs = ue.get_decomposition(storey) if storey is not None else model.by_type("IfcSpace")
    spaces = sorted((e for e in objs if e.is_a("IfcSpace") and e.Representation),
                    key=lambda e: e.id())
    out: dict[str, list[list[float]]] = {}
    for space, verts, faces, _, _ in _shapes(model, spaces, settings):
        area, normal = face_areas_normals(verts, faces)
        seen = area * np.abs(normal[:, 2]) > 1e-6  # the triangle's area seen from above
        shape = union_all([Polygon(t) for t in verts[faces[seen]][:, :, :2]])
        if shape.is_empty:
            continue
        if shape.geom_type != "Polygon":  # a space in pieces: its largest
            shape = max(shape.geoms, key=lambda g: g.area)
        ring = np.asarray(shape.simplify(1e-3).exterior.coords)[:-1]
        name = space.LongName or space.Name or f"#{space.id()}"
        if name in out:
            name = f"{name} #{space.id()}"
        out[name] = ring.round(4).tolist()
    return out


def load_ifc(path: Path, storey: str | None, doors: str) -> tuple[list[Part], dict]:
    """The elements of one storey of an IFC file, in metres, Z up, classed by IFC type.

    Returns:
        parts (named ``IfcType/name/material``) and info: ``storey``, ``elevation`` (m),
        ``storeys`` (name -> elevation), ``elements`` (count), ``schema``, ``spaces`` (the
        storey's rooms: ``space_footprints``).
    """
    import ifcopenshell.geom

    model = _open(path)
    storeys = storey_elevations(model)
    index = choose_storey(storeys, storey, path) if storeys else 0
    own, above = _elements(model, storeys, index, doors)
    if not own:
        raise ValueError(f"{path}: the storey has no elements with geometry")
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    name, z = (storeys[index][0].Name, storeys[index][1]) if storeys else (None, -np.inf)
    parts = _parts(_shapes(model, own, settings), False, z - 0.05)
    _reveals(model, settings, parts)
    parts += _parts(_shapes(model, above, settings), True)
    spaces = space_footprints(model, storeys[index][0] if storeys else None, settings)
    return parts, {"schema": model.schema, "storey": name, "elevation": float(max(z, -1e9)),
                   "spaces": spaces,
                   "storeys": {s.Name or f"#{s.id()}": round(e, 3) for s, e in storeys},
                   "elements": len(own), "ceiling_elements": len(above), "units": 1.0}
