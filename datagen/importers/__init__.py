"""Import a building model (Gazebo SDF, a mesh file, IFC) as one triangle mesh with a class
per face: ``load_building(path, settings) -> Building``. ``python -m datagen.importers FILE``
checks an import (counts, class shares, missing models, a plan image)."""

from datagen.importers.config import ImportConfig, NameRule
from datagen.importers.load import EXTENSIONS, load_building
from datagen.mesh.building import Building

__all__ = ["EXTENSIONS", "Building", "ImportConfig", "NameRule", "load_building"]
