"""Edge pieces chained into polylines and simplified into straight segments.

A class boundary or a crease of a scanned mesh runs along many short triangle sides, a few
centimetres each, zig-zagging about the true line. Chained end to end (pieces of one group
meeting at a point where no third piece of the group does) and simplified (Douglas-Peucker:
a polyline point is kept when it lies farther than ``tol`` from the chord it would be dropped
from), they become the few straight segments a camera sees. A straight chain (a CAD edge cut
by the triangulation) becomes its two ends.
"""

from __future__ import annotations

import numpy as np


def simplify_segments(segments: np.ndarray, group: np.ndarray, tol: float,
                      key_m: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Chain the pieces of each group into polylines and simplify them.

    Args:
        segments: (M, 2, 3) metres. group: (M,) int, pieces chain only within their group
            (a class pair, a pair of regions).
        tol: metres, the Douglas-Peucker tolerance (0: only exactly collinear points go).
        key_m: metres; end points closer than this (on a grid of this size) are one point.

    Returns:
        out (K, 2, 3) metres; member (K,) the index into ``segments`` of the longest piece
        each output segment replaces (to carry its classes and crease over).
    """
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3)
    if len(segments) == 0:
        return segments, np.zeros(0, dtype=np.int64)
    group = np.asarray(group, dtype=np.int64)
    ends = segments.reshape(-1, 3)
    _, point = np.unique(np.round(ends / key_m).astype(np.int64), axis=0, return_inverse=True)
    point = point.ravel()
    _, gi = np.unique(group, return_inverse=True)
    # a node is a point of one group: chains never cross groups
    _, node = np.unique(np.stack([np.repeat(gi.ravel(), 2), point], 1), axis=0,
                        return_inverse=True)
    node = node.ravel().reshape(-1, 2)
    length = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    xyz = np.zeros((node.max() + 1, 3))
    xyz[node.ravel()] = ends
    out, member = [], []
    for chain_nodes, chain_edges in _chains(node):
        pts = xyz[chain_nodes]
        keep = _douglas_peucker(pts, tol) if len(pts) > 2 else np.arange(len(pts))
        for a, b in zip(keep[:-1], keep[1:], strict=True):
            piece = np.asarray(chain_edges[a:b])
            out.append((pts[a], pts[b]))
            member.append(piece[np.argmax(length[piece])])
    return np.asarray(out, dtype=np.float64).reshape(-1, 2, 3), np.asarray(member, np.int64)


def _chains(node: np.ndarray) -> list[tuple[list[int], list[int]]]:
    """Polylines of an edge list (M, 2) of node ids: (nodes in order, edges in order), each
    running between nodes of degree other than 2, then the closed loops (split at their first
    node and, for simplification, at the node farthest round)."""
    m = len(node)
    deg = np.bincount(node.ravel())
    inc_order = np.argsort(node.ravel(), kind="stable")
    inc_start = np.r_[0, np.cumsum(deg)]
    incident = (inc_order // 2).tolist()
    starts = inc_start.tolist()
    ends = node.tolist()
    degree = deg.tolist()
    used = [False] * m
    chains = []

    def walk(start: int, edge: int) -> tuple[list[int], list[int]]:
        nodes, edges = [start], []
        at = start
        while True:
            used[edge] = True
            edges.append(edge)
            a, b = ends[edge]
            at = b if a == at else a
            nodes.append(at)
            if degree[at] != 2 or at == start:
                return nodes, edges
            nxt = [e for e in incident[starts[at]:starts[at + 1]] if not used[e]]
            if not nxt:
                return nodes, edges
            edge = nxt[0]

    for v in range(len(degree)):
        if degree[v] == 2:
            continue
        for e in incident[starts[v]:starts[v + 1]]:
            if not used[e]:
                chains.append(walk(v, e))
    for e in range(m):
        if not used[e]:
            nodes, edges = walk(ends[e][0], e)
            half = max(1, len(edges) // 2)
            chains.append((nodes[:half + 1], edges[:half]))
            chains.append((nodes[half:], edges[half:]))
    return chains


def _douglas_peucker(pts: np.ndarray, tol: float) -> np.ndarray:
    """Indices (ascending, first and last included) of the points (N, 3) of a polyline kept
    by Douglas-Peucker with tolerance ``tol`` metres."""
    keep = np.zeros(len(pts), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(pts) - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        d = pts[j] - pts[i]
        dn = np.linalg.norm(d)
        rel = pts[i + 1:j] - pts[i]
        if dn < 1e-12:
            dist = np.linalg.norm(rel, axis=1)
        else:
            dist = np.linalg.norm(np.cross(rel, d / dn), axis=1)
        k = int(np.argmax(dist))
        if dist[k] > tol:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return np.flatnonzero(keep)


def merge_near_collinear(segments: np.ndarray, group: np.ndarray, tol: float,
                         gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Join segments of one group that lie on one line within ``tol`` and touch, overlap or
    leave gaps up to ``gap``: a straightened crease of a scan, cut where a noise spur met it.

    The longest segment not yet taken gives the line; every segment of its group with both
    ends within ``tol`` of that line joins it; their extents along the line are united
    (gaps up to ``gap`` closed) and the interval holding the longest segment is one output
    segment on its line (the other intervals wait for a line of their own).

    Args:
        segments: (M, 2, 3) metres; group: (M,) int; tol, gap: metres (tol 0: nothing is
            merged).

    Returns:
        out (K, 2, 3) metres; member (K,) index of the segment whose line each output lies on.
    """
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3)
    if len(segments) == 0 or tol <= 0:
        return segments, np.arange(len(segments))
    group = np.asarray(group)
    vec = segments[:, 1] - segments[:, 0]
    length = np.linalg.norm(vec, axis=1)
    taken = np.zeros(len(segments), dtype=bool)
    out, member = [], []
    for s in np.argsort(-length, kind="stable"):
        if taken[s]:
            continue
        if length[s] < 1e-12:
            taken[s] = True
            continue
        d = vec[s] / length[s]
        p0 = segments[s, 0]
        cand = np.flatnonzero(~taken & (group == group[s]))
        rel = segments[cand] - p0  # (C, 2, 3)
        along = rel @ d  # (C, 2)
        off = np.linalg.norm(rel - along[..., None] * d, axis=2).max(axis=1)
        near = cand[off <= tol]
        t = (segments[near] - p0) @ d  # (N, 2)
        lo, hi = t.min(axis=1), t.max(axis=1)
        # intervals united with the seed's, gaps up to ``gap`` closed; the rest wait
        order = np.argsort(lo)
        lo, hi, near = lo[order], hi[order], near[order]
        reach = np.maximum.accumulate(hi)
        start = np.r_[True, lo[1:] > reach[:-1] + gap]
        label = np.cumsum(start) - 1
        mine = label == label[np.flatnonzero(near == s)[0]]
        taken[near[mine]] = True
        a, b = lo[mine].min(), hi[mine].max()
        out.append((p0 + a * d, p0 + b * d))
        member.append(s)
    return np.asarray(out).reshape(-1, 2, 3), np.asarray(member, dtype=np.int64)
