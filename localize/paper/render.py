"""Class and depth images of the structural model alone, rendered with Mitsuba's ``aov``.

Used by the paper-faithful likelihood (``localize.paper.faithful``: the model rendered at a
particle's pose, as the paper does with Gazebo) and by tests that check projection and
visibility against a render. One un-jittered sample per pixel centre with a box filter, so the
class image has hard edges.
"""

from __future__ import annotations

import math

import numpy as np

from core import classes as C
from core.dataset import Camera, World
from core.imaging.camera import mitsuba_to_world


def centred(camera: Camera) -> bool:
    """Square pixels and the principal point at the image's centre (what ``ModelRenderer``
    renders)."""
    K = camera.K
    return (abs(K[0, 0] - K[1, 1]) <= 1e-6 * K[0, 0]
            and abs(K[0, 2] - (camera.width - 1) / 2) <= 1e-6
            and abs(K[1, 2] - (camera.height - 1) / 2) <= 1e-6)


class ModelRenderer:
    """Renders (labels, depth) of a World from OpenCV-convention camera poses.

    Args:
        world: the model (one Mitsuba mesh per class).
        camera: intrinsics (square pixels, centred principal point) and size.
        variant: Mitsuba variant (``auto`` = llvm if it works, else scalar).
    """

    def __init__(self, world: World, camera: Camera, variant: str = "auto"):
        from core.imaging.variant import choose_variant

        choose_variant(variant)
        import mitsuba as mi

        from core.imaging.variant import shape_index

        self.mi, self.camera = mi, camera
        K = camera.K
        if not centred(camera):
            raise ValueError("ModelRenderer needs square pixels and a centred principal point")
        hfov = math.degrees(2 * math.atan(camera.width / 2 / K[0, 0]))
        scene: dict = {"type": "scene"}
        class_of: dict[str, int] = {}
        for cls in np.unique(world.face_class):
            F = np.asarray(world.faces)[world.face_class == cls]
            used, inv = np.unique(F, return_inverse=True)
            V = np.asarray(world.vertices)[used]
            name = f"class{int(cls)}"
            mesh = mi.Mesh(name, len(V), len(F), has_vertex_normals=False,
                           has_vertex_texcoords=False)
            p = mi.traverse(mesh)
            p["vertex_positions"] = mi.Float(np.ascontiguousarray(V, dtype=np.float32).ravel())
            p["faces"] = mi.UInt32(np.ascontiguousarray(inv.reshape(-1, 3),
                                                        dtype=np.uint32).ravel())
            p.update()
            scene[name] = mesh
            class_of[name] = int(cls)
        scene["sensor"] = {"type": "perspective", "fov": hfov, "fov_axis": "x",
                           "near_clip": 0.01, "far_clip": 1000.0,
                           "sampler": {"type": "stratified", "sample_count": 1, "jitter": False},
                           "film": {"type": "hdrfilm", "width": camera.width,
                                    "height": camera.height, "pixel_format": "rgb",
                                    "rfilter": {"type": "box"}}}
        self.scene = mi.load_dict(scene)
        self.params = mi.traverse(self.scene)
        self.aov = mi.load_dict({"type": "aov", "aovs": "si:shape_index,dd:depth"})
        lut = np.zeros(1, dtype=np.uint8)
        for pos, shape in enumerate(self.scene.shapes()):
            index = shape_index(mi, shape, pos)
            if index >= len(lut):
                lut = np.concatenate([lut, np.zeros(index + 1 - len(lut), dtype=np.uint8)])
            lut[index] = class_of[shape.id()]
        self._lut = lut
        u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
        rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1],
                         np.ones(u.shape)], axis=-1)
        self._ray_norm = np.linalg.norm(rays, axis=-1)

    def render(self, world_from_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Labels (H, W) uint8 (0 = nothing hit) and z depth (H, W) float32 metres (0 = none).

        Args:
            world_from_cam: (4, 4) OpenCV-convention camera pose.
        """
        self.params["sensor.to_world"] = self.mi.ScalarTransform4f(
            mitsuba_to_world(world_from_cam).tolist())
        self.params.update()
        out = np.asarray(self.mi.render(self.scene, integrator=self.aov, spp=1, seed=0))
        index = np.rint(out[..., 0]).astype(np.int64)
        index = np.where((index >= 0) & (index < len(self._lut)), index, 0)
        label = self._lut[index]
        t = out[..., 1]
        label[t <= 0] = C.VOID
        return label, (t / self._ray_norm).astype(np.float32)
