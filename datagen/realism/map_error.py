"""The map the localizer reads, made from the rendered world with a surveyor's errors
(``realism.map``, ``MapErrorConfig``).

A user's model of a building is a floor plan or a scan, not the building: walls a few cm off,
the ceiling height off, a door drawn that was never built or one left out, a built-in
cabinet or pillar nobody drew. Datagen renders the truth and writes, as the dataset's
``world/`` (the files the localizer reads), the truth edited:

- ``missing_openings`` doors or windows of the world flattened into their wall (the recess's
  back moved onto the wall's plane, its faces classed wall, the faces left without area
  dropped);
- every wall (a connected flat piece of class wall, with the door and window recesses it
  holds) shifted along its normal by ``N(0, wall_std_m)``, every ceiling up by
  ``N(0, ceiling_std_m)``: each vertex moves by the least-squares displacement meeting the
  shifts of the planes it lies on, so corners stay corners;
- ``extra_openings`` doors or windows drawn on plain walls (a door- or window-classed
  rectangle 2 mm in front of the wall, where the wall is whole);

then its model edges and free space are made from the edited mesh as the truth's were. The
truth is written to ``world_truth/`` with the ``builtins`` (unmodelled cabinets and pillars,
class wall, ``datagen.realism.builtin_objects``) that the flights' renders show and the map
lacks; they stand against walls off every flight's camera path. Everything is drawn from the
dataset's map-error generator and listed in dataset.json's ``map_error``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core import classes as C
from core.config import as_config
from core.dataset import World
from core.imaging.realism import MapErrorConfig
from core.occupancy import OccupancyMap
from datagen.config import DoorSize, WindowSize
from datagen.mesh.edges import extract_edges

WHERE = "realism.map"
OPENING_KINDS = {"door": C.DOOR, "window": C.WINDOW}
BUILTIN_KINDS = ("cabinet", "pillar")
#: m an opening made as its own mesh may stand off the wall it is in (its host).
HOST_REACH = 0.3
#: m the drawn opening stands in front of its wall.
EXTRA_OFFSET = 0.002
#: tries at placing one extra opening or built-in object before giving up (a warning in the
#: record: fewer than asked).
TRIES = 200


def check_settings(settings: MapErrorConfig | Mapping | None,
                   where: str = WHERE) -> MapErrorConfig:
    """The settings typed and checked.

    Raises:
        ValueError: a negative or non-finite std or count, an unknown kind, a bad size,
            naming ``where.<key>`` and the fix.
    """
    c = as_config(MapErrorConfig, settings, where)
    for key in ("wall_std_m", "ceiling_std_m", "builtin_clearance_m"):
        v = float(getattr(c, key))
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{where}.{key} = {v} must be finite and >= 0 (m); 0 turns it off")
    for key in ("wall_std_m", "ceiling_std_m"):
        if getattr(c, key) > 0.5:
            raise ValueError(f"{where}.{key} = {getattr(c, key)} m is not a survey error; give "
                             "a few cm (e.g. 0.03)")
    for key in ("missing_openings", "extra_openings", "builtins"):
        v = getattr(c, key)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"{where}.{key} = {v!r} must be a count >= 0; 0 turns it off")
    for key, known in (("extra_kinds", OPENING_KINDS), ("builtin_kinds", BUILTIN_KINDS)):
        kinds = list(getattr(c, key))
        bad = [k for k in kinds if k not in known]
        if not kinds or bad:
            raise ValueError(f"{where}.{key} = {kinds} must be a non-empty list of "
                             f"{sorted(known)}")
    for key, n in (("builtin_cabinet_m", 3), ("builtin_pillar_m", 2)):
        size = list(getattr(c, key))
        if len(size) != n or not all(math.isfinite(float(s)) and s > 0 for s in size):
            raise ValueError(f"{where}.{key} = {size} must be {n} positive sizes in m")
    return c


def is_active(c: MapErrorConfig) -> bool:
    """Whether the map differs from the truth."""
    return (c.wall_std_m > 0 or c.ceiling_std_m > 0 or c.missing_openings > 0
            or c.extra_openings > 0 or c.builtins > 0)


# --------------------------------------------------------------------------- mesh pieces


def _normals_areas(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3) unit normals (zero for a face without area) and (F,) areas, m^2."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    return n / np.maximum(norm, 1e-300)[:, None], norm / 2


def _plane_keys(normals: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(F,) int64 key of each face's plane: its normal to 1e-3 and offset to 1 mm."""
    nk = np.round(normals * 1000).astype(np.int64) + 1000
    dk = np.round(np.einsum("ij,ij->i", normals, points) * 1000).astype(np.int64)
    return ((nk[:, 0] * 2001 + nk[:, 1]) * 2001 + nk[:, 2]) * (1 << 24) + dk


