"""Small building model files written by the importer tests (COLLADA, SDF, IFC)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

#: An open room (floor and four walls, no ceiling) of 4 x 3 m, walls 2.5 m high.
ROOM = (4.0, 3.0, 2.5)


def open_room(size: tuple[float, float, float] = ROOM) -> trimesh.Trimesh:
    """Floor (up) and walls (facing in) of a box room x in [0, sx], y in [0, sy], no top."""
    sx, sy, h = size
    box = trimesh.creation.box(extents=size)
    box.apply_translation(np.array(size) / 2)
    inward = box.faces[:, ::-1]
    normals = -box.face_normals
    return trimesh.Trimesh(box.vertices, inward[normals[:, 2] > -0.5], process=False)


def write_dae(path: Path, pieces: list[tuple[str, np.ndarray, np.ndarray]],
              unit: float = 1.0, matrix: np.ndarray | None = None,
              colours: dict[str, tuple[float, float, float]] | None = None,
              textures: dict[str, tuple[str, np.ndarray]] | None = None) -> Path:
    """A COLLADA file (pycollada) with one geometry per (material name, vertices in file
    units, faces) piece, all under one node with ``matrix``, and ``<unit meter=unit>``;
    ``textures``: material name -> (image file name next to the file, (n, 2) UV per vertex)
    for pieces with an image texture."""
    from collada import Collada, asset, geometry, material, scene, source

    doc = Collada()
    doc.assetInfo.unitmeter = unit
    doc.assetInfo.unitname = "unit"
    doc.assetInfo.upaxis = asset.UP_AXIS.Y_UP  # declared, not applied (as Gazebo does)
    nodes = []
    for i, (name, verts, faces) in enumerate(pieces):
        rgb = (colours or {}).get(name, (0.5, 0.5, 0.5))
        sources = [source.FloatSource(f"verts{i}", np.asarray(verts, np.float32).ravel(),
                                      ("X", "Y", "Z"))]
        inputs = source.InputList()
        inputs.addInput(0, "VERTEX", f"#verts{i}")
        if name in (textures or {}):
            file, uv = textures[name]
            image = material.CImage(f"image{i}", file)
            surface = material.Surface(f"surface{i}", image)
            sampler = material.Sampler2D(f"sampler{i}", surface)
            effect = material.Effect(f"effect{i}", [surface, sampler], "lambert",
                                     diffuse=material.Map(sampler, "UVSET0"))
            doc.images.append(image)
            sources.append(source.FloatSource(f"uv{i}", np.asarray(uv, np.float32).ravel(),
                                              ("S", "T")))
            inputs.addInput(0, "TEXCOORD", f"#uv{i}", set="0")
        else:
            effect = material.Effect(f"effect{i}", [], "phong", diffuse=rgb)
        mat = material.Material(f"material{i}", name, effect)
        doc.effects.append(effect)
        doc.materials.append(mat)
        geom = geometry.Geometry(doc, f"geometry{i}", f"piece{i}", sources)
        geom.primitives.append(geom.createTriangleSet(np.asarray(faces, np.int32).ravel(),
                                                      inputs, f"symbol{i}"))
        doc.geometries.append(geom)
        nodes.append(scene.GeometryNode(geom, [scene.MaterialNode(f"symbol{i}", mat, [])]))
    transforms = [] if matrix is None else [scene.MatrixTransform(
        np.asarray(matrix, np.float32).ravel())]
    root = scene.Node("root", children=nodes, transforms=transforms)
    doc.scenes.append(scene.Scene("scene", [root]))
    doc.scene = doc.scenes[0]
    path.parent.mkdir(parents=True, exist_ok=True)
    doc.write(str(path))
    return path


def write_model(models: Path, name: str, body: str) -> Path:
    """A Gazebo model folder ``models/name`` with model.config and model.sdf (``body``: the
    inside of ``<model>``)."""
    folder = models / name
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.config").write_text(
        f'<?xml version="1.0"?>\n<model><name>{name}</name>'
        f'<sdf version="1.6">model.sdf</sdf></model>\n')
    (folder / "model.sdf").write_text(
        f'<?xml version="1.0"?>\n<sdf version="1.6"><model name="{name}">{body}</model></sdf>\n')
    return folder


def write_world(path: Path, body: str) -> Path:
    """A Gazebo world file whose ``<world>`` holds ``body``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<?xml version="1.0"?>\n<sdf version="1.6"><world name="w">{body}'
                    f'</world></sdf>\n')
    return path


def visual(geometry: str, pose: str = "0 0 0 0 0 0", name: str = "visual") -> str:
    """A ``<link>`` with one ``<visual>`` of ``geometry`` (plus a collision that must be
    ignored)."""
    return (f'<link name="link"><visual name="{name}"><pose>{pose}</pose><geometry>{geometry}'
            f'</geometry></visual><collision name="c"><geometry><box><size>50 50 50</size>'
            f'</box></geometry></collision></link>')


