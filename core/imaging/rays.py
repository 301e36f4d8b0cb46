"""Ray casting against a triangle mesh: occlusion tests and first hits.

Rays go through Mitsuba (llvm variant: ``ray_test`` / ``ray_intersect_preliminary``,
millions of rays per second, float32); with the scalar fallback variant trimesh's ray
intersector does it, slower.
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)


class RayCaster:
    """Rays against one mesh: ``vertices`` (V, 3) metres, ``faces`` (F, 3) vertex indices.

    ``variant``: Mitsuba variant (``core.imaging.variant.choose_variant``; ``scalar_rgb`` uses
    trimesh)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, variant: str = "auto"):
        from core.imaging.variant import choose_variant

        self.use_mitsuba = choose_variant(variant) != "scalar_rgb"
        if self.use_mitsuba:
            self.mi, self.scene = _mitsuba_scene(vertices, faces)
        else:
            import trimesh

            log.warning("rays: casting with trimesh (no llvm Mitsuba variant); slow")
            self.tm = trimesh.Trimesh(vertices, faces, process=False)

    def _ray(self, o: np.ndarray, d: np.ndarray, maxt: np.ndarray):
        mi = self.mi
        ray = mi.Ray3f(mi.Point3f(*[np.ascontiguousarray(o[:, i], dtype=np.float32)
                                    for i in range(3)]),
                       mi.Vector3f(*[np.ascontiguousarray(d[:, i], dtype=np.float32)
                                     for i in range(3)]))
        ray.maxt = mi.Float(np.asarray(maxt, dtype=np.float32))
        return ray

    def hidden(self, origins: np.ndarray, targets: np.ndarray, eps: float) -> np.ndarray:
        """(n,) bool: the segment from origins[i] to targets[i] (both (n, 3) float64, metres)
        hits the mesh before ``eps`` metres short of the target."""
        o, d = origins, targets - origins
        if len(o) == 0:
            return np.zeros(0, dtype=bool)
        dist = np.linalg.norm(d, axis=1)
        d = d / np.maximum(dist, 1e-12)[:, None]
        maxt = np.maximum(dist - eps, 0.0)
        if self.use_mitsuba:
            hit = np.asarray(self.scene.ray_test(self._ray(o, d, maxt)), dtype=bool)
        else:
            loc, idx_ray, _ = self.tm.ray.intersects_location(o, d, multiple_hits=True)
            hit = np.zeros(len(o), dtype=bool)
            if len(idx_ray):
                t = np.einsum("ij,ij->i", loc - o[idx_ray], d[idx_ray])
                hit[idx_ray[(t > 1e-6) & (t < maxt[idx_ray])]] = True
        return hit & (dist > eps)

    def first_hit(self, origins: np.ndarray, directions: np.ndarray,
                  maxt: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """The first face each ray hits within ``maxt`` metres.

        Args:
            origins: (n, 3) metres. directions: (n, 3) unit vectors.
            maxt: (n,) or scalar, metres.

        Returns:
            face (n,) int64 index of the face hit, -1 for none; t (n,) float64 distance in
            metres (inf for none).
        """
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        maxt = np.broadcast_to(np.asarray(maxt, dtype=np.float64), (len(o),))
        face, t = np.full(len(o), -1, dtype=np.int64), np.full(len(o), np.inf)
        if len(o) == 0:
            return face, t
        if self.use_mitsuba:
            pi = self.scene.ray_intersect_preliminary(self._ray(o, d, maxt))
            tt = np.asarray(pi.t, dtype=np.float64)
            ok = np.isfinite(tt) & (tt <= maxt)
            face[ok] = np.asarray(pi.prim_index, dtype=np.int64)[ok]
            t[ok] = tt[ok]
            return face, t
        tri, ray, loc = self.tm.ray.intersects_id(o, d, multiple_hits=True,
                                                  return_locations=True)
        tt = np.einsum("ij,ij->i", loc - o[ray], d[ray]) if len(ray) else np.zeros(0)
        ok = (tt > 1e-9) & (tt <= maxt[ray])
        tri, ray, tt = tri[ok], ray[ok], tt[ok]
        order = np.lexsort((tt, ray))  # per ray, nearest first
        tri, ray, tt = tri[order], ray[order], tt[order]
        first = np.r_[True, ray[1:] != ray[:-1]] if len(ray) else np.zeros(0, bool)
        face[ray[first]], t[ray[first]] = tri[first], tt[first]
        return face, t


def _mitsuba_scene(vertices: np.ndarray, faces: np.ndarray):
    import mitsuba as mi

    mesh = mi.Mesh("model", len(vertices), len(faces), has_vertex_normals=False,
                   has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.ascontiguousarray(
        vertices, dtype=np.float32).ravel())
    params["faces"] = mi.UInt32(np.ascontiguousarray(faces, dtype=np.uint32).ravel())
    params.update()
    return mi, mi.load_dict({"type": "scene", "model": mesh})
