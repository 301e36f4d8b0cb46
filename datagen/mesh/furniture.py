"""Which faces of a building mesh are the model's own furniture (a geometric test).

A piece of furniture stands on the floor and does not reach the ceiling; a wall (a room's
wall, a partition, a column) reaches it and bounds the free space. Pieces are the connected
components (shared vertices) of the faces under test, with the floor's surface cut away first
(a scan fuses the desks' feet with the floor); low pieces whose boxes touch go together (a
CAD table top resting on separate legs). A piece that reaches the ceiling may still hold
furniture fused with it (a scanned desk against a wall): it is split by planar regions
(``planar_regions``; coplanar regions sharing a vertex count as one plane, so a CAD wall
triangulated with T-junctions stays one plane), the planes reaching the ceiling are
structure, and the rest is grouped into pieces again. The heights: ``FURNITURE_TOP``,
``CEILING_GAP``, ``STAND``.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from datagen.mesh.building import face_areas_normals
from datagen.mesh.planar_regions import RegionConfig, face_pairs, planar_regions

#: m above the floor: the highest a piece of furniture reaches. Tall bookcases, wardrobes and
#: shelf racks stay under 2.2 m (reach height); the AWS hospital's elevator car (2.48 m) and
#: portal (2.72 m), which bound a space of their own, stay walls; desks and counters measure
#: 0.75-1.1 m (bookstore, ICL office scan), the scan's desks with monitors 1.25 m.
FURNITURE_TOP = 2.2
#: m; and at least this far below the storey's top (a 2.4 m office: 1.9 m).
CEILING_GAP = 0.5
#: m: the highest a piece's lowest point is above the floor for it to stand there (a rail
#: 0.28 m up inside the hospital's elevator car does not; a desk's legs reach the floor).
STAND = 0.1
TOUCH = 0.01  # m, the gap up to which two low pieces' boxes touch (one rests on the other)
HORIZONTAL = 0.9  # |normal z| from which a face or plane is horizontal (as classify.py)
COPLANAR_DEG = 10.0  # degrees between two regions' normals still one plane
REGIONS = RegionConfig(region_deg=20.0, plane_tol=0.03, min_area=0.02)  # a scan's noise
CHUNK = 256  # pieces per block of the box-touch test (memory 3 x CHUNK x pieces bools)


def components(faces: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """(F,) int64 label of the connected piece (faces in ``sel`` (F,) bool sharing a vertex)
    each face belongs to, 0..N-1; -1 outside ``sel``."""
    label = np.full(len(faces), -1, np.int64)
    if not sel.any():
        return label
    used, node = np.unique(faces[sel], return_inverse=True)
    node = node.reshape(-1, 3)
    n = len(used)
    graph = coo_matrix((np.ones(2 * len(node)), (node[:, [0, 1]].ravel(),
                                                 node[:, [1, 2]].ravel())), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    _, label[sel] = np.unique(comp[node[:, 0]], return_inverse=True)
    return label


def touching(lo: np.ndarray, hi: np.ndarray, gap: float = TOUCH) -> np.ndarray:
    """(N,) int64 group of each box, boxes (lo, hi: (N, 3) m corners) that overlap or lie
    within ``gap`` of each other joined (transitively)."""
    n = len(lo)
    rows, cols = [], []
    for s in range(0, n, CHUNK):  # blocks of boxes, not faces
        near = ((lo[s:s + CHUNK, None] <= hi[None] + gap)
                & (hi[s:s + CHUNK, None] + gap >= lo[None])).all(axis=2)
        i, j = np.nonzero(near)
        rows.append(i + s)
        cols.append(j)
    r, c = np.concatenate(rows), np.concatenate(cols)
    return connected_components(coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)),
                                directed=False)[1]


def standing_low(label: np.ndarray, tri: np.ndarray, floor_z: float, tolerance: float,
                 limit: float) -> np.ndarray:
    """(F,) bool: the face's piece is furniture.

    A piece (``label`` (F,), 0..N-1, -1 none) is low when it tops out above ``tolerance``
    over ``floor_z`` (not the floor's own relief) and below ``limit`` (m); low pieces whose
    boxes touch (``touching``) form a group, and a group whose lowest point lies from
    ``tolerance`` below the floor to ``STAND`` above stands on it: its pieces are furniture.
    ``tri`` (F, 3, 3) the faces' corners (m).
    """
    out = np.zeros(len(label), bool)
    inside = label >= 0
    if not inside.any():
        return out
    n = int(label.max()) + 1
    lo, hi = np.full((n, 3), np.inf), np.full((n, 3), -np.inf)
    np.minimum.at(lo, label[inside], tri[inside].min(axis=1))
    np.maximum.at(hi, label[inside], tri[inside].max(axis=1))
    low = np.flatnonzero((hi[:, 2] > floor_z + tolerance) & (hi[:, 2] < limit))
    if not len(low):
        return out
    group = touching(lo[low], hi[low])
    bottom = np.full(group.max() + 1, np.inf)
    np.minimum.at(bottom, group, lo[low, 2])
    piece = np.zeros(n, bool)
    piece[low] = ((bottom >= floor_z - tolerance) & (bottom <= floor_z + STAND))[group]
    out[inside] = piece[label[inside]]
    return out


def planes(vertices: np.ndarray, faces: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(F,) int64 plane of each face: planar regions (``REGIONS``) joined where two share a
    vertex, their normals lie within ``COPLANAR_DEG`` and each one's centroid within twice
    the regions' ``plane_tol`` of the other's plane. Args: vertices (V, 3) m, faces (F, 3),
    normal (F, 3) unit."""
    _, count, f0, f1 = face_pairs(faces)
    two = count == 2
    region, rn = planar_regions(vertices, faces, normal, np.stack([f0[two], f1[two]], 1),
                                REGIONS)
    r = len(rn)
    area = face_areas_normals(vertices, faces)[0] + 1e-12
    centre = vertices[faces].mean(axis=1)
    w = np.bincount(region, area, r)
    c = np.stack([np.bincount(region, area * centre[:, k], r) for k in range(3)], 1)
    c /= w[:, None]
    v_r = np.unique(np.stack([faces.ravel(), np.repeat(region, 3)], 1), axis=0)
    inc = coo_matrix((np.ones(len(v_r)), (v_r[:, 1], v_r[:, 0])),
                     shape=(r, int(faces.max()) + 1)).tocsr()
    share = (inc @ inc.T).tocoo()
    a, b = share.row[share.row < share.col], share.col[share.row < share.col]
    d = c[b] - c[a]
    tol = 2 * REGIONS.plane_tol
    same = ((np.abs(np.einsum("ij,ij->i", rn[a], rn[b])) >= np.cos(np.radians(COPLANAR_DEG)))
            & (np.abs(np.einsum("ij,ij->i", rn[a], d)) <= tol)
            & (np.abs(np.einsum("ij,ij->i", rn[b], d)) <= tol))
    graph = coo_matrix((np.ones(int(same.sum())), (a[same], b[same])), shape=(r, r))
    return connected_components(graph, directed=False)[1][region]


def furniture_faces(vertices: np.ndarray, faces: np.ndarray, normal: np.ndarray,
                    sel: np.ndarray, floor_z: float, top: float, tolerance: float
                    ) -> np.ndarray:
    """(F,) bool: the faces of ``sel`` that are furniture.

    The faces of ``sel`` less the floor's (up-facing horizontal within ``tolerance`` of the
    floor) are grouped into pieces (``components``); a piece standing on the floor and
    topping out below ``limit`` = min(floor + ``FURNITURE_TOP``, ``top`` - ``CEILING_GAP``)
    is furniture (``standing_low``). The pieces reaching ``limit`` are cut into ``planes``;
    the planes reaching ``limit`` are structure, those at the floor (up-facing within
    ``tolerance`` of it: its noisy surface; or topping out within it: the walls' feet)
    neither, and the rest is grouped and tested again.

    Args:
        vertices: (V, 3) metres, Z up; faces: (F, 3); normal: (F, 3) unit face normals;
        sel: (F,) bool, the faces under test; floor_z, top: the storey floor's and top's
            heights (m); tolerance: m, how near the floor is on the floor.
    """
    limit = min(floor_z + FURNITURE_TOP, top - CEILING_GAP)
    tri = vertices[faces]
    z_hi, z_mid = tri[:, :, 2].max(axis=1), tri[:, :, 2].mean(axis=1)
    floor = (normal[:, 2] >= HORIZONTAL) & (np.abs(z_mid - floor_z) <= tolerance)
    cand = sel & ~floor
    label = components(faces, cand)
    out = standing_low(label, tri, floor_z, tolerance, limit)
    reach = np.zeros(int(label.max()) + 2, bool)  # [-1]: outside
    reach[label[cand & (z_hi >= limit)]] = True
    high = np.flatnonzero(reach[label])
    if not len(high):
        return out
    plane = planes(vertices, faces[high], normal[high])
    p = int(plane.max()) + 1
    p_hi = np.full(p, -np.inf)
    np.maximum.at(p_hi, plane, z_hi[high])
    area = face_areas_normals(vertices, faces[high])[0]
    p_area = np.bincount(plane, area, p) + 1e-12
    p_up = np.bincount(plane, normal[high, 2] * area, p) / p_area
    p_mid = np.bincount(plane, z_mid[high] * area, p) / p_area
    at_floor = (p_hi <= floor_z + tolerance) | ((p_up >= HORIZONTAL)
                                                & (np.abs(p_mid - floor_z) <= tolerance))
    rest = np.zeros(len(faces), bool)
    rest[high] = (p_hi[plane] < limit) & ~at_floor[plane]
    out |= standing_low(components(faces, rest), tri, floor_z, tolerance, limit)
    return out
