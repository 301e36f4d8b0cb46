"""The budget of visible samples per particle (``likelihood.max_samples``): a bounded frame.

A particle's likelihood costs work in proportion to the model samples it may see. In a corridor
that is a few hundred to two thousand; in a large open building at 15 m of visibility range,
tens of thousands, and a frame of 500 particles takes seconds. The budget bounds it: a particle
that may see more than ``max_samples`` samples scores only those on a lattice of the sample ids,
``id % s == 0`` with s the smallest power of two that brings its count within the budget. The
samples of a segment are consecutive ids, so the lattice keeps every s-th sample along each
segment (the visible samples are thinned evenly along the image lines); lattices of powers of
two are nested, so particles of different strides still share their columns. A particle within
the budget keeps stride 1 and scores exactly as without a budget.

What a particle "may see" is counted without projecting: the samples listed for its
visibility cell (``visibility.SparseVisibility``) within the azimuths that the particles of
that cell whose heading lies in the same ``SECTORS``-th of the circle face (the conservative
cone of ``projection.in_view_cone``, for those particles together). Its visible samples are a
subset of those, so the budget bounds them exactly. The stride depends only on the particle
set, not on how particles are grouped into blocks (``likelihood.chunk``) or threads.
"""

from __future__ import annotations

import numpy as np

from localize.filter.projection import in_cone
from localize.filter.visibility import SparseVisibility

#: Heading sectors of the circle: the particles of one cell and one sector are counted together.
SECTORS = 8
#: Most lattice levels tried (stride up to 2^MAX_LEVEL); past it the count is 0 or 1 per cell.
MAX_LEVEL = 30
#: Entries (listed samples) gathered at once when counting, bounding the temporaries.
GATHER_CHUNK = 1 << 22


def group_cones(centres: np.ndarray, yaws: np.ndarray, group: np.ndarray, groups: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cone of each group of cameras, as ``projection.in_view_cone`` makes it for one.

    Args:
        centres: (n, 3) camera centres, metres.
        yaws: (n,) body headings, radians.
        group: (n,) int group of each camera, in [0, groups), every group non-empty.
        groups: G.

    Returns:
        mean_yaw (G,), spread (G,) radians; mid (G, 2) mean centre and r (G,) the largest
        distance of a member from it, metres.
    """
    count = np.bincount(group, minlength=groups).astype(np.float64)
    mean_yaw = np.arctan2(np.bincount(group, np.sin(yaws), groups),
                          np.bincount(group, np.cos(yaws), groups))
    spread = np.zeros(groups)
    np.maximum.at(spread, group, np.abs(np.angle(np.exp(1j * (yaws - mean_yaw[group])))))
    mid = np.stack([np.bincount(group, centres[:, k], groups) / count for k in (0, 1)], axis=1)
    r = np.zeros(groups)
    np.maximum.at(r, group, np.linalg.norm(centres[:, :2] - mid[group], axis=1))
    return mean_yaw, spread, mid, r


def strides(vis: SparseVisibility, points: np.ndarray, rows: np.ndarray, centres: np.ndarray,
            yaws: np.ndarray, half_width: float, budget: int) -> np.ndarray:
    """Each particle's sample stride under the budget (module docstring).

    Args:
        vis: the visibility lists.
        points: (P, 3) the model samples, metres.
        rows: (N,) the visibility row of each particle's camera.
        centres: (N, 3) camera centres, metres.
        yaws: (N,) body headings, radians.
        half_width: the view's half-width (``projection.view_half_width``), radians.
        budget: most samples a particle may see (0: no budget).

    Returns:
        (N,) int64 powers of two; 1 where the particle may see at most ``budget`` samples.
    """
    rows = np.asarray(rows, dtype=np.int64)
    out = np.ones(len(rows), dtype=np.int64)
    if budget <= 0 or len(rows) == 0:
        return out
    yaws = np.asarray(yaws, np.float64)
    sector = np.floor(np.mod(yaws, 2 * np.pi) * (SECTORS / (2 * np.pi))).astype(np.int64)
    keys, inv = np.unique(rows * SECTORS + np.clip(sector, 0, SECTORS - 1),
                          return_inverse=True)
    inv = inv.ravel()
    urows = keys // SECTORS  # the row of each (row, sector) group
    listed = np.diff(vis.indptr)[urows]
    big = np.flatnonzero(listed > budget)  # groups whose row lists more than the budget
    if len(big) == 0:
        return out
    slot = np.full(len(urows), -1, dtype=np.int64)
    slot[big] = np.arange(len(big))
    member = slot[inv]
    on = member >= 0
    cones = group_cones(np.asarray(centres, np.float64)[on], yaws[on], member[on], len(big))
    stride = np.ones(len(big), dtype=np.int64)
    ends = np.searchsorted(np.cumsum(listed[big]), np.arange(GATHER_CHUNK, listed[big].sum()
                                                             + GATHER_CHUNK, GATHER_CHUNK),
                           side="right")
    ends = np.unique(np.clip(np.r_[ends, len(big)], 1, len(big)))
    for a, b in zip(np.r_[0, ends[:-1]], ends, strict=True):  # rows of about GATHER_CHUNK
        ids, which = vis.gather(urows[big[a:b]])
        which = which + a
        keep = in_cone(points[ids], *(c[which] for c in cones), half_width)
        ids, which = ids[keep], which[keep]
        level_s = np.ones(b - a, dtype=np.int64)
        todo = np.bincount(which - a, minlength=b - a) > budget
        for level in range(1, MAX_LEVEL + 1):
            if not todo.any():
                break
            s = 1 << level
            on_lattice = (ids & (s - 1)) == 0
            n = np.bincount(which[on_lattice] - a, minlength=b - a)
            level_s[todo] = s
            todo &= n > budget
        stride[a:b] = level_s
    out[on] = stride[member[on]]
    return out


def line_minimum(minimum: int, stride: np.ndarray) -> np.ndarray:
    """(n,) int the visible samples a line needs at each stride (n,): ``minimum`` at stride 1,
    ``ceil(minimum / stride)`` (at least 1) beyond, so a line needs the same length in
    metres."""
    stride = np.asarray(stride, np.int64)
    return np.where(stride == 1, int(minimum), np.maximum(-(-int(minimum) // stride), 1))
