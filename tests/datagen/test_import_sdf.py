"""Gazebo SDF import: includes, nested models and poses, COLLADA with <unit>, primitives,
name rules, the open-top ceiling, missing models."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from core import classes as C
from datagen.importers import load_building
from datagen.importers.meshfile import Y_UP_TO_Z_UP
from tests.datagen.building_files import (
    ROOM,
    open_room,
    visual,
    write_dae,
    write_model,
    write_world,
)

WINDOW_RGB = (0.2, 0.6, 0.9)


def room_pieces() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The 4 x 3 x 2.5 m open room in centimetres as pieces named by material, with a door
    frame on the y = 0 wall and a window pane on the x = 4 wall."""
    room = open_room()
    up = room.face_normals[:, 2] > 0.9
    floor = room.submesh([up], append=True)
    walls = room.submesh([~up], append=True)
    frame = np.array([[1.0, 0.01, 0.0], [2.0, 0.01, 0.0], [2.0, 0.01, 2.1], [1.0, 0.01, 2.1]])
    pane = np.array([[3.99, 1.0, 1.0], [3.99, 1.0, 2.0], [3.99, 2.0, 2.0], [3.99, 2.0, 1.0]])
    quad = np.array([[0, 2, 1], [0, 3, 2]])
    return [("floor_tiles", floor.vertices, floor.faces), ("wall_paint", walls.vertices,
            walls.faces), ("doorframe_wood", frame, quad), ("window_glass", pane, quad)]


def write_room_model(models):
    """model://room: the room as a COLLADA file in cm, geometry Y-up under a node matrix
    that turns it Z-up (as the AWS hospital's files are)."""
    to_y_up = np.linalg.inv(Y_UP_TO_Z_UP)[:3, :3]
    pieces = [(n, 100 * v @ to_y_up.T, f) for n, v, f in room_pieces()]
    write_dae(models / "room" / "meshes" / "room.dae", pieces, unit=0.01, matrix=Y_UP_TO_Z_UP,
              colours={"window_glass": WINDOW_RGB})
    write_model(models, "room", visual("<mesh><uri>model://room/meshes/room.dae</uri></mesh>"))


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """SDF's rotation: Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


NESTED = """
<model name="outer"><pose>1 2 0 0 0 1.5707963267948966</pose>
  <model name="inner"><pose>1 0 0.5 0 0 0</pose>
    <link name="link"><pose>0 1 0 0 0 0</pose>
      <visual name="cube"><pose>0 0 1 0 0 0</pose>
        <geometry><box><size>0.2 0.2 0.2</size></box></geometry></visual></link></model>
</model>
<model name="tilted"><static>true</static>
  <link name="link"><visual name="bar"><pose>5 5 1 0.3 0.2 0.5</pose>
    <geometry><box><size>1 0.2 0.1</size></box></geometry></visual></link></model>
