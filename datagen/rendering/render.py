"""A renderer of a ``datagen.worlds.scene.Scene`` (the corridor or an imported building) that moves
the camera and re-dresses the scene.

The Mitsuba scene is loaded once per world (and per set of distractor meshes); per frame only
parameters change through ``mi.traverse``: the camera pose, texture images, light radiance,
distractor positions and colours. That re-uses Dr.Jit's compiled kernels.

RGB: path tracer (spp, max_depth), Gaussian pixel filter, then (optionally) the albedo-
demodulation denoiser of ``datagen.rendering.denoise``, sRGB 8-bit output.
Labels: ``aov`` integrator (``shape_index``) through a second sensor with a box filter and one
un-jittered sample at each pixel centre, mapped to class ids; 255 (ignore) where nothing is hit:
the world is closed, so such a ray slipped through a crack between triangles (isolated pixels
that would otherwise be labelled void and count as a class of their own in the metrics).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from core import classes as C
from core.dataset import Camera
from core.imaging.camera import mitsuba_to_world
from core.imaging.colour import linear_to_srgb8
from core.imaging.variant import shape_index
from datagen.config import RenderConfig
from datagen.rendering.denoise import denoise, segment_ids
from datagen.worlds.scene import GLASS, QUAD, Scene

HIDDEN_Z = -100.0  # distractors not in use wait below the (closed) corridor floor, each
# shrunk to a point there (degenerate triangles cost the acceleration structure's rebuild,
# which every moved object triggers, little: docs/notes/render_cost.md)

@dataclass(frozen=True)
class Traced:
    """The raw passes of one view, as ``Renderer.trace`` returns them.

    aux: (H, W, 5) float32 at the pixel centres: shape index, ray length (m; 0 = no hit),
    shading normal. rgb: (H, W, 3) float32 linear path-traced radiance. albedo: (H, W, 3)
    float32 linear albedo from the same samples, or None.
    """

    aux: np.ndarray
    rgb: np.ndarray
    albedo: np.ndarray | None


def _set(params, key: str, value: np.ndarray) -> None:
    """Assign a numpy array to a traversed parameter, whatever the variant's array type."""
    current = params[key]
    params[key] = type(current)(np.ascontiguousarray(value))


def _hfov_deg(camera: Camera) -> float:
    """The horizontal field of view (degrees) of a camera the renderer can model: square
    pixels and a centred principal point."""
    K = camera.K
    if abs(K[0, 0] - K[1, 1]) > 1e-6 * K[0, 0] or abs(K[0, 2] - (camera.width - 1) / 2) > 1e-6 \
            or abs(K[1, 2] - (camera.height - 1) / 2) > 1e-6:
        raise ValueError("camera: the renderer needs square pixels and a centred principal "
                         "point (use core.imaging.camera.intrinsics)")
    return math.degrees(2 * math.atan(camera.width / 2 / K[0, 0]))


def _ray_norm(camera: Camera) -> np.ndarray:
    """(H, W) |K^-1 [u, v, 1]| per pixel: ray length -> z depth factor, z = t / |...|."""
    K = camera.K
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u,
                    dtype=float)], axis=-1)
    return np.linalg.norm(rays, axis=-1)


def _mesh(mi, name: str, V: np.ndarray, F: np.ndarray, UV: np.ndarray | None, bsdf,
          emitter=None, colour: np.ndarray | None = None):
    """A Mitsuba mesh of vertices V (n, 3), faces F (m, 3), optional texture coordinates
    UV (n, 2) and optional per-vertex colours (n, 3) (the ``vertex_color`` attribute a
    ``mesh_attribute`` texture reads), with a loaded bsdf and emitter."""
    props = mi.Properties()
    props["bsdf"] = bsdf
    if emitter is not None:
        props["emitter"] = emitter
    m = mi.Mesh(name, len(V), len(F), props=props, has_vertex_normals=False,
                has_vertex_texcoords=UV is not None)
    p = mi.traverse(m)
    _set(p, "vertex_positions", V.astype(np.float32).ravel())
    _set(p, "faces", F.astype(np.uint32).ravel())
    if UV is not None:
        _set(p, "vertex_texcoords", UV.astype(np.float32).ravel())
    p.update()
    if colour is not None:
        m.add_attribute("vertex_color", 3, np.ascontiguousarray(colour, np.float32).ravel())
    return m


