"""localize.world_file: ``world=FILE``, a building file as the map with no dataset rendered:
imported by datagen's importer in its own process, cached by content; the world=FILE path
reproduces the dataset path on a recording of a rendered flight."""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core.config import compose_config, expand_aliases
from core.dataset import load_world
from localize.config import ALIASES
from localize.resolve import override_keys, resolve
from localize.world_file import INPUTS, content_key, file_map
from tests.buildings import ring
from tests.localize.conftest import QUICK, localize_cfg, palette_segnet

SHARED = Path(__file__).resolve().parents[3] / "shared" / "worlds"


def write_ring(path: Path, width: float = 2.0) -> Path:
    """The 10 m ring corridor of tests/buildings.py as a glTF binary (Y up)."""
    v, f, _ = ring(width=width)
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path)
    return path


def assert_same_map(a: Path, b: Path) -> None:
    """model.npz, edges.npz and free.npz of two map folders hold equal arrays."""
    for name in ("model.npz", "edges.npz", "free.npz"):
        x, y = np.load(a / name), np.load(b / name)
        assert sorted(x.files) == sorted(y.files), name
        for k in x.files:
            np.testing.assert_array_equal(x[k], y[k], err_msg=f"{name}:{k}")


@pytest.fixture(scope="module")
def ring_map(tmp_path_factory):
    """The ring imported once into a cache: (file, cache, FileMap)."""
    d = tmp_path_factory.mktemp("ring")
    glb = write_ring(d / "building" / "ring.glb")
    return glb, d / "cache", file_map(glb, {}, str(d / "cache"))


class TestCache:
    def test_first_import_writes_the_map_and_its_inputs(self, ring_map):
        glb, cache, found = ring_map
        assert not found.reused and found.folder.parent.parent == cache
        inputs = json.loads((found.folder / INPUTS).read_text())
        assert inputs == {"inputs": []}  # a glb reads nothing beside itself
        w = found.world()
        assert len(w.segments) > 16 and w.free.area > 40
        assert not list(found.folder.parent.glob(".tmp-*"))  # written atomically, no leftover

    def test_the_map_is_datagen_world_files(self, ring_map, tmp_path):
        """The map equals what python -m datagen world=file writes to world/."""
        from datagen.config import FileWorldConfig
        from datagen.worlds.save import save_world
        from datagen.worlds.site import file_site

        glb, _, found = ring_map
        save_world(tmp_path / "world", file_site(FileWorldConfig(path=str(glb))).world)
        assert_same_map(tmp_path / "world", found.folder)

    def test_same_content_under_another_name_is_reused(self, ring_map, tmp_path, caplog):
        glb, cache, found = ring_map
        other = tmp_path / "elsewhere" / "copy_of_it.glb"
        other.parent.mkdir()
        shutil.copy(glb, other)
        with caplog.at_level(logging.INFO, logger="localize.world_file"):
            again = file_map(other, {}, str(cache))
        assert again.reused and again.folder == found.folder and again.digest == found.digest
        assert "reusing its map" in caplog.text

    def test_changed_file_or_settings_import_again(self, ring_map, tmp_path):
        glb, cache, found = ring_map
        assert content_key(glb, {"crease_deg": 30.0}) != content_key(glb, {})
        changed = write_ring(tmp_path / "ring.glb", width=2.5)
        assert content_key(changed, {}) != content_key(glb, {})
        new = file_map(changed, {}, str(cache))
        assert not new.reused and new.folder != found.folder
        assert load_world(new.folder).free.area > found.world().free.area  # wider corridors

    def test_a_changed_input_beside_the_file_imports_again(self, tmp_path):
        """An OBJ's .mtl is read by the import: changing it (not the OBJ) makes a new map."""
        d = tmp_path / "scan"
        v, f, _ = ring()
        d.mkdir()
        (d / "room.mtl").write_text("newmtl wall\nKd 0.8 0.8 0.8\n")
        lines = ["mtllib room.mtl", "usemtl wall"] + [f"v {x} {y} {z}" for x, y, z in v]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
        (d / "room.obj").write_text("\n".join(lines) + "\n")
        cache = str(tmp_path / "cache")
        first = file_map(d / "room.obj", {"up_axis": "+z"}, cache)
        inputs = json.loads((first.folder / INPUTS).read_text())["inputs"]
        assert [i["path"] for i in inputs] == ["room.mtl"]  # named beside the file
        assert file_map(d / "room.obj", {"up_axis": "+z"}, cache).reused
        (d / "room.mtl").write_text("newmtl wall\nKd 0.2 0.3 0.4\n")
        again = file_map(d / "room.obj", {"up_axis": "+z"}, cache)
        assert not again.reused and again.folder != first.folder


