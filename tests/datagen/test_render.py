"""Rendering against the model: projected model edges land on rendered label boundaries."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from core import classes as C
from core.config import compose_config
from core.imaging.outline import seen_pairs
from core.imaging.rays import RayCaster
from core.poses import pose_from_xyz_rpy
from datagen.appearance.textures import sample_textures
from datagen.job import make_camera
from datagen.worlds.corridor import build_world
from datagen.worlds.scene import corridor_scene


def _seen_changes(w, world_from_cam: np.ndarray) -> np.ndarray:
    """(M,) bool: the segments whose midpoint the camera sees as a class change
    (``core.imaging.outline.seen_pairs``)."""
    mid = w.segments.mean(axis=1)
    eye = np.broadcast_to(world_from_cam[:3, 3], mid.shape)
    return seen_pairs(w.segment_classes, w.normals, mid, eye, RayCaster(w.vertices, w.faces),
                      w.face_class) > 0


@pytest.fixture(scope="module")
def view():
    """A 160x120 render of the default corridor from a tilted pose looking down +Y."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    cfg = compose_config("datagen", ["camera.width=160", "camera.height=120"])
    model = build_world(cfg["world"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 32, cfg["appearance"])
    r = Renderer(corridor_scene(model), camera, tex)
    r.set_lights(np.full((r.num_lights, 3), 6.0))
    body = pose_from_xyz_rpy([0.25, 0.8, 1.3], [0.06, -0.08, np.pi / 2 + 0.25])[0]
    world_from_cam = body @ camera.body_from_cam
    r.set_camera(world_from_cam)
    rgb, label, depth = r.render(spp=2, seed=0)
    return model, camera, world_from_cam, rgb, label, depth


def _boundary_distance(label: np.ndarray) -> np.ndarray:
    """Distance (px) from each pixel centre to the nearest pixel next to a class change."""
    b = np.zeros(label.shape, bool)
    b[:, 1:] |= label[:, 1:] != label[:, :-1]
    b[:, :-1] |= label[:, 1:] != label[:, :-1]
    b[1:] |= label[1:] != label[:-1]
    b[:-1] |= label[1:] != label[:-1]
    return cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, 5)


def _visible_projection(model, camera, world_from_cam, depth, points):
    from core.imaging.camera import project

    uv, z = project(camera.K, np.linalg.inv(world_from_cam), points)
    H, W = depth.shape
    ok = ((z > 0.2) & (z < 6.0) & (uv[:, 0] > 2) & (uv[:, 0] < W - 3)
          & (uv[:, 1] > 2) & (uv[:, 1] < H - 3))
    uv, z = uv[ok], z[ok]
    iu, iv = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    # visible: some pixel in the 3x3 neighbourhood renders this depth
    near = np.stack([depth[iv + dv, iu + du] for dv in (-1, 0, 1) for du in (-1, 0, 1)], 1)
    vis = (np.abs(near - z[:, None]) < 0.005 * z[:, None] + 0.01).any(axis=1)
    return uv[vis], iu[vis], iv[vis]


class TestRender:
    def test_outputs(self, view):
        _, camera, _, rgb, label, depth = view
        assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
        assert label.shape == (120, 160) and label.dtype == np.uint8
        assert set(np.unique(label)) <= set(range(C.NUM_CLASSES)) | {C.IGNORE}
        assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR} <= set(np.unique(label))
        assert (depth > 0).all() and depth.max() < 12.0
        assert 20 < rgb.mean() < 235  # neither black nor blown out

    def test_model_corners_on_rendered_corners(self, view):
        """Visible segment endpoints (3D corners) project within 1 px of a label corner."""
        model, camera, T, _, label, depth = view
        w = model.world
        change = _seen_changes(w, T)
        corners = np.unique(w.segments[change].reshape(-1, 3), axis=0)
        uv, iu, iv = _visible_projection(model, camera, T, depth, corners)
        assert len(uv) >= 6, "the test view should show several model corners"
        dist = _boundary_distance(label)
        assert (dist[iv, iu] <= 1.0).all(), dist[iv, iu]

    def test_model_edges_on_label_boundaries(self, view):
        """Points along visible class-changing model edges lie on label boundaries."""
        model, camera, T, _, label, depth = view
        w = model.world
        seg = w.segments[_seen_changes(w, T)]
        t = np.linspace(0, 1, 200)[None, :, None]
        pts = (seg[:, :1] * (1 - t) + seg[:, 1:] * t).reshape(-1, 3)
        uv, iu, iv = _visible_projection(model, camera, T, depth, pts)
        assert len(uv) > 300
        dist = _boundary_distance(label)
        assert np.mean(dist[iv, iu] <= 1.0) > 0.98

    def test_mirrored_pose_does_not_match(self, view):
        """The check above can fail: a camera mirrored left-right misses the boundaries."""
        model, camera, T, _, label, depth = view
        w = model.world
        seg = w.segments[w.segment_classes[:, 0] != w.segment_classes[:, 1]]
        t = np.linspace(0, 1, 200)[None, :, None]
        pts = (seg[:, :1] * (1 - t) + seg[:, 1:] * t).reshape(-1, 3)
        from core.imaging.camera import project

        uv, z = project(camera.K, np.linalg.inv(T), pts)
        uv[:, 0] = camera.width - 1 - uv[:, 0]
        ok = (z > 0.2) & (uv[:, 0] > 0) & (uv[:, 0] < 159) & (uv[:, 1] > 0) & (uv[:, 1] < 119)
        dist = _boundary_distance(label)
        iu, iv = np.rint(uv[ok, 0]).astype(int), np.rint(uv[ok, 1]).astype(int)
        assert np.mean(dist[iv, iu] <= 1.0) < 0.6


