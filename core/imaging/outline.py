"""Outlines: model edges seen only from where one of their two faces turns away.

A crease between two faces of one class (the front edge of a frame on a wall) is a class
boundary in an image only where it is the object's outline: one face towards the camera, the
other away, so that what lies behind shows beside it. Such an edge carries its faces' normals
(wound alike, ``datagen.mesh.edges.EdgeSet.outline``), the face turned towards the camera
first: the class behind it was found looking that way (a crease may be two outlines, one
each way round); every other edge carries NaN.
"""

from __future__ import annotations

import numpy as np


def outline_seen(normals: np.ndarray, points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """Whether each point's edge is seen as an outline from its eye.

    Args:
        normals: (P, 2, 3) the two face normals of the point's edge; NaN: an edge seen from
            everywhere.
        points: (P, 3) points on the edges, metres. eyes: (P, 3) camera centres, metres.

    Returns:
        (P,) bool: True where the edge is seen from everywhere, or the first face faces the
        eye and the second turns away.
    """
    v = np.asarray(eyes, np.float64) - np.asarray(points, np.float64)
    a = np.einsum("pj,pj->p", normals[:, 0], v)
    b = np.einsum("pj,pj->p", normals[:, 1], v)
    return np.isnan(a) | ((a > 0) & (b < 0))
