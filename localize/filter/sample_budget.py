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

The counting's in-cone ids are kept (``Budget``, up to ``KEEP_ENTRIES``) and are the blocks'
columns: a block scores the union of its groups' lists on its lattice, so each list is gathered
and cone-tested once a frame, and a group's cone (one cell, 45 degrees of heading) is narrower
than a block's. ``Budget.own``, what each particle may see alone, is what a block of particles
far apart (``likelihood.BLOCK_COLUMNS``) is split by.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from localize.filter.projection import in_cone
from localize.filter.visibility import SparseVisibility

#: Heading sectors of the circle: the particles of one cell and one sector are counted together.
SECTORS = 8
#: Most lattice levels tried (stride up to 2^MAX_LEVEL); past it the count is 0 or 1 per cell.
MAX_LEVEL = 30
#: Entries (listed samples) gathered and cone-tested at once when counting: temporaries that
#: stay in a core's cache (2.3x faster than 1 << 22 on the bookstore's injection frames).
GATHER_CHUNK = 1 << 15
#: Most listed entries whose in-cone ids the counting keeps for the blocks (``Budget``).
KEEP_ENTRIES = 1 << 23


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


@dataclass(frozen=True)
class Budget:
    """What the counting of the budget found, shared with the block selection
    (``likelihood.EdgeLikelihood._seen`` and ``_parts``).

    Attributes:
        stride: (N,) int64 each particle's sample stride (powers of two; 1 within the budget).
        own: (N,) int64 samples each particle may see on its lattice: the in-cone count of its
            (cell, sector) group where that was counted, else its cell's listed count (an upper
            bound). A block whose particles see far more together is split.
        group: (N,) int64 each particle's counted group, -1 where its cell lists at most the
            budget (not counted).
        indptr: (G + 1,) int64 and ids (E,) int32: the counted groups' in-cone sample ids,
            ascending per group (all lattices); None when more than ``KEEP_ENTRIES`` (a
            global set), then the blocks select their samples themselves.
    """

    stride: np.ndarray
    own: np.ndarray
    group: np.ndarray
    indptr: np.ndarray | None = None
    ids: np.ndarray | None = None

    def columns(self, particles: np.ndarray, stride: int) -> np.ndarray | None:
        """(C,) int64 ascending: the samples on the lattice of ``stride`` that the counted
        groups of ``particles`` (block indices into the particle set) may see; None when one
        of them is not counted or the lists were not kept."""
        g = self.group[particles]
        if self.ids is None or len(g) == 0 or (g < 0).any():
            return None
        g = np.unique(g)
        start, n = self.indptr[g], np.diff(self.indptr)[g]
        at = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n - start, n)
        ids = self.ids[at]
        if stride > 1:
            ids = ids[(ids & (stride - 1)) == 0]
        if len(g) == 1:
            return ids.astype(np.int64)
        mark = np.zeros(int(ids.max(initial=-1)) + 1, dtype=bool)
        mark[ids] = True
        return np.flatnonzero(mark)

    def part(self, particles: np.ndarray) -> Budget:
        """The budget of a subset of the particles (the groups' lists shared)."""
        return Budget(self.stride[particles], self.own[particles], self.group[particles],
                      self.indptr, self.ids)


