"""How well a model's edges match what a render of the model shows: recall and precision.

From each camera pose the model's label map is ray-cast (the class of the first face hit at
each pixel centre: what the label sensor of ``datagen.rendering.render`` shows of the model,
without the distractors and people added at render time), and its class boundaries are found
(a pixel whose right or lower neighbour has another class, both structural: what the
label modes' edge images hold). The model's segments with a structural class on a side are
sampled every ``spacing`` metres, projected, kept where in view and not hidden (a ray from
the camera reaches them within ``eps``), and drawn with the class pair the camera sees along
them (``core.imaging.outline``: a crease with one face turned away shows that face's class
against what lies behind it).

- **recall**: the share of boundary pixels with an edge pixel *of the same class pair* within
  ``tol_px`` (a boundary the model has no edge for is a miss: a wall standing on a slab it
  shares no vertex with, a door jamb no face adjacency gives);
- **precision**: the share of edge pixels with a boundary pixel of the same pair within
  ``tol_px`` (an edge where the render shows none, or with the wrong classes).

Counts are pooled over the poses. The check needs no dataset: poses from free space
(``free_space_poses``) serve the import summary, a flight's ground truth the benchmark.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from core import classes as C
from core.classes import class_changes, pair_code, structural_mask
from core.imaging.camera import project
from core.imaging.outline import seen_pairs, structural_change
from core.imaging.rays import RayCaster
from datagen.mesh.contacts import split_pieces


@dataclass(frozen=True)
class EdgeAgreement:
    """Pooled agreement of projected model edges with rendered label boundaries.

    Attributes:
        recall: share of boundary pixels with a same-pair edge pixel within ``tol_px``.
        precision: share of edge pixels with a same-pair boundary pixel within ``tol_px``.
        boundary_px: boundary pixels counted; edge_px: edge pixels counted.
        views: poses used; tol_px: the tolerance, pixels.
        missed: pair name -> boundary pixels of that pair without an edge (largest first).
    """

    recall: float
    precision: float
    boundary_px: int
    edge_px: int
    views: int
    tol_px: float
    missed: dict[str, int]

    def line(self) -> str:
        """One printed line: ``rendered-edge recall 0.97, precision 0.93 at 2 px (30 views)``."""
        worst = ", ".join(f"{k} {v}" for k, v in list(self.missed.items())[:3])
        return (f"rendered-edge recall {self.recall:.3f}, precision {self.precision:.3f} at "
                f"{self.tol_px:g} px ({self.views} views)"
                + (f"; boundary px missed most: {worst}" if worst else ""))

    def as_dict(self) -> dict:
        return {"recall": round(self.recall, 4), "precision": round(self.precision, 4),
                "boundary_px": self.boundary_px, "edge_px": self.edge_px, "views": self.views,
                "tol_px": self.tol_px, "missed": self.missed}


def label_boundaries(label: np.ndarray) -> np.ndarray:
    """(H, W) int32 pair code at the boundary pixels of a label map, 0 elsewhere.

    A pixel is a boundary pixel when its right or lower neighbour holds another structural
    class and it is structural itself (``core.classes.class_changes``: what the label modes'
    edge images hold); the pair is that of the first such neighbour."""
    out = np.zeros(label.shape, np.int32)
    changes = class_changes(label, structural_mask(label))
    for axis in (1, 0):  # the right neighbour first, then the lower one
        diff, a, b = changes[axis]
        view = out[: label.shape[0] - (axis == 0), : label.shape[1] - (axis == 1)]
        new = diff & (view == 0)
        view[new] = pair_code(a[new], b[new])
    return out


def ray_directions(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H * W, 3) unit ray directions through the pixel centres, camera frame (OpenCV)."""
    u, v = np.meshgrid(np.arange(width) + 0.0, np.arange(height) + 0.0)
    d = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    d = d.reshape(-1, 3)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


