"""A face's class from the evidence together (the most specific name first, geometry over a
name), the up axis found by itself, relative Gazebo mesh URIs, parts far from the rest and
the import summary's flags: synthetic models, fast."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from core import classes as C
from datagen.importers import load_building
from datagen.importers.classify import name_evidence
from datagen.importers.config import default_name_rules
from datagen.importers.orient import AXES, find_up_axis, to_z_up
from datagen.importers.summary import import_summary, unit_guess, vertical_edges
from tests.datagen.building_files import open_room, write_dae, write_model, write_world

INCH = 0.0254
SIZE = (8.0, 6.0, 2.7)  # m, the office room


def quad(x0, y0, x1, y1, z, up: bool) -> tuple[np.ndarray, np.ndarray]:
    """A horizontal rectangle at height z, facing up or down."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]]) if up else np.array([[0, 2, 1], [0, 3, 2]])
    return v, f


def office_pieces() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """A SketchUp-like room in metres, pieces named by material: half the floor carpet, half
    a nameless material, walls in a nameless colour, a nameless ceiling, a door threshold."""
    sx, sy, h = SIZE
    room = open_room(SIZE)
    walls = room.submesh([room.face_normals[:, 2] < 0.5], append=True)
    return [("Carpet_Loop_Gray", *quad(0, 0, sx / 2, sy, 0.0, True)),
            ("Material_7", *quad(sx / 2, 0, sx, sy, 0.0, True)),
            ("Color_A01", walls.vertices, walls.faces),
            ("Material_12", *quad(0, 0, sx, sy, h, False)),
            ("Door_Frame", *quad(3.0, 0.0, 3.9, 0.1, 0.01, True))]


def sketchup_world(root, pieces=None, uri: str = "model://office/meshes/office.dae"):
    """repo/worlds/office.world including model://office: one link ``walls`` whose COLLADA
    (in inches, ``<unit meter=0.0254>``) holds the floor, the walls and the ceiling."""
    pieces = office_pieces() if pieces is None else pieces
    inches = [(n, v / INCH, f) for n, v, f in pieces]
    write_dae(root / "models" / "office" / "meshes" / "office.dae", inches, unit=INCH)
    write_model(root / "models", "office",
                f'<static>true</static><link name="walls"><visual name="visual"><geometry>'
                f'<mesh><uri>{uri}</uri></mesh></geometry></visual></link>')
    return write_world(root / "worlds" / "office.world",
                       "<include><uri>model://office</uri></include>")


def classes_of(b, material: str) -> set[int]:
    return set(b.face_class[np.array([material in n for n in b.names])[b.face_name]].tolist())


def test_sketchup_room_in_inches_imports_with_the_defaults(tmp_path):
    """The link ``walls`` names every face; the material decides where it says something
    (carpet: floor), geometry where the surface is plainly floor or ceiling."""
    b = load_building(sketchup_world(tmp_path))
    assert classes_of(b, "Carpet_Loop_Gray") == {C.FLOOR}  # the material before the link
    assert classes_of(b, "Material_7") == {C.FLOOR}  # geometry over the link's name
    assert classes_of(b, "Material_12") == {C.CEILING}  # down-facing at the top
    assert classes_of(b, "Color_A01") == {C.WALL}
    assert classes_of(b, "Door_Frame") == {C.DOOR}  # small: the name stays
    assert b.info["classed_by"]["geometry_over_name"] == 4
    np.testing.assert_allclose(b.vertices.max(axis=0), SIZE, atol=1e-4)  # <unit> applied
    assert b.info["floor_z"] == pytest.approx(0.0, abs=1e-6)
    assert b.info["wall_top_z"] == pytest.approx(SIZE[2], abs=1e-4)
    assert b.info["ceiling_added"] == 0
    s = import_summary(b, free_area_m2=30.0, vertical=4)
    assert s["flags"] == [] and s["wall_height_m"] == pytest.approx(2.7)