def components(faces: np.ndarray, mask: np.ndarray, key: np.ndarray) -> np.ndarray:
    """(F,) int label of each masked face's piece, -1 elsewhere: masked faces sharing a vertex
    and a key are one piece. Labels are numbered by their lowest face index."""
    sel = np.flatnonzero(mask)
    labels = np.full(len(faces), -1, dtype=np.int64)
    if not len(sel):
        return labels
    _, kid = np.unique(key[sel], return_inverse=True)
    V = int(faces.max()) + 1
    node = (np.repeat(kid, 3) * V + faces[sel].ravel())  # (key, vertex) nodes
    _, nid = np.unique(node, return_inverse=True)
    n_faces = len(sel)
    rows = np.repeat(np.arange(n_faces), 3)
    graph = sparse.coo_matrix((np.ones(len(rows)), (rows, n_faces + nid)),
                              shape=(n_faces + nid.max() + 1,) * 2)
    _, lab = connected_components(graph, directed=False)
    lab = lab[:n_faces]
    first = np.full(lab.max() + 1, len(sel))
    np.minimum.at(first, lab, np.arange(n_faces))
    order = np.argsort(first[np.unique(lab)])
    rank = np.empty(lab.max() + 1, dtype=np.int64)
    rank[np.unique(lab)[order]] = np.arange(len(order))
    labels[sel] = rank[lab]
    return labels


@dataclass
class Pieces:
    """The planes of a mesh the edits move.

    walls: (F,) wall piece per face (-1: none); wall_normal (W, 3), wall_point (W, 3): a
    wall's unit normal (pointing as its faces do) and a point on it. openings: (F,) door or
    window piece per face; opening_class (O,); host (O,) the wall piece each opening is cut
    into (parallel, sharing vertices; -1: none); back (F,) bool: an opening's faces parallel to
    its host (the door leaf, the glass). ceilings: (F,) ceiling piece per face.
    """

    walls: np.ndarray
    wall_normal: np.ndarray
    wall_point: np.ndarray
    openings: np.ndarray
    opening_class: np.ndarray
    host: np.ndarray
    back: np.ndarray
    ceilings: np.ndarray