class EdgeChecker:
    """Renders the label maps and edge maps of one model for ``agreement``.

    Args:
        vertices: (V, 3) metres; faces: (F, 3); face_class: (F,) class ids.
        segments: (M, 2, 3) model edge segments, metres; classes: (M, 2) their two classes.
        normals: (M, 2, 3) the creases' face normals, NaN for other edges
            (``datagen.mesh.edges.EdgeSet.normals``); None: none.
        K: (3, 3) intrinsics; width, height: pixels.
        spacing: metres between edge samples (5 mm: at 0.5 m and 70 deg across 320 px, 2.3 px).
        eps: metres; an occluder nearer than this to an edge sample does not hide it.
        variant: Mitsuba variant of the ray caster.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, face_class: np.ndarray,
                 segments: np.ndarray, classes: np.ndarray, K: np.ndarray, width: int,
                 height: int, normals: np.ndarray | None = None, spacing: float = 0.005,
                 eps: float = 0.02, variant: str = "auto"):
        self.caster = RayCaster(vertices, faces, variant)
        self.face_class = np.asarray(face_class, np.uint8)
        self.K, self.width, self.height, self.eps = np.asarray(K, float), width, height, eps
        self.rays = ray_directions(self.K, width, height)
        seg = np.asarray(segments, np.float64).reshape(-1, 2, 3)
        cls = np.asarray(classes).reshape(-1, 2)
        nrm = np.full((len(seg), 2, 3), np.nan) if normals is None else np.asarray(normals)
        keep = np.isin(cls, C.STRUCTURAL).any(axis=1)
        seg, cls, nrm = seg[keep], cls[keep], nrm[keep]
        pieces, which = split_pieces(seg[:, 0], seg[:, 1], spacing)
        self.points = np.concatenate([pieces[:, 0], seg[:, 1]])
        which = np.concatenate([which, np.arange(len(seg))])
        self.classes, self.normals = cls[which], nrm[which]

    def labels(self, world_from_cam: np.ndarray) -> np.ndarray:
        """(H, W) uint8 class of the first face at each pixel centre (IGNORE: nothing hit)."""
        R, o = world_from_cam[:3, :3], world_from_cam[:3, 3]
        d = self.rays @ R.T
        face, _ = self.caster.first_hit(np.broadcast_to(o, d.shape), d, 1e3)
        out = np.where(face >= 0, self.face_class[np.maximum(face, 0)], C.IGNORE)
        return out.astype(np.uint8).reshape(self.height, self.width)

    def edges(self, world_from_cam: np.ndarray) -> np.ndarray:
        """(H, W) int32 pair code of the visible model edge drawn at each pixel, 0 elsewhere."""
        uv, depth = project(self.K, np.linalg.inv(world_from_cam), self.points)
        px = np.floor(uv).astype(np.int64)
        inside = ((depth > 0.05) & (px[:, 0] >= 0) & (px[:, 0] < self.width) & (px[:, 1] >= 0)
                  & (px[:, 1] < self.height))
        idx = np.flatnonzero(inside)
        eye = world_from_cam[:3, 3]
        seen = idx[~self.caster.hidden(np.broadcast_to(eye, (len(idx), 3)), self.points[idx],
                                       self.eps)]
        pairs = seen_pairs(self.classes[seen], self.normals[seen], self.points[seen],
                           np.broadcast_to(eye, (len(seen), 3)), self.caster, self.face_class)
        keep = structural_change(pairs)
        out = np.zeros((self.height, self.width), np.int32)
        out[px[seen[keep], 1], px[seen[keep], 0]] = pairs[keep]
        return out


def _near(codes: np.ndarray, code: int, tol_px: float) -> np.ndarray:
    """(H, W) bool: within ``tol_px`` of a pixel holding ``code``."""
    mask = (codes != code).astype(np.uint8)
    if mask.all():
        return np.zeros(codes.shape, bool)
    return cv2.distanceTransform(mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) <= tol_px


def agreement(checker: EdgeChecker, poses: np.ndarray, tol_px: float = 2.0) -> EdgeAgreement:
    """Recall and precision of the model edges against the label boundaries, pooled over
    ``poses`` (N, 4, 4) world_from_cam (OpenCV camera) poses."""
    hit_b = tot_b = hit_e = tot_e = 0
    missed: dict[int, int] = {}
    for pose in np.asarray(poses, np.float64).reshape(-1, 4, 4):
        bnd = label_boundaries(checker.labels(pose))
        edg = checker.edges(pose)
        for code in np.union1d(np.unique(bnd[bnd > 0]), np.unique(edg[edg > 0])):
            b, e = bnd == code, edg == code
            nb, ne = int(b.sum()), int(e.sum())
            if nb:
                got = int((b & _near(edg, code, tol_px)).sum())
                hit_b, tot_b = hit_b + got, tot_b + nb
                missed[int(code)] = missed.get(int(code), 0) + nb - got
            if ne:
                hit_e += int((e & _near(bnd, code, tol_px)).sum())
                tot_e += ne
    names = {int(c): f"{C.NAMES[c // 16]}|{C.NAMES[c % 16]}" for c in missed}
    top = sorted(((v, names[k]) for k, v in missed.items() if v), reverse=True)
    return EdgeAgreement(hit_b / tot_b if tot_b else 1.0, hit_e / tot_e if tot_e else 1.0,
                         tot_b, tot_e, len(poses), tol_px, {k: v for v, k in top})


def free_space_poses(free, body_from_cam: np.ndarray, n: int, rng: np.random.Generator
                     ) -> np.ndarray:
    """(n, 4, 4) world_from_cam poses of a level body over random cells of ``free`` (an
    ``OccupancyMap``) at random heights of its band and random yaws."""
    from core.poses import pose_from_xyz_rpy

    xy = free.sample(rng, n)
    z = rng.uniform(*free.band, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    rpy = np.c_[np.zeros((n, 2)), yaw]
    return pose_from_xyz_rpy(np.c_[xy, z], rpy) @ body_from_cam
