"""The paper's likelihood as described, one particle at a time, for comparison.

For each particle (Buyval et al. 2017, Sec. III): render the 3D model at the particle's pose
(here Mitsuba's ``aov`` class image, ``localize.paper.render``), find the model's contours
(the boundaries between classes in the render) and the Hough line segments on them, place
``samples_per_line`` points on each line, search the image edge map along each point's normal
up to ``search_px`` pixels for the nearest edge (d in pixels, divided by ``search_px`` as in
``likelihood``), score ``g = exp(-d^2 / (2 sigma^2))``, line score ``l = mean g`` and
``log W = k * mean l`` (the paper's alpha cancels in the normalized weights). Normal-search
points on unknown (masked) pixels score the chance level, as in the vectorized model.

It costs a render plus a Hough transform per particle (a Python loop over particles), which is
the point of comparing it with ``likelihood.EdgeLikelihood``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from core.dataset import Camera, World
from localize.config import HoughConfig, LikelihoodConfig
from localize.filter.projection import cam_from_world
from localize.frontend.boundaries import label_edges
from localize.frontend.edge_image import EdgeImage
from localize.paper.render import ModelRenderer


@dataclass
class PaperFaithfulConfig:
    """How the paper-faithful likelihood renders and searches (benchmarks/paper_faithful.py).

    Attributes:
        render_variant: Mitsuba variant of the renders.
        hough: on the rendered model's class boundaries.
        samples_per_line: S normals per model line.
        search_px: reach of the normal search, pixels (as ``likelihood.search_px``).
    """

    render_variant: str = "auto"
    hough: HoughConfig = field(default_factory=lambda: HoughConfig(20, 15, 3))
    samples_per_line: int = 10
    search_px: float = 10.0


def normal_search(edges: np.ndarray, points: np.ndarray, normals: np.ndarray,
                  reach: int) -> np.ndarray:
    """Distance along the normal to the nearest edge pixel, both ways.

    Args:
        edges: (H, W) bool edge map.
        points: (L, 2) pixel coordinates (u, v).
        normals: (L, 2) unit normals.
        reach: search range in pixels.

    Returns:
        (L,) float distance in pixels (``reach`` where no edge is within reach).
    """
    H, W = edges.shape
    offsets = np.arange(-reach, reach + 1, dtype=np.float64)
    q = points[:, None, :] + offsets[None, :, None] * normals[:, None, :]  # (L, 2R+1, 2)
    u = np.rint(q[..., 0]).astype(np.int64)
    v = np.rint(q[..., 1]).astype(np.int64)
    inside = (u >= 0) & (u < W) & (v >= 0) & (v < H)
    hit = np.zeros(u.shape, dtype=bool)
    hit[inside] = edges[v[inside], u[inside]]
    dist = np.where(hit, np.abs(offsets)[None, :], np.inf).min(axis=1)
    return np.minimum(dist, float(reach))


class PaperFaithfulLikelihood:
    """Render-per-particle likelihood (see the module docstring).

    Args:
        world, camera: the model and camera.
        params: k, sigma (same units as the vectorized likelihood).
        settings: ``PaperFaithfulConfig``: ``hough`` (on the rendered contours),
            ``samples_per_line`` (S points per model line), ``search_px`` (normal search reach,
            pixels; d is divided by it), ``render_variant`` (Mitsuba variant of the renders).
    """

    def __init__(self, world: World, camera: Camera, params: LikelihoodConfig,
                 settings: PaperFaithfulConfig):
        self.camera, self.params = camera, params
        self.hough = settings.hough
        self.S = int(settings.samples_per_line)
        self.reach = int(round(settings.search_px))
        self.renderer = ModelRenderer(world, camera, settings.render_variant)

    def model_lines(self, state: np.ndarray, tilt: np.ndarray | None = None) -> np.ndarray:
        """Hough line segments (L, 4) [u0, v0, u1, v1] of the model rendered at a state (4,)."""
        T = cam_from_world(np.asarray(state, dtype=np.float64)[None],
                           self.camera.body_from_cam, tilt)[0]
        labels, _ = self.renderer.render(np.linalg.inv(T))
        contours = label_edges(labels, dilate_px=0).edges.astype(np.uint8) * 255
        h = self.hough
        lines = cv2.HoughLinesP(contours, 1, np.pi / 180, int(h.threshold),
                                minLineLength=float(h.min_length), maxLineGap=float(h.max_gap))
        return np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4).astype(np.float64)

    def score(self, lines: np.ndarray, edge: EdgeImage, g0: float) -> float:
        """Mean line score of model lines (L, 4) against an edge image."""
        if len(lines) == 0:
            return g0
        t = (np.arange(self.S) + 0.5) / self.S
        p0, p1 = lines[:, None, :2], lines[:, None, 2:]
        pts = (p0 + t[None, :, None] * (p1 - p0)).reshape(-1, 2)
        d = (lines[:, 2:] - lines[:, :2])
        n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(
            np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        normals = np.repeat(n, self.S, axis=0)
        dist = normal_search(edge.edges & edge.known, pts, normals, self.reach)
        dn = dist / self.reach
        g = np.exp(-dn ** 2 / (2 * self.params.sigma ** 2))
        H, W = edge.known.shape
        u = np.clip(np.rint(pts[:, 0]).astype(np.int64), 0, W - 1)
        v = np.clip(np.rint(pts[:, 1]).astype(np.int64), 0, H - 1)
        g = np.where(edge.known[v, u], g, g0)
        return float(g.reshape(-1, self.S).mean(axis=1).mean())

    def log_likelihood(self, states: np.ndarray, edge: EdgeImage,
                       tilt: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``log W`` (N,) and score (N,) of particle states (N, 4); one render per particle."""
        g0 = float(np.exp(-1.0 / (2 * self.params.sigma ** 2)))
        scores = np.array([self.score(self.model_lines(s, tilt), edge, g0)
                           for s in np.asarray(states)])
        return self.params.k * scores, scores