#: The ground storey's rooms (IfcSpace) in write_ifc: name -> corners, m (the Lab an L).
SPACES = {"Office": [(0.2, 0.2), (3.0, 0.2), (3.0, 3.8), (0.2, 3.8)],
          "Lab": [(3.0, 0.2), (5.8, 0.2), (5.8, 3.8), (4.5, 3.8), (4.5, 2.0), (3.0, 2.0)]}


def write_ifc(path: Path, upper: bool = True) -> Path:
    """An IFC4 file (ifcopenshell.api), metres: storey "Ground" at 0 m with four 3 m walls
    around 6 x 4 m (inside 0.2..5.8 x 0.2..3.8), a floor slab (top at 0), a 0.9 x 2.1 m door
    in the y = 0 wall at x 2..2.9 and a 1.2 x 1 m window in the x = 6 wall, two rooms
    (``SPACES``); with ``upper`` a storey "Level 1" at 3 m with a slab (its underside is the
    ground storey's ceiling)."""
    from ifcopenshell.api import aggregate, context, feature, geometry, project, root, spatial, unit

    m = project.create_file(version="IFC4")
    project = root.create_entity(m, ifc_class="IfcProject", name="Test")
    unit.assign_unit(m, length={"is_metric": True, "raw": "METERS"})
    model = context.add_context(m, context_type="Model")
    body = context.add_context(m, context_type="Model", context_identifier="Body",
                               target_view="MODEL_VIEW", parent=model)

    def place(elem, x: float, y: float, z: float, yaw: float = 0.0) -> None:
        mat = np.eye(4)
        mat[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        mat[:3, 3] = x, y, z
        geometry.edit_object_placement(m, product=elem, matrix=mat, is_si=True)

    def slab(storey, z: float, name: str):
        s = root.create_entity(m, ifc_class="IfcSlab", name=name)
        place(s, 0, 0, z - 0.2)
        rep = geometry.add_slab_representation(m, context=body, depth=0.2,
                                               polyline=[(0, 0), (6, 0), (6, 4), (0, 4)])
        geometry.assign_representation(m, product=s, representation=rep)
        spatial.assign_container(m, relating_structure=storey, products=[s])

    site = root.create_entity(m, ifc_class="IfcSite", name="Site")
    building = root.create_entity(m, ifc_class="IfcBuilding", name="Building")
    aggregate.assign_object(m, relating_object=project, products=[site])
    aggregate.assign_object(m, relating_object=site, products=[building])
    storeys = []
    for name, z in [("Ground", 0.0), ("Level 1", 3.0)][: 2 if upper else 1]:
        st = root.create_entity(m, ifc_class="IfcBuildingStorey", name=name)
        st.Elevation = z
        place(st, 0, 0, z)
        aggregate.assign_object(m, relating_object=building, products=[st])
        storeys.append(st)
    ground = storeys[0]
    walls = []
    for p1, p2 in [((0, 0), (6, 0)), ((6, 0), (6, 4)), ((6, 4), (0, 4)), ((0, 4), (0, 0))]:
        w = root.create_entity(m, ifc_class="IfcWall", name="Wall")
        rep = geometry.create_2pt_wall(m, element=w, context=body, p1=p1, p2=p2,
                                       elevation=0.0, height=3.0, thickness=0.2)
        geometry.assign_representation(m, product=w, representation=rep)
        spatial.assign_container(m, relating_structure=ground, products=[w])
        walls.append(w)
    slab(ground, 0.0, "Ground slab")
    if upper:
        slab(storeys[1], 3.0, "Level 1 slab")

    def filled(wall, cls: str, name: str, x: float, y: float, z: float, yaw: float,
               width: float, height: float, at: tuple[float, float]):
        op = root.create_entity(m, ifc_class="IfcOpeningElement")
        place(op, x, y, z, yaw)
        rep = geometry.add_wall_representation(m, context=body, length=width, height=height,
                                               thickness=0.6)
        geometry.assign_representation(m, product=op, representation=rep)
        feature.add_feature(m, feature=op, element=wall)
        el = root.create_entity(m, ifc_class=cls, name=name)
        add = (geometry.add_door_representation if cls == "IfcDoor"
               else geometry.add_window_representation)
        rep = add(m, context=body, overall_height=height, overall_width=width)
        geometry.assign_representation(m, product=el, representation=rep)
        spatial.assign_container(m, relating_structure=ground, products=[el])
        place(el, *at, z, yaw)
        feature.add_filling(m, opening=op, element=el)

    for name, corners in SPACES.items():  # the rooms, extruded 3 m down from 3 m
        sp = root.create_entity(m, ifc_class="IfcSpace", name=name)
        place(sp, 0, 0, 3.0)
        rep = geometry.add_slab_representation(m, context=body, depth=3.0, polyline=corners)
        geometry.assign_representation(m, product=sp, representation=rep)
        aggregate.assign_object(m, relating_object=ground, products=[sp])
    filled(walls[0], "IfcDoor", "Door", 2.0, -0.3, 0.0, 0.0, 0.9, 2.1, (2.0, 0.05))
    filled(walls[1], "IfcWindow", "Window", 6.3, 1.5, 0.9, np.pi / 2, 1.2, 1.0, (5.95, 1.5))
    m.write(str(path))
    return path