def find_pieces(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                ceiling_above: float = -np.inf) -> Pieces:
    """Walls (vertical faces of class wall, by connected plane), doors and windows (connected
    faces of one class) and their host walls (sharing vertices; else the nearest parallel wall
    within ``HOST_REACH``), ceilings (downward faces of class ceiling above ``ceiling_above``
    m: the ones over the flyable heights, not a slab's underside)."""
    normals, area = _normals_areas(vertices, faces)
    centre = vertices[faces].mean(axis=1)
    # a plane's key whichever way its faces turn (an imported wall may hold faces of both)
    first = np.take_along_axis(normals, np.argmax(np.abs(normals) > 1e-6, axis=1)[:, None], 1)
    canonical = normals * np.where(first < 0, -1.0, 1.0)
    key = _plane_keys(canonical, centre)
    good = area > 1e-12
    vertical = good & (np.abs(normals[:, 2]) < 0.1)
    walls = components(faces, vertical & (face_class == C.WALL), key)
    W = walls.max() + 1
    on = walls >= 0
    wall_normal = np.zeros((W, 3))
    np.add.at(wall_normal, walls[on], canonical[on] * area[on, None])
    wall_normal /= np.maximum(np.linalg.norm(wall_normal, axis=1), 1e-300)[:, None]
    facing = np.zeros(W)  # turned the way most of the wall's area faces
    np.add.at(facing, walls[on], area[on] * np.einsum("ij,ij->i", normals[on],
                                                      wall_normal[walls[on]]))
    wall_normal *= np.where(facing < 0, -1.0, 1.0)[:, None]
    first = np.full(W, len(faces))
    np.minimum.at(first, walls[walls >= 0], np.flatnonzero(walls >= 0))
    wall_point = vertices[faces[np.minimum(first, len(faces) - 1), 0]] if W else np.zeros((0, 3))
    is_opening = good & np.isin(face_class, list(OPENING_KINDS.values()))
    openings = components(faces, is_opening, face_class.astype(np.int64))
    O = openings.max() + 1
    opening_class = np.zeros(O, dtype=np.uint8)
    opening_class[openings[openings >= 0]] = face_class[openings >= 0]
    # each vertex's wall pieces, as (vertex, wall) pairs
    wf = np.flatnonzero(walls >= 0)
    pairs = np.unique(np.stack([faces[wf].ravel(), np.repeat(walls[wf], 3)], axis=1), axis=0)
    host = np.full(O, -1, dtype=np.int64)
    back = np.zeros(len(faces), dtype=bool)
    for o in range(O):
        fo = np.flatnonzero(openings == o)
        verts = np.unique(faces[fo])
        touching = pairs[np.isin(pairs[:, 0], verts), 1]
        cand, count = np.unique(touching, return_counts=True)
        along = np.array([area[fo] @ (np.abs(normals[fo] @ wall_normal[w]) > 0.999)
                          for w in cand])
        if len(cand) and along.max() > 0:
            w = int(cand[np.argmax(along * 1e6 + count)])
        else:  # a separate door or window mesh: the nearest parallel wall
            w = _nearest_wall(vertices, faces, walls, wall_normal, wall_point,
                              normals[fo], area[fo], vertices[verts])
            if w < 0:
                continue
        host[o] = w
        back[fo] = np.abs(normals[fo] @ wall_normal[w]) > 0.999
    ceilings = components(faces, good & (face_class == C.CEILING) & (normals[:, 2] < -0.9)
                          & (centre[:, 2] > ceiling_above), key)
    return Pieces(walls, wall_normal, wall_point, openings, opening_class, host, back, ceilings)


def _nearest_wall(vertices: np.ndarray, faces: np.ndarray, walls: np.ndarray,
                  wall_normal: np.ndarray, wall_point: np.ndarray, normals: np.ndarray,
                  area: np.ndarray, points: np.ndarray) -> int:
    """The wall an opening's faces ((K, 3) normals, (K,) areas, its (P, 3) vertices) stand
    in: parallel to its largest face, its plane within ``HOST_REACH`` of every vertex, its
    faces' bounds (grown by ``HOST_REACH``) holding the opening's centre; -1 for none."""
    n = normals[np.argmax(area)]
    centre = points.mean(axis=0)
    best, dist = -1, HOST_REACH
    for w in np.flatnonzero(np.abs(wall_normal @ n) > 0.999):
        d = np.abs((points - wall_point[w]) @ wall_normal[w]).max()
        if d > dist:
            continue
        tri = vertices[faces[walls == w]].reshape(-1, 3)
        if np.all(centre >= tri.min(0) - HOST_REACH) and np.all(centre <= tri.max(0) + HOST_REACH):
            best, dist = int(w), d
    return best


