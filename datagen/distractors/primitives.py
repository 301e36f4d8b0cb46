"""Mesh primitives of the distractors (trimesh), in an object frame with z up: boxes (one or
many at once), rods, capsules, ellipsoids, frustums, their union turned by a yaw, and a union
whose parts carry tones (``_painted``: the parts' colours, the footprint as circles)."""

from __future__ import annotations

import numpy as np
import trimesh

from datagen.appearance.materials import ITEM


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float],
         yaw: float = 0.0) -> trimesh.Trimesh:
    """Axis box of the given extents (m) centred at centre, rotated by yaw about z."""
    T = trimesh.transformations.rotation_matrix(yaw, (0, 0, 1))
    T[:3, 3] = centre
    return trimesh.creation.box(extents=extents, transform=T)


def _rod(p0: np.ndarray, p1: np.ndarray, radius: float, sections: int = 10) -> trimesh.Trimesh:
    """Closed cylinder between two points."""
    return trimesh.creation.cylinder(radius=radius, segment=np.array([p0, p1], float),
                                     sections=sections)


def _capsule(p0: np.ndarray, p1: np.ndarray, radius: float) -> trimesh.Trimesh:
    """Capsule whose axis runs from p0 to p1 (the caps extend radius beyond them)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    mesh = trimesh.creation.capsule(height=max(length, 1e-3), radius=radius, count=[8, 8])
    T = trimesh.geometry.align_vectors([0, 0, 1], axis / max(length, 1e-9))
    T[:3, 3] = (p0 + p1) / 2
    mesh.apply_transform(T)
    return mesh


def _ellipsoid(centre: tuple[float, float, float], radii: tuple[float, float, float],
               subdivisions: int = 1) -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.apply_scale(radii)
    mesh.apply_translation(centre)
    return mesh


def _frustum(r_bottom: float, r_top: float, height: float, sections: int = 14) -> trimesh.Trimesh:
    """Closed truncated cone standing on z = 0 (a pot)."""
    mesh = trimesh.creation.cylinder(radius=1.0, height=height, sections=sections)
    v = mesh.vertices.copy()
    top = v[:, 2] > 0
    v[:, :2] *= np.where(top, r_top, r_bottom)[:, None]
    v[:, 2] += height / 2
    return trimesh.Trimesh(v, mesh.faces, process=False)


def _join(parts: list[trimesh.Trimesh], yaw: float = 0.0) -> trimesh.Trimesh:
    """Concatenate parts, rotate by yaw and re-centre the footprint on the origin."""
    mesh = trimesh.util.concatenate(parts)
    if yaw:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, (0, 0, 1)))
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return mesh


_UNIT_BOX = trimesh.creation.box()  # 8 corners at +/-0.5, 12 outward faces


def _boxes(centres: np.ndarray, extents: np.ndarray,
           hidden: tuple[tuple[int, int], ...] = ()) -> trimesh.Trimesh:
    """Many axis boxes as one mesh, 8 vertices and 12 faces each, built at once.

    Args:
        centres, extents: (N, 3) m.
        hidden: sides (axis 0-2, sign -1 or 1) left out of every box, e.g. ((2, -1),) its
            bottom: the faces no view sees (a book's on the shelf and against the back).

    Returns:
        The mesh; ``metadata["items"]`` (8 N,) the box each vertex belongs to (each box an
        item of its own colour when painted with tone ITEM, ``_painted``).
    """
    c = np.asarray(centres, np.float64).reshape(-1, 3)
    e = np.asarray(extents, np.float64).reshape(-1, 3)
    n = len(c)
    V = c[:, None, :] + _UNIT_BOX.vertices[None] * e[:, None, :]
    normals = np.round(_UNIT_BOX.face_normals).astype(int)
    keep = ~np.any([normals[:, axis] == sign for axis, sign in hidden], axis=0) if hidden \
        else np.ones(12, bool)
    F = _UNIT_BOX.faces[keep][None] + 8 * np.arange(n)[:, None, None]
    mesh = trimesh.Trimesh(V.reshape(-1, 3), F.reshape(-1, 3), process=False)
    mesh.metadata["items"] = np.repeat(np.arange(n), 8)
    return mesh


def _cover(rects: np.ndarray) -> np.ndarray:
    """(C, 3) circles x, y, r (m) covering rectangles (R, 4) x0, y0, x1, y1: a chain along
    each one's long side, one circle per piece of at most half its short side (a circle
    reaches 6 % of the short side beyond the long sides)."""
    out = []
    for x0, y0, x1, y1 in np.asarray(rects, np.float64).reshape(-1, 4):
        lx, ly = x1 - x0, y1 - y0
        long, short = max(lx, ly), max(min(lx, ly), 1e-3)
        n = int(np.ceil(2 * long / short - 1e-9))
        t = (np.arange(n) + 0.5) / n
        xs = x0 + t * lx if lx >= ly else np.full(n, (x0 + x1) / 2)
        ys = y0 + t * ly if lx < ly else np.full(n, (y0 + y1) / 2)
        out.append(np.column_stack([xs, ys, np.full(n, np.hypot(long / n, short) / 2)]))
    return np.concatenate(out)


def _painted(pieces: list[tuple[int, trimesh.Trimesh]], rects: np.ndarray | None = None
             ) -> trimesh.Trimesh:
    """Join (tone, mesh) pieces as ``_join`` does (footprint centred on the origin, standing
    on z = 0) and record in ``metadata``: ``parts`` (V,) the part each vertex belongs to and
    ``tones`` (P,) each part's tone (``datagen.appearance.materials.TONES``): the pieces of
    one tone are one part, but a piece of tone ITEM made by ``_boxes`` gives each box a part
    of its own (books of many colours); ``footprint`` (C, 3) circles x, y, r (m) covering the
    rectangles ``rects`` (R, 4) x0, y0, x1, y1 (before centring; None: the mesh's XY
    bounds)."""
    tones, parts, seen = [], [], {}
    for tone, mesh in pieces:
        items = mesh.metadata.get("items") if tone == ITEM else None
        if items is not None:
            parts.append(len(tones) + items)
            tones += [ITEM] * (int(items.max()) + 1)
            continue
        if tone not in seen:
            seen[tone] = len(tones)
            tones.append(tone)
        parts.append(np.full(len(mesh.vertices), seen[tone]))
    mesh = trimesh.util.concatenate([m for _, m in pieces])
    lo, hi = mesh.bounds
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    mesh.apply_translation(shift)
    if rects is None:
        rects = np.array([[lo[0], lo[1], hi[0], hi[1]]])
    rects = np.asarray(rects, np.float64).reshape(-1, 4) + np.tile(shift[:2], 2)
    mesh.metadata.pop("items", None)
    mesh.metadata.update(parts=np.concatenate(parts), tones=np.asarray(tones),
                         footprint=_cover(rects))
    return mesh
