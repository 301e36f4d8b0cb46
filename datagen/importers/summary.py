"""The import summary: the figures of an imported building that show whether it came in
right, and flags for what looks wrong, each naming the ``world.*`` key to set.

Printed by ``python -m datagen.importers`` and by ``world=file`` runs, and saved as JSON
(``<name>_summary.json`` next to the CLI's ``<name>_import.json``; ``world/import_summary.json``
of a dataset).
"""

from __future__ import annotations

import numpy as np

from core import classes as C
from datagen.importers.orient import find_up_axis
from datagen.mesh.building import Building, face_areas_normals

#: Metres per file unit of the units a model is commonly drawn in (``world.units``).
UNITS = {"mm": 0.001, "cm": 0.01, "inch": 0.0254, "foot": 0.3048, "m": 1.0}
STOREY = (2.0, 6.0)  # m, a plausible floor-to-top height of a storey
EXTENT = (1.5, 2000.0)  # m, a plausible horizontal size of a building model
MIN_FLOOR_SHARE = 0.05  # of the surface area: less is a tiny floor
MIN_FREE_RATIO = 0.25  # free space over the floor's footprint: less is far smaller
UNSURE = 0.1  # an up axis found (auto) with less sureness is flagged
CONTRADICT = 0.3  # a mesh looking like another up axis than the one applied, this sure, is
# flagged
VERTICAL_EDGE = 0.9  # |direction z| from which a model edge is vertical
MIN_FLOOR_EDGES = 0.5  # floor-to-structure edges over the free space's outline: less is short
CHECK_VIEWS = 30  # camera poses the rendered-edge check draws from the free space


def vertical_edges(segments: np.ndarray) -> int:
    """How many (M, 2, 3) model edge segments run within ~25 deg of vertical."""
    if not len(segments):
        return 0
    d = segments[:, 1] - segments[:, 0]
    length = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
    return int((np.abs(d[:, 2]) / length >= VERTICAL_EDGE).sum())


def unit_guess(height: float, units: float) -> tuple[str, float] | None:
    """The common unit (name, metres per file unit) that makes a storey ``height`` m
    (read with ``units`` metres per file unit) plausible, nearest to 2.8 m; None if none."""
    raw = height / units
    fits = [(abs(np.log(raw * u / 2.8)), name, u) for name, u in UNITS.items()
            if STOREY[0] <= raw * u <= STOREY[1] and u != units]
    return min(fits)[1:] if fits else None


def check_size(source: object, lo: np.ndarray, hi: np.ndarray, units: float,
               unit_key: bool) -> None:
    """Refuse a model wider than any building (``EXTENT``): one drawn in mm or cm read as
    metres. ``load_building`` calls it on the parts as read, before anything whose cost grows
    with the model's area (the free space, the plan image).

    Args:
        source: the file, named in the error.
        lo, hi: (3,) m, the model's bounds (Z up).
        units: metres per file unit the import applied.
        unit_key: whether the format takes ``world.units`` (OBJ, PLY, STL); else its units
            come from the file.

    Raises:
        ValueError: naming the file, the size and the ``world.units`` value to set (for a
            height that fits a storey in mm, cm, inch or foot, that unit's).
    """
    extent, height = float(max(hi[:2] - lo[:2])), float(hi[2] - lo[2])
    if extent <= EXTENT[1]:
        return
    what = (f"{source}: the model is {extent:.1f} m across and {height:.1f} m high at {units} "
            f"m per file unit, wider than a building (at most {EXTENT[1]:.0f} m)")
    if not unit_key:
        raise ValueError(f"{what}; this format gives its own units (world.units does not "
                         f"apply): scale the model in the file")
    guess = unit_guess(height, units)
    if guess is None:
        raise ValueError(f"{what}; set world.units to the metres per file unit ("
                         + ", ".join(f"{k}: {v}" for k, v in UNITS.items() if k != "m")
                         + "; python -m datagen.importers: --units U)")
    name, value = guess
    raise ValueError(f"{what}; in {name} it would be {extent / units * value:.1f} m across and "
                     f"{height / units * value:.1f} m high: set world.units={value} (python -m "
                     f"datagen.importers: --units {value})")


def footprint(points: np.ndarray) -> float:
    """Area (m^2) of the convex hull of (n, 3) points seen from above (holes and furniture
    in a floor do not shrink it); 0 for fewer than three or collinear points."""
    from scipy.spatial import ConvexHull, QhullError

    if len(points) < 3:
        return 0.0
    try:
        return float(ConvexHull(points[:, :2]).volume)
    except QhullError:
        return 0.0