def merge_vertices(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                   tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices closer than ``tol`` (m, on a grid) merged; faces left without area dropped."""
    q = np.round(vertices / tol).astype(np.int64)
    _, first, inv = np.unique(q, axis=0, return_index=True, return_inverse=True)
    v = vertices[first]
    f = inv.ravel()[faces]
    _, area = _normals_areas(v, f)
    keep = (area > 1e-10) & (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f, cls = f[keep], face_class[keep]
    used, f = np.unique(f, return_inverse=True)
    return v[used], f.reshape(-1, 3), cls


# --------------------------------------------------------------------------- the edits


def remove_openings(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                    count: int, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
    """``count`` doors or windows (drawn among those with a host wall) flattened into their
    wall: their vertices projected onto the wall's plane, their faces classed wall, the faces
    left without area (jambs, the recess's floor) dropped.

    Returns:
        vertices, faces, face_class of the edited mesh; the record of each removal (kind,
        centre (3,) m, width, height m, depth m it was recessed by).
    """
    p = find_pieces(vertices, faces, face_class)
    hosted = np.flatnonzero(p.host >= 0)
    pick = rng.permutation(hosted)[:count]
    v, cls = vertices.copy(), face_class.copy()
    record = []
    for o in sorted(int(x) for x in pick):
        fo = np.flatnonzero(p.openings == o)
        verts = np.unique(faces[fo])
        n, p0 = p.wall_normal[p.host[o]], p.wall_point[p.host[o]]
        depth = (v[verts] - p0) @ n
        v[verts] -= depth[:, None] * n
        cls[fo] = C.WALL
        lo, hi = v[verts].min(0), v[verts].max(0)
        record.append({"kind": "door" if p.opening_class[o] == C.DOOR else "window",
                       "centre": np.round((lo + hi) / 2, 4).tolist(),
                       "width": round(float(np.linalg.norm((hi - lo)[:2])), 4),
                       "height": round(float(hi[2] - lo[2]), 4),
                       "depth": round(float(-depth.min()), 4)})
    v, f, cls = merge_vertices(v, faces, cls)
    return v, f, cls, record


def shift_planes(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                 wall_std: float, ceiling_std: float, rng: np.random.Generator,
                 ceiling_above: float = -np.inf) -> tuple[np.ndarray, list[dict], list[dict]]:
    """Every wall shifted along its normal by ``N(0, wall_std)`` m (its openings' backs with
    it), every ceiling (above ``ceiling_above`` m) raised by ``N(0, ceiling_std)`` m; each
    vertex moves by the least-squares displacement meeting the shifts of the planes it lies
    on (a corner of two walls meets both; a vertex on one wall slides along the floor).

    Returns:
        (V, 3) moved vertices; per wall {normal, point, shift_m, area_m2}; per ceiling
        {point, dz_m, area_m2}.
    """
    p = find_pieces(vertices, faces, face_class, ceiling_above)
    _, area = _normals_areas(vertices, faces)
    W, Cn = p.wall_normal.shape[0], p.ceilings.max() + 1
    wall_shift = wall_std * rng.standard_normal(W)
    ceil_dz = ceiling_std * rng.standard_normal(Cn)
    rows_v, rows_n, rows_s = [], [], []
    # (vertex, wall) of wall faces and of the openings' backs (moving with their host)
    host = np.append(p.host, -1)  # -1: a face of no opening
    host_of_face = np.where(p.back, host[np.where(p.openings >= 0, p.openings, -1)], -1)
    owner = np.where(p.walls >= 0, p.walls, host_of_face)
    wf = np.flatnonzero(owner >= 0)
    if len(wf):
        pairs = np.unique(np.stack([faces[wf].ravel(), np.repeat(owner[wf], 3)], axis=1), axis=0)
        rows_v.append(pairs[:, 0])
        rows_n.append(p.wall_normal[pairs[:, 1]])
        rows_s.append(wall_shift[pairs[:, 1]])
    for c in range(Cn):  # a ceiling's vertices, and every vertex at its height under it (the
        # tops of walls modelled as their own blocks)
        cv = vertices[np.unique(faces[p.ceilings == c])]
        lo, hi = cv.min(0), cv.max(0)
        at = np.flatnonzero((np.abs(vertices[:, 2] - cv[:, 2].mean()) < 1e-3)
                            & np.all((vertices[:, :2] >= lo[:2] - 1e-6)
                                     & (vertices[:, :2] <= hi[:2] + 1e-6), axis=1))
        rows_v.append(at)
        rows_n.append(np.tile([0.0, 0.0, 1.0], (len(at), 1)))
        rows_s.append(np.full(len(at), ceil_dz[c]))
    moved = vertices.copy()
    if rows_v:
        rv, rn, rs = np.concatenate(rows_v), np.concatenate(rows_n), np.concatenate(rows_s)
        A = np.zeros((len(vertices), 3, 3))
        b = np.zeros((len(vertices), 3))
        np.add.at(A, rv, rn[:, :, None] * rn[:, None, :])
        np.add.at(b, rv, rn * rs[:, None])
        at = np.unique(rv)
        moved[at] += np.einsum("vij,vj->vi", np.linalg.pinv(A[at], rcond=0.05), b[at])
    walls = []
    for w in range(W):
        fw = p.walls == w
        walls.append({"normal": (np.round(p.wall_normal[w], 4) + 0.0).tolist(),
                      "point": np.round(p.wall_point[w], 4).tolist(),
                      "shift_m": round(float(wall_shift[w]), 6),
                      "area_m2": round(float(area[fw].sum()), 3)})
    ceilings = []
    for c in range(Cn):
        fc = np.flatnonzero(p.ceilings == c)
        ceilings.append({"point": np.round(vertices[faces[fc[0], 0]], 4).tolist(),
                         "dz_m": round(float(ceil_dz[c]), 6),
                         "area_m2": round(float(area[fc].sum()), 3)})
    return moved, walls, ceilings


def _covered(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(P,) bool: 2D points inside any of the (T, 3, 2) triangles (edges included)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = np.abs(det) > 1e-12
    d = points[:, None, :] - a[None]
    u = (d[..., 0] * e2[:, 1] - d[..., 1] * e2[:, 0]) / np.where(ok, det, 1.0)
    w = (e1[:, 0] * d[..., 1] - e1[:, 1] * d[..., 0]) / np.where(ok, det, 1.0)
    return np.any(ok & (u >= -1e-9) & (w >= -1e-9) & (u + w <= 1 + 1e-9), axis=1)


def add_openings(vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray, count: int,
                 kinds: list[str], rng: np.random.Generator, floor_z: float = 0.0,
                 free: OccupancyMap | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
    """``count`` doors or windows drawn on walls: each a rectangle (a door: ``DoorSize``'s
    width x height from the floor, ``floor_z`` m; a window: ``WindowSize``'s at its sill) of the
    opening's class, ``EXTRA_OFFSET`` in front of a wall that is whole behind it (wall faces
    at every point of a 9 x 9 lattice over it) and, given ``free``, facing the free space
    (its centre's footprint, the margin and a cell in front, within a cell of a free cell),
    appended as its own two triangles.

    Returns:
        vertices, faces, face_class with the rectangles; the record of each (kind, centre (3,)
        m, normal (3,), width, height m).
    """
    p = find_pieces(vertices, faces, face_class)
    _, area = _normals_areas(vertices, faces)
    W = p.wall_normal.shape[0]
    wall_area = np.bincount(p.walls[p.walls >= 0], area[p.walls >= 0], minlength=W)
    door, window = DoorSize(), WindowSize()
    new_v, new_f, new_c, record = [vertices], [faces], [face_class], []
    placed: list[tuple[int, float, float, float, float]] = []  # wall, u0, u1, z0, z1
    nv = len(vertices)
    g = (np.arange(9) + 0.5) / 9
    lattice = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    for _ in range(count):
        kind = str(kinds[rng.integers(len(kinds))])
        width, height = ((door.width, door.height) if kind == "door"
                         else (window.width, window.height))
        for _try in range(TRIES):
            if not W or wall_area.sum() <= 0:
                break
            w = int(rng.choice(W, p=wall_area / wall_area.sum()))
            n = p.wall_normal[w]
            u_axis = np.array([-n[1], n[0], 0.0]) / max(math.hypot(n[0], n[1]), 1e-12)
            tri = vertices[faces[p.walls == w]]
            uz = np.stack([tri @ u_axis, tri[..., 2]], axis=-1)  # (T, 3, 2)
            lo, hi = uz.reshape(-1, 2).min(0), uz.reshape(-1, 2).max(0)
            z0 = floor_z + (0.0 if kind == "door" else window.sill)
            if hi[0] - lo[0] < width:
                continue
            u0 = rng.uniform(lo[0], hi[0] - width)
            box = np.array([u0, z0]), np.array([u0 + width, z0 + height])
            pts = box[0] + lattice * (box[1] - box[0])
            if not _covered(pts, uz).all():
                continue
            if any(pw == w and u0 < b1 and u0 + width > b0 for pw, b0, b1, _, _ in placed):
                continue
            if free is not None:
                ahead = (u0 + width / 2) * u_axis + float(p.wall_point[w] @ n) * n
                ahead = ahead[:2] + (free.margin + free.cell) * n[:2]
                if free.outside_distance(ahead[None])[0] > free.cell:
                    continue
            plane = float(p.wall_point[w] @ n) + EXTRA_OFFSET
            corners_uz = np.array([[u0, z0], [u0 + width, z0], [u0 + width, z0 + height],
                                   [u0, z0 + height]])
            along = corners_uz[:, :1] * u_axis + plane * n
            corners = along + corners_uz[:, 1:] * np.array([0.0, 0.0, 1.0])
            quad = np.array([[0, 1, 2], [0, 2, 3]]) + nv
            if np.cross(corners[1] - corners[0], corners[2] - corners[0]) @ n < 0:
                quad = quad[:, ::-1]
            new_v.append(corners)
            new_f.append(quad)
            new_c.append(np.full(2, OPENING_KINDS[kind], dtype=face_class.dtype))
            nv += 4
            placed.append((w, u0, u0 + width, z0, z0 + height))
            record.append({"kind": kind, "centre": np.round(corners.mean(0), 4).tolist(),
                           "normal": (np.round(n, 4) + 0.0).tolist(), "width": width,
                           "height": height})
            break
    return (np.concatenate(new_v), np.concatenate(new_f), np.concatenate(new_c), record)


# --------------------------------------------------------------------------- the map


def make_map(truth: World, c: MapErrorConfig, crease_deg: float,
             rng: np.random.Generator) -> tuple[World, dict]:
    """The map: the truth's mesh edited (``remove_openings``, ``shift_planes``,
    ``add_openings``, in that order), its model edges (``extract_edges``) and free space
    (``OccupancyMap.from_mesh``, the truth's band, margin and cell) made from it.

    Args:
        truth: the rendered world (without the built-ins: the map lacks them anyway).
        c: the settings (``check_settings``).
        crease_deg: the world's crease threshold.
        rng: the dataset's map-error generator.

    Returns:
        The map, and the record of its edits (dataset.json's ``map_error``, without the
        built-ins).
    """
    v, f, cls = truth.vertices, truth.faces, truth.face_class
    v, f, cls, missing = remove_openings(v, f, cls, c.missing_openings, rng)
    v, walls, ceilings = shift_planes(v, f, cls, c.wall_std_m, c.ceiling_std_m, rng,
                                      truth.free.band[1])
    v, f, cls, extra = add_openings(v, f, cls, c.extra_openings, list(c.extra_kinds), rng,
                                    float(truth.info.get("floor_z", 0.0)), truth.free)
    segments, seg_classes, crease, normals = extract_edges(v, f, cls, crease_deg)
    tf = truth.free
    free = OccupancyMap.from_mesh(v, f, cls, tf.band, tf.margin, tf.cell)
    info = {k: val for k, val in truth.info.items() if k != "free_space"}
    info.update({
        "map_of": "world_truth (dataset.json's map_error lists the edits)",
        "free_space": {"z_range": list(free.band), "cell": tf.cell, "margin": tf.margin,
                       "area_m2": round(free.area, 3)},
        "num_faces": int(len(f)), "num_edges": int(len(segments)),
    })
    world = World(v, f, cls, segments, seg_classes, crease, free, info, normals)
    record = {"walls": walls, "ceilings": ceilings, "missing_openings": missing,
              "extra_openings": extra}
    return world, record
