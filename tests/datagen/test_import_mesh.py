"""Single mesh files (glTF, OBJ, PLY, STL, DAE), name rules, the geometry fallback and bad
input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from core import classes as C
from datagen.importers import ImportConfig, NameRule, load_building
from datagen.importers.classify import name_classes
from datagen.importers.meshfile import Y_UP_TO_Z_UP
from tests.datagen.building_files import ROOM, open_room, write_dae

DOOR_RGBA = (0.8, 0.4, 0.1, 1.0)


def named(mesh: trimesh.Trimesh, name: str, rgba=(0.7, 0.7, 0.7, 1.0)) -> trimesh.Trimesh:
    mesh = mesh.copy()
    mesh.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(name=name, baseColorFactor=rgba))
    return mesh


def test_gltf_is_y_up_metres_with_material_names(tmp_path):
    door = trimesh.creation.box(extents=[0.9, 0.05, 2.1])
    door.apply_translation([2.0, 0.05, 1.05])
    table = trimesh.creation.box(extents=[1.0, 0.6, 0.05])
    table.apply_translation([1.0, 1.5, 0.75])
    scene = trimesh.Scene()
    scene.add_geometry(named(open_room(), "plaster"), node_name="shell")
    scene.add_geometry(named(door, "oak_door", DOOR_RGBA), node_name="entrance")
    scene.add_geometry(named(table, "top"), node_name="desk_1")
    scene.apply_transform(np.linalg.inv(Y_UP_TO_Z_UP))  # glTF is Y-up
    path = tmp_path / "room.glb"
    scene.export(path)
    b = load_building(path, {"units": 100.0, "up_axis": "z"})  # both ignored for glTF
    np.testing.assert_allclose(b.vertices.min(axis=0), [0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(b.vertices.max(axis=0), [4, 3, 2.5], atol=1e-6)
    by_name = {n: b.face_class[b.face_name == i] for i, n in enumerate(b.names)}
    door_cls = next(v for n, v in by_name.items() if "oak_door" in n)
    assert set(door_cls) == {C.DOOR}
    desk = next(v for n, v in by_name.items() if "desk" in n)
    assert set(desk) == {C.CLUTTER}
    door_rgb = b.face_colour[b.face_name == b.names.index(
        next(n for n in b.names if "oak_door" in n))]
    np.testing.assert_allclose(door_rgb, np.tile(DOOR_RGBA[:3], (len(door_rgb), 1)), atol=0.01)
    assert b.info["format"] == "glb" and b.info["up_axis"] == "+y"
    assert b.info["up_axis_from"] == "format"


def obj_text(mesh: trimesh.Trimesh) -> str:
    v = "\n".join(f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices)
    f = "\n".join(f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces)
    return f"o shell\n{v}\n{f}\n"


def test_obj_units_and_up_axis(tmp_path):
    room = open_room()
    room.apply_transform(np.linalg.inv(Y_UP_TO_Z_UP))
    room.apply_scale(1000.0)  # millimetres, Y up
    path = tmp_path / "room.obj"
    path.write_text(obj_text(room))
    b = load_building(path, {"units": 0.001, "up_axis": "y"})
    np.testing.assert_allclose(b.vertices.min(axis=0), [0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(b.vertices.max(axis=0), ROOM, atol=1e-6)
    assert b.info["units"] == 0.001
    # geometry fallback: the name "shell" matches no rule
    assert set(b.face_class) == {C.FLOOR, C.WALL, C.CEILING}
    assert b.info["ceiling_added"] > 0
    assert b.info["up_axis"] == "+y" and b.info["up_axis_from"] == "setting"
    found = load_building(path, {"units": 0.001})  # up_axis: auto
    assert found.info["up_axis"] == "+y" and found.info["up_axis_from"] == "auto"
    np.testing.assert_allclose(found.vertices.max(axis=0), ROOM, atol=1e-6)
    on_side = load_building(path, {"units": 0.001, "up_axis": "z"})  # the room on its side
    np.testing.assert_allclose(on_side.vertices.max(axis=0) - on_side.vertices.min(axis=0),
                               [4, 2.5, 3], atol=1e-6)


@pytest.mark.parametrize("ext", [".ply", ".stl"])
def test_ply_stl(tmp_path, ext):
    path = tmp_path / f"room{ext}"
    open_room().export(path)
    b = load_building(path)
    np.testing.assert_allclose(b.vertices.max(axis=0), ROOM, atol=1e-5)
    assert {C.FLOOR, C.WALL, C.CEILING} <= set(b.face_class)


def test_dae_single_file_unit(tmp_path):
    room = open_room()
    path = write_dae(tmp_path / "room.dae", [("shell", room.vertices * 100,
                                              room.faces)], unit=0.01)
    b = load_building(path)
    np.testing.assert_allclose(b.vertices.max(axis=0), ROOM, atol=1e-5)
    assert b.info["units"] == 0.01


def test_geometry_fallback(tmp_path):
    table = trimesh.creation.box(extents=[1.0, 0.6, 0.05])
    table.apply_translation([1.0, 1.5, 0.75])
    mesh = trimesh.util.concatenate([open_room(), table])
    path = tmp_path / "plain.ply"
    mesh.export(path)
    b = load_building(path, {"name_rules": []})
    z = b.vertices[b.faces][:, :, 2].mean(axis=1)
    up = np.cross(*(b.vertices[b.faces[:, 1:]] - b.vertices[b.faces[:, :1]]).transpose(1, 0, 2)
                  )[:, 2] > 0
    assert (b.face_class[(z < 0.01) & up] == C.FLOOR).all()
    table_top = (np.abs(z - 0.775) < 1e-6)
    assert (b.face_class[table_top] == C.WALL).all()  # up-facing but not near the floor
    assert (b.face_class[np.abs(z - 0.725) < 1e-6] == C.CEILING).all()  # its underside
    assert b.info["floor_z"] == pytest.approx(0.0)


def test_name_rules():
    rules = ImportConfig().name_rules
    names = ["hospital_floor_01_walls/aws_robomaker_hospital_floor_01_doorframes_big",
             "hospital_floor_01_walls/aws_robomaker_hospital_floor_01_doorsign",
             "hospital_floor_01_walls/aws_robomaker_hospital_floor_01_walls",
             "hospital_floor_01_ceiling/link/visual/hospital_floor_01_ceiling",
             "hospital_floor_01_floor/link/visual/hospital_floor_01_floor",
             "Window_Glass", "KitchenCabinet_01/link/visual/Material", "mesh0"]
    want = [C.DOOR, C.CLUTTER, C.WALL, C.CEILING, C.FLOOR, C.WINDOW, C.CLUTTER, 255]
    assert name_classes(names, rules).tolist() == want
    custom = [NameRule("^mesh", "floor")]
    assert name_classes(names, custom).tolist() == [255] * 7 + [C.FLOOR]
    with pytest.raises(ValueError, match=r"name_rules\[0\].cls"):
        name_classes(names, [NameRule("x", "roof")])
    with pytest.raises(ValueError, match=r"name_rules\[0\].pattern"):
        name_classes(names, [NameRule("(", "wall")])


def test_bad_input(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_building(tmp_path / "nothing.obj")
    odd = tmp_path / "model.xyz"
    odd.write_text("1 2 3\n")
    with pytest.raises(ValueError, match="unknown extension '.xyz'"):
        load_building(odd)
    with pytest.raises(ValueError, match="up_axis"):
        load_building(odd, {"up_axis": "sideways"})
    with pytest.raises(ValueError, match="units"):
        load_building(odd, {"units": 0.0})
    with pytest.raises(ValueError, match="world.unknown"):
        load_building(odd, {"unknown": 1})
    broken = tmp_path / "broken.glb"
    broken.write_bytes(b"not a glb")
    with pytest.raises(ValueError, match="broken.glb"):
        load_building(broken)
    path = tmp_path / "walls.stl"
    wall = trimesh.creation.box(extents=[4, 0.2, 2.5])
    wall.apply_translation([2, 0, 1.25])
    wall.export(path)
    with pytest.raises(ValueError, match="no floor"):
        load_building(path)