def _bitmap(mi, img: np.ndarray) -> dict:
    """A repeating, raw (linear) bitmap texture of an (R, R, 3) image, row 0 = top."""
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.flipud(img).astype(np.float32)),
            "wrap_mode": "repeat", "raw": True}


def _sensors(camera: Camera, hfov: float) -> dict[str, dict]:
    """The RGB sensor (Gaussian pixel filter) and the label sensor (box filter, one
    un-jittered sample at each pixel centre)."""
    film = {"type": "hdrfilm", "width": camera.width, "height": camera.height,
            "pixel_format": "rgb"}
    return {
        "sensor": {"type": "perspective", "fov": hfov, "fov_axis": "x",
                   "near_clip": 0.01, "far_clip": 1000.0,
                   "film": {**film, "rfilter": {"type": "gaussian"}}},
        "label_sensor": {"type": "perspective", "fov": hfov, "fov_axis": "x",
                         "near_clip": 0.01, "far_clip": 1000.0,
                         "sampler": {"type": "stratified", "sample_count": 1,
                                     "jitter": False},
                         "film": {**film, "rfilter": {"type": "box"}}},
    }


class Renderer:
    """Renders RGB, labels and depth of a ``Scene`` from OpenCV-convention poses.

    Args:
        scene: the surfaces and light panels (``datagen.worlds.scene.corridor_scene``,
            ``building_scene``).
        camera: intrinsics and image size (K must be centred with square pixels).
        textures: name -> (R, R, 3) float32 linear RGB, row 0 = top, for every texture key
            the scene's textured surfaces use (``sample_textures``).
        clutter: distractor meshes labelled clutter (origin on the floor, z up).
        people: distractor meshes labelled person.
        max_depth: path length limit of the path tracer.
        near_lights: at each ``trace`` weight each light's chance to be sampled by its mean
            radiance over its squared distance to the camera (at least 1 m^2): unbiased, and
            much less noise where most of many lights are out of view (a building floor);
            False: Mitsuba's uniform choice (the corridor's renders as they were).
        glossy_floor: the procedurally textured floor is a blend of the diffuse texture and a
            rough plastic of the same texture, whose weight and roughness
            ``set_floor_gloss`` sets per image (weight 0, the start: the diffuse floor);
            False: the diffuse floor only.
    """

    def __init__(self, scene: Scene, camera: Camera, textures: Mapping[str, np.ndarray],
                 clutter: Sequence[trimesh.Trimesh] = (), people: Sequence[trimesh.Trimesh] = (),
                 max_depth: int = RenderConfig.max_depth, near_lights: bool = False,
                 glossy_floor: bool = False):
        import mitsuba as mi

        if not isinstance(scene, Scene):
            raise TypeError("Renderer takes a datagen.worlds.scene.Scene, got "
                            f"{type(scene).__name__}"
                            " (use corridor_scene(model) or building_scene(building, free))")
        self.mi = mi
        self.camera = camera
        hfov = _hfov_deg(camera)
        self.slots = [(m, C.CLUTTER) for m in clutter] + [(m, C.PERSON) for m in people]
        self._slot_vertices = [np.asarray(m.vertices, dtype=np.float64) for m, _ in self.slots]
        self._slot_parts = [m.metadata.get("parts") for m, _ in self.slots]  # (V,) or None
        self._slot_palette: dict[int, np.ndarray] = {}  # the last colours set per slot
        self._slot_pose: dict[int, np.ndarray] = {}  # the last pose set per slot (all hidden)
        for i in range(len(self.slots)):
            self._slot_pose[i] = np.full(3, np.nan)
        self.num_lights = scene.num_lights
        self.near_lights = near_lights
        self._light_centres = np.asarray(scene.lights, np.float64).reshape(-1, 4, 3).mean(1)
        self._radiance = np.ones((self.num_lights, 3), np.float32)
        self._camera_at = np.zeros(3)
        self.class_of: dict[str, int] = {}  # shape id -> class id
        self._texture_keys: list[tuple[str, str]] = []  # (parameter key, texture name)
        self.glossy_floor = glossy_floor
        self._gloss_shapes: list[str] = []  # the floor shapes with a blended BSDF
        self._gloss = (0.0, 0.1)  # their (weight, alpha) set last (as loaded)
        desc = {"type": "scene", "integrator": {"type": "path", "max_depth": int(max_depth)}}
        desc.update(self._surface_shapes(scene, textures))
        desc.update(self._light_shapes(scene))
        desc.update(self._object_shapes())
        desc.update(_sensors(camera, hfov))
        self.scene = mi.load_dict(desc)
        self.params = mi.traverse(self.scene)
        self.aov = mi.load_dict({"type": "aov", "aovs": "si:shape_index,dd:depth,nn:sh_normal"})
        # Albedo in its own pass: an aov integrator wrapping the path tracer is ~5x slower.
        self.albedo = mi.load_dict({"type": "aov", "aovs": "al:albedo"})
        lut, raw = self._class_lookup()
        self._textures = {k: np.asarray(v).shape for k, v in textures.items()}
        self.developer = Developer(lut, raw, _ray_norm(camera))

    def _surface_shapes(self, scene: Scene, textures: Mapping[str, np.ndarray]
                        ) -> dict[str, object]:
        """The scene's surfaces: procedurally textured (the window's view is an emitter), in
        the file's images or in their own vertex colours; ``GLASS`` ones a thin dielectric
        (a path through one sheet still gets its direct light at ``max_depth`` 3, through two
        it is black; the denoiser blurs what is seen through it as one segment: frosted)."""
        mi, out = self.mi, {}
        for s in scene.surfaces:
            F = np.arange(len(s.vertices)).reshape(-1, 3)
            if s.colour is not None:
                bsdf = mi.load_dict({"type": "diffuse", "reflectance": {
                    "type": "mesh_attribute", "name": "vertex_color"}})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, None, bsdf, colour=s.colour)
            elif s.texture == "window":
                bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                                         "value": 0.05}})
                emitter = mi.load_dict({"type": "area",
                                        "radiance": _bitmap(mi, textures["window"])})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, s.uv, bsdf, emitter)
                self._texture_keys.append((f"{s.name}.emitter.radiance.data", s.texture))
            elif s.texture == GLASS:  # see-through: a thin sheet of glass, no texture
                bsdf = mi.load_dict({"type": "thindielectric"})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, None, bsdf)
            elif s.texture in scene.images:  # the file's own image, fixed
                bsdf = mi.load_dict({"type": "diffuse",
                                     "reflectance": _bitmap(mi, scene.images[s.texture])})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, s.uv, bsdf)
            elif self.glossy_floor and s.texture == "floor":  # one texture, two lobes
                tex = mi.load_dict(_bitmap(mi, textures[s.texture]))
                bsdf = mi.load_dict({"type": "blendbsdf", "weight": 0.0,
                                     "bsdf_0": {"type": "diffuse", "reflectance": tex},
                                     "bsdf_1": {"type": "roughplastic", "alpha": 0.1,
                                                "diffuse_reflectance": tex}})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, s.uv, bsdf)
                self._texture_keys.append((f"{s.name}.bsdf.bsdf_0.reflectance.data", s.texture))
                self._gloss_shapes.append(s.name)
            else:
                bsdf = mi.load_dict({"type": "diffuse",
                                     "reflectance": _bitmap(mi, textures[s.texture])})
                out[s.name] = _mesh(mi, s.name, s.vertices, F, s.uv, bsdf)
                self._texture_keys.append((f"{s.name}.bsdf.reflectance.data", s.texture))
            self.class_of[s.name] = s.class_id
        return out

    def _light_shapes(self, scene: Scene) -> dict[str, object]:
        """The ceiling light panels, labelled ceiling."""
        mi, out = self.mi, {}
        for i, corners in enumerate(scene.lights):
            name = f"light{i}"
            emitter = mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": 1.0}})
            bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.8}})
            out[name] = _mesh(mi, name, corners, QUAD, None, bsdf, emitter)
            self.class_of[name] = C.CEILING
        return out

    def _object_shapes(self) -> dict[str, object]:
        """The distractor slots, hidden below the floor until ``set_objects`` places them; a
        mesh whose parts have their own colours (``metadata["parts"]``) in vertex colours."""
        mi, out = self.mi, {}
        for i, (m, cls) in enumerate(self.slots):
            name = f"object{i}"
            V = np.zeros_like(self._slot_vertices[i]) + [0.0, 0.0, HIDDEN_Z]
            F = np.asarray(m.faces)
            if self._slot_parts[i] is None:
                bsdf = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                                         "value": 0.5}})
                out[name] = _mesh(mi, name, V, F, None, bsdf)
            else:
                bsdf = mi.load_dict({"type": "diffuse", "reflectance": {
                    "type": "mesh_attribute", "name": "vertex_color"}})
                out[name] = _mesh(mi, name, V, F, None, bsdf,
                                  colour=np.full((len(V), 3), 0.5, np.float32))
            self.class_of[name] = cls
        return out

    def _class_lookup(self) -> tuple[np.ndarray, np.ndarray]:
        """Map aov ``shape_index`` values to class ids, and to whether the denoiser keeps the
        shape's pixels as rendered (built right after loading): (S,) uint8, (S,) bool.

        Kept raw are the emitters only (the ceiling lights and the window's outdoor view: their
        radiance is not shading); the window's frame faces (its jambs, head and sill,
        labelled window) are diffuse surfaces and denoised like the others."""
        mi = self.mi
        shapes = list(self.scene.shapes())
        lut = np.zeros(len(shapes) + 2, dtype=np.uint8)
        raw = np.zeros(len(shapes) + 2, dtype=bool)
        for pos, shape in enumerate(shapes):
            index = shape_index(mi, shape, pos)
            if index >= len(lut):
                lut = np.concatenate([lut, np.zeros(index + 1 - len(lut), dtype=np.uint8)])
                raw = np.concatenate([raw, np.zeros(index + 1 - len(raw), dtype=bool)])
            lut[index] = self.class_of[shape.id()]
            raw[index] = shape.is_emitter()
        return lut, raw

    # --- per-frame state (applied to the scene by the next ``render``) ----------------------

    def set_camera(self, world_from_cam: np.ndarray) -> None:
        """Place both sensors at an OpenCV-convention pose (4, 4)."""
        self._camera_at = np.asarray(world_from_cam, np.float64)[:3, 3].copy()
        T = self.mi.ScalarTransform4f(mitsuba_to_world(world_from_cam).tolist())
        self.params["sensor.to_world"] = T
        self.params["label_sensor.to_world"] = T

    def set_textures(self, textures: Mapping[str, np.ndarray]) -> None:
        """Replace the texture image of every textured surface in place (shapes must match the
        ones the scene was built with)."""
        for key, name in self._texture_keys:
            self._put_texture(key, name, textures[name])

    def _put_texture(self, key: str, name: str, img: np.ndarray) -> None:
        if img.shape != self._textures[name]:
            raise ValueError(f"texture {name!r} has shape {img.shape}, the scene was built with "
                             f"{self._textures[name]}; keep appearance.resolution fixed")
        self.params[key] = self.mi.TensorXf(np.flipud(img).astype(np.float32).copy())

    def set_lights(self, radiance: np.ndarray) -> None:
        """Set the ceiling lights' emitted radiance, (L, 3) linear RGB (0 = off)."""
        radiance = np.asarray(radiance, dtype=np.float32).reshape(self.num_lights, 3)
        self._radiance = radiance.copy()
        for i, rad in enumerate(radiance):
            self.params[f"light{i}.emitter.radiance.value"] = self.mi.Color3f(*rad.tolist())

    def set_floor_gloss(self, weight: float, alpha: float) -> None:
        """Make the floor glossy (a renderer built with ``glossy_floor``): weight in [0, 1] of
        the rough plastic lobe (0: the diffuse floor), alpha its GGX roughness (> 0)."""
        if not self.glossy_floor:
            raise ValueError("set_floor_gloss needs a Renderer built with glossy_floor=True")
        # weight 0 leaves alpha as it is: the lobe is then neither evaluated nor sampled, and a
        # new alpha costs the rough plastic's precomputation (~as much as a BVH rebuild)
        gloss = (float(weight), float(max(alpha, 1e-3)) if weight > 0 else self._gloss[1])
        for name in self._gloss_shapes:  # (an unchanged value is no update)
            self.params[f"{name}.bsdf.weight.value"] = gloss[0]
            self.params[f"{name}.bsdf.bsdf_1.alpha"] = gloss[1]
        self._gloss = gloss

    def _weigh_lights(self) -> None:
        """Sampling weights of the lights for the current camera (``near_lights``)."""
        d2 = np.sum((self._light_centres - self._camera_at) ** 2, axis=1)
        w = self._radiance.mean(axis=1) / np.maximum(d2, 1.0)
        w = w if w.max() > 0 else np.ones(self.num_lights)  # all off: any distribution
        for i, wi in enumerate(w.tolist()):
            self.params[f"light{i}.emitter.sampling_weight"] = wi

    def set_objects(self, poses: np.ndarray, colors: Sequence[np.ndarray]) -> None:
        """Place the distractor slots.

        Args:
            poses: (S, 3) x, y (metres), yaw (radians) per slot; NaN x hides the slot.
            colors: per slot, (3,) linear RGB reflectance, or for a mesh with parts (P, 3)
                one per part (``metadata["parts"]``; a (3,) colour paints them all): (S, 3)
                when no slot has parts.
        """
        poses = np.asarray(poses, dtype=np.float64).reshape(len(self.slots), 3)
        for i, (pose, col) in enumerate(zip(poses, colors, strict=True)):
            col = np.asarray(col, dtype=np.float32)
            parts = self._slot_parts[i]
            # a hidden slot keeps its colours, a shown one changes only those that differ: a
            # changed parameter of a shape costs the acceleration structure's rebuild
            if not np.isnan(pose[0]) and not np.array_equal(self._slot_palette.get(i), col):
                if parts is None:
                    self.params[f"object{i}.bsdf.reflectance.value"] = self.mi.Color3f(
                        *col.reshape(3).tolist())
                else:
                    palette = col.reshape(-1, 3)
                    if len(palette) not in (1, int(parts.max()) + 1):
                        raise ValueError(f"set_objects: slot {i} has {int(parts.max()) + 1} "
                                         f"parts, got {len(palette)} colours")
                    _set(self.params, f"object{i}.vertex_color",
                         palette[np.minimum(parts, len(palette) - 1)].ravel())
                self._slot_palette[i] = col
            last = self._slot_pose[i]
            if np.array_equal(last, pose, equal_nan=True):
                continue  # unchanged geometry: no acceleration-structure rebuild
            self._slot_pose[i] = pose.copy()
            V = self._slot_vertices[i]
            if np.isnan(pose[0]):
                V = np.zeros_like(V) + [0.0, 0.0, HIDDEN_Z]
            else:
                c, s = math.cos(pose[2]), math.sin(pose[2])
                R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                V = V @ R.T + [pose[0], pose[1], 0.0]
            _set(self.params, f"object{i}.vertex_positions", V.astype(np.float32).ravel())

    # --- rendering -------------------------------------------------------------------------

    def render(self, spp: int, seed: int, exposure: float = RenderConfig.exposure,
               denoise_sigma_px: float = RenderConfig.denoise_sigma_px
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render the current view: ``develop(trace(...))``.

        Args:
            spp: path-tracer samples per pixel. seed: sample seed.
            exposure: linear scale before sRGB encoding.
            denoise_sigma_px: shading blur of the denoiser, pixels; 0 switches it off.

        Returns:
            rgb (H, W, 3) uint8 sRGB; label (H, W) uint8 class ids (255 = ignore where nothing
            is hit);
            depth (H, W) float32 z in metres (0 where nothing is hit).
        """
        return self.develop(self.trace(spp, seed, denoise_sigma_px > 0), exposure,
                            denoise_sigma_px)

    def trace(self, spp: int, seed: int, albedo: bool = True) -> Traced:
        """The Mitsuba passes of the current view (applies the pending scene changes).

        The result holds numpy-owned arrays only, so the scene may change (or ``trace`` run
        again) while another thread develops it with ``developer`` (never with this renderer:
        no Mitsuba object may be used or freed on another thread while this one renders).

        Args:
            spp: path-tracer samples per pixel. seed: sample seed.
            albedo: also trace the albedo pass the denoiser needs.
        """
        mi = self.mi
        if self.near_lights and self.num_lights:
            self._weigh_lights()
        self.params.update()
        # np.array copies: np.asarray would view Dr.Jit's memory, and freeing that on another
        # thread while this one renders deadlocks Dr.Jit.
        aux = np.array(mi.render(self.scene, sensor=1, integrator=self.aov, spp=1, seed=0))
        rgb = np.array(mi.render(self.scene, sensor=0, spp=int(spp), seed=int(seed)))[..., :3]
        alb = (np.array(mi.render(self.scene, sensor=0, integrator=self.albedo, spp=int(spp),
                                  seed=int(seed)))[..., :3] if albedo else None)
        return Traced(aux, rgb, alb)

    def develop(self, traced: Traced, exposure: float = RenderConfig.exposure,
               denoise_sigma_px: float = RenderConfig.denoise_sigma_px
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``self.developer.develop``: see ``Developer.develop``."""
        return self.developer.develop(traced, exposure, denoise_sigma_px)


@dataclass(frozen=True)
class Developer:
    """Turns a ``Traced`` view into the frame's images: numpy only, holds no Mitsuba object, so
    it may run on another thread while the renderer it came from traces the next view.

    lut: (S,) uint8 class id per Mitsuba shape index. raw: (S,) bool, the shapes whose pixels
    the denoiser keeps as rendered (emitters; ``Renderer._class_lookup``).
    ray_norm: (H, W) |K^-1 [u, v, 1]| per pixel (ray length -> z depth).
    """

    lut: np.ndarray
    raw: np.ndarray
    ray_norm: np.ndarray

    def develop(self, traced: Traced, exposure: float = RenderConfig.exposure,
               denoise_sigma_px: float = RenderConfig.denoise_sigma_px
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Labels, depth and the denoised sRGB image of a traced view.

        Returns:
            As ``Renderer.render``.
        """
        rgb, label, depth = self.develop_linear(traced, exposure, denoise_sigma_px)
        return linear_to_srgb8(rgb), label, depth

    def develop_linear(self, traced: Traced, exposure: float = RenderConfig.exposure,
                       denoise_sigma_px: float = RenderConfig.denoise_sigma_px
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As ``develop``, with the image in linear light before its sRGB encoding: (H, W, 3)
        float32 (denoised, times ``exposure``; 1 = the white level, not clipped)."""
        aux = traced.aux
        index = np.rint(aux[..., 0]).astype(np.int64)
        index = np.where((index >= 0) & (index < len(self.lut)), index, 0)
        t = aux[..., 1]
        label = self.lut[index]
        label[t <= 0] = C.IGNORE
        rgb = traced.rgb
        if denoise_sigma_px > 0:
            if traced.albedo is None:
                raise ValueError("develop: denoise_sigma_px > 0 needs a trace with albedo=True")
            keep = self.raw[index]
            rgb = denoise(rgb, traced.albedo, segment_ids(index, aux[..., 2:5]), keep,
                          denoise_sigma_px)
        return rgb * exposure, label, (t / self.ray_norm).astype(np.float32)

