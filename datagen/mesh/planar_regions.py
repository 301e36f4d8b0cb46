"""Planar regions of a triangle mesh: faces grown into near-planar patches.

A scanned surface is a plane under noise: its triangles' normals scatter by several degrees
and a few by tens, so a crease test on single faces finds creases everywhere. Grown into
regions first (seeded region growing on face adjacency: a face joins its neighbour's region
when its normal lies within ``region_deg`` of the region's fitted normal and its centre
within ``plane_tol`` of the region's plane), a wall is one region and the crease test runs
on the regions' fitted normals. Regions smaller than ``min_area`` (a noise bump, the strip of
a rounded corner) join the neighbouring region whose normal is closest, so the corner
between two walls is one region boundary. A CAD mesh's flat faces form exactly its facets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from datagen.mesh.building import face_areas_normals


@dataclass(frozen=True)
class RegionConfig:
    """How faces are grown into planar regions.

    Attributes:
        region_deg: degrees; a face joins a region when its normal is within this of the
            region's fitted normal (either orientation: imported winding is arbitrary).
        plane_tol: metres; ... and its centre within this of the region's plane.
        min_area: m²; smaller regions join the adjacent region with the closest normal.
    """

    region_deg: float = 30.0
    plane_tol: float = 0.02
    min_area: float = 0.01


def face_pairs(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The mesh's unique edges and the faces on each.

    Args:
        faces: (F, 3) vertex indices, shared vertices merged.

    Returns:
        edges (E, 2) sorted vertex indices; count (E,) faces on each; f0, f1 (E,) the first
        two of them (f1 = -1 on an edge with one face); f0 is the lower face index.
    """
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(faces)), 3)
    uniq, inv, count = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    order = np.argsort(inv.ravel(), kind="stable")
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    f0 = owner[order[start]]
    f1 = np.where(count >= 2, owner[order[np.minimum(start + 1, len(order) - 1)]], -1)
    return uniq, count, f0, f1


def winding_agrees(faces: np.ndarray, edges: np.ndarray, f0: np.ndarray,
                   f1: np.ndarray) -> np.ndarray:
    """(P,) bool: the faces f0, f1 on each edge (P, 2) are wound consistently (they run the
    shared edge in opposite directions), so their normals compare as they are."""
    def forward(f):  # the face runs the edge from edges[:, 0] to edges[:, 1]
        tri = faces[f]
        nxt = np.roll(tri, -1, axis=1)
        return ((tri == edges[:, :1]) & (nxt == edges[:, 1:])).any(axis=1)

    return forward(f0) != forward(f1)


