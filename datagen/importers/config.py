"""The settings of a building import (``load_building``): one typed dataclass, defaults once.

Lengths in metres. Not yet part of ``DatagenConfig``; the keys are meant to become ``world.*``
of ``python -m datagen world=file`` (``world.path``, ``world.model_path``, ...).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING


@dataclass
class NameRule:
    """A face whose name (``model/link/visual/material`` for SDF, the node and material for a
    mesh file, ``IfcType/name`` for IFC) has a part (between ``/``) in which ``pattern`` (a
    Python regex, case-insensitive) occurs gets class ``cls`` (a name of core.classes:
    floor, wall, ...); the parts are tried from the last (the material) to the first."""

    pattern: str = MISSING
    cls: str = MISSING


def default_name_rules() -> list[NameRule]:
    """Tried in order on each part of a name, the most specific part first; in one part the
    first match decides (a door sign is clutter, not a door; a model ``..._floor_01_walls``
    is wall, not floor)."""
    return [
        NameRule("sign|portrait|poster|painting|picture|frame_art", "clutter"),
        NameRule("door", "door"),
        NameRule("window|glass|glazing", "window"),
        NameRule("ceiling", "ceiling"),
        NameRule("wall|rail|stair|column|pillar|beam", "wall"),
        NameRule("floor|ground|carpet|rug", "floor"),
        NameRule("chair|table|desk|sofa|couch|bed|cabinet|shelf|rack|cart|trolley|trash|"
                 "drawer|tv_|computer|monitor|fridge|refrigerator|curtain|plant|lamp|"
                 "furniture|station|clutter|sink|toilet|shower|machine|stand|book|bicycle|"
                 "camera|clock|horologe|holder|conditioner|speaker|light|laptop|phone|printer|"
                 "tablet|cube|toy|bottle|vase", "clutter"),
    ]


@dataclass
class ImportConfig:
    """How ``datagen.importers.load_building`` reads a building model.

    Classes come first from the format (IFC type), then from ``name_rules`` (the most
    specific part of a name first), geometry overruling a name where a large horizontal
    surface is plainly floor or ceiling, then from geometry: a piece standing on the floor
    and not reaching the storey's top is furniture, clutter (datagen/mesh/furniture.py); a
    horizontal face within ``floor_tolerance`` of the storey's floor is floor, a down-facing
    one ceiling, the rest wall (datagen/importers/classify.py).
    """

    path: str = ""  # the model file (.world/.sdf, .glb/.gltf/.obj/.ply/.dae/.stl, .ifc)
    model_path: list[str] = field(default_factory=list)  # extra Gazebo model folders, searched
    # before the world's ../models, $GAZEBO_MODEL_PATH and ~/.gazebo/models
    units: float = 1.0  # metres per file unit for OBJ/PLY/STL (COLLADA: its <unit>; glTF, IFC:
    # metres)
    up_axis: str = "auto"  # auto | +x -x +y -y +z -z (x y z: +x +y +z): the up axis of
    # OBJ/PLY/STL/DAE files; auto: found from the large horizontal planes (datagen/importers/
    # orient.py). glTF is +y by its spec, Gazebo SDF +z; COLLADA's <up_axis> is not applied
    # inside SDF, as in Gazebo
    storey: str | None = None  # IFC: storey name; None: the ground storey (the lowest
    # elevation >= -0.5 m, else the lowest)
    doors: str = "open"  # open: IFC door leaves left out (openings kept) | closed
    ceiling: str = "auto"  # auto: add a ceiling over the floor at the walls' height unless
    # ceiling faces above mid-height cover half the floor | none: keep the sky
    floor_tolerance: float = 0.3  # m, how far above/below the storey floor a horizontal face
    # is still floor (geometry rule)
    name_rules: list[NameRule] = field(default_factory=default_name_rules)
