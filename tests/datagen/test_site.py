"""datagen.worlds.site: the corridor and a building file give one structure; world=file settings."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from core import classes as C
from core.config import compose_config
from datagen.config import FileWorldConfig, WorldConfig, world_config
from datagen.worlds.site import STANDING_BAND, build_site
from tests.buildings import BAND, MARGIN, ring, ring_area


def write_ring_glb(path, width: float = 2.0) -> str:
    """The 10 m square ring corridor of tests/buildings.py as a glTF binary (Y up, as glTF is)."""
    v, f, _ = ring(width=width)
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    mesh.export(path)
    return str(path)


class TestCorridor:
    def test_corridor_site(self):
        site = build_site(None)
        w = site.world
        assert site.corridor is not None and w.info["name"] == "corridor_paper"
        np.testing.assert_allclose(site.route, [[0.0, 0.3], [0.0, 9.7]])
        assert site.world.free.contains(site.route).all()
        assert site.floor.band == STANDING_BAND and site.floor.margin == 0.0
        # people and objects stand anywhere on the floor: more room than the camera has
        assert site.floor.area > w.free.area + 0.5 * 10.0
        assert set(w.info["class_shares"]) == {"floor", "wall", "ceiling", "door", "window"}


class TestFile:
    def test_ring_glb(self, tmp_path):
        path = write_ring_glb(tmp_path / "ring.glb")
        site = build_site({"kind": "file", "path": path, "free_cell": 0.05})
        w = site.world
        assert site.corridor is None and site.route is None
        assert w.info["kind"] == "file" and w.info["source"] == path
        assert w.free.band == pytest.approx(BAND) and w.free.margin == MARGIN
        assert w.free.area == pytest.approx(ring_area(10.0, 10.0, 2.0, MARGIN), rel=0.05)
        assert {"floor", "wall", "ceiling"} <= set(w.info["class_shares"])
        assert w.info["ceiling_added"] > 0  # an open-top model gets a ceiling (ceiling: auto)
        classes = set(np.unique(w.segment_classes))
        assert C.FLOOR in classes and C.WALL in classes and C.CEILING in classes
        assert len(w.segments) >= 16  # at least the ring's 8 wall/floor and 8 wall/ceiling
        assert site.floor.area > w.free.area
        summary = w.info["import_summary"]  # also world/import_summary.json
        assert summary["free_area_m2"] == pytest.approx(w.free.area, abs=0.1)
        assert summary["vertical_edges"] > 0 and summary["up_axis"]["axis"] == "+y"
        from datagen.worlds.save import save_world

        save_world(tmp_path / "world", w)
        assert json.loads((tmp_path / "world" / "import_summary.json").read_text()) == summary

    def test_hydra_world_file(self, tmp_path):
        path = write_ring_glb(tmp_path / "ring.glb")
        cfg = compose_config("datagen", ["world=file", f"world.path={path}",
                                         "world.camera_margin=0.25"])
        spec = world_config(cfg["world"])
        assert isinstance(spec, FileWorldConfig)
        assert spec.path == path and spec.camera_margin == 0.25 and spec.ceiling == "auto"
        assert spec.up_axis == "auto"
        assert isinstance(world_config(compose_config("datagen", [])["world"]), WorldConfig)

    @pytest.mark.parametrize("settings,error,match", [
        ({"path": "building.xyz"}, ValueError, "unknown extension"),
        ({"path": "missing.glb"}, FileNotFoundError, "no such file"),
        ({"path": ""}, ValueError, "world.path: no building model file given"),
        ({"camera_margin": 1.5}, ValueError, "world.camera_margin"),
        ({"z_range": [2.0, 1.0]}, ValueError, "world.z_range"),
        ({"kind": "cave"}, ValueError, "world.kind: unknown world kind 'cave'"),
        ({"ceiling": "maybe"}, ValueError, "ceiling"),
    ])
    def test_bad_settings(self, tmp_path, settings, error, match):
        if settings.get("path") == "building.xyz":
            (tmp_path / "building.xyz").write_text("solid nothing\n")
        path = write_ring_glb(tmp_path / "ring.glb")
        spec = {"kind": "file", "path": path, **settings}
        if settings.get("path"):
            spec["path"] = str(tmp_path / settings["path"])
        with pytest.raises(error, match=match):
            build_site(spec)

    @pytest.mark.parametrize("what", ["no walls", "no floor"])
    def test_models_without_floor_or_walls(self, tmp_path, what):
        """A floor alone, or walls alone, is not a building: the error names the file."""
        if what == "no walls":
            mesh = trimesh.Trimesh([[0, 0, 0], [6, 0, 0], [6, 4, 0], [0, 4, 0]],
                                   [[0, 1, 2], [0, 2, 3]])
            match = "flat.ply: no wall faces found"
        else:
            mesh = trimesh.creation.box(extents=[4.0, 0.2, 2.5])
            mesh.apply_translation([0.0, 0.0, 1.25])
            match = "flat.ply: no floor"
        path = tmp_path / "flat.ply"
        mesh.export(path)
        with pytest.raises(ValueError, match=match):
            build_site({"kind": "file", "path": str(path)})