class TestErrors:
    def test_missing_file(self, tmp_path):
        with pytest.raises(FileNotFoundError, match=r"world=.*nope\.glb: not found; name a "
                                                    "building model file"):
            file_map(tmp_path / "nope.glb", {}, str(tmp_path / "cache"))

    def test_unsupported_format_leaves_no_cache_entry(self, tmp_path):
        bad = tmp_path / "building.xyz"
        bad.write_text("not a building")
        with pytest.raises(ValueError, match=r"world=.*building\.xyz: .*unknown extension "
                                             r"'\.xyz'; a building model is one of"):
            file_map(bad, {}, str(tmp_path / "cache"))
        assert not any((tmp_path / "cache").iterdir())

    def test_bad_import_setting_names_the_key(self, ring_map, tmp_path):
        glb, _, _ = ring_map
        with pytest.raises(ValueError, match="camera_margin"):
            file_map(glb, {"camera_margin": 5.0}, str(tmp_path / "cache"))

    def test_world_with_dataset_or_without_recording(self, ring_map):
        glb, _, _ = ring_map
        both = [f"world.path={glb}", "dataset=outputs/datasets/demo", "recording=rec"]
        with pytest.raises(ValueError, match="both name the building model: give one"):
            resolve(localize_cfg(both), both)
        alone = [f"world.path={glb}"]
        with pytest.raises(ValueError, match="a building file has no flights to localize; "
                                             "give a recording in it"):
            resolve(localize_cfg(alone), alone)
        from hydra import compose, initialize_config_dir

        from core.config import CONF
        from localize.ros2.config import Ros2Config

        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            node = compose(config_name="ros2", overrides=alone)
        resolve(node, alone, None, Ros2Config, "conf/ros2.yaml")  # the node: no recording

    def test_auto_model_is_the_shipped_generalist(self, ring_map):
        glb, _, _ = ring_map
        args = [f"world.path={glb}", "recording=rec"]
        cfg = localize_cfg(args)
        resolve(cfg, args)
        assert Path(cfg.onnx_model).parts[-3:] == ("models", "generalist", "segnet.onnx")

    def test_recording_without_intrinsics_names_the_file(self, ring_map, tmp_path):
        from localize.offline.recorded import run_recording

        glb, cache, _ = ring_map
        rec = tmp_path / "rec"
        (rec / "images").mkdir(parents=True)
        cfg = localize_cfg([f"world.path={glb}", f"world.cache={cache}", f"recording={rec}",
                            f"out_root={tmp_path / 'out'}", *QUICK])
        with pytest.raises(FileNotFoundError, match=r"rec/camera\.yaml not found: a folder "
                                                    "recording needs the camera calibration"):
            run_recording(cfg)


def test_world_alias_is_world_path():
    argv = ["world=hospital.world", "world.units=0.01", "dataset=x", "+world=a"]
    assert expand_aliases(argv, ALIASES) == ["world.path=hospital.world", "world.units=0.01",
                                             "dataset=x", "+world=a"]
    assert override_keys(expand_aliases(["world=a.glb"], ALIASES)) == ["world.path"]


# --------------------------------------------------------------------------- the two paths


@pytest.mark.slow
def test_world_file_reproduces_the_dataset_path(tmp_path):
    """A flight rendered by python -m datagen world=file, exported as a folder recording:
    localized with world=FILE (imported here, no dataset) it gives the dataset path's map and
    the same trajectories, in modes none and cnn."""
    from datagen.generate import run
    from localize.offline.recorded import run_recording
    from localize.recordings.export import export_folder

    glb = write_ring(tmp_path / "ring.glb")
    cfg = compose_config("datagen", [
        "world=file", f"world.path={glb}", "camera.width=128", "camera.height=96",
        "splits.train=0", "splits.val=0", "splits.test=0", "render.spp=2",
        "flights.paper.num_frames=30", "render_flights=[paper]", "val_flights=[]",
        "name=ring", f"out_dir={tmp_path / 'ds'}"])
    ds = run(cfg, progress=False)
    rec = tmp_path / "rec"
    export_folder(ds, "paper", rec)
    onnx = palette_segnet(tmp_path / "segnet.onnx", 96, 128)
    common = [f"recording={rec}", f"onnx_model={onnx}", "modes=[none,cnn]",
              f"out_root={tmp_path / 'reports'}", *QUICK]
    run_recording(localize_cfg([f"dataset={ds}", "name=dataset", *common]))
    cache = tmp_path / "cache"
    run_recording(localize_cfg([f"world.path={glb}", f"world.cache={cache}", "name=world",
                                *common]))
    (entry,) = [p for p in cache.glob("*/*") if p.is_dir()]
    assert_same_map(ds / "world", entry)
    for mode in ("none", "cnn"):
        a = (tmp_path / "reports" / "dataset" / "recordings" / "rec" / "trajectories"
             / f"{mode}.txt").read_text()
        b = (tmp_path / "reports" / "world" / "recordings" / "rec" / "trajectories"
             / f"{mode}.txt").read_text()
        assert a == b, mode
    metrics = json.loads((tmp_path / "reports" / "world" / "recordings" / "rec"
                          / "metrics.json").read_text())
    assert metrics["world"]["path"] == str(glb) and "dataset" not in metrics
    assert metrics["flights"]["rec"]["none"]["mean_position_error_m"] < 0.3


@pytest.mark.slow
@pytest.mark.skipif(not (SHARED / "aws_bookstore").is_dir(), reason="../shared/worlds absent")
def test_shared_bookstore_map_is_datagen_world(tmp_path):
    """The AWS bookstore (a Gazebo world with 70 included models): the world=FILE map equals
    datagen's world/ files, and its inputs are the models' files, named beside the world."""
    from datagen.config import FileWorldConfig
    from datagen.worlds.save import save_world
    from datagen.worlds.site import file_site

    world = SHARED / "aws_bookstore" / "worlds" / "bookstore.world"
    found = file_map(world, {}, str(tmp_path / "cache"))
    save_world(tmp_path / "world", file_site(FileWorldConfig(path=str(world))).world)
    assert_same_map(tmp_path / "world", found.folder)
    inputs = json.loads((found.folder / INPUTS).read_text())["inputs"]
    assert len(inputs) > 50 and all(i["path"].startswith("../models/") for i in inputs)
