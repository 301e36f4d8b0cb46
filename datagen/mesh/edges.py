"""3D edge segments of a classed triangle mesh: creases, boundaries and class changes.

An edge shared by two faces is a model edge when the faces' planar regions
(``datagen.mesh.planar_regions``) meet at an angle above the crease threshold or the faces carry
different classes; an edge with one face is a boundary edge. Seams inside a region
(triangulation diagonals, grid splits, a scan's noise) are dropped. Creases and boundary
edges are straightened (``datagen.mesh.edge_polylines``); collinear touching pieces with the same
class pair and angle are merged into one segment.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from core import classes as C
from datagen.mesh.building import face_areas_normals
from datagen.mesh.contacts import (
    ContactConfig,
    contact_lines,
    split_pieces,
)
from datagen.mesh.edge_polylines import merge_near_collinear, simplify_segments
from datagen.mesh.planar_regions import (
    RegionConfig,
    face_pairs,
    planar_regions,
    winding_agrees,
)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals (F, 3) of triangles (right-hand rule on the vertex order)."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


class EdgeSet(NamedTuple):
    """A model's edges (``extract_edges``).

    Attributes:
        segments: (M, 2, 3) endpoints, metres.
        classes: (M, 2) uint8, the classes on the two sides (ascending; 0 = void).
        crease: (M,) degrees between the two surfaces (0 for a class change on a flat
            surface, 90 at a boundary edge meeting nothing).
        normals: (M, 2, 3) for a crease between two faces, their normals in the order of
            ``classes``, each turned away from the other face: where exactly one of them faces
            the camera the crease is an outline of that face's class against what lies behind
            it (``core.imaging.outline``); NaN for an edge that is no such crease.
    """

    segments: np.ndarray
    classes: np.ndarray
    crease: np.ndarray
    normals: np.ndarray


#: degrees; a face with a neighbour this close in angle is exact (a CAD facet's triangle).
FLAT_DEG = 0.01


@dataclass(frozen=True)
class EdgeExtractionConfig:
    """How model edges are found beyond the crease threshold (``extract_edges``).

    Attributes:
        regions: how faces are grown into planar regions, whose fitted normals the crease
            test compares (``planar_regions.RegionConfig``).
        contacts: how lines where a surface meets another it shares no vertex with are
            found (``contacts.ContactConfig``).
        simplify_m: metres, the tolerance of straightening chained pieces
            (``edge_polylines.simplify_segments``; 0: exactly collinear points only).
        min_length: metres; shorter segments (after merging) are dropped.
        straighten_class_changes: straighten the boundaries between two classes too; off,
            they keep the triangle sides the classes change along, which is what a label
            image rendered from the mesh shows (straightened, a scan's jagged class
            boundaries lie off the labels' and the label modes track worse:
            docs/notes/edges.md).
    """

    regions: RegionConfig = field(default_factory=RegionConfig)
    contacts: ContactConfig = field(default_factory=ContactConfig)
    simplify_m: float = 0.02
    min_length: float = 0.05
    straighten_class_changes: bool = False


def extract_edges(
    vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray, crease_deg: float = 20.0,
    probe: BoundaryProbe | None = None, settings: EdgeExtractionConfig | None = None,
) -> EdgeSet:
    """Model edges of a mesh.

    Faces lying on a face that faces them (``covered_faces``: the bottom of a wall block
    standing on a floor, blocks side by side) are dropped first. The rest are grown into
    planar regions (``planar_regions``): an edge between two faces is a crease when their
    regions' fitted normals meet above ``crease_deg`` (scan noise inside a region makes
    none), and a class edge when the faces' classes differ; a face of class void takes its
    region's class (the area-majority of its classed faces). Boundary edges (one face) are
    classed by the surface they meet (``probe_boundary``): a wall standing on a floor as a
    separate mesh gives a floor|wall edge; an edge meeting nothing stays (void, X) at 90
    degrees. Lines where a surface meets another it shares no vertex with (a wall sunk into
    a slab, a door frame on a wall) are found by cutting the large flat regions' planes
    (``contacts.contact_lines``). A crease keeps its two faces' normals (``EdgeSet.normals``):
    seen with one face turned away it is an outline against what lies behind it (a wall end
    against the floor, a frame against the wall: ``core.imaging.outline``). The creases and
    boundary edges are straightened (``straighten``, ``settings.simplify_m``),
    the class boundaries kept as they run (``settings.straighten_class_changes``);
    collinear touching pieces are merged (``merge_collinear``) and those under
    ``settings.min_length`` dropped.

    Args:
        vertices: (V, 3) metres. faces: (F, 3) vertex indices, shared vertices merged.
        face_class: (F,) class id per face.
        crease_deg: minimum angle between region normals for a crease, degrees.
        probe: settings of the boundary probes (None: the defaults).
        settings: regions, straightening, minimum length (None: the defaults).

    Returns:
        The ``EdgeSet``: segments, classes, crease and, for the creases, face normals.
    """
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {faces.shape}")
    settings = settings or EdgeExtractionConfig()
    vertices = np.asarray(vertices, dtype=np.float64)
    face_class = np.asarray(face_class)
    normals = face_normals(vertices, faces)
    hidden = covered_faces(vertices, faces, normals, probe)
    if hidden.any():
        faces, face_class, normals = faces[~hidden], face_class[~hidden], normals[~hidden]
    uniq, count, f0, f1 = face_pairs(faces)
    two = count == 2
    region, rnormal = planar_regions(vertices, faces, normals,
                                     np.stack([f0[two], f1[two]], 1), settings.regions)
    face_class = region_classes(face_class, region, vertices, faces)
    g1 = np.maximum(f1, 0)
    angle = _degrees(normals[f0], normals[g1])
    # crease between regions: their fitted normals, each turned as its face on this edge,
    # the second as wound consistently with the first
    na = rnormal[region[f0]] * _sign(normals[f0], rnormal[region[f0]])
    nb = rnormal[region[g1]] * _sign(normals[g1], rnormal[region[g1]])
    agree = np.where(winding_agrees(faces, uniq, f0, g1), 1.0, -1.0)[:, None]
    r_angle = _degrees(na, agree * nb)
    # inside a region, a crease between two exact faces (each with a coplanar neighbour: a
    # CAD facet, not a scan's noise) stays, at the faces' own angle
    f_angle = _degrees(normals[f0], agree * normals[g1])
    flat = np.zeros(len(faces), dtype=bool)
    coplanar = two & (f_angle < FLAT_DEG)
    flat[f0[coplanar]] = flat[g1[coplanar]] = True
    inside = region[f0] == region[g1]
    r_angle = np.where(inside, np.where(flat[f0] & flat[g1], f_angle, 0.0), r_angle)
    angle = np.where(two, r_angle, np.where(count == 1, 90.0, angle))
    c0 = face_class[f0]
    c1 = np.where(count >= 2, face_class[g1], 0)
    keep = (count > 2) | (two & ((angle > crease_deg) | (c0 != c1)))
    # a crease's two face normals, each turned away from the other face (core.imaging.outline)
    crease = keep & two & (angle > crease_deg)
    nrm = np.full((len(uniq), 2, 3), np.nan)
    na_c = np.where(inside[:, None], normals[f0], na)[crease]
    nb_c = np.where(inside[:, None], normals[g1], nb)[crease]
    nrm[crease] = crease_normals(vertices, faces, uniq[crease], f0[crease], g1[crease],
                                 na_c, nb_c)
    seg = [vertices[uniq[keep]]]
    cls = [np.stack([c0, c1], axis=1)[keep]]
    nrm = [nrm[keep]]
    ang = [np.round(angle[keep], 6)]
    part = [np.sort(np.stack([region[f0], region[g1]], 1)[keep], axis=1)]
    if (count == 1).any():
        b_seg, b_cls, b_ang, b_edge = probe_boundary(vertices, faces, face_class, normals,
                                                     uniq[count == 1], f0[count == 1], probe)
        kept = (b_ang > crease_deg) | (b_cls[:, 0] != b_cls[:, 1])
        seg.append(b_seg[kept])
        cls.append(b_cls[kept])
        nrm.append(np.full((int(kept.sum()), 2, 3), np.nan))
        ang.append(b_ang[kept])
        owner = region[f0[count == 1]][b_edge[kept]]
        part.append(np.stack([owner, np.full(len(owner), -1)], 1))
    seg, ang, cls, nrm = (np.concatenate(seg), np.concatenate(ang), np.concatenate(cls),
                          np.concatenate(nrm))
    swap = cls[:, 0] > cls[:, 1]  # classes ascending, the normals in their order
    cls = np.sort(cls, axis=1).astype(np.uint8)
    nrm[swap] = nrm[swap][:, ::-1]
    part = np.concatenate(part)
    c_seg, c_cls, c_ang, c_plane = contact_lines(
        vertices, faces, face_class, normals, region, rnormal, (seg, cls),
        (probe or BoundaryProbe()).variant, settings.contacts)
    kept = (c_ang > crease_deg) | (c_cls[:, 0] != c_cls[:, 1])
    c_seg, c_ang = c_seg[kept], c_ang[kept]
    c_cls = np.sort(c_cls[kept], axis=1)
    c_part = np.stack([-2 - c_plane[kept], np.full(kept.sum(), -2)], 1)
    c_seg, c_cls, c_ang = straighten(c_seg, c_cls, c_ang, c_part, crease_deg,
                                     settings.simplify_m)[:3]
    # class boundaries between two classes stay where the faces' classes change (what a
    # label image shows, triangle side by triangle side); the rest are straightened
    exact = (cls[:, 0] != cls[:, 1]) & (cls[:, 0] != C.VOID)
    if settings.straighten_class_changes:
        exact[:] = False
    s_seg, s_cls, s_ang, member = straighten(seg[~exact], cls[~exact], ang[~exact],
                                             part[~exact], crease_deg, settings.simplify_m)
    seg = np.concatenate([seg[exact], s_seg, c_seg])
    cls = np.concatenate([cls[exact], s_cls, c_cls])
    ang = np.concatenate([ang[exact], s_ang, c_ang])
    nrm = np.concatenate([nrm[exact], nrm[~exact][member], np.full((len(c_seg), 2, 3), np.nan)])
    seg, cls, ang, nrm = merge_collinear(seg, cls, ang, nrm)
    long = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) >= settings.min_length
    return EdgeSet(seg[long], cls[long], ang[long], nrm[long])


def crease_normals(vertices: np.ndarray, faces: np.ndarray, edges: np.ndarray, fa: np.ndarray,
                   fb: np.ndarray, na: np.ndarray, nb: np.ndarray) -> np.ndarray:
    """(E, 2, 3) the normals ``na``, ``nb`` (E, 3) of faces ``fa``, ``fb`` (E,) meeting along
    ``edges`` (E, 2) vertex indices, each turned away from the other face (a convex corner's
    outward normals, whatever the mesh's winding: ``core.imaging.outline``)."""
    p = vertices[edges[:, 0]]
    e = vertices[edges[:, 1]] - p
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)

    def into(f: np.ndarray, n: np.ndarray) -> np.ndarray:
        """(E, 3) from the edge into face f across the edge, in the plane of normal n."""
        t = np.cross(e, n)
        return t * np.where(np.einsum("ij,ij->i", t, vertices[faces[f]].mean(axis=1) - p) < 0,
                            -1.0, 1.0)[:, None]

    na = na * np.where(np.einsum("ij,ij->i", na, into(fb, nb)) > 0, -1.0, 1.0)[:, None]
    nb = nb * np.where(np.einsum("ij,ij->i", nb, into(fa, na)) > 0, -1.0, 1.0)[:, None]
    return np.stack([na, nb], axis=1)


