"""Mesh primitives of the distractors (trimesh), in an object frame with z up: boxes, rods,
capsules, ellipsoids, frustums, and their union turned by a yaw."""

from __future__ import annotations

import numpy as np
import trimesh


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float],
         yaw: float = 0.0) -> trimesh.Trimesh:
    """Axis box of the given extents (m) centred at centre, rotated by yaw about z."""
    T = trimesh.transformations.rotation_matrix(yaw, (0, 0, 1))
    T[:3, 3] = centre
    return trimesh.creation.box(extents=extents, transform=T)


def _rod(p0: np.ndarray, p1: np.ndarray, radius: float, sections: int = 10) -> trimesh.Trimesh:
    """Closed cylinder between two points."""
    return trimesh.creation.cylinder(radius=radius, segment=np.array([p0, p1], float),
                                     sections=sections)


def _capsule(p0: np.ndarray, p1: np.ndarray, radius: float) -> trimesh.Trimesh:
    """Capsule whose axis runs from p0 to p1 (the caps extend radius beyond them)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    mesh = trimesh.creation.capsule(height=max(length, 1e-3), radius=radius, count=[8, 8])
    T = trimesh.geometry.align_vectors([0, 0, 1], axis / max(length, 1e-9))
    T[:3, 3] = (p0 + p1) / 2
    mesh.apply_transform(T)
    return mesh


def _ellipsoid(centre: tuple[float, float, float], radii: tuple[float, float, float],
               subdivisions: int = 1) -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.apply_scale(radii)
    mesh.apply_translation(centre)
    return mesh


def _frustum(r_bottom: float, r_top: float, height: float, sections: int = 14) -> trimesh.Trimesh:
    """Closed truncated cone standing on z = 0 (a pot)."""
    mesh = trimesh.creation.cylinder(radius=1.0, height=height, sections=sections)
    v = mesh.vertices.copy()
    top = v[:, 2] > 0
    v[:, :2] *= np.where(top, r_top, r_bottom)[:, None]
    v[:, 2] += height / 2
    return trimesh.Trimesh(v, mesh.faces, process=False)


def _join(parts: list[trimesh.Trimesh], yaw: float = 0.0) -> trimesh.Trimesh:
    """Concatenate parts, rotate by yaw and re-centre the footprint on the origin."""
    mesh = trimesh.util.concatenate(parts)
    if yaw:
        mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, (0, 0, 1)))
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return mesh
