"""What a camera sees along a crease: its two classes, or one of them against what lies behind.

A crease between two faces (a wall's corner, a door jamb meeting the wall, the front edge of
a frame) shows the classes of its two faces where the camera sees both (or looks into the
corner between them). Where exactly one face turns towards the camera, the crease is an
outline: the class beside it in an image is that face's against what the camera sees past the
edge (a wall end against the floor below, the wall behind and the ceiling above; a door
jamb's wall face against the next room).

A crease carries the normals of its two faces (``datagen.mesh.edges.EdgeSet.normals``), in
the order of its classes, each turned away from the other face (a convex corner's outward
normals; no mesh winding is needed). From an eye, with ``v`` the direction from the edge to
the eye, face k is turned towards it when ``n_k . v > 0``: both or neither (inside a concave
corner) show the two faces' classes; exactly one makes an outline. Edges that are not creases
between two faces (a contact line, a boundary edge) carry NaN and always show their classes.
"""

from __future__ import annotations

import numpy as np

from core import classes as C


def outline_side(normals: np.ndarray, points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """Which face of each point's crease is alone turned towards its eye.

    Args:
        normals: (P, 2, 3) the crease's two face normals (see the module), NaN for an edge
            that is no crease.
        points: (P, 3) points on the edges, metres. eyes: (P, 3) camera centres, metres.

    Returns:
        (P,) int8: 0 or 1, the face turned towards the eye while the other turns away (an
        outline); -1 where the edge shows its own two classes.
    """
    v = np.asarray(eyes, np.float64) - np.asarray(points, np.float64)
    a = np.einsum("pj,pj->p", normals[:, 0], v) > 0
    b = np.einsum("pj,pj->p", normals[:, 1], v) > 0
    return np.where(a & ~b, 0, np.where(b & ~a, 1, -1)).astype(np.int8)


def behind_class(caster, face_class: np.ndarray, points: np.ndarray, eyes: np.ndarray,
                 eps: float = 0.01) -> np.ndarray:
    """The class a camera at each eye sees just past each outline point: the first face the
    ray from the eye through the point meets beyond it (starting ``eps`` metres past it, so
    the outline's own faces, turned away, are not met).

    Args:
        caster: a ``core.imaging.rays.RayCaster`` of the model; face_class: (F,) its classes.
        points: (P, 3) outline points, metres. eyes: (P, 3) camera centres, metres.

    Returns:
        (P,) uint8 class behind each point; ``core.classes.IGNORE`` where the ray meets
        nothing.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    d = points - np.asarray(eyes, np.float64).reshape(-1, 3)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    face, _ = caster.first_hit(points + eps * d, d, 1e3)
    return np.where(face >= 0, np.asarray(face_class)[np.maximum(face, 0)],
                    C.IGNORE).astype(np.uint8)


def seen_pairs(classes: np.ndarray, normals: np.ndarray, points: np.ndarray, eyes: np.ndarray,
               caster, face_class: np.ndarray) -> np.ndarray:
    """The class pair each eye sees along each edge point: its two classes, or for an outline
    (``outline_side``) its front face's class and the class behind (``behind_class``).

    Args:
        classes: (P, 2) the classes of the point's edge, in the order of ``normals``.
        normals: (P, 2, 3) as ``outline_side``'s. points, eyes: (P, 3) metres.
        caster, face_class: the model, as ``behind_class``'s.

    Returns:
        (P,) uint8 ``core.classes.pair_code`` of the two classes seen; 0 where they are one
        class or nothing lies behind an outline.
    """
    classes = np.asarray(classes).reshape(-1, 2).astype(np.int64)
    a, b = classes[:, 0].copy(), classes[:, 1].copy()
    side = outline_side(normals, points, eyes)
    out = np.flatnonzero(side >= 0)
    if len(out):
        a[out] = classes[out, side[out]]
        b[out] = behind_class(caster, face_class, np.asarray(points)[out],
                              np.asarray(eyes)[out])
    ok = (a != b) & (b != C.IGNORE)
    return np.where(ok, C.pair_code(a, np.where(ok, b, 0)), 0).astype(np.uint8)


def structural_change(codes: np.ndarray) -> np.ndarray:
    """(...) bool: pair codes of two different structural classes (what label edges show)."""
    lo, hi = C.pair_classes(np.asarray(codes, np.int64))
    return (lo != hi) & np.isin(lo, C.STRUCTURAL) & np.isin(hi, C.STRUCTURAL)
