"""The nearest-edge measurement model (Buyval et al. 2017), vectorized over particles.

For every particle the model edge samples (``projection.ModelSamples``) are projected into its
camera; samples behind the camera, outside the image or occluded (``visibility``) are dropped.
With visibility lists (``visibility.SparseVisibility``) the particles are grouped by cell
(rows run tile by tile) and a block of them projects only the samples its cells see and its
cameras face (``projection.in_view_cone``); a line's sums still run over all its samples, the
others 0, so the scores are those of projecting everything. Work per frame grows with what
the cameras can see, not with the building.
Each remaining sample reads ``g(d) = exp(-d^2 / (2 sigma^2))`` from a precomputed score map,
where d is the distance from the pixel to the nearest image edge:

- **Unit of d and sigma.** d is measured in pixels by a Euclidean distance transform of the edge
  image (OpenCV's 5x5 chamfer approximation, ``distance_to``), truncated at ``search_px`` (the
  reach of the paper's normal search) and divided by it, so d is in [0, 1] and sigma is a
  fraction of the search range: the paper's ``sigma = 0.3`` with ``search_px = 10`` is a
  3-pixel tolerance; a sample with no edge within reach scores
  ``exp(-1 / (2 sigma^2))``.
- **Direction of the search.** The paper searches along the line's normal. A plain distance
  transform looks in every direction; with ``orientation_bins = B > 0`` the edge pixels are split
  by their orientation (structure tensor of the edge map) into B overlapping bins and each bin
  gets its own distance transform; a sample reads the map of the bin matching its projected
  line's normal, so it only matches edges running roughly parallel to the model line, which is
  what a normal search finds first (directional chamfer matching).
- **Class pairs** (``class_pairs``, label modes only). A model edge separates two classes
  (wall | door, floor | wall, ...), and so does a label boundary in the image. With
  ``class_pairs`` each pair the model has gets its own distance transforms (per orientation
  bin), so a sample only matches image boundaries between the same two classes: a wall | window
  line no longer fits a wall | door boundary. The chance level g0 stays that of all edges
  together, so a model line with no boundary of its pair in reach still pays for it. Edge
  images without classes (mode ``none``) are matched as without it.
- **Unknown pixels** (masked objects that are not in the model) score the image's chance level
  g0, the mean score of a known pixel; so do known pixels whose nearest edge is farther than
  the mask (the true edge might be hidden), unless they already score more.

Scores aggregate as in the paper: line score ``l = mean g`` over a line's visible samples,
``score = mean l`` over lines with at least ``min_line_samples`` visible samples. A particle
seeing fewer than ``min_lines`` lines is padded with g0. Finally ``log W = k * score`` (the
paper's constant factor alpha cancels when the weights are normalized). The likelihood stays
finite for any input: with no edges at all every particle gets the same score.

**Fit quality** (what recovery watches): apart from the score, each particle's visible samples
on known pixels are judged by their mean log-ratio ``log(g + eps) - log(g0 + eps)`` against
the chance level g0 (eps = ``FIT_EPS``), over that of a sample on an edge: 1 when all lie on
edges, 0 at chance, negative when worse; NaN with fewer than ``min_quality_samples`` of them.

**Few lines in view** (``lines_ref``): a mean over lines weighs a frame that shows four model
lines (the camera close to an end wall) as much as one that shows forty, so one misplaced
boundary in such a view moves the pose as far as forty consistent ones. With ``lines_ref`` R
the frame's k is scaled by ``min(1, m / R)``, m the particles' median count of lines (lines
with at least ``min_line_samples`` visible samples): below R lines the log-likelihood is
``k / R`` times the *sum* of the line scores, as if each line were one independent
observation, and the odometry carries more of the estimate. One scale per frame, not per
particle, so a pose is not favoured for seeing more or fewer lines.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from core import classes as C
from core.dataset import Camera
from localize.filter.config import LikelihoodConfig
from localize.filter.projection import (
    ModelSamples,
    cam_from_world,
    camera_centres,
    image_directions,
    in_view_cone,
    pixel_index,
    projection_matrices,
    view_half_width,
)
from localize.filter.sample_budget import count, line_minimum
from localize.filter.visibility import SparseVisibility
from localize.frontend.edge_image import EdgeImage, edge_normal_angle

#: Under a budget, a block of particles that may see together more than this many times
#: what the most seeing of them may see alone (``sample_budget.Budget.own``) is split
#: (``EdgeLikelihood._parts``).
BLOCK_COLUMNS = 2
#: eps of the fit quality's log-ratio ``log(g + eps) - log(g0 + eps)``: a sample far from any
#: edge costs ``log((g0 + eps) / eps)``, not an unbounded amount.
FIT_EPS = 0.05


@dataclass
class Observation:
    """Score maps of one frame.

    Attributes:
        g: (Q * B * H * W + 1,) float32 flattened score maps, one per class pair (Q = 1
            without ``class_pairs``) and orientation bin (B = 1 without), pair-major, and a
            final 0 read by samples that are not visible.
        fit: (Q * B * H * W + 1,) float32 log-ratio ``log(g + eps) - log(g0 + eps)`` of the
            fit quality (eps = ``FIT_EPS``), laid out as ``g``; exactly 0 on unknown pixels
            and at the final entry (and nudged off 0 elsewhere, so zeros count unknowns).
        g0: (B,) chance score per bin (mean over known pixels, all edges).
        width, height: image size.
        bins: B (0 for a plain distance transform, stored as 1 map).
        pairs: Q, the number of class-pair map sets (0: not split by class pair, Q = 1).
    """

    g: np.ndarray
    fit: np.ndarray
    g0: np.ndarray
    width: int
    height: int
    bins: int
    pairs: int = 0

    @property
    def chance(self) -> float:
        """The neutral score used for padding."""
        return float(self.g0.mean())


def frame_k(k: float, lines: np.ndarray, lines_ref: int) -> float:
    """The frame's likelihood sharpness: ``k * min(1, median(lines) / lines_ref)``.

    Args:
        k: the configured sharpness.
        lines: (N,) lines each particle sees (those with enough visible samples).
        lines_ref: the line count from which a frame counts fully; 0 returns ``k``.
    """
    if lines_ref <= 0 or len(lines) == 0:
        return float(k)
    return float(k) * min(1.0, float(np.median(lines)) / lines_ref)


@functools.cache
def _pool(workers: int, pid: int) -> ThreadPoolExecutor:
    """A shared pool of ``workers`` threads, made once per count and process (``pid``: a
    forked child does not inherit its parent's threads, so it makes its own)."""
    return ThreadPoolExecutor(workers, thread_name_prefix="likelihood")


def run_all(fn: Callable, items: Iterable, workers: int) -> list:
    """``[fn(x) for x in items]``, on ``workers`` threads when more than one (same order)."""
    items = list(items)
    if workers <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    return list(_pool(workers, os.getpid()).map(fn, items))


def distance_to(mask: np.ndarray) -> np.ndarray:
    """Euclidean distance (H, W) float32, pixels, to the nearest True pixel (1e6 if none).

    OpenCV's 5x5-mask chamfer approximation of the Euclidean distance: within 0.04 px of the
    exact one up to 4 px and 2 % beyond (a fraction of the likelihood's 1-pixel sigma), at
    half the exact transform's time (docs/localize.md).
    """
    if not mask.any():
        return np.full(mask.shape, 1e6, dtype=np.float32)
    return cv2.distanceTransform(np.logical_not(mask).view(np.uint8), cv2.DIST_L2,
                                 cv2.DIST_MASK_5)


def _bin_masks(edges: np.ndarray, bins: int) -> np.ndarray:
    """Edge pixels split by the orientation of their normal.

    Each edge pixel goes in the bins whose centre b * pi / B is closer than pi / B to its normal
    angle (the two nearest); only edge pixels and their neighbouring bins are tested, as
    (3, n_edge) arrays instead of (B, H, W).

    Args:
        edges: (H, W) bool.
        bins: B; 0 keeps all edges in one mask.

    Returns:
        (max(B, 1), H, W) bool.
    """
    if bins <= 0:
        return edges[None]
    H, W = edges.shape
    ys, xs = np.nonzero(edges)
    theta = edge_normal_angle(edges, at=(ys, xs))
    lower = np.floor(theta.astype(np.float64) * (bins / np.pi)).astype(np.intp)
    masks = np.zeros((bins, H, W), dtype=bool)
    for cand in ((lower - 1) % bins, lower % bins, (lower + 1) % bins):
        diff = np.abs(theta - cand * np.pi / bins)
        ok = np.minimum(diff, np.pi - diff) < np.pi / bins
        masks[cand[ok], ys[ok], xs[ok]] = True
    return masks


class _ScoreMaps:
    """How one frame's edges become score maps g(d) and fit maps (see ``observe``).

    Args:
        known: (H, W) bool, where edges are known.
        params: sigma, search_px.
    """

    def __init__(self, known: np.ndarray, params: LikelihoodConfig):
        self.known = known
        self.unknown = ~known
        s2 = 2.0 * float(params.sigma) ** 2
        self.g_far = np.float32(np.exp(-1.0 / s2))
        # often no unknown pixel (no object in view): their handling is skipped
        self.any_unknown = bool(self.unknown.any())
        self.dist_unknown = distance_to(self.unknown) if self.any_unknown else None
        self.known_u8 = known.view(np.uint8)  # OpenCV's masks
        self.any_known = bool(known.any())
        self.reach = np.float32(params.search_px)
        # g = exp(scale * min(d, reach)^2)
        self.scale = np.float32(-1.0 / (s2 * float(self.reach) ** 2))
        self.eps = np.float32(FIT_EPS)

    def score(self, m: np.ndarray, g0b: np.float32 | None, out: np.ndarray) -> np.float32:
        """g(d) (H, W) of the edges ``m`` into ``out``; returns the chance level: ``g0b``, or
        when None the mean score of a known pixel."""
        d = distance_to(m)
        # g = exp(scale * min(d, search_px)^2), OpenCV's vectorized min, product and exp
        cv2.min(d, float(self.reach), dst=out)
        cv2.multiply(out, out, dst=out, scale=float(self.scale))
        cv2.exp(out, dst=out)
        if not self.any_unknown:
            return np.float32(out.mean()) if g0b is None else g0b
        # the nearest edge may hide behind an object (also true on unknown pixels: they are
        # set to g0 below)
        hidden = cv2.compare(d, self.dist_unknown, cv2.CMP_GT)
        if g0b is None:
            g0b = np.float32(cv2.mean(out, mask=self.known_u8)[0] if self.any_known
                             else self.g_far)
        cv2.copyTo(cv2.max(out, float(g0b)), hidden, out)
        np.copyto(out, g0b, where=self.unknown)
        return g0b

    def fit(self, g: np.ndarray, g0b: np.float32, out: np.ndarray) -> None:
        """Fit map (H, W) from a g map into ``out``: ``log(g + eps) - log(g0 + eps)``, exactly 0 on
        unknown pixels and nudged off 0 elsewhere."""
        cv2.add(g, float(self.eps), dst=out)
        cv2.log(out, dst=out)
        cv2.subtract(out, float(np.log(g0b + self.eps)), dst=out)
        np.copyto(out, np.float32(1e-7), where=out == 0)  # unknown pixels: 0 again below
        if self.any_unknown:
            np.copyto(out, np.float32(0.0), where=self.unknown)


def observe(edge: EdgeImage, params: LikelihoodConfig,
            pair_codes: np.ndarray | None = None) -> Observation:
    """Score maps g(d) of an edge image (see the module docstring).

    Args:
        edge: the frame's edges and known mask, (H, W).
        params: sigma, search_px, orientation_bins, class_pairs.
        pair_codes: (Q,) uint8 class-pair codes of the model (``edges.pair_code``), the order
            of the pair map sets; used with ``params.class_pairs`` when the edge image has
            ``pairs``.

    Returns:
        The observation.
    """
    H, W = edge.edges.shape
    B = int(params.orientation_bins)
    masks = _bin_masks(edge.edges & edge.known, B)
    maps = _ScoreMaps(edge.known, params)
    paired = (params.class_pairs and edge.pairs is not None and pair_codes is not None
              and len(pair_codes) > 0)
    n = (len(pair_codes) if paired else 1) * len(masks)
    # flat buffers with one trailing 0 that invalid samples read
    g_flat = np.empty(n * H * W + 1, dtype=np.float32)
    f_flat = np.empty(n * H * W + 1, dtype=np.float32)
    g_flat[-1] = f_flat[-1] = 0.0
    g = g_flat[:-1].reshape(n, H, W)
    f = f_flat[:-1].reshape(n, H, W)

    def plain_bin(b: int) -> np.float32:
        """Map b of all edges; its chance level (with class pairs only that, as scratch:
        pair q = 0's maps overwrite it)."""
        g0b = maps.score(masks[b], None, g[b])
        if not paired:
            maps.fit(g[b], g0b, f[b])
        return g0b

    def pair_bin(i: int) -> None:
        """Map i = q * B + b: the edges of class pair q in bin b."""
        q, b = divmod(i, len(masks))
        maps.score(masks[b] & pms[q], g0[b], g[i])
        maps.fit(g[i], g0[b], f[i])

    # the maps are independent: on params.workers threads
    g0 = np.array(run_all(plain_bin, range(len(masks)), params.workers), np.float32)
    if paired:  # one distance transform per (pair, bin)
        pms = [_pair_mask(edge.pairs, c) for c in np.asarray(pair_codes, np.uint8)]
        run_all(pair_bin, range(n), params.workers)
    return Observation(g_flat, f_flat, g0, W, H, B, len(pair_codes) if paired else 0)


def _pair_mask(pairs: np.ndarray, code: int) -> np.ndarray:
    """(H, W) bool: the edge pixels of class pair ``code``; for a crease inside one class
    (an outline of it against whatever lies behind: ``core.imaging.outline``), those with
    that class on a side."""
    a, b = C.pair_classes(int(code))
    if a != b:
        return pairs == code
    lo, hi = C.pair_classes(pairs)
    return (pairs > 0) & ((lo == a) | (hi == a))


def _part(near: tuple, particles: np.ndarray) -> tuple:
    """``near`` (``EdgeLikelihood._block``) of some of its particles (indices (m,))."""
    rows, centres, half_width, budget = near
    return rows[particles], centres[particles], half_width, budget.part(particles)


class EdgeLikelihood:
    """Log-likelihood of particle poses given a frame's edges.

    Args:
        samples: the model edge samples.
        camera: K, image size and body_from_cam.
        params: likelihood settings.
        visibility: per-cell visible samples (None: every in-view sample counts as
            visible).
        sample_pairs: (P,) uint8 ``edges.pair_code`` of the two classes each sample's segment
            separates; needed with ``params.class_pairs``.
    """

    def __init__(self, samples: ModelSamples, camera: Camera, params: LikelihoodConfig,
                 visibility: SparseVisibility | None = None,
                 sample_pairs: np.ndarray | None = None):
        if visibility is not None and visibility.num_samples != len(samples):
            raise ValueError(f"visibility lists index {visibility.num_samples} samples, the "
                             f"model {len(samples)}; rebuild them for these samples")
        self.samples, self.camera, self.params, self.visibility = (samples, camera, params,
                                                                   visibility)
        # run starts of segments, for per-line sums along the sample axis
        self._starts = samples.starts
        # (P, 2) the samples' x, y (the budget's cone tests, ``sample_budget.count``)
        self._xy = np.ascontiguousarray(samples.points[:, :2], dtype=np.float64)
        # (S, 3) each sampled segment's direction (its bin is found once; ``_block``)
        self._segment_dirs = np.ascontiguousarray(samples.dirs[self._starts])
        self.pair_codes = None  # (Q,) the model's class pairs, the order of the pair maps
        self._pair_slot = None  # (P,) int32 index of each sample's pair in pair_codes
        if params.class_pairs:
            if sample_pairs is None or len(sample_pairs) != len(samples):
                raise ValueError("likelihood.class_pairs needs the class pair of every model "
                                 f"sample ({len(samples)}), got "
                                 f"{None if sample_pairs is None else len(sample_pairs)}")
            self.pair_codes, slot = np.unique(np.asarray(sample_pairs, np.uint8),
                                              return_inverse=True)
            self._pair_slot = slot.astype(np.int32)

    def observe(self, edge: EdgeImage) -> Observation:
        """Score maps of a frame (see ``observe``)."""
        if edge.edges.shape != (self.camera.height, self.camera.width):
            raise ValueError(f"edge image {edge.edges.shape} does not match the camera "
                             f"{self.camera.height}x{self.camera.width}")
        return observe(edge, self.params, self.pair_codes)

    def scores(self, states: np.ndarray, obs: Observation,
               tilt: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Edge score of each particle and the mean g of its visible samples.

        Args:
            states: (N, 4) x, y, z, yaw.
            obs: the frame's observation.
            tilt: (3, 3) roll/pitch of the body for this frame, or (N, 3, 3) one per particle
                (``projection.corrected_tilts``); None: level.

        Returns:
            score (N,) float64 in [0, 1]; quality (N,) float64, how well the visible samples
            on known pixels fit, their mean log-ratio over that of a perfect fit (1: all on
            edges, 0: chance, negative: worse; module docstring), NaN with fewer than
            ``min_quality_samples`` of them. Recovery watches the best particle's quality.
        """
        score, quality, _, _ = self._evaluate(states, obs, tilt)
        return score, quality

    def visible_samples(self, states: np.ndarray, obs: Observation,
                        tilt: np.ndarray | None = None) -> np.ndarray:
        """(N,) int the model samples each particle scores: in front of its camera, in the
        image, visible from its cell, on its lattice of the sample budget
        (``likelihood.max_samples``, ``sample_budget``); arguments as ``scores``."""
        return self._evaluate(states, obs, tilt)[3]

    def _evaluate(self, states: np.ndarray, obs: Observation, tilt: np.ndarray | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``scores``, (N,) int the lines each particle sees (see ``frame_k``) and (N,) int
        its visible samples (``visible_samples``)."""
        states = np.asarray(states, dtype=np.float64)
        if states.ndim != 2 or states.shape[1] != 4:
            raise ValueError(f"states must be (N, 4), got {states.shape}")
        N = len(states)
        per_particle = tilt is not None and np.ndim(tilt) == 3
        if per_particle and len(tilt) != N:
            raise ValueError(f"{len(tilt)} tilts for {N} particles")
        score = np.empty(N)
        quality = np.empty(N)
        lines = np.empty(N, dtype=np.int64)
        seen = np.empty(N, dtype=np.int64)
        # blocks of at most ``chunk``, at least one per worker
        step = max(1, min(int(self.params.chunk), -(-N // max(1, self.params.workers))))
        order, near = np.arange(N), None
        if self.visibility is not None:  # blocks of particles in neighbouring cells
            cam = self.camera
            centres = camera_centres(states, cam.body_from_cam, tilt)
            rows = self.visibility.rows(centres)
            half = view_half_width(cam.K, cam.width, cam.height, cam.body_from_cam, tilt)
            budget = count(self.visibility, self._xy, rows, centres, states[:, 3], half,
                           self.params.max_samples,
                           lambda fn, xs: run_all(fn, xs, self.params.workers))
            stride = budget.stride
            # particles of one stride together (a block projects its smallest stride's samples)
            order = (np.argsort(rows, kind="stable") if (stride == 1).all()
                     else np.lexsort((rows, stride)))
            near = (rows, centres, half, budget)
        blocks = [order[i:i + step] for i in range(0, N, step)]  # vectorized within a block
        parts = [(b, None) for b in blocks]
        if near is not None:  # a block of particles far apart in parts, all on the threads
            parts = [x for found in run_all(lambda b: self._parts(b, near, states[b, 3]),
                                            blocks, self.params.workers) for x in found]
            blocks = [b for b, _ in parts]
        done = run_all(lambda bc: self._block(
            states[bc[0]], None if near is None else _part(near, bc[0]), obs,
            tilt[bc[0]] if per_particle else tilt, bc[1]), parts, self.params.workers)
        for b, (s_b, q_b, l_b, v_b) in zip(blocks, done, strict=True):
            score[b], quality[b], lines[b], seen[b] = s_b, q_b, l_b, v_b
        return score, quality, lines, seen

    def _seen(self, near: tuple, yaws: np.ndarray) -> np.ndarray:
        """The samples a block of particles may see, (C,) ascending, at least one: on the
        lattice of its smallest stride (ids divisible by it), those its particles' (cell,
        sector) groups see within their cones where the budget counted them all
        (``Budget.columns``), else those visible from one of its rows within the azimuths its
        cameras see (``in_view_cone``). ``near``: see ``_block``; ``yaws`` (n,) radians."""
        rows, centres, half_width, budget = near
        stride = int(budget.stride.min())
        live = budget.columns(np.arange(len(rows)), stride)
        if live is None:
            cand = np.flatnonzero(self.visibility.union(rows))
            if stride > 1:
                cand = cand[(cand & (stride - 1)) == 0]
            live = cand[in_view_cone(self.samples.points[cand], centres, yaws, half_width)]
        return live if len(live) else np.zeros(1, np.int64)  # none: one sample, masked

    def _project(self, states: np.ndarray, near: tuple | None, tilt: np.ndarray | None,
                 bins: int, cols: np.ndarray | None = None) -> tuple:
        """Pixel indices of the samples a block scores, see ``_block`` (``cols``: its
        ``_seen`` samples when known).

        Returns:
            idx (n, C) int32 flat pixel (plus the orientation bin's map offset when ``bins``),
            valid (n, C) bool, cols (C,) the sample ids, starts (L,) each line's first column,
            lines (L,) the lines (None: all of them, in order), thinned: whether the block
            scores a lattice of the samples (``sample_budget``).
        """
        p, cam, s = self.params, self.camera, self.samples
        W, H = cam.width, cam.height
        proj = projection_matrices(cam_from_world(states, cam.body_from_cam, tilt), cam.K)
        if near is None:
            cols, starts, lines = slice(None), self._starts, None
            idx, valid, xh = pixel_index(proj, s.points_h, W, H, p.near)
        else:
            stride = near[3].stride
            if cols is None:
                cols = self._seen(near, states[:, 3])
            lines, line_of = np.unique(s.run[cols], return_inverse=True)
            line_of = line_of.ravel()
            starts = np.flatnonzero(np.r_[True, line_of[1:] != line_of[:-1]])
            idx, valid, xh = pixel_index(proj, s.points_h[:, cols], W, H, p.near)
            valid &= self.visibility.visible_in(near[0], cols)
            if (stride > stride.min()).any():  # each particle's own lattice
                valid &= (cols[None] & (stride[:, None] - 1)) == 0
        if bins:
            # a 3D segment projects onto one image line: (du, dv) is the same at each of its
            # samples (``image_directions``), so its bin is found once, at its first sample
            if lines is None:
                seg_dirs, xh0 = self._segment_dirs, xh[:, :, starts]
            else:
                seg_dirs = self._segment_dirs[lines]
                xh0 = pixel_index(proj, s.points_h[:, s.starts[lines]], W, H, p.near)[2]
            du, dv = image_directions(proj, seg_dirs, xh0)
            self._add_bin(idx, du, dv, bins, s.run[cols] if lines is None else line_of)
        thinned = near is not None and bool(near[3].stride.min() > 1)
        return idx, valid, cols, starts, lines, thinned

    def _add_bin(self, idx: np.ndarray, du: np.ndarray, dv: np.ndarray, bins: int,
                 line: np.ndarray) -> None:
        """Offset ``idx`` (n, C) by the score map of each sample's orientation bin, from the
        image direction (du, dv) (n, L) of its line; ``line`` (C,) each column's line."""
        # normal of the projected line (-dv, du): its angle in [0, pi) picks the bin
        theta = np.arctan2(du, -dv)
        b = np.rint(theta * np.float32(bins / np.pi)).astype(np.int32) % bins
        b *= np.int32(self.camera.width * self.camera.height)
        idx += b[:, line]

    def _line_sums(self, g: np.ndarray, cols: np.ndarray, lines: np.ndarray | None,
                   starts: np.ndarray, thinned: bool = False) -> np.ndarray:
        """(n, L) float32 sums of g (n, C) over each line's samples. With culled columns the
        sums run over every sample of the lines, the others 0, as without culling (float32
        sums depend on where the zeros are); a block on a lattice of the samples
        (``thinned``) sums its columns alone."""
        if lines is None or thinned:
            return np.add.reduceat(g, starts, axis=1)
        s = self.samples
        n = np.diff(np.r_[s.starts, len(s)])[lines]
        whole = np.cumsum(n) - n  # each line's start in the whole-line layout
        full = np.zeros((len(g), int(n.sum())), dtype=np.float32)
        full[:, cols - s.starts[s.run[cols]] + np.repeat(whole, np.diff(np.r_[starts,
                                                                           len(cols)]))] = g
        return np.add.reduceat(full, whole, axis=1)

    def _parts(self, block: np.ndarray, near: tuple, yaws: np.ndarray
               ) -> list[tuple[np.ndarray, np.ndarray]]:
        """A block of particles (indices (n,) into ``near``'s arrays, headings ``yaws`` (n,)
        radians) as parts and the samples each may see (``_seen``).

        Under a budget, a block whose particles may see together more than ``BLOCK_COLUMNS``
        times the samples the most seeing of them may see alone (particles far apart:
        injected ones, a global set) is cut into parts of about that many columns, and so
        on, so each particle's work stays near what it may see (a score does not depend on
        its part but for the float32 rounding of a line's sum, ~1e-8)."""
        mine = _part(near, block)
        cols = self._seen(mine, yaws)
        alone = int(mine[3].own.max())
        if not (self.params.max_samples and len(block) > 1
                and len(cols) > max(BLOCK_COLUMNS * alone, self.params.max_samples)):
            return [(block, cols)]
        k = min(len(block), int(np.ceil(len(cols) / max(alone, 1))))
        cut = np.linspace(0, len(block), k + 1).round().astype(np.int64)
        return [x for a, b in zip(cut[:-1], cut[1:], strict=True)
                for x in self._parts(block[a:b], near, yaws[a:b])]

    def _block(self, states: np.ndarray, near: tuple | None, obs: Observation,
               tilt: np.ndarray | None, cols: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scores of a block of particles; ``near``: their visibility rows (n,), camera
        centres (n, 3), the view's half-width (radians) and their ``sample_budget.Budget``,
        or None without visibility; ``cols``: the samples they may see (``_parts``), None:
        found here. Also returns the lines and the visible samples of each particle."""
        p, cam = self.params, self.camera
        idx, valid, cols, starts, lines, thinned = self._project(states, near, tilt, obs.bins,
                                                                 cols)
        stride = np.ones(len(states), np.int64) if near is None else near[3].stride
        if obs.pairs:
            if self.pair_codes is None or obs.pairs != len(self.pair_codes):
                raise ValueError(f"the observation has {obs.pairs} class-pair map sets, this "
                                 "likelihood's model another count; make it with its observe()")
            idx += self._pair_slot[cols] * np.int32(max(obs.bins, 1) * cam.width * cam.height)
        idx = np.where(valid, idx, np.int32(len(obs.g) - 1))  # the last entry reads 0
        chance = obs.chance
        fit = obs.fit[idx]  # exactly 0 where not visible or unknown
        known = np.count_nonzero(fit, axis=1)
        fit_mean = fit.sum(axis=1, dtype=np.float64) / np.maximum(known, 1)
        # how well the known visible samples fit: 1 = all on edges, 0 = chance
        fit_top = np.log((1.0 + FIT_EPS) / (chance + FIT_EPS))
        quality = np.where(known >= line_minimum(p.min_quality_samples, stride),
                           fit_mean / fit_top, np.nan)
        ns = np.add.reduceat(valid.view(np.uint8), starts, axis=1, dtype=np.int16)
        # (n, L) lines with enough visible samples (as many metres of line at any stride)
        ok = ns >= (p.min_line_samples if not thinned and (stride == 1).all()
                    else line_minimum(p.min_line_samples, stride)[:, None])
        m = ok.sum(axis=1)
        gs = self._line_sums(obs.g[idx], cols, lines, starts, thinned)
        line = np.where(ok, gs / np.maximum(ns, 1), np.float32(0.0))
        total = line.sum(axis=1, dtype=np.float64) + np.maximum(p.min_lines - m, 0) * chance
        # the visible samples: the lines' counts summed, not a second pass over (n, C)
        return (total / np.maximum(np.maximum(m, p.min_lines), 1), quality, m,
                ns.sum(axis=1, dtype=np.int64))

    def log_likelihood(self, states: np.ndarray, obs: Observation,
                       tilt: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``log W = k * score`` per particle, k scaled down in a frame of few
        lines (``frame_k``, with ``lines_ref``).

        Returns:
            log_w (N,) float64 (finite); quality (N,) in [0, 1] (see ``scores``).
        """
        score, quality, lines, _ = self._evaluate(states, obs, tilt)
        k = frame_k(self.params.k, lines, self.params.lines_ref)
        return k * score, quality