def file_units(info: dict) -> float:
    """Metres per file unit the import applied: a mesh file's, or the most common of an SDF
    world's meshes (1 without)."""
    units = info.get("units", 1.0)
    if isinstance(units, dict):
        return float(max(units, key=units.get)) if units else 1.0
    return float(units)


def edge_figures(b: Building, edges, free, rng: np.random.Generator | None = None) -> dict:
    """What the model edges give a camera: floor-to-structure edge length against the free
    space's outline, and the rendered-edge check (``datagen.mesh.edge_check``) from
    ``CHECK_VIEWS`` poses in the free space at the default camera.

    Args:
        b: the building; edges: its ``datagen.mesh.edges.EdgeSet``; free: its camera free
            space (``core.occupancy.OccupancyMap``); rng: the poses' generator (None: seed 0).

    Returns:
        ``floor_edges_m`` (floor | wall, door or window),
        ``free_outline_m`` (the outer outline of the free space), ``rendered_edges``
        (``EdgeAgreement.as_dict``).
    """
    import cv2

    from datagen.config import CameraConfig
    from datagen.job import make_camera
    from datagen.mesh.edge_check import EdgeChecker, agreement, free_space_poses

    seg, cls = edges.segments, np.sort(edges.classes, axis=1)
    floor = (cls[:, 0] == C.FLOOR) & np.isin(cls[:, 1], (C.WALL, C.DOOR, C.WINDOW))
    floor_m = float(np.linalg.norm(seg[floor, 1] - seg[floor, 0], axis=1).sum())
    contours, _ = cv2.findContours(free.free.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_SIMPLE)
    outline_m = float(sum(cv2.arcLength(c, True) for c in contours) * free.cell)
    cam = make_camera(CameraConfig())
    checker = EdgeChecker(b.vertices, b.faces, b.face_class, seg, edges.classes, cam.K,
                          cam.width, cam.height, edges.normals)
    poses = free_space_poses(free, cam.body_from_cam, CHECK_VIEWS,
                             rng or np.random.default_rng(0))
    return {"floor_edges_m": round(floor_m, 1), "free_outline_m": round(outline_m, 1),
            "rendered_edges": agreement(checker, poses).as_dict()}


def import_summary(b: Building, free_area_m2: float | None = None,
                   vertical: int | None = None, edges: dict | None = None) -> dict:
    """The summary of an import (``load_building``'s ``b.info`` and the mesh).

    Args:
        b: the imported building.
        free_area_m2: the camera free space's area (``datagen.worlds.site.camera_free_space``), or
            None if not built.
        vertical: the number of vertical model edges (``vertical_edges``), or None.
        edges: ``edge_figures``, or None.

    Returns:
        figures (floor share, area and footprint, free area, wall height, up axis and how
        sure, faces classed by name / by geometry, missing meshes and models, far parts) and
        ``flags``:
        [{"what": ..., "key": ...}], ``key`` the ``world.*`` setting to look at.
    """
    info = b.info
    area, _ = face_areas_normals(b.vertices, b.faces)
    floor = b.face_class == C.FLOOR
    floor_area = float(area[floor].sum())
    shares = info.get("class_shares", {})
    height = float(info["wall_top_z"] - info["floor_z"])
    lo, hi = np.asarray(info["bounds"][0]), np.asarray(info["bounds"][1])
    extent = float(max(hi[:2] - lo[:2]))
    up = up_axis_figures(b)
    out = {
        "floor_share": shares.get("floor", 0.0), "floor_area_m2": round(floor_area, 1),
        "floor_footprint_m2": round(footprint(b.vertices[np.unique(b.faces[floor])]), 1),
        "free_area_m2": None if free_area_m2 is None else round(float(free_area_m2), 1),
        "wall_height_m": round(height, 2), "extent_m": round(extent, 2), "up_axis": up,
        "classed_by": info.get("classed_by", {}), "vertical_edges": vertical,
        "missing_meshes": len(info.get("missing_meshes", {})),
        "missing_models": int(sum(info.get("missing_models", {}).values())),
        "far_parts": len(info.get("far_parts", {})),
        **(edges or {}),
    }
    out["flags"] = flags(out, file_units(info))
    return out


def up_axis_figures(b: Building) -> dict:
    """The up axis applied, where it came from and how sure; for an axis the import did not
    find itself (format, setting), the check of the imported mesh (``check``: the axis
    ``find_up_axis`` sees in it, +z when it agrees)."""
    info = b.info
    out = {"axis": info.get("up_axis", "+z"), "from": info.get("up_axis_from", "format")}
    found = info.get("up_axis_found")
    if found is not None:
        out["sureness"] = found["sureness"]
        return out
    check = find_up_axis(b.vertices, b.faces)
    out.update(check=check.axis, sureness=round(check.sureness, 3))
    return out


