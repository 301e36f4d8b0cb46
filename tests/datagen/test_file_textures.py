"""The file's own image textures (COLLADA through pycollada, glTF through trimesh): read with
their UVs, kept through the import, and drawn the right way round."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import trimesh

from core import classes as C
from core.config import compose_config
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyz_rpy
from datagen.appearance.textures import sample_textures
from datagen.importers import load_building
from datagen.importers.meshfile import Y_UP_TO_Z_UP
from datagen.job import make_camera
from datagen.worlds.scene import building_scene
from tests.datagen.building_files import open_room, write_dae

#: The poster's image: top-left red, top-right green, bottom-left blue, bottom-right white.
QUADRANTS = np.zeros((32, 32, 3), np.uint8)
QUADRANTS[:16, :16] = (255, 0, 0)
QUADRANTS[:16, 16:] = (0, 255, 0)
QUADRANTS[16:, :16] = (0, 0, 255)
QUADRANTS[16:, 16:] = (255, 255, 255)
#: A 1 x 1 m poster on the room's x = 4 wall facing -x (seen from inside, +y is on the left):
#: corners bottom-left, bottom-right, top-right, top-left, and their UVs (v up).
POSTER = np.array([[3.95, 2.0, 0.8], [3.95, 1.0, 0.8], [3.95, 1.0, 1.8], [3.95, 2.0, 1.8]])
POSTER_UV = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
POSTER_FACES = np.array([[0, 1, 2], [0, 2, 3]])


def room_parts() -> list[tuple[str, np.ndarray, np.ndarray]]:
    room = open_room()
    up = room.face_normals[:, 2] > 0.9
    return [(name, part.vertices, part.faces) for name, part in
            [("floor_tiles", room.submesh([up], append=True)),
             ("wall_paint", room.submesh([~up], append=True))]]


def write_collada(tmp_path):
    """room.dae (Z-up, metres): the room, its walls textured grey, and the poster."""
    cv2.imwrite(str(tmp_path / "quadrants.png"), cv2.cvtColor(QUADRANTS, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(tmp_path / "grey.png"), np.full((8, 8, 3), 128, np.uint8))
    pieces = [*room_parts(), ("poster_art", POSTER, POSTER_FACES)]
    walls = pieces[1][1]
    return write_dae(tmp_path / "room.dae", pieces, textures={
        "poster_art": ("quadrants.png", POSTER_UV),
        "wall_paint": ("grey.png", walls[:, :2] / 4.0)})


def write_gltf(tmp_path):
    """room.glb: the room and the poster (a baseColorTexture), Y-up as glTF is."""
    from PIL import Image

    scene = trimesh.Scene()
    for name, v, f in room_parts():
        scene.add_geometry(trimesh.Trimesh(v, f, process=False), node_name=name)
    poster = trimesh.Trimesh(POSTER, POSTER_FACES, process=False)
    poster.visual = trimesh.visual.TextureVisuals(
        uv=POSTER_UV, material=trimesh.visual.material.PBRMaterial(
            name="poster_art", baseColorTexture=Image.fromarray(QUADRANTS)))
    scene.add_geometry(poster, node_name="poster_art")
    scene.apply_transform(np.linalg.inv(Y_UP_TO_Z_UP))
    path = tmp_path / "room.glb"
    scene.export(path)
    return path


@pytest.fixture(scope="module", params=["dae", "glb"])
def building(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    path = write_collada(d) if request.param == "dae" else write_gltf(d)
    return request.param, load_building(path)


def poster_faces(b) -> np.ndarray:
    return np.array(["poster" in b.names[i] for i in b.face_name])


def test_textures_and_corner_uvs_are_imported(building):
    fmt, b = building
    poster = poster_faces(b)
    assert set(b.face_class[poster]) == {C.CLUTTER}
    k = b.face_texture[poster][0]
    assert (b.face_texture[poster] == k).all() and k >= 0
    img = b.textures[k]
    assert img.dtype == np.float32 and img.shape == (32, 32, 3)
    np.testing.assert_allclose(img[0, 0], [1, 0, 0], atol=1e-3)  # row 0 = top: red
    np.testing.assert_allclose(img[-1, 0], [0, 0, 1], atol=1e-3)
    # each corner's UV is the one written for its position
    corners = b.vertices[b.faces[poster]].reshape(-1, 3)
    want = POSTER_UV[np.argmin(np.linalg.norm(corners[:, None] - POSTER[None], axis=2), 1)]
    np.testing.assert_allclose(b.face_uv[poster].reshape(-1, 2), want, atol=1e-6)
    ceiling = b.face_class == C.CEILING  # added by the importer: no texture
    assert (b.face_texture[ceiling] == -1).all() and np.isnan(b.face_uv[ceiling]).all()
    assert len(b.textures) == (2 if fmt == "dae" else 1)


def test_structure_takes_the_file_look_only_when_asked(building):
    fmt, b = building
    free = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class, (0.5, 2.2), 0.3, 0.1)
    names = {s.name for s in building_scene(b, free).surfaces}
    k = b.face_texture[poster_faces(b)][0]
    assert f"clutter_image{k}" in names and "wall" in names
    scene = building_scene(b, free, file_look=True)
    if fmt == "dae":  # its walls have an image
        assert "wall" not in {s.name for s in scene.surfaces}
        assert any(s.name.startswith("wall_image") for s in scene.surfaces)
    assert set(scene.images) == {s.texture for s in scene.surfaces if s.texture in scene.images}


def test_the_poster_renders_the_right_way_round(building):
    """Seen from inside the room, the poster's image reads as it was drawn: red top left,
    green top right, blue bottom left, white bottom right."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    _, b = building
    free = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class, (0.5, 2.2), 0.3, 0.1)
    cfg = compose_config("datagen", ["camera.width=96", "camera.height=72"])
    camera = make_camera(cfg["camera"])
    tex = sample_textures(np.random.default_rng(0), 16, cfg["appearance"])
    r = Renderer(building_scene(b, free), camera, tex)
    r.set_lights(np.full((r.num_lights, 3), 20.0))
    r.set_camera(pose_from_xyz_rpy([1.0, 1.5, 1.3], [0, 0, 0])[0] @ camera.body_from_cam)
    rgb, label, _ = r.render(spp=8, seed=0)
    rows, cols = np.nonzero(label == C.CLUTTER)
    assert len(rows) > 100
    rm, cm = (rows.min() + rows.max()) / 2, (cols.min() + cols.max()) / 2
    inner = (np.abs(rows - rm) > 2) & (np.abs(cols - cm) > 2)  # away from the seams
    top, left = rows < rm, cols < cm
    mean = {q: rgb[rows[m & inner], cols[m & inner]].astype(float).mean(axis=0) for q, m in
            [("tl", top & left), ("tr", top & ~left), ("bl", ~top & left),
             ("br", ~top & ~left)]}
    assert np.argmax(mean["tl"]) == 0 and np.argmax(mean["tr"]) == 1, mean
    assert np.argmax(mean["bl"]) == 2 and mean["br"].min() > 0.6 * mean["br"].max(), mean
