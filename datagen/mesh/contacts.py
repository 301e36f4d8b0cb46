"""Contact lines: where one surface meets another without sharing a vertex with it.

A wall standing on (or sunk into) a floor slab it was modelled apart from, a door frame on a
wall, a ceiling laid on (or through) the walls' tops: a render shows a line there, between
the two surfaces' classes, but mesh adjacency finds no edge. Each large flat surface's plane
(``ContactConfig.min_area``) of a structural class is cut just off the surface, on both sides
(``trimesh.intersections.mesh_plane``); a cut piece is a contact line where a probe beside
it, on either side, reaches the surface within the cut's offset (so the piece stands on the
surface, not beside or beyond it), probed at both ends of pieces ``step`` long, a piece
standing on it (or on one class of it) at one end only bisected to where that stops.
Pieces are put back onto the plane and take the classes of the surface and of the face cut.
Pieces along an edge the mesh already has with the same classes (within ``dup_m``; the
surface's class taken as its plane's area majority) are dropped before any probe.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from core import classes as C
from core.classes import pair_code
from datagen.mesh.building import face_areas_normals


@dataclass(frozen=True)
class ContactConfig:
    """How contact lines are found (``contact_lines``).

    Attributes:
        min_area: m²; a flat region at least this large has its plane cut (a wall, a floor, a
            ceiling, the face of a cabinet; not a frame's narrow side).
        flat_m: metres; a region whose faces' centres lie further than this (RMS) from its
            fitted plane is not flat enough to cut.
        offset: metres off the surface the plane is cut at: a surface standing on it less
            far than this, or touching it, is found; one protruding less is not.
        step: metres; cut segments are split into pieces at most this long, each probed at
            both ends (a contact narrower than a step may be missed).
        dup_m: metres; a piece within this of an edge with the same classes is a duplicate.
    """

    min_area: float = 0.25
    flat_m: float = 0.01
    offset: float = 0.01
    step: float = 0.05
    dup_m: float = 0.008


def split_pieces(p: np.ndarray, q: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Segments p -> q (K, 3) each cut into equal pieces at most ``step`` metres long.

    Returns:
        pieces (P, 2, 3); which (P,) the segment each piece is of.
    """
    length = np.linalg.norm(q - p, axis=1)
    n = np.maximum(np.ceil(length / step).astype(np.int64), 1)
    which = np.repeat(np.arange(len(p)), n)
    j = np.arange(len(which)) - np.repeat(np.cumsum(n) - n, n)
    a, b = (j / n[which])[:, None], ((j + 1) / n[which])[:, None]
    pieces = np.stack([(1 - a) * p[which] + a * q[which], (1 - b) * p[which] + b * q[which]],
                      axis=1)
    return pieces, which


def cut_planes(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
               region: np.ndarray, rnormal: np.ndarray, settings: ContactConfig
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The planes of the large flat structural regions (most of their area floor, wall,
    ceiling, door or window: what the label modes see), regions on one plane (to 1 deg,
    1 cm) merged.

    Returns:
        normal (N, 3) unit, offset (N,) metres (plane: normal . x = offset), cls (N,) the
        class of most of each plane's area, face_plane (F,) the plane each face's region lies
        on (-1: none).
    """
    area, _ = face_areas_normals(vertices, faces)
    centre = vertices[faces].mean(axis=1)
    n_r = len(rnormal)
    r_area = np.bincount(region, area, n_r)
    n = rnormal / np.maximum(np.linalg.norm(rnormal, axis=1, keepdims=True), 1e-12)
    d_face = np.einsum("ij,ij->i", n[region], centre)
    r_off = np.bincount(region, area * d_face, n_r) / np.maximum(r_area, 1e-12)
    rms = np.sqrt(np.bincount(region, area * (d_face - r_off[region]) ** 2, n_r)
                  / np.maximum(r_area, 1e-12))
    table = np.zeros((n_r, 256))
    np.add.at(table, (region, face_class), area)
    structural = np.isin(np.argmax(table, axis=1), C.STRUCTURAL)
    big = (r_area >= settings.min_area) & (rms <= settings.flat_m) & structural
    if not big.any():
        return (np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64),
                np.full(len(faces), -1, np.int64))
    # one orientation per plane: the first clearly non-zero component positive
    first = np.argmax(np.abs(n) > 1e-3, axis=1)
    sign = np.where(n[np.arange(n_r), first] < 0, -1.0, 1.0)
    n, r_off = n * sign[:, None], r_off * sign
    key = np.c_[np.round(n * 57.3).astype(np.int64), np.round(r_off / 0.01).astype(np.int64)]
    _, plane = np.unique(key[big], axis=0, return_inverse=True)
    plane = plane.ravel()
    r_plane = np.full(n_r, -1, np.int64)
    r_plane[big] = plane
    w = r_area[big]
    count = plane.max() + 1
    normal = np.stack([np.bincount(plane, w * n[big, i], count) for i in range(3)], 1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    offset = np.bincount(plane, w * r_off[big], count) / np.maximum(np.bincount(plane, w, count),
                                                                   1e-12)
    p_table = np.zeros((count, table.shape[1]))
    np.add.at(p_table, plane, table[big])
    return normal, offset, np.argmax(p_table, axis=1), r_plane[region]


def contact_lines(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                  normals: np.ndarray, region: np.ndarray, rnormal: np.ndarray,
                  existing: tuple[np.ndarray, np.ndarray], variant: str = "auto",
                  settings: ContactConfig | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Contact lines of a mesh not already among its edges.

    Args:
        vertices: (V, 3) metres; faces: (F, 3); face_class: (F,); normals: (F, 3) unit.
        region: (F,) planar region per face; rnormal: (R, 3) their fitted normals
            (``planar_regions``).
        existing: (segments (M, 2, 3) metres, classes (M, 2)) the edges found otherwise.
        variant: Mitsuba variant of the probes' ray caster.
        settings: None: the defaults.

    Returns:
        pieces (K, 2, 3) metres; classes (K, 2) (surface, face standing on it); crease (K,)
        degrees between the two (0..90, to 0.1); plane (K,) the surface's plane id.
    """
    import trimesh

    from core.imaging.rays import RayCaster

    s = settings or ContactConfig()
    empty = (np.zeros((0, 2, 3)), np.zeros((0, 2), np.uint8), np.zeros(0), np.zeros(0, np.int64))
    p_normal, p_offset, p_class, face_plane = cut_planes(vertices, faces, face_class, region,
                                                         rnormal, s)
    if len(p_normal) == 0:
        return empty
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    tri = vertices[faces]
    f_lo, f_hi = tri.min(axis=1), tri.max(axis=1)
    on = face_plane >= 0
    p_lo = np.full((len(p_normal), 3), np.inf)
    p_hi = np.full((len(p_normal), 3), -np.inf)
    np.minimum.at(p_lo, face_plane[on], f_lo[on])
    np.maximum.at(p_hi, face_plane[on], f_hi[on])
    reach = s.offset + 0.01
    # the faces of each plane, and a mask of their vertices (set per plane)
    by_plane = np.argsort(face_plane, kind="stable")
    starts = np.searchsorted(face_plane[by_plane], np.arange(len(p_normal) + 1))
    shared = np.zeros(len(vertices), bool)
    seg, cut, plane, side = [], [], [], []
    for k, (n, off) in enumerate(zip(p_normal, p_offset, strict=True)):
        own = faces[by_plane[starts[k]:starts[k + 1]]]
        shared[own] = True
        # faces whose boxes meet the surface's box (the others cannot stand on it) and that
        # share no vertex with it (where they do, mesh adjacency has the edge: a scan's wall
        # and ceiling meet along the triangle sides its labels change along)
        near = np.flatnonzero((f_lo <= p_hi[k] + reach).all(axis=1)
                              & (f_hi >= p_lo[k] - reach).all(axis=1) & (face_plane != k))
        near = near[~shared[faces[near]].any(axis=1)]
        shared[own] = False
        dots = vertices @ n - off
        fd = dots[faces[near]]
        for sgn in (1.0, -1.0):
            level = sgn * s.offset
            cand = near[(fd.min(axis=1) < level) & (fd.max(axis=1) > level)]
            if len(cand) == 0:
                continue
            lines, idx = trimesh.intersections.mesh_plane(
                mesh, n, n * (off + level), return_faces=True, local_faces=cand,
                cached_dots=dots - level)
            if len(lines) == 0:
                continue
            seg.append(lines)
            cut.append(idx)
            plane.append(np.full(len(idx), k))
            side.append(np.full(len(idx), sgn))
    if not seg:
        return empty
    seg, cut = np.concatenate(seg), np.concatenate(cut)
    plane, side = np.concatenate(plane), np.concatenate(side)
    pieces, which = split_pieces(seg[:, 0], seg[:, 1], s.step)
    cut, plane, side = cut[which], plane[which], side[which]
    n = p_normal[plane]
    d = pieces[:, 1] - pieces[:, 0]
    length = np.linalg.norm(d, axis=1)
    ok = length > 1e-6
    pieces, cut, plane, side, n, d = (a[ok] for a in (pieces, cut, plane, side, n, d))
    # back onto the plane (where the line is drawn), then those along an edge the mesh has
    # already are that edge (its classes were found there)
    drop = (side * s.offset)[:, None] * n
    pair = np.stack([p_class[plane], face_class[cut]], 1)
    new = ~duplicates(pieces - drop[:, None], pair, *existing, s.dup_m)
    pieces, cut, plane, side, n, d, drop = (a[new] for a in (pieces, cut, plane, side, n, d,
                                                              drop))
    if len(pieces) == 0:
        return empty
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    across = np.cross(n, d)
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
    caster = RayCaster(vertices, faces, variant)

    def surface(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(K,) face of piece ``rows``'s surface a probe beside ``points`` (K, 3) reaches
        within the offset, on either side of the piece; -1 for none."""
        hit = np.full(len(rows), -1, np.int64)
        for way in (1.0, -1.0):
            miss = np.flatnonzero(hit < 0)
            r = rows[miss]
            h, _ = caster.first_hit(points[miss] + way * s.offset * across[r],
                                    -side[r, None] * n[r], s.offset + 0.005)
            good = (h >= 0) & (face_plane[np.maximum(h, 0)] == plane[r])
            hit[miss[good]] = h[good]
        return hit

    rows = np.arange(len(pieces))
    ha = surface(pieces[:, 0] + 1e-3 * d, rows)
    hb = surface(pieces[:, 1] - 1e-3 * d, rows)
    ca = np.where(ha >= 0, face_class[np.maximum(ha, 0)].astype(np.int64), -1)
    cb = np.where(hb >= 0, face_class[np.maximum(hb, 0)].astype(np.int64), -1)
    out, hit, keep = [], [], []
    whole = (ca >= 0) & (ca == cb)
    out.append(pieces[whole])
    hit.append(ha[whole])
    keep.append(np.flatnonzero(whole))
    # a piece on the surface's class at one end only: bisected to where that stops (to 1 mm)
    for end, c_end, c_far, h_end in ((0, ca, cb, ha), (1, cb, ca, hb)):
        part = np.flatnonzero((c_end >= 0) & (c_end != c_far))
        good, bad = pieces[part, end].copy(), pieces[part, 1 - end].copy()
        for _ in range(6):
            mid = (good + bad) / 2
            h = surface(mid, part)
            on = (h >= 0) & (face_class[np.maximum(h, 0)] == c_end[part])
            good[on], bad[~on] = mid[on], mid[~on]
        piece = pieces[part].copy()
        piece[:, 1 - end] = good
        out.append(piece)
        hit.append(h_end[part])
        keep.append(part)
    out, hit, keep = np.concatenate(out), np.concatenate(hit), np.concatenate(keep)
    out = out - drop[keep][:, None]
    cls = np.stack([face_class[hit], face_class[cut[keep]]], axis=1).astype(np.uint8)
    crease = np.round(np.degrees(np.arccos(np.clip(
        np.abs(np.einsum("ij,ij->i", n[keep], normals[cut[keep]])), 0.0, 1.0))), 1)
    return out, cls, crease, plane[keep]


def duplicates(pieces: np.ndarray, classes: np.ndarray, segments: np.ndarray,
               seg_classes: np.ndarray, tol: float) -> np.ndarray:
    """(K,) bool: pieces (K, 2, 3) whose ends and middle all lie within ``tol`` metres of
    segments (M, 2, 3) of their class pair (``classes`` (K, 2), ``seg_classes`` (M, 2),
    unordered)."""
    out = np.zeros(len(pieces), bool)
    if len(pieces) == 0 or len(segments) == 0:
        return out
    mine = pair_code(classes[:, 0], classes[:, 1])
    theirs = pair_code(seg_classes[:, 0], seg_classes[:, 1])
    for c in np.intersect1d(mine, theirs):
        seg = segments[theirs == c]
        pts, _ = split_pieces(seg[:, 0], seg[:, 1], tol / 2)
        tree = cKDTree(np.concatenate([pts[:, 0], seg[:, 1]]))
        k = np.flatnonzero(mine == c)
        q = np.concatenate([pieces[k, 0], pieces[k].mean(axis=1), pieces[k, 1]])
        dist, _ = tree.query(q, distance_upper_bound=tol)
        out[k] = np.isfinite(dist).reshape(3, -1).all(axis=0)
    return out