def count(vis: SparseVisibility, points: np.ndarray, rows: np.ndarray, centres: np.ndarray,
          yaws: np.ndarray, half_width: float, budget: int, run: Callable | None = None
          ) -> Budget:
    """Each particle's sample stride under the budget (module docstring), and what the
    counting saw (``Budget``).

    Args:
        vis: the visibility lists.
        points: (P, 3) the model samples, or (P, 2) their x, y (contiguous float64), metres.
        rows: (N,) the visibility row of each particle's camera.
        centres: (N, 3) camera centres, metres.
        yaws: (N,) body headings, radians.
        half_width: the view's half-width (``projection.view_half_width``), radians.
        budget: most samples a particle may see (0: no budget, nothing counted).
        run: ``run(fn, items) -> [fn(x) for x in items]``, on threads (``likelihood.run_all``);
            None: in turn.
    """
    rows = np.asarray(rows, dtype=np.int64)
    N = len(rows)
    out = np.ones(N, dtype=np.int64)
    own = np.diff(vis.indptr)[rows]
    group = np.full(N, -1, dtype=np.int64)
    if budget <= 0 or N == 0:
        return Budget(out, own, group)
    yaws = np.asarray(yaws, np.float64)
    sector = np.floor(np.mod(yaws, 2 * np.pi) * (SECTORS / (2 * np.pi))).astype(np.int64)
    keys, inv = np.unique(rows * SECTORS + np.clip(sector, 0, SECTORS - 1),
                          return_inverse=True)
    inv = inv.ravel()
    urows = keys // SECTORS  # the row of each (row, sector) group
    listed = np.diff(vis.indptr)[urows]
    big = np.flatnonzero(listed > budget)  # groups whose row lists more than the budget
    if len(big) == 0:
        return Budget(out, own, group)
    slot = np.full(len(urows), -1, dtype=np.int64)
    slot[big] = np.arange(len(big))
    member = slot[inv]
    on = member >= 0
    cones = group_cones(np.asarray(centres, np.float64)[on], yaws[on], member[on], len(big))
    xy = points if points.shape[1] == 2 else np.ascontiguousarray(points[:, :2], np.float64)
    keep = int(listed[big].sum()) <= KEEP_ENTRIES
    ends = np.searchsorted(np.cumsum(listed[big]), np.arange(GATHER_CHUNK, listed[big].sum()
                                                             + GATHER_CHUNK, GATHER_CHUNK),
                           side="right")
    ends = np.unique(np.clip(np.r_[ends, len(big)], 1, len(big)))

    def one(span: tuple[int, int]) -> tuple:
        """Groups a..b: in-cone ids (when kept), in-cone counts, strides, counts on them."""
        a, b = span
        ids, which = vis.gather(urows[big[a:b]])
        inside = in_cone(xy[ids], *(c[a:b] for c in cones), half_width, which)
        ids, which = ids[inside], which[inside]
        n = np.bincount(which, minlength=b - a)
        level_s, level_n = np.ones(b - a, dtype=np.int64), n.copy()
        todo = n > budget
        for level in range(1, MAX_LEVEL + 1):
            if not todo.any():
                break
            s = 1 << level
            on_lattice = (ids & (s - 1)) == 0
            m = np.bincount(which[on_lattice], minlength=b - a)
            level_s[todo], level_n[todo] = s, m[todo]
            todo &= m > budget
        return ids.astype(np.int32) if keep else None, n, level_s, level_n

    # rows of about GATHER_CHUNK entries at a time
    done = (run or _serial)(one, list(zip(np.r_[0, ends[:-1]], ends, strict=True)))
    kept, inside_n, stride, seen = (list(x) for x in zip(*done, strict=True))
    stride, seen, inside_n = (np.concatenate(x) for x in (stride, seen, inside_n))
    out[on] = stride[member[on]]
    own[on] = seen[member[on]]
    group[on] = member[on]
    if not keep:
        return Budget(out, own, group)
    return Budget(out, own, group, np.r_[0, np.cumsum(inside_n)], np.concatenate(kept))


def _serial(fn: Callable, items: list) -> list:
    """``[fn(x) for x in items]``."""
    return [fn(x) for x in items]


def strides(vis: SparseVisibility, points: np.ndarray, rows: np.ndarray, centres: np.ndarray,
            yaws: np.ndarray, half_width: float, budget: int) -> np.ndarray:
    """(N,) int64 each particle's sample stride under the budget (``count``'s ``stride``):
    powers of two, 1 where the particle may see at most ``budget`` samples."""
    return count(vis, points, rows, centres, yaws, half_width, budget).stride


def line_minimum(minimum: int, stride: np.ndarray) -> np.ndarray:
    """(n,) int the visible samples a line needs at each stride (n,): ``minimum`` at stride 1,
    ``ceil(minimum / stride)`` (at least 1) beyond, so a line needs the same length in
    metres."""
    stride = np.asarray(stride, np.int64)
    return np.where(stride == 1, int(minimum), np.maximum(-(-int(minimum) // stride), 1))