"""


@pytest.fixture()
def world(tmp_path):
    """worlds/test.world (two rooms, a nested model, a tilted bar, two missing includes) and
    its ../models."""
    write_room_model(tmp_path / "models")
    body = f"""
    <include><uri>model://room</uri><pose>10 0 0 0 0 0</pose></include>
    <model name="wrapper"><include><uri>model://room</uri><name>room2</name>
      <pose>0 20 0 0 0 1.5707963267948966</pose></include></model>
    <include><uri>model://NotHere</uri></include>
    <include><uri>model://NotHere</uri><pose>1 1 0 0 0 0</pose></include>
    {NESTED}"""
    return write_world(tmp_path / "worlds" / "test.world", body)


def faces_named(b, pattern: str) -> np.ndarray:
    """Mask of the faces whose name contains ``pattern``."""
    hit = np.array([pattern in n for n in b.names])
    return hit[b.face_name]


def test_world_includes_poses_units_and_classes(world, caplog):
    with caplog.at_level(logging.WARNING):
        b = load_building(world)
    assert b.info["format"] == "sdf"
    assert b.info["missing_models"] == {"NotHere": 2}
    assert sum("not found" in r.getMessage() for r in caplog.records) == 1
    # room 1: cm -> m, Y-up geometry turned Z-up by its node matrix, at x + 10
    r1 = faces_named(b, "room/link") & ~faces_named(b, "room2")
    v = b.vertices[b.faces[r1]].reshape(-1, 3)
    np.testing.assert_allclose(v.min(axis=0), [10, 0, 0], atol=1e-5)
    np.testing.assert_allclose(v.max(axis=0), [14, 3, 2.5], atol=1e-5)
    # room 2: included under a wrapper model, named room2, turned 90 deg: (x, y) -> (-y, x)
    v = b.vertices[b.faces[faces_named(b, "wrapper/room2/link")]].reshape(-1, 3)
    np.testing.assert_allclose(v.min(axis=0), [-3, 20, 0], atol=1e-5)
    np.testing.assert_allclose(v.max(axis=0), [0, 24, 2.5], atol=1e-5)
    # nested model, link and visual poses compose
    cube = b.vertices[np.unique(b.faces[faces_named(b, "outer/inner/link/cube")])]
    np.testing.assert_allclose(cube.mean(axis=0), [0, 3, 1.5], atol=1e-6)
    # roll, pitch, yaw as SDF defines them
    bar = b.vertices[np.unique(b.faces[faces_named(b, "tilted/link/bar")])]
    corners = np.array(np.meshgrid([-0.5, 0.5], [-0.1, 0.1], [-0.05, 0.05])).reshape(3, -1).T
    want = corners @ rpy_matrix(0.3, 0.2, 0.5).T + [5, 5, 1]
    np.testing.assert_allclose(np.sort(bar, axis=0), np.sort(want, axis=0), atol=1e-6)
    # the collision boxes (50 m) are not imported
    assert np.ptp(b.vertices[:, 0]) < 20


def test_world_name_rules_colours_and_auto_ceiling(world):
    b = load_building(world)
    for name, cls in [("floor_tiles", C.FLOOR), ("wall_paint", C.WALL),
                      ("doorframe_wood", C.DOOR), ("window_glass", C.WINDOW)]:
        assert set(b.face_class[faces_named(b, name)]) == {cls}, name
    np.testing.assert_allclose(b.face_colour[faces_named(b, "window_glass")],
                               np.tile(WINDOW_RGB, (4, 1)), atol=1e-6)
    assert np.isnan(b.face_colour[faces_named(b, "/box")]).all()
    # open top: a ceiling over each room's floor at the walls' height, facing down
    ceiling = faces_named(b, "auto_ceiling")
    assert b.info["ceiling_added"] == ceiling.sum() > 0
    assert (b.face_class[ceiling] == C.CEILING).all()
    tri = b.vertices[b.faces[ceiling]]
    np.testing.assert_allclose(tri[:, :, 2], 2.5, atol=1e-9)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (normal[:, 2] < 0).all()
    area = np.linalg.norm(normal, axis=1).sum() / 2
    assert area == pytest.approx(2 * ROOM[0] * ROOM[1])
    assert b.info["floor_z"] == pytest.approx(0.0)
    assert set(b.info["class_shares"]) >= {"floor", "wall", "ceiling", "door", "window"}
    assert sum(b.info["class_shares"].values()) == pytest.approx(1.0, abs=1e-3)
    # ceiling: none keeps the sky
    assert not faces_named(load_building(world, {"ceiling": "none"}), "auto_ceiling").any()


def test_model_search_path(tmp_path, monkeypatch):
    elsewhere = tmp_path / "lib"
    write_room_model(elsewhere)
    world = write_world(tmp_path / "w" / "a.world",
                        "<include><uri>model://room</uri></include>")
    b = load_building(world, {"model_path": [str(elsewhere)]})
    assert not b.info["missing_models"]
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(elsewhere))
    assert len(load_building(world).faces) == len(b.faces)
    monkeypatch.delenv("GAZEBO_MODEL_PATH")
    with pytest.raises(ValueError, match="no triangles"):
        load_building(world)  # the only model is missing


def test_model_sdf_and_mesh_scale(tmp_path):
    folder = tmp_path / "models"
    write_room_model(folder)
    write_model(folder, "big", visual("<mesh><uri>model://room/meshes/room.dae</uri>"
                                      "<scale>2 0.5 1</scale></mesh>"))
    b = load_building(folder / "big" / "model.sdf")
    np.testing.assert_allclose(b.vertices.max(axis=0), [8, 1.5, 2.5], atol=1e-5)


PRIMITIVES = """
<include><uri>model://ground_plane</uri></include>
<model name="ground_plane"><link name="link"><visual name="v"><geometry>
  <plane><normal>0 0 1</normal><size>100 100</size></plane></geometry></visual></link></model>
<model name="blocks"><link name="link">
  <visual name="north"><pose>3 6 1.25 0 0 0</pose><geometry><box><size>6 0.2 2.5</size></box>
    </geometry></visual>
  <visual name="south"><pose>3 0 1.25 0 0 0</pose><geometry><box><size>6 0.2 2.5</size></box>
    </geometry></visual>
  <visual name="pillar"><pose>2 3 1.25 0 0 0</pose><geometry><cylinder><radius>0.25</radius>
    <length>2.5</length></cylinder></geometry></visual>
  <visual name="ball"><pose>4 3 1 0 0 0</pose><geometry><sphere><radius>0.3</radius></sphere>
    </geometry><material><diffuse>1 0 0 1</diffuse></material></visual></link></model>
