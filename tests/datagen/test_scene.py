"""Scenes of any geometry: the corridor's (unchanged renders), an imported building's surfaces,
UVs, colours and lights, and a rendered imported room."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from core.config import compose_config
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyz_rpy
from datagen.appearance.textures import sample_textures
from datagen.importers import load_building
from datagen.job import make_camera
from datagen.worlds.corridor import build_world
from datagen.worlds.scene import (
    BUILDING_TEXTURE_EXTENT,
    DEFAULT_COLOUR,
    box_uv,
    building_scene,
    ceiling_above,
    corridor_scene,
    light_centres,
)
from tests import buildings
from tests.datagen import building_files as files
from tests.datagen.building_files import ROOM

CABINET_RGB = (0.8, 0.1, 0.1)


def write_room_world(tmp_path, light: bool = True):
    """worlds/room.world: the 4 x 3 x 2.5 m open room (COLLADA, metres; the importer adds its
    ceiling), a red 0.6 x 0.6 x 0.8 m cabinet at (3, 1.5) and a point light over the room's
    centre."""
    room = files.open_room()
    up = room.face_normals[:, 2] > 0.9
    pieces = [(name, part.vertices, part.faces) for name, part in
              [("floor_tiles", room.submesh([up], append=True)),
               ("wall_paint", room.submesh([~up], append=True))]]
    files.write_dae(tmp_path / "models" / "room" / "meshes" / "room.dae", pieces)
    files.write_model(tmp_path / "models", "room",
                      files.visual("<mesh><uri>model://room/meshes/room.dae</uri></mesh>"))
    cabinet = files.visual("<box><size>0.6 0.6 0.8</size></box>", name="cabinet").replace(
        "</geometry>", "</geometry><material><diffuse>{} {} {} 1</diffuse></material>".format(
            *CABINET_RGB), 1)
    bulb = '<light name="bulb" type="point"><pose>2 1.5 2.3 0 0 0</pose></light>'
    body = (f'<include><uri>model://room</uri></include>{bulb if light else ""}'
            f'<model name="cabinet"><pose>3 1.5 0.4 0 0 0</pose>{cabinet}</model>')
    return files.write_world(tmp_path / "worlds" / "room.world", body)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    """The imported room and its free space."""
    b = load_building(write_room_world(tmp_path_factory.mktemp("room")))
    free = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class, (0.5, 2.2), 0.3, 0.1)
    return b, free


# ---------------------------------------------------------------- surfaces, UVs, colours


def test_building_surfaces_by_class_with_box_uvs_and_file_colours(room):
    b, free = room
    scene = building_scene(b, free)
    by_name = {s.name: s for s in scene.surfaces}
    assert set(by_name) == {"floor", "wall", "ceiling", "clutter_colour"}
    assert sum(len(s.vertices) for s in scene.surfaces) == 3 * len(b.faces)
    for s in scene.surfaces:
        assert s.class_id == C.ID[s.name.split("_")[0]] and s.uv.shape == (len(s.vertices), 2)
        assert (s.colour is None) == (s.name != "clutter_colour")
    np.testing.assert_allclose(by_name["clutter_colour"].colour, np.tile(CABINET_RGB, (36, 1)))
    assert by_name["wall"].texture == "wall" and by_name["floor"].texture == "floor"
    # floors: u = x, v = y in texture repeats
    floor = by_name["floor"]
    np.testing.assert_allclose(floor.uv, floor.vertices[:, :2] / BUILDING_TEXTURE_EXTENT["floor"])
    # walls: v from the floor up, in repeats of the wall texture's height
    wall = by_name["wall"]
    np.testing.assert_allclose(wall.uv[:, 1], wall.vertices[:, 2] / 2.8, atol=1e-9)


def test_colourless_faces_get_the_default_colour(room):
    b, free = room
    b2 = type(b)(**{**vars(b), "face_colour": np.full_like(b.face_colour, np.nan)})
    clutter = next(s for s in building_scene(b2, free).surfaces if s.name == "clutter_colour")
    np.testing.assert_allclose(clutter.colour, np.tile(DEFAULT_COLOUR, (36, 1)))


@pytest.mark.parametrize("normal", [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)])
def test_box_uv_reads_left_to_right_from_the_front(normal):
    """On a wall facing ``normal``, u grows to the viewer's right (1 per extent) and v up from
    v0, whichever way the wall faces."""
    n = np.array(normal, float)
    right = -np.cross(n, [0, 0, 1])  # the viewer looks along -n
    base = np.array([5.0, 5.0, 0.0])
    tri = np.array([base, base + right, base + [0, 0, 1]])
    if np.cross(tri[1] - tri[0], tri[2] - tri[0]) @ n < 0:
        tri = tri[[0, 2, 1]]
    uv = box_uv(tri[None], (2.0, 2.5), v0=-0.5)[0]
    du = {tuple(p): u for p, (u, _) in zip(tri, uv, strict=True)}
    assert du[tuple(base + right)] - du[tuple(base)] == pytest.approx(0.5)
    np.testing.assert_allclose(uv[:, 1], (tri[:, 2] + 0.5) / 2.5)


# ---------------------------------------------------------------- lights


def test_lights_from_the_file_go_under_the_ceiling(room):
    b, free = room
    assert b.info["lights"] == [[2.0, 1.5, 2.3]]
    lights = building_scene(b, free).lights
    assert lights.shape == (1, 4, 3)
    np.testing.assert_allclose(lights[0].mean(axis=0), [2, 1.5, ROOM[2] - 0.01])
    # emits downwards: the right-hand normal of the quad's triangles points down
    q = lights[0]
    assert np.cross(q[1] - q[0], q[2] - q[0])[2] < 0
    b2 = type(b)(**{**vars(b), "info": {**b.info, "lights": [[2.0, 1.5, 4.0], [9, 9, 2]]}})
    np.testing.assert_allclose(building_scene(b2, free).lights.mean(axis=1),
                               [[2, 1.5, ROOM[2] - 0.01], [9, 9, 2]])  # (9, 9): no ceiling


def test_lattice_lights_under_the_ceiling_over_the_free_space(room):
    b, free = room
    lights = building_scene(b, free, light_spacing=1.5, file_lights=False).lights
    centres = lights.mean(axis=1)
    assert len(lights) >= 2
    assert free.contains(centres[:, :2]).all()
    np.testing.assert_allclose(centres[:, 2], 2.49)


def test_light_centres_follow_corridors_and_cover_the_free_space():
    """On a 2 m wide ring corridor: the lights sit on the centre line, 3 m apart or more, and
    every free cell is within 3 m of one."""
    free = buildings.occupancy("ring")
    xy = light_centres(free, 3.0)
    assert free.distance(xy).min() >= 0.9  # the centre line: 1 m from both walls
    cells = free.centres(np.array(np.nonzero(free.free)))
    nearest = np.min(np.linalg.norm(cells[:, None] - xy[None], axis=2), axis=1)
    assert nearest.max() < 3.0
    apart = np.linalg.norm(xy[:, None] - xy[None], axis=2) + 9 * np.eye(len(xy))
    assert apart.min() >= 3.0
    assert 32 / 6 <= len(xy) <= 32 / 3  # the centre line is 32 m long: 3-6 m apart


def test_no_lattice_light_without_a_ceiling():
    v, f, c = buildings.ring()
    free = buildings.occupancy("ring")
    up = np.array([[5.0, 1.0, 2.2], [1.0, 5.0, 2.2]])
    assert np.isnan(ceiling_above(v, f, up)).all()
    v, f, c = buildings.with_ceiling((v, f, c))
    np.testing.assert_allclose(ceiling_above(v, f, up), buildings.HEIGHT)
    with pytest.raises(ValueError, match="light_spacing"):
        light_centres(free, 0.0)


# ---------------------------------------------------------------- rendering


@pytest.fixture(scope="module")
def room_view(room):
    """A 64x48 render (4 spp) from (0.8, 1.5, 1.2) looking +x at the far wall and the
    cabinet."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    b, free = room
    cfg = compose_config("datagen", ["camera.width=64", "camera.height=48"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    r = Renderer(building_scene(b, free), camera, tex)
    r.set_lights(np.full((r.num_lights, 3), 20.0))
    world_from_cam = pose_from_xyz_rpy([0.8, 1.5, 1.2], [0, 0, 0])[0] @ camera.body_from_cam
    r.set_camera(world_from_cam)
    return (*r.render(spp=4, seed=0), world_from_cam[0, 3])


def test_room_render_labels_match_the_faces_seen(room_view):
    rgb, label, depth, cam_x = room_view
    H, W = label.shape
    assert set(np.unique(label)) <= {C.FLOOR, C.WALL, C.CEILING, C.CLUTTER}
    mid = label[H // 2 - 4: H // 2, W // 4: 3 * W // 4]  # just above the horizon: far wall
    assert (mid == C.WALL).mean() > 0.95
    np.testing.assert_allclose(np.median(depth[H // 2 - 4: H // 2, W // 2]), ROOM[0] - cam_x,
                               atol=0.02)
    assert (label[-1] == C.FLOOR).mean() > 0.5 and (label[0] == C.CEILING).mean() > 0.5
    assert (label == C.CLUTTER).sum() > 40  # the cabinet, below the horizon
    assert rgb.mean() > 20  # the light lights the room


def test_room_render_draws_clutter_in_its_file_colour(room_view):
    rgb, label, _, _ = room_view
    cabinet = rgb[label == C.CLUTTER].astype(float).mean(axis=0)
    assert cabinet[0] > 2 * cabinet[1] and cabinet[0] > 2 * cabinet[2], cabinet


def test_corridor_render_unchanged():
    """A fixed corridor view renders as before ``Scene`` existed (figures recorded with the
    renderer that read the CorridorModel). 1 sRGB level is allowed on the mean colour: LLVM
    compiles the renderer for the CPU's vector width, and an AVX2 CPU's mean differs by up to
    0.8 level from the AVX-512 one the figures were recorded on."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    cfg = compose_config("datagen", ["camera.width=96", "camera.height=72"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 32, cfg["appearance"])
    r = Renderer(corridor_scene(build_world(cfg["world"])), camera, tex)
    r.set_lights(np.full((r.num_lights, 3), 6.0))
    body = pose_from_xyz_rpy([0.25, 0.8, 1.3], [0.0, -0.05, np.pi / 2 + 0.25])[0]
    r.set_camera(body @ camera.body_from_cam)
    rgb, label, depth = r.render(spp=4, seed=0)
    assert np.bincount(label.ravel(), minlength=8).tolist() == CORRIDOR_LABELS
    np.testing.assert_allclose(rgb.reshape(-1, 3).mean(axis=0), CORRIDOR_RGB, atol=1.0)
    assert float(depth.mean()) == pytest.approx(CORRIDOR_DEPTH, abs=1e-4)


CORRIDOR_LABELS = [0, 786, 4118, 993, 781, 234, 0, 0]  # pixels per class
CORRIDOR_RGB = [95.184, 100.76, 100.023]  # mean sRGB
CORRIDOR_DEPTH = 3.39807  # m, mean z


def test_near_lights_sampling_is_unbiased_and_skips_lights_off(room):
    """Weighting the lights by radiance / distance^2 keeps the mean radiance, and a light that
    is off is never sampled."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    b, free = room
    scene = building_scene(b, free, light_spacing=1.0, file_lights=False)
    cfg = compose_config("datagen", ["camera.width=32", "camera.height=24"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    means = []
    radiance = np.full((scene.num_lights, 3), 10.0)
    radiance[0] = 0.0
    for near in (False, True):
        r = Renderer(scene, camera, tex, near_lights=near)
        r.set_lights(radiance)
        r.set_camera(pose_from_xyz_rpy([0.8, 1.5, 1.2], [0, 0, 0])[0] @ camera.body_from_cam)
        means.append(r.trace(spp=64, seed=1, albedo=False).rgb.mean())
    assert scene.num_lights >= 4
    assert means[1] == pytest.approx(means[0], rel=0.03)
    assert r.params["light0.emitter.sampling_weight"] == 0.0
    assert r.params["light1.emitter.sampling_weight"] > 0.0