def test_name_evidence_most_specific_part_first():
    rules = default_name_rules()
    names = ["office/walls/visual/geometry0/Carpet_Loop_Gray",
             "office/walls/visual/geometry0/Material_7",
             "KitchenCabinet_01/link/visual/Material",
             "hospital_floor_01_walls/link/visual/ID43/hospital_floor_01_walls",
             "hospital_floor_01_walls/link/visual/ID106/hospital_floor_01_doorsign",
             "DoorB_01/link/visual/mesh/WorldGridMaterial", "mesh0"]
    cls, depth = name_evidence(names, rules)
    assert cls.tolist() == [C.FLOOR, C.WALL, C.CLUTTER, C.WALL, C.CLUTTER, C.DOOR, 255]
    assert depth.tolist() == [0, 3, 3, 0, 0, 4, -1]


def furnished_room(floor_seen: float = 1.0, ceiling: bool = True) -> trimesh.Trimesh:
    """A 5 x 4 x 2.5 m room, Z up: walls, the floor (only ``floor_seen`` of its length, as a
    scan that missed it under furniture sees it: less than the ceiling), a ceiling, a desk
    top at 0.75 m and a shelf block standing on the floor."""
    room = open_room((5.0, 4.0, 2.5))
    walls = room.submesh([room.face_normals[:, 2] < 0.5], append=True)
    parts = [walls, trimesh.Trimesh(*quad(0, 0, 5 * floor_seen, 4, 0.0, True), process=False)]
    if ceiling:
        parts.append(trimesh.Trimesh(*quad(0, 0, 5, 4, 2.5, False), process=False))
    desk = trimesh.Trimesh(*quad(1.0, 1.0, 2.6, 1.8, 0.75, True), process=False)
    shelf = trimesh.creation.box(extents=[1.0, 0.4, 1.2])
    shelf.apply_translation([3.5, 3.6, 0.6])
    return trimesh.util.concatenate([*parts, desk, shelf])


@pytest.mark.parametrize("axis", AXES)
@pytest.mark.parametrize("floor_seen, ceiling", [(1.0, False), (1.0, True), (0.6, True)])
def test_up_axis_found(axis, floor_seen, ceiling):
    """Any of the six axes, without a ceiling, with one, and with a ceiling larger than the
    floor (a scan that missed the floor under furniture)."""
    room = furnished_room(floor_seen, ceiling)
    m = np.linalg.inv(to_z_up(axis))  # Z-up room -> the file's frame
    found = find_up_axis(room.vertices @ m[:3, :3].T, room.faces)
    assert found.axis == axis, found
    assert found.sureness > 0.3