def flags(s: dict, units: float) -> list[dict]:
    """What looks wrong in a summary's figures, each with the key to set."""
    out = []

    def flag(what: str, key: str | None) -> None:
        out.append({"what": what, "key": key})

    up = s["up_axis"]
    if up.get("check", "+z") != "+z" and up["sureness"] >= CONTRADICT:
        flag(f"the model looks like its up axis is {up['check']} (sureness "
             f"{up['sureness']:.2f}), not the {up['axis']} applied ({up['from']})",
             "world.up_axis")
    elif up["sureness"] < UNSURE and up["from"] == "auto":
        flag(f"up axis {up['axis']} found with low sureness ({up['sureness']:.2f})",
             "world.up_axis")
    if s["floor_share"] < MIN_FLOOR_SHARE:
        flag(f"tiny floor share ({100 * s['floor_share']:.1f} % of the surface): the floor "
             f"may be classed as something else, or the model is on its side",
             "world.name_rules")
    free, floor = s["free_area_m2"], s["floor_footprint_m2"]
    if free is not None and free < MIN_FREE_RATIO * floor:
        flag(f"free space {free:.1f} m2 is far smaller than the floor's footprint "
             f"{floor:.1f} m2 (holes, furniture or low ceilings in the camera heights)",
             "world.z_range / world.camera_margin")
    floor_m, outline_m = s.get("floor_edges_m"), s.get("free_outline_m")
    if floor_m is not None and outline_m and floor_m < MIN_FLOOR_EDGES * outline_m:
        flag(f"short floor-to-structure edges: {floor_m:.1f} m of floor | wall, door or window "
             f"against a free-space outline of {outline_m:.1f} m (walls on a slab they do not "
             "touch? the floor classed as something else?)", "world.name_rules")
    if s["vertical_edges"] == 0:
        flag("no vertical model edges (no wall corners, door or window jambs)",
             "world.up_axis")
    height, extent = s["wall_height_m"], s["extent_m"]
    if not STOREY[0] <= height <= STOREY[1] or not EXTENT[0] <= extent <= EXTENT[1]:
        guess = unit_guess(height, units)
        hint = (f"; in {guess[0]} it would be {height / units * guess[1]:.2f} m: "
                f"world.units={guess[1]}" if guess else "")
        flag(f"implausible size: walls {height:.2f} m high, {extent:.1f} m across, read at "
             f"{units} m per file unit{hint}", "world.units")
    if s["missing_meshes"]:
        flag(f"{s['missing_meshes']} mesh files not found", "world.model_path")
    if s["missing_models"]:
        flag(f"{s['missing_models']} included models not found", "world.model_path")
    if s["far_parts"]:
        flag(f"{s['far_parts']} parts far from the rest were left out", None)
    return out


def summary_lines(s: dict) -> list[str]:
    """The printed lines of a summary: its figures, then one line per flag."""
    up = s["up_axis"]
    by = s["classed_by"]
    free = "not built" if s["free_area_m2"] is None else f"{s['free_area_m2']:.1f} m2"
    lines = [f"up axis {up['axis']} ({up['from']}, sureness {up['sureness']:.2f}"
             + (f", the mesh looks {up['check']}" if up.get("check", "+z") != "+z" else "")
             + f"); walls {s['wall_height_m']:.2f} m high, {s['extent_m']:.1f} m across",
             f"floor {100 * s['floor_share']:.1f} % of the surface, {s['floor_area_m2']:.1f} m2 "
             f"(footprint {s['floor_footprint_m2']:.1f} m2); free space {free}"
             + ("" if s["vertical_edges"] is None else
                f"; {s['vertical_edges']} vertical model edges"),
             "faces classed by " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                             for k, v in by.items())]
    if "rendered_edges" in s:
        r = s["rendered_edges"]
        worst = ", ".join(f"{k} {v}" for k, v in list(r["missed"].items())[:3])
        lines.append(f"model edges: {s['floor_edges_m']:.1f} m between the floor and "
                     f"structure (free-space outline {s['free_outline_m']:.1f} m); against "
                     f"renders of the model from {r['views']} poses: recall {r['recall']:.3f}, "
                     f"precision {r['precision']:.3f} at {r['tol_px']:g} px"
                     + (f" (boundary px missed most: {worst})" if worst else ""))
    lines += [f"check: {f['what']}" + (f" (set {f['key']})" if f["key"] else "")
              for f in s["flags"]]
    return lines