def planar_regions(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                   pairs: np.ndarray, settings: RegionConfig | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Grow faces into planar regions.

    Seeds are taken in order of how well a face agrees with its neighbours (the flattest
    first); each grows over ``pairs`` while a face's normal is within ``region_deg`` of the
    region's area-weighted normal and its centre within ``plane_tol`` of the plane through
    the region's centroid. Then small regions (``min_area``) join their closest-normal
    neighbour, pass after pass while any has a large neighbour.

    Args:
        vertices: (V, 3) metres; faces: (F, 3); normals: (F, 3) unit (NaN for degenerate).
        pairs: (P, 2) face indices of adjacent faces (manifold edges).
        settings: None: the defaults.

    Returns:
        region (F,) int64 region id per face (0..R-1); normal (R, 3) each region's fitted
        unit normal, oriented as the region's seed face.
    """
    s = settings or RegionConfig()
    n_f = len(faces)
    area = face_areas_normals(vertices, faces)[0]
    centre = vertices[faces].mean(axis=1)
    good = np.isfinite(normals).all(axis=1)
    n = np.where(good[:, None], normals, 0.0)
    pairs = pairs[good[pairs].all(axis=1)]
    adj = sp.coo_matrix((np.ones(2 * len(pairs)), (np.r_[pairs[:, 0], pairs[:, 1]],
                                                   np.r_[pairs[:, 1], pairs[:, 0]])),
                        shape=(n_f, n_f)).tocsr()
    # roughness: mean (1 - |cos|) to the neighbours; faces without neighbours last
    cos = np.abs(np.einsum("ij,ij->i", n[pairs[:, 0]], n[pairs[:, 1]]))
    rough = np.bincount(pairs.ravel(), np.r_[1 - cos, 1 - cos], n_f)
    deg = np.bincount(pairs.ravel(), minlength=n_f)
    rough = np.where(deg > 0, rough / np.maximum(deg, 1), 2.0)
    order = np.lexsort((-area, rough)).tolist()
    region = _grow(order, adj.indptr.tolist(), adj.indices.tolist(), n.tolist(),
                   centre.tolist(), area.tolist(), good.tolist(),
                   float(np.cos(np.radians(s.region_deg))), float(s.plane_tol))
    region, normal = _fit(region, n, area)
    if s.min_area > 0 and len(pairs):
        while True:  # a small region among small ones joins once its neighbours have
            before = len(normal)
            region, normal = _absorb_small(region, normal, n, area, pairs, s.min_area)
            if len(normal) == before:
                break
    return region, normal


def _grow(order: list, indptr: list, indices: list, n: list, c: list, area: list,
          good: list, cos_tol: float, plane_tol: float) -> np.ndarray:
    """Seeded region growing (plain Python lists: one pass over the faces)."""
    region = [-1] * len(n)
    r = 0
    for seed in order:
        if region[seed] >= 0:
            continue
        region[seed] = r
        if not good[seed]:
            r += 1
            continue
        a = area[seed]
        sx, sy, sz = (a * v for v in n[seed])
        cx, cy, cz = (a * v for v in c[seed])
        total = a
        stack = [seed]
        while stack:
            f = stack.pop()
            norm = (sx * sx + sy * sy + sz * sz) ** 0.5 or 1.0
            ux, uy, uz = sx / norm, sy / norm, sz / norm
            px, py, pz = cx / total, cy / total, cz / total
            for g in indices[indptr[f]:indptr[f + 1]]:
                if region[g] >= 0:
                    continue
                gx, gy, gz = n[g]
                d = gx * ux + gy * uy + gz * uz
                if abs(d) < cos_tol:
                    continue
                qx, qy, qz = c[g]
                if abs((qx - px) * ux + (qy - py) * uy + (qz - pz) * uz) > plane_tol:
                    continue
                region[g] = r
                w = area[g] if d > 0 else -area[g]
                sx, sy, sz = sx + w * gx, sy + w * gy, sz + w * gz
                ag = area[g]
                cx, cy, cz = cx + ag * qx, cy + ag * qy, cz + ag * qz
                total += ag
                stack.append(g)
        r += 1
    return np.asarray(region, dtype=np.int64)


def _fit(region: np.ndarray, n: np.ndarray, area: np.ndarray
         ) -> tuple[np.ndarray, np.ndarray]:
    """Regions renumbered 0..R-1 and their area-weighted normals, each face's normal turned
    to agree with the region's first face (in region order)."""
    _, region = np.unique(region, return_inverse=True)
    region = region.ravel()
    first = np.full(region.max() + 1, -1)
    first[region[::-1]] = np.arange(len(region))[::-1]
    ref = n[first[region]]
    sign = np.where(np.einsum("ij,ij->i", n, ref) < 0, -1.0, 1.0)
    w = (sign * np.maximum(area, 1e-12))[:, None] * n
    normal = np.stack([np.bincount(region, w[:, k], region.max() + 1) for k in range(3)], 1)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.where(length > 0, length, 1.0), n[first])
    return region, normal


def _absorb_small(region: np.ndarray, normal: np.ndarray, n: np.ndarray, area: np.ndarray,
                  pairs: np.ndarray, min_area: float) -> tuple[np.ndarray, np.ndarray]:
    """Each region under ``min_area`` joins the adjacent region of at least ``min_area``
    whose normal is closest (|cos|, either orientation); one without such a neighbour stays."""
    big = np.bincount(region, area, len(normal)) >= min_area
    ra, rb = region[pairs[:, 0]], region[pairs[:, 1]]
    cross = ra != rb
    ra, rb = np.r_[ra[cross], rb[cross]], np.r_[rb[cross], ra[cross]]
    cand = ~big[ra] & big[rb]
    ra, rb = ra[cand], rb[cand]
    if len(ra) == 0:
        return region, normal
    score = np.abs(np.einsum("ij,ij->i", normal[ra], normal[rb]))
    order = np.lexsort((-score, ra))
    ra, rb = ra[order], rb[order]
    head = np.r_[True, ra[1:] != ra[:-1]]
    target = np.arange(len(normal))
    target[ra[head]] = rb[head]
    return _fit(target[region], n, area)