def test_to_z_up():
    for axis in AXES:
        u = np.zeros(3)
        u["xyz".index(axis[1])] = 1 if axis[0] == "+" else -1
        m = to_z_up(axis)
        np.testing.assert_allclose(m[:3, :3] @ u, [0, 0, 1], atol=1e-12)
        assert np.linalg.det(m[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(to_z_up("y"), to_z_up("+y"))


def test_obj_y_down_imports_with_the_defaults(tmp_path):
    """A scan in its scanner's frame (y pointing down) comes in Z-up by itself."""
    room = furnished_room(0.6)
    m = np.linalg.inv(to_z_up("-y"))
    path = tmp_path / "scan.obj"
    room.apply_transform(m)
    room.export(path)
    b = load_building(path)
    assert b.info["up_axis"] == "-y" and b.info["up_axis_from"] == "auto"
    assert b.info["wall_top_z"] - b.info["floor_z"] == pytest.approx(2.5, abs=0.01)


def test_units_flagged(tmp_path):
    """A room drawn in inches or centimetres read as metres is flagged with world.units."""
    for unit, name in ((INCH, "inch"), (0.01, "cm")):
        path = tmp_path / f"room_{name}.ply"
        room = furnished_room()
        room.apply_scale(1 / unit)
        room.export(path)
        b = load_building(path)
        s = import_summary(b, None, vertical_edges(np.zeros((0, 2, 3))))
        keys = {f["key"] for f in s["flags"]}
        assert "world.units" in keys, s["flags"]
        assert f"world.units={unit}" in next(f["what"] for f in s["flags"]
                                             if f["key"] == "world.units")
    assert unit_guess(2.5, 1.0) is None  # plausible: no guess needed
    assert unit_guess(2.5 / INCH, 1.0) == ("inch", INCH)


def test_summary_flags(tmp_path):
    """Free space far below the floor, no vertical edges and a missing mesh each name their
    key; a tiny floor share names the name rules."""
    pieces = office_pieces()
    world = sketchup_world(tmp_path, pieces)
    (tmp_path / "worlds" / "office.world").write_text(world.read_text().replace(
        "</world>", '<model name="ghost"><link name="l"><visual name="v"><geometry><mesh>'
                    '<uri>model://office/meshes/none.dae</uri></mesh></geometry></visual>'
                    '</link></model></world>'))
    b = load_building(world)
    s = import_summary(b, free_area_m2=2.0, vertical=0)
    keys = {f["key"] for f in s["flags"]}
    assert {"world.z_range / world.camera_margin", "world.up_axis", "world.model_path"} <= keys
    assert s["missing_meshes"] == 1 and s["floor_footprint_m2"] == pytest.approx(48.0)
    b.face_class[b.face_class == C.FLOOR] = C.WALL
    b.face_class[0] = C.FLOOR
    b.info["class_shares"] = {"floor": 0.001}
    assert "world.name_rules" in {f["key"] for f in import_summary(b)["flags"]}


def test_file_uri_from_the_repository_root(tmp_path):
    """``file://models/...`` (the AWS worlds' models) is found from the world's repository
    root, as Gazebo's resource path does; a name differing in case is found too."""
    b = load_building(sketchup_world(tmp_path, uri="file://models/office/meshes/office.dae"))
    assert not b.info["missing_meshes"] and classes_of(b, "Carpet") == {C.FLOOR}
    b = load_building(sketchup_world(tmp_path / "case",
                                     uri="file://models/office/meshes/OFFICE.dae"))
    assert not b.info["missing_meshes"]


def test_far_parts_left_out(tmp_path):
    pieces = office_pieces()
    v, f = quad(0, 0, 0.2, 0.2, 3.4e5, True)
    b = load_building(sketchup_world(tmp_path, [*pieces, ("Book_far", v, f)]))
    assert list(b.info["far_parts"]) == ["office/walls/visual/piece5/Book_far"]
    assert b.vertices[:, 2].max() < 3.0


def test_ambiguous_box_flagged(tmp_path):
    """A closed empty corridor narrower than high gives the cues nothing to tell its floor
    from its walls: whatever axis comes out, the summary says to set world.up_axis."""
    box = trimesh.creation.box(extents=[2.0, 10.0, 2.8])
    box.apply_translation([0.0, 5.0, 1.4])
    box.invert()  # faces looking in
    path = tmp_path / "corridor.ply"
    box.export(path)
    b = load_building(path)
    assert b.info["up_axis_found"]["sureness"] < 0.1
    assert "world.up_axis" in {f["key"] for f in import_summary(b)["flags"]}
    assert load_building(path, {"up_axis": "z"}).info["wall_top_z"] == pytest.approx(2.8)


def test_short_floor_edges_flagged(tmp_path):
    """The SketchUp office: its floor-to-wall edges run about the free space's outline, and
    the rendered-edge check sees them; with the floor | wall segments taken out, the summary
    flags short floor-to-structure edges and the check's recall falls."""
    from datagen.config import FileWorldConfig
    from datagen.importers.summary import edge_figures
    from datagen.mesh.edges import EdgeSet, extract_edges
    from datagen.worlds.site import camera_free_space

    world = sketchup_world(tmp_path, office_pieces())
    b = load_building(world)
    free = camera_free_space(b, FileWorldConfig(path=str(world)))
    edges = extract_edges(b.vertices, b.faces, b.face_class)
    full = edge_figures(b, edges, free)
    assert full["floor_edges_m"] >= full["free_outline_m"] > 0
    assert full["rendered_edges"]["recall"] > 0.9
    flag = "short floor-to-structure edges"
    assert not any(flag in f["what"] for f in import_summary(b, free.area, 4, full)["flags"])
    floor_wall = (np.sort(edges.classes, axis=1) == [C.FLOOR, C.WALL]).all(axis=1)
    cut = EdgeSet(*(a[~floor_wall] for a in edges))
    short = edge_figures(b, cut, free)
    assert short["floor_edges_m"] < 0.5 * short["free_outline_m"]
    assert short["rendered_edges"]["recall"] < full["rendered_edges"]["recall"] - 0.1
    assert any(flag in f["what"] for f in import_summary(b, free.area, 4, short)["flags"])