def test_render_is_develop_of_trace():
    """``render`` = ``develop(trace(...))``; the traced arrays survive the scene moving on."""
    from datagen.rendering.render import Renderer

    cfg = compose_config("datagen", ["camera.width=64", "camera.height=48"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    r = Renderer(corridor_scene(build_world(cfg["world"])), camera, tex)
    r.set_lights(np.full((r.num_lights, 3), 6.0))
    poses = [pose_from_xyz_rpy([0.2, y, 1.3], [0.0, 0.0, np.pi / 2])[0] @ camera.body_from_cam
             for y in (0.8, 2.0)]
    r.set_camera(poses[0])
    direct = r.render(spp=1, seed=3)
    r.set_camera(poses[0])
    traced = r.trace(spp=1, seed=3)
    r.set_camera(poses[1])
    r.trace(spp=1, seed=4)  # the next frame, traced before the first is developed
    for x, y in zip(direct, r.develop(traced), strict=True):
        assert x.shape == y.shape and x.dtype == y.dtype
        assert np.abs(x.astype(float) - y.astype(float)).max() <= 1  # LLVM: rare 1-level noise
    assert traced.albedo is not None and traced.aux.shape == (48, 64, 5)
    for a in (traced.aux, traced.rgb, traced.albedo):  # numpy's own memory, not Dr.Jit's
        while isinstance(a.base, np.ndarray):
            a = a.base
        assert a.flags.owndata, "a traced array views Dr.Jit memory"
    dev = r.developer  # what the worker thread gets: numpy only
    assert all(isinstance(v, np.ndarray | tuple) for v in vars(dev).values())
    with pytest.raises(ValueError, match="albedo=True"):
        r.develop(r.trace(spp=1, seed=3, albedo=False))
    rgb, label, _ = r.develop(r.trace(spp=1, seed=3, albedo=False), denoise_sigma_px=0)
    assert rgb.shape == (48, 64, 3) and label.shape == (48, 64)


def test_denoiser_keeps_only_emitters_raw():
    """The denoiser leaves the emitters as rendered (the ceiling lights, the window's outdoor
    view) and smooths every diffuse surface, the window's frame faces too (labelled window)."""
    from core.imaging.variant import shape_index
    from datagen.rendering.render import Renderer

    cfg = compose_config("datagen", ["camera.width=32", "camera.height=24"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    model = build_world(cfg["world"])
    r = Renderer(corridor_scene(model), camera, tex)
    shapes = list(r.scene.shapes())
    raw = r.developer.raw[[shape_index(r.mi, s, i) for i, s in enumerate(shapes)]]
    emitter = np.array([s.is_emitter() for s in shapes])
    frame = np.array([s.id() == "window_frame" for s in shapes])
    assert emitter.sum() == r.num_lights + 1 and frame.sum() == 1  # lights, window view
    assert r.developer.lut[shape_index(r.mi, shapes[int(np.argmax(frame))],
                                       int(np.argmax(frame)))] == C.WINDOW
    np.testing.assert_array_equal(raw, emitter)


def test_develop_smooths_all_but_the_raw_shapes():
    """A noisy flat view, shape 1 on the left (diffuse), shape 2 on the right (kept raw)."""
    from core.imaging.colour import linear_to_srgb8
    from datagen.rendering.render import Developer, Traced

    H, W = 16, 32
    aux = np.zeros((H, W, 5), np.float32)
    aux[..., 0] = np.where(np.arange(W) < W // 2, 1, 2)
    aux[..., 1] = 2.0  # every pixel hits at 2 m
    aux[..., 4] = 1.0  # normal +z
    rng = np.random.default_rng(0)
    rgb = (0.4 * (1 + 0.5 * rng.standard_normal((H, W, 3)))).astype(np.float32)
    albedo = np.full((H, W, 3), 0.5, np.float32)
    dev = Developer(np.array([0, C.WINDOW, C.WINDOW], np.uint8), np.array([False, False, True]),
                    np.ones((H, W)))
    out, label, _ = dev.develop(Traced(aux, rgb, albedo), exposure=1.0)
    assert (label == C.WINDOW).all()
    np.testing.assert_array_equal(out[:, W // 2:], linear_to_srgb8(rgb[:, W // 2:]))
    assert out[:, : W // 2].std() < 0.2 * linear_to_srgb8(rgb[:, : W // 2]).std()


def test_set_textures_reaches_every_textured_surface():
    """The door and window frames (texture ``frame``, surfaces of their own) follow
    ``set_textures`` like the rest."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()

    cfg = compose_config("datagen", ["camera.width=32", "camera.height=24"])
    camera = make_camera(cfg["camera"])
    first = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    second = sample_textures(np.random.default_rng(1), 16, cfg["appearance"])
    r = Renderer(corridor_scene(build_world(cfg["world"])), camera, first)
    r.set_textures(second)
    for name in ("door_frame", "window_frame", "wall"):
        tex = "wall" if name == "wall" else "frame"
        got = np.array(r.params[f"{name}.bsdf.reflectance.data"])
        np.testing.assert_allclose(got, np.flipud(second[tex]), atol=1e-6)


def test_renderer_takes_a_scene():
    from datagen.rendering.render import Renderer

    cfg = compose_config("datagen", ["camera.width=32", "camera.height=24"])
    with pytest.raises(TypeError, match="corridor_scene"):
        Renderer(build_world(cfg["world"]), make_camera(cfg["camera"]), {})


def test_glossy_floor():
    """A renderer built with glossy_floor: weight 0 renders the diffuse floor (as a plain
    renderer, within path-tracing noise); a smooth glossy floor mirrors the ceiling lights
    (brighter highlights on the floor); a plain renderer refuses set_floor_gloss."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    cfg = compose_config("datagen", ["camera.width=80", "camera.height=60"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 32, cfg["appearance"])
    scene = corridor_scene(build_world(cfg["world"]))
    pose = pose_from_xyz_rpy([0.2, 0.8, 1.3], [0.0, 0.25, np.pi / 2])[0] @ camera.body_from_cam

    def floor_pixels(r, gloss=None):
        r.set_lights(np.full((r.num_lights, 3), 6.0))
        if gloss is not None:
            r.set_floor_gloss(*gloss)
        r.set_camera(pose)
        rgb, label, _ = r.render(spp=4, seed=1)
        return rgb[label == C.FLOOR].astype(float)

    plain = Renderer(scene, camera, tex)
    glossy = Renderer(scene, camera, tex, glossy_floor=True)
    base = floor_pixels(plain)
    assert len(base) > 500
    matte = floor_pixels(glossy, (0.0, 0.1))
    assert abs(matte.mean() - base.mean()) < 0.03 * base.mean() + 1
    shiny = floor_pixels(glossy, (1.0, 0.03))
    assert np.percentile(shiny.mean(1), 99) > np.percentile(base.mean(1), 99) + 10
    with pytest.raises(ValueError, match="glossy_floor"):
        plain.set_floor_gloss(1.0, 0.1)


def test_hidden_slots_come_back_whole():
    """A distractor slot shown again after hiding (its colours not set while hidden) renders
    the labels, depth and image of a slot shown straight away (plain and part-coloured
    meshes); hidden, it is in no pixel."""
    import trimesh

    from core.imaging.variant import choose_variant
    from datagen.distractors.meshes import make_clutter_mesh
    from datagen.rendering.render import Renderer

    choose_variant()
    cfg = compose_config("datagen", ["camera.width=96", "camera.height=72"])
    model = build_world(cfg["world"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    box = trimesh.creation.box([0.6, 0.6, 1.0])
    box.apply_translation([0.0, 0.0, 0.5])
    meshes = [box, make_clutter_mesh("shelf", np.random.default_rng(2))]
    assert meshes[1].metadata.get("parts") is not None
    body = pose_from_xyz_rpy([0.0, 0.5, 1.3], [0.0, 0.1, np.pi / 2])[0]
    shown = np.array([[-0.3, 2.6, 0.3], [0.4, 3.4, -0.2]])
    hidden = np.full_like(shown, np.nan)
    parts = int(meshes[1].metadata["parts"].max()) + 1
    colours = [np.array([0.6, 0.2, 0.1]), np.random.default_rng(4).uniform(0.1, 0.8, (parts, 3))]

    def renderer():
        r = Renderer(corridor_scene(model), camera, tex, clutter=meshes)
        r.set_lights(np.full((r.num_lights, 3), 6.0))
        r.set_camera(body @ camera.body_from_cam)
        return r

    direct = renderer()
    empty = direct.render(spp=1, seed=3)[1]
    direct.set_objects(shown, colours)
    want = direct.render(spp=1, seed=3)
    assert (want[1] == C.CLUTTER).mean() > 0.05 and not (empty == C.CLUTTER).any()

    again = renderer()
    again.set_objects(shown + [[0.5, -0.4, 1.0]], colours)
    again.render(spp=1, seed=3)
    again.set_objects(hidden, [c * 0.5 for c in colours])  # not set: hidden
    np.testing.assert_array_equal(again.render(spp=1, seed=3)[1], empty)
    again.set_objects(shown, colours)
    got = again.render(spp=1, seed=3)
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_allclose(got[2], want[2], atol=1e-5)
    assert np.abs(got[0].astype(int) - want[0]).max() <= 1
