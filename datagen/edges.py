"""3D edge segments of a classed triangle mesh: creases, boundaries and class changes.

An edge shared by two faces is a model edge when the faces meet at an angle above the crease
threshold or carry different classes; an edge with one face is a boundary edge. Seams between
coplanar faces of one class (triangulation diagonals, grid splits) are dropped. Collinear
touching pieces with the same class pair and angle are merged into one segment.
"""

from __future__ import annotations

import numpy as np


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals (F, 3) of triangles (right-hand rule on the vertex order)."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def extract_edges(
    vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray, crease_deg: float = 20.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Model edges of a mesh.

    Args:
        vertices: (V, 3) metres. faces: (F, 3) vertex indices, shared vertices merged.
        face_class: (F,) class id per face.
        crease_deg: minimum angle between face normals for a crease, degrees.

    Returns:
        segments (M, 2, 3) endpoints in metres; classes (M, 2) uint8, the classes on the two
        sides (ascending; 0 = void for a boundary edge); crease (M,) angle between the normals
        in degrees (0 for a class change on a flat surface, 90 at a boundary edge).
    """
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must be (F, 3), got {faces.shape}")
    vertices = np.asarray(vertices, dtype=np.float64)
    normals = face_normals(vertices, faces)
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(faces)), 3)
    uniq, inv, count = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    f0 = owner[order[start]]
    f1 = np.where(count >= 2, owner[order[np.minimum(start + 1, len(order) - 1)]], -1)
    cos = np.einsum("ij,ij->i", normals[f0], normals[np.maximum(f1, 0)])
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    angle = np.where(count == 1, 90.0, angle)
    c0 = face_class[f0]
    c1 = np.where(count >= 2, face_class[np.maximum(f1, 0)], 0)
    keep = (count != 2) | (angle > crease_deg) | (c0 != c1)
    seg = vertices[uniq[keep]]
    cls = np.sort(np.stack([c0, c1], axis=1)[keep], axis=1).astype(np.uint8)
    return merge_collinear(seg, cls, np.round(angle[keep], 6))


def merge_collinear(
    segments: np.ndarray, classes: np.ndarray, crease: np.ndarray, tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Join collinear segments that touch end to end and share class pair and angle.

    Args:
        segments: (M, 2, 3); classes: (M, 2); crease: (M,).

    Returns:
        The merged (segments, classes, crease), same layout, in a deterministic order.
    """
    if len(segments) == 0:
        return segments.reshape(0, 2, 3), classes.reshape(0, 2), crease.reshape(0)
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
                          classes.astype(float), crease[:, None]], axis=1).round(6)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    order = np.lexsort((lo, group))
    out_seg, out_cls, out_ang = [], [], []
    i = 0
    while i < len(order):
        k = order[i]
        g, a, b = group[k], lo[k], hi[k]
        j = i + 1
        while j < len(order) and group[order[j]] == g and lo[order[j]] <= b + tol:
            b = max(b, hi[order[j]])
            j += 1
        out_seg.append([foot[k] + a * d[k], foot[k] + b * d[k]])
        out_cls.append(classes[k])
        out_ang.append(crease[k])
        i = j
    return np.array(out_seg), np.array(out_cls, dtype=np.uint8), np.array(out_ang)