def straighten(seg: np.ndarray, cls: np.ndarray, ang: np.ndarray, part: np.ndarray,
               crease_deg: float, tol: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Edge pieces (M, 2, 3) chained within their class pair, pair of regions ``part``
    (M, 2) and crease (to a degree), straightened with tolerance ``tol`` metres
    (``simplify_segments``), then joined along lines within ``tol`` with gaps up to
    2.5 ``tol`` (``merge_near_collinear``, within the class pair and crease or not).

    Returns:
        (segments, classes, crease, member) of the straight segments; each takes the classes
        and crease of the longest piece it replaces, ``member`` (its index).
    """
    if len(seg) == 0:
        return seg.reshape(0, 2, 3), cls, ang, np.zeros(0, np.int64)
    key = np.c_[cls.astype(np.int64), part, np.round(ang).astype(np.int64)]
    _, group = np.unique(key, axis=0, return_inverse=True)
    seg, member = simplify_segments(seg, group.ravel(), tol)
    _, line_group = np.unique(np.c_[cls[member], ang[member] > crease_deg], axis=0,
                              return_inverse=True)
    seg, member2 = merge_near_collinear(seg, line_group.ravel(), tol, 2.5 * tol)
    member = member[member2]
    return seg, cls[member], ang[member], member


def _degrees(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) degrees between unit vectors a, b (K, 3)."""
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _sign(n: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(K, 1) +-1: the orientation of ``ref`` (K, 3) that agrees with ``n`` (K, 3)."""
    return np.where(np.einsum("ij,ij->i", n, ref) < 0, -1.0, 1.0)[:, None]


def region_classes(face_class: np.ndarray, region: np.ndarray, vertices: np.ndarray,
                   faces: np.ndarray) -> np.ndarray:
    """(F,) the face classes with each void face given its region's class: the class holding
    most of the region's classed area (void where the region has none)."""
    void = face_class == C.VOID
    if not void.any():
        return face_class
    area = face_areas_normals(vertices, faces)[0]
    n_cls = int(face_class.max()) + 1
    table = np.zeros((region.max() + 1, n_cls))
    np.add.at(table, (region[~void], face_class[~void].astype(np.int64)), area[~void])
    best = np.argmax(table, axis=1)
    best = np.where(table.max(axis=1) > 0, best, C.VOID)
    out = face_class.copy()
    out[void] = best[region[void]].astype(face_class.dtype)
    return out


@dataclass(frozen=True)
class BoundaryProbe:
    """How a boundary edge finds the surface it meets.

    Attributes:
        step: metres; an edge is cut into pieces at most this long, each probed at its middle
            (a wall's bottom edge along a door opening meets the floor only in part).
        offset: metres the probe starts in front of (then behind) the face, and back from the
            edge inside the face's plane.
        reach: metres the probe reaches past the edge.
        variant: Mitsuba variant of the ray caster (``core.imaging.rays.RayCaster``).
    """

    step: float = 0.25
    offset: float = 0.01
    reach: float = 0.05
    variant: str = "auto"


def covered_faces(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                  probe: BoundaryProbe | None = None) -> np.ndarray:
    """(F,) bool: faces lying wholly on other faces turned towards them.

    A face F is covered when faces with the opposite normal (within about 2.5 degrees) lie in
    F's plane (within 2 mm) at 7 points of F (its centre, near its corners, near its sides'
    middles): a wall block's bottom on a floor slab's top, the touching sides of two blocks.
    Neither is seen; their edges are not model edges. A face covered in part (a slab's top
    under the walls) is not. Found by plane keys, then one ray per point from
    ``probe.offset`` in front of F back through it, cast against the candidates of the other
    hemisphere of normals only (a coincident face of F's own orientation cannot hide the
    answer).
    """
    probe = probe or BoundaryProbe()
    out = np.zeros(len(faces), dtype=bool)
    centre = vertices[faces].mean(axis=1)
    good = np.isfinite(normals).all(axis=1)
    n = np.nan_to_num(normals)
    nk = np.round(n * 100).astype(np.int64) + 100
    dk = np.round(np.einsum("ij,ij->i", n, centre) / 0.002).astype(np.int64)
    span = 1 << 32
    key = ((nk[:, 0] * 201 + nk[:, 1]) * 201 + nk[:, 2]) * span + dk
    opposite = (((200 - nk[:, 0]) * 201 + 200 - nk[:, 1]) * 201 + 200 - nk[:, 2]) * span - dk
    table = np.unique(key[good])
    cand = np.zeros(len(faces), dtype=bool)
    for shift in (-1, 0, 1):
        at = np.clip(np.searchsorted(table, opposite + shift), 0, len(table) - 1)
        cand |= table[at] == opposite + shift
    cand &= good
    if not cand.any():
        return out
    from core.imaging.rays import RayCaster

    # hemisphere of each normal: sign of its first non-zero rounded component
    first = np.argmax(nk != 100, axis=1)
    upper = nk[np.arange(len(nk)), first] > 100
    for side in (True, False):
        mine = np.flatnonzero(cand & (upper == side))
        theirs = np.flatnonzero(cand & (upper != side))
        if len(mine) == 0 or len(theirs) == 0:
            continue
        caster = RayCaster(vertices, faces[theirs], probe.variant)
        points = np.einsum("kj,fjd->fkd", _COVER_WEIGHTS, vertices[faces[mine]])
        normal = np.repeat(n[mine], len(_COVER_WEIGHTS), axis=0)
        hit, t = caster.first_hit(points.reshape(-1, 3) + probe.offset * normal, -normal,
                                  probe.offset + 0.005)
        facing = np.einsum("ij,ij->i", normal, n[theirs[np.maximum(hit, 0)]]) < -0.999
        ok = (hit >= 0) & facing & (np.abs(t - probe.offset) < 0.005)
        out[mine] = ok.reshape(len(mine), -1).all(axis=1)
    return out


#: (7, 3) barycentric weights of the points a covered face must be covered at.
_COVER_WEIGHTS = np.array([[1 / 3, 1 / 3, 1 / 3], [0.8, 0.1, 0.1], [0.1, 0.8, 0.1],
                           [0.1, 0.1, 0.8], [0.45, 0.45, 0.1], [0.1, 0.45, 0.45],
                           [0.45, 0.1, 0.45]])


def probe_boundary(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                   normals: np.ndarray, edges: np.ndarray, owner: np.ndarray,
                   probe: BoundaryProbe | None = None,
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Class and crease of boundary edges from the surface each piece of them meets.

    Each edge is cut into pieces (``probe.step``); from ``offset`` in front of the owning
    face's middle of a piece, ``offset`` back from the edge, a ray runs in the face's plane
    across the edge, away from the face, ``offset + reach`` metres long. The first face hit
    gives the other class and the crease (the angle between the two faces' lines,
    arccos |n0 . n1|, 0..90 degrees, to 0.1 degree: imported faces' winding is arbitrary).
    No hit in front: the same from behind the face (one-sided sheets), then a probe through
    the plane just beyond the edge (a coplanar surface: a door flush in a wall, wall panels
    side by side; ``_first_faces``). No hit: void, 90.

    Args:
        vertices: (V, 3) metres; faces: (F, 3); face_class: (F,); normals: (F, 3) unit.
        edges: (B, 2) vertex indices of the boundary edges; owner: (B,) their face.
        probe: settings (None: defaults).

    Returns:
        pieces (K, 2, 3) metres; classes (K, 2) (owner's class, other); crease (K,) degrees;
        which (K,) the boundary edge (index into ``edges``) each piece is of.
    """
    probe = probe or BoundaryProbe()
    p, q = vertices[edges[:, 0]], vertices[edges[:, 1]]
    length = np.linalg.norm(q - p, axis=1)
    pieces, which = split_pieces(p, q, probe.step)
    # in-plane direction across the edge, away from the owning face's third vertex
    third = vertices[faces[owner].sum(axis=1) - edges.sum(axis=1)]
    d = (q - p) / np.maximum(length, 1e-12)[:, None]
    w = (p + q) / 2 - third
    u = w - np.einsum("ij,ij->i", w, d)[:, None] * d
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
    nf = normals[owner]
    ok = np.isfinite(nf).all(axis=1) & (np.linalg.norm(u, axis=1) > 0.5)
    hit = np.full(len(which), -1, dtype=np.int64)
    probed = np.flatnonzero(ok[which])
    if len(probed):
        hit[probed] = _first_faces(vertices, faces, pieces[probed].mean(axis=1),
                                   nf[which[probed]], u[which[probed]], probe)
    other = np.where(hit >= 0, face_class[np.maximum(hit, 0)], 0)
    cos = np.abs(np.einsum("ij,ij->i", nf[which], normals[np.maximum(hit, 0)]))
    crease = np.where(hit >= 0, np.round(np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))), 1),
                      90.0)
    classes = np.stack([face_class[owner[which]], other], axis=1)
    return pieces, classes, crease, which


def _first_faces(vertices: np.ndarray, faces: np.ndarray, mid: np.ndarray, normal: np.ndarray,
                 across: np.ndarray, probe: BoundaryProbe) -> np.ndarray:
    """(K,) first face hit by the probes at edge points ``mid`` (K, 3); -1 for none.

    In turn, for the edges still without a hit: across the edge in front of the face
    (+``normal``), across it behind the face, then through the face's plane just beyond
    the edge (``offset`` out, from ``offset`` in front to ``offset`` behind: a coplanar
    surface, which the first two run parallel to).
    """
    from core.imaging.rays import RayCaster

    caster = RayCaster(vertices, faces, probe.variant)
    off, reach = probe.offset, probe.offset + probe.reach
    back, beyond = mid - off * across, mid + off * across
    probes = ((back, normal, across, reach), (back, -normal, across, reach),
              (beyond, normal, -normal, 2 * off))
    hit = np.full(len(mid), -1, dtype=np.int64)
    for start, side, direction, length in probes:
        miss = np.flatnonzero(hit < 0)
        if len(miss) == 0:
            break
        hit[miss], _ = caster.first_hit(start[miss] + off * side[miss], direction[miss], length)
    return hit


def merge_collinear(
    segments: np.ndarray, classes: np.ndarray, crease: np.ndarray,
    normals: np.ndarray | None = None, tol: float = 1e-6
) -> tuple[np.ndarray, ...]:
    """Join collinear segments that touch end to end and share class pair, angle and (given)
    face normals.

    Args:
        segments: (M, 2, 3); classes: (M, 2); crease: (M,); normals: (M, 2, 3) or None.

    Returns:
        The merged (segments, classes, crease[, normals]), same layout, in a deterministic
        order.
    """
    extra = (np.zeros((len(segments), 0)) if normals is None
             else np.nan_to_num(normals, nan=9.0).reshape(-1, 6))  # NaN: no crease
    if len(segments) == 0:
        empty = (segments.reshape(0, 2, 3), classes.reshape(0, 2), crease.reshape(0))
        return empty if normals is None else (*empty, np.asarray(normals).reshape(0, 2, 3))
    segments = np.asarray(segments, dtype=np.float64)
    d = segments[:, 1] - segments[:, 0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # Canonical direction: first non-zero component positive.
    first = np.argmax(np.abs(d) > tol, axis=1)
    flip = d[np.arange(len(d)), first] < 0
    d[flip] *= -1
    p0 = segments[:, 0]
    # Line key: direction and the foot of the perpendicular from the origin.
    foot = p0 - np.einsum("ij,ij->i", p0, d)[:, None] * d
    t0 = np.einsum("ij,ij->i", segments[:, 0], d)
    t1 = np.einsum("ij,ij->i", segments[:, 1], d)
    lo, hi = np.minimum(t0, t1), np.maximum(t0, t1)
    key = np.concatenate([np.round(d / tol) * tol, np.round(foot / tol) * tol,
                          classes.astype(float), crease[:, None], np.round(extra, 3)],
                         axis=1).round(6)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    order = np.lexsort((lo, group))
    g, lo, hi = group[order], lo[order], hi[order]
    # running max of hi within each group, exact: dense ranks, offset per group
    uh, rank = np.unique(hi, return_inverse=True)
    key = np.maximum.accumulate(g.astype(np.int64) * (len(uh) + 1) + rank.ravel())
    reach = uh[key - g.astype(np.int64) * (len(uh) + 1)]
    start = np.r_[True, (g[1:] != g[:-1]) | (lo[1:] > reach[:-1] + tol)]
    first = np.flatnonzero(start)
    k = order[first]
    b = np.maximum.reduceat(hi, first)
    out = np.stack([foot[k] + lo[first, None] * d[k], foot[k] + b[:, None] * d[k]], axis=1)
    merged = (out, classes[k].astype(np.uint8), crease[k].astype(np.float64))
    return merged if normals is None else (*merged, np.asarray(normals)[k])