"""


def test_primitives_and_ground_plane(tmp_path):
    b = load_building(write_world(tmp_path / "p.world", PRIMITIVES))
    assert b.info["missing_models"] == {"ground_plane": 1}  # not installed here
    floor = b.face_class == C.FLOOR
    plane = faces_named(b, "ground_plane/link/v/plane")
    v = b.vertices[b.faces[plane]].reshape(-1, 3)
    np.testing.assert_allclose(v.min(axis=0), [0, -0.1, 0])  # cut to the blocks' extent
    np.testing.assert_allclose(v.max(axis=0), [6, 6.1, 0])
    assert floor[plane].all()
    pillar = b.vertices[np.unique(b.faces[faces_named(b, "pillar/cylinder")])]
    radius = np.hypot(pillar[:, 0] - 2, pillar[:, 1] - 3)
    np.testing.assert_allclose(radius[radius > 1e-9], 0.25, atol=1e-9)  # and the caps' centres
    np.testing.assert_allclose([pillar[:, 2].min(), pillar[:, 2].max()], [0, 2.5], atol=1e-9)
    ball = b.vertices[np.unique(b.faces[faces_named(b, "ball/sphere")])]
    np.testing.assert_allclose(np.linalg.norm(ball - [4, 3, 1], axis=1), 0.3, atol=1e-9)
    assert (b.face_colour[faces_named(b, "ball/sphere")] == [1, 0, 0]).all()
    # geometry rules: box tops (up, 2.5 m) are wall, box bottoms (down) ceiling-facing
    assert (b.face_class[faces_named(b, "north/box")] != C.FLOOR).all()


def test_world_errors(tmp_path):
    with pytest.raises(ValueError, match="no floor"):
        load_building(write_world(tmp_path / "walls.world", """<model name="m"><link name="l">
            <visual name="v"><pose>0 0 1.25 0 0 0</pose><geometry><box><size>6 0.2 2.5</size>
            </box></geometry></visual></link></model>"""))
    bad = tmp_path / "bad.world"
    bad.write_text("<sdf><world><model name='x'></world></sdf>")
    with pytest.raises(ValueError, match="not well-formed"):
        load_building(bad)
    other = tmp_path / "other.sdf"
    other.write_text("<robot name='r'/>")
    with pytest.raises(ValueError, match="not <sdf>"):
        load_building(other)
    pose = write_world(tmp_path / "pose.world", "<model name='m'><pose>1 2</pose></model>")
    with pytest.raises(ValueError, match="pose"):
        load_building(pose)


def test_model_config_not_well_formed(tmp_path):
    """A bare & in model.config (as in the AWS hospital's elevator) still finds its SDF."""
    folder = write_model(tmp_path / "models", "lift", "")
    (folder / "model.sdf").unlink()
    (folder / "lift.sdf").write_text(
        '<sdf version="1.6"><model name="lift">' + visual(
            "<box><size>1 1 1</size></box>", "0 0 0.5 0 0 0") + "</model></sdf>")
    (folder / "model.config").write_text(
        '<?xml version="1.0"?><model><name>lift</name><sdf version="1.6">lift.sdf</sdf>'
        "<description>portal, door & car</description></model>")
    world = write_world(tmp_path / "worlds" / "a.world",
                        "<include><uri>model://lift</uri></include><model name='g'>"
                        + visual("<plane><size>4 4</size></plane>") + "</model>")
    b = load_building(world)
    assert not b.info["missing_models"]
    np.testing.assert_allclose(b.vertices.max(axis=0), [0.5, 0.5, 1.0])


def test_lights(tmp_path):
    """Point and spot lights of the world and of links (poses composed) are kept as positions;
    directional ones (a world's own and an included sun) are counted only."""
    write_room_model(tmp_path / "models")
    sun = tmp_path / "models" / "sun"
    sun.mkdir()
    (sun / "model.sdf").write_text('<?xml version="1.0"?><sdf version="1.6"><light name="sun" '
                                   'type="directional"><pose>0 0 10 0 0 0</pose></light></sdf>')
    body = """
    <include><uri>model://room</uri></include>
    <include><uri>model://sun</uri></include>
    <light name="bulb" type="point"><pose>1 1.5 2.3 0 0 0</pose></light>
    <light name="sky" type="directional"><pose>0 0 5 0 0 0</pose></light>
    <model name="lamp"><pose>2 0 0 0 0 1.5707963267948966</pose>
      <link name="link"><pose>1 0 0 0 0 0</pose>
        <light name="spot" type="spot"><pose>0 0 2 0 0 0</pose></light></link></model>"""
    b = load_building(write_world(tmp_path / "worlds" / "lights.world", body))
    np.testing.assert_allclose(b.info["lights"], [[1, 1.5, 2.3], [2, 1, 2]], atol=1e-9)
    assert b.info["directional_lights"] == 2
