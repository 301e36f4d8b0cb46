"""The datagen job: layout, determinism, resume after a crash, bad config."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest
from hydra.errors import ConfigCompositionException

import datagen.generate as gen
import datagen.rendering.flight as render_flight
import datagen.rendering.frame as render_frame
import datagen.rendering.split as render_split
from core import classes as C
from core.atomic import read_png
from core.config import compose_config
from core.dataset import Dataset
from core.occupancy import PATH_RGB
from core.outputs import LOCK_NAME, SETUP_LOCK_NAME, OutputFolderError
from datagen.job import prepare, shard_range
from datagen.rendering.pipeline import Pipeline

SMALL = ["camera.width=64", "camera.height=48", "splits.train=4", "splits.val=1",
         "splits.test=0", "render.spp=1", "training.chunk=2", "render_flights=[cluttered]",
         "flights.cluttered.num_frames=3", "val_flights=[]"]


def small_cfg(out: Path, *extra: str) -> dict:
    return compose_config("datagen", [*SMALL, f"out_dir={out}", *extra])


def tree_bytes(root: Path) -> dict[str, bytes]:
    """Every file's bytes, except the timing statistics and the lock files."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and not str(p.relative_to(root)).startswith("stats")
            and p.name not in (LOCK_NAME, SETUP_LOCK_NAME)}


class TestLayout:
    def test_tiny_dataset(self, tiny_dataset):
        ds = Dataset(tiny_dataset)
        assert ds.meta["counts"]["train"] == 12
        assert [c["name"] for c in ds.classes] == list(C.NAMES)
        rgb, lab = ds.split("train")
        assert len(rgb) == 12 and all(p.is_file() for p in lab)
        labels = np.stack([read_png(p, rgb=False) for p in lab])
        assert labels.shape == (12, 96, 128) and labels.dtype == np.uint8
        assert set(np.unique(labels)) <= set(range(C.NUM_CLASSES)) | {C.IGNORE}
        assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR} <= set(np.unique(labels))
        assert read_png(rgb[0]).shape == (96, 128, 3)
        assert ds.split_poses("train").shape == (12, 4, 4)
        assert ds.flight_names() == ["cluttered", "paper", "paper_val"]
        assert ds.flight_names("test") == ["cluttered", "paper"]
        assert ds.flight_names("val") == ["paper_val"]
        val = ds.flight("paper_val")
        assert val.flight_set == "val" and val.info["preset_name"] == "paper"
        assert len(val.rgb) == 30 and all(p.is_file() for p in val.rgb)
        f = ds.flight("paper")
        assert len(f.rgb) == 30 and all(p.is_file() for p in f.rgb + f.label)
        assert f.groundtruth.shape == f.odometry.shape == (30, 4, 4)
        np.testing.assert_allclose(f.groundtruth[0], f.odometry[0], atol=1e-6)
        assert f.flight_set == "test"
        # the validation flight is another draw of the preset: another path, other images
        assert np.abs(val.groundtruth[:, :3, 3] - f.groundtruth[:, :3, 3]).max() > 0.2
        assert not np.array_equal(read_png(val.rgb[5]), read_png(f.rgb[5]))
        assert not (tiny_dataset / "flights" / "paper" / "images.txt").exists()  # ideal
        w = ds.world()
        assert w.segments.shape[1:] == (2, 3) and len(w.segments) == len(w.segment_classes)
        stats = json.loads((tiny_dataset / "stats.json").read_text())
        assert stats["images_per_second"] > 0
        assert stats["render"]["width"] == 128

    def test_flight_people_move_and_label_person(self, tiny_dataset):
        ds = Dataset(tiny_dataset)
        f = ds.flight("cluttered")
        labels = [read_png(p, rgb=False) for p in f.label]
        assert any((lab == C.PERSON).any() or (lab == C.CLUTTER).any() for lab in labels)


@pytest.mark.slow
class TestDeterminismAndResume:
    def test_same_seed_same_bytes_and_resume(self, tmp_path, monkeypatch):
        full = tmp_path / "full"
        gen.run(small_cfg(full), progress=False)
        rate = json.loads((full / "stats.json").read_text())["images_per_second"]
        gen.run(small_cfg(full), progress=False)  # nothing left to render: keeps the timing
        assert json.loads((full / "stats.json").read_text())["images_per_second"] == rate > 0

        # A run that dies after two frames, then is re-run.
        crashed = tmp_path / "crashed"
        real_write, calls = render_frame.write_frame, {"n": 0}

        def dying_write(*args, **kwargs):
            if calls["n"] == 2:
                raise KeyboardInterrupt("simulated kill")
            calls["n"] += 1
            return real_write(*args, **kwargs)

        monkeypatch.setattr(render_frame, "write_frame", dying_write)
        with pytest.raises(KeyboardInterrupt):
            gen.run(small_cfg(crashed), progress=False)
        monkeypatch.setattr(render_frame, "write_frame", real_write)
        assert len(list((crashed / "train" / "rgb").glob("*.png"))) == 2
        gen.run(small_cfg(crashed), progress=False)

        a, b = tree_bytes(full), tree_bytes(crashed)
        assert sorted(a) == sorted(b)
        assert all(a[k] == b[k] for k in a), [k for k in a if a[k] != b[k]]
        assert not [k for k in a if Path(k).name.startswith(".")], "temp files left behind"

        # Developing and writing on the caller's thread instead of the worker: the same bytes.
        serial = tmp_path / "serial"
        serial_pipeline = functools.partial(Pipeline, enabled=False)
        monkeypatch.setattr(render_split, "Pipeline", serial_pipeline)
        monkeypatch.setattr(render_flight, "Pipeline", serial_pipeline)
        gen.run(small_cfg(serial), progress=False)
        c = tree_bytes(serial)
        assert sorted(a) == sorted(c)
        assert all(a[k] == c[k] for k in a), [k for k in a if a[k] != c[k]]

    def test_new_scene_every_frame(self, tmp_path):
        """A scene loaded per frame (chunk 1) while the worker develops the last one's frame."""
        out = tmp_path / "c1"
        gen.run(small_cfg(out, "training.chunk=1", "splits.train=12", "render_flights=[]"),
                progress=False)
        assert len(list((out / "train" / "rgb").glob("*.png"))) == 12

    def test_other_seed_other_images(self, tmp_path):
        gen.run(small_cfg(tmp_path / "s1", "seed=1", "splits.val=0",
                          "render_flights=[]"), progress=False)
        gen.run(small_cfg(tmp_path / "s0", "splits.val=0", "render_flights=[]"),
                progress=False)
        a = read_png(tmp_path / "s0" / "train" / "rgb" / "000000.png")
        b = read_png(tmp_path / "s1" / "train" / "rgb" / "000000.png")
        assert not np.array_equal(a, b)

    def test_shards_cover_all_frames(self):
        frames = [list(shard_range(10, k, 3)) for k in range(3)]
        assert sum(frames, []) == list(range(10))


class TestBadConfig:
    @pytest.mark.parametrize("override,match", [
        ("seed=-1", r"seed = -1 must be >= 0"),
        ("camera.width=-320", "camera.width"),
        ("splits.train=-1", "splits.train"),
        ("world.length=-10", "world.length"),
        ("world.z_range=[0.5,3.5]", "z_range"),
        ("camera.mount.xyz=[0.0,0.0,0.9]", "camera.mount.xyz"),
        ("+training.distractors.crowded=1.0", "unknown preset 'crowded'"),
        ("render_flights=[spiral]", "unknown flight preset 'spiral'"),
        ("flights.cluttered.distractors=crowd", "unknown preset 'crowd'"),
        ("shard=2", "shard=2"),
        ("flights.cluttered.num_frames=0", "flights.cluttered: num_frames"),
        ("flights.cluttered.route=[[0,1],[0,50]]", r"flights.cluttered.route: .*waypoint 1"),
        ("flights.cluttered.route=[[-2,6.2],[0,9]]", r"flights.cluttered.route: .*blocked"),
        ("flights.paper.route=spiral", r"flights.paper.route must be 'auto'"),
    ])
    def test_clear_error_before_rendering(self, tmp_path, override, match):
        out = tmp_path / "bad"
        with pytest.raises(ValueError, match=match):
            gen.run(small_cfg(out, override), progress=False)
        assert not out.exists(), "nothing may be written for a bad config"

    @pytest.mark.parametrize("override", ["training.opening_view=0.4", "world.frames=wall",
                                          "render.spp=many"])
    def test_unknown_key_or_wrong_type_fails_at_compose(self, tmp_path, override):
        with pytest.raises(ConfigCompositionException, match=override.split("=")[0]):
            small_cfg(tmp_path / "bad", override)

    def test_camera_outside_corridor(self, tmp_path):
        cfg = small_cfg(tmp_path / "bad", "world.z_range=[2.5,2.79]",
                        "camera.mount.xyz=[0.0,0.0,0.45]")
        with pytest.raises(ValueError, match="outside the free space"):
            gen.run(cfg, progress=False)

    def test_existing_output_with_other_config(self, tmp_path):
        out = tmp_path / "ds"
        gen.run(small_cfg(out, "splits.val=0", "render_flights=[]"), progress=False)
        with pytest.raises(OutputFolderError, match=r"another config: seed \(0 -> 3\)"):
            gen.run(small_cfg(out, "splits.val=0", "render_flights=[]", "seed=3"),
                    progress=False)
        gen.run(small_cfg(out, "splits.val=0", "render_flights=[]", "seed=3",
                          "overwrite=true"), progress=False)
        assert json.loads((out / "dataset.json").read_text())["seed"] == 3

    def test_world_files(self, tmp_path):
        """world/: the free space map, the class shares and the plan with the flights."""
        out = tmp_path / "ds"
        gen.run(small_cfg(out, "splits.train=1", "splits.val=0", "splits.test=0"),
                progress=False)
        ds = Dataset(out)
        w = ds.world()
        assert w.free.area == pytest.approx(w.info["free_space"]["area_m2"], abs=1e-3)
        assert w.free.band == (0.5, 2.2)
        assert set(w.info["class_shares"]) == {"floor", "wall", "ceiling", "door", "window"}
        assert sum(w.info["class_shares"].values()) == pytest.approx(1.0, abs=1e-3)
        plan = read_png(out / "world" / "plan.png")
        flown = np.all(plan == PATH_RGB[0], axis=2).sum()
        assert flown >= 5, "the first flight is drawn on the plan"

    def test_more_frames_grow_the_dataset(self, tmp_path):
        out, base = tmp_path / "ds", ["splits.val=0", "render_flights=[]"]
        gen.run(small_cfg(out, *base, "splits.train=2"), progress=False)
        first = tree_bytes(out / "train" / "rgb")
        gen.run(small_cfg(out, *base, "splits.train=4"), progress=False)
        assert Dataset(out).meta["counts"]["train"] == 4
        grown = tree_bytes(out / "train" / "rgb")
        assert sorted(grown) == ["000000.png", "000001.png", "000002.png", "000003.png"]
        assert all(grown[k] == first[k] for k in first), "existing frames must be kept"
        gen.run(small_cfg(out, *base, "splits.train=5", "overwrite=true"), progress=False)
        assert all(tree_bytes(out / "train" / "rgb")[k] == grown[k] for k in grown), \
            "overwrite=true grows too: deleting the frames would only render them again"
        fresh = tmp_path / "fresh"
        gen.run(small_cfg(fresh, *base, "splits.train=4"), progress=False)
        a = read_png(fresh / "train" / "rgb" / "000003.png").astype(int)
        b = read_png(out / "train" / "rgb" / "000003.png").astype(int)
        assert np.abs(a - b).max() <= 1, "a grown frame is the frame a fresh run renders"
        with pytest.raises(OutputFolderError, match=r"splits.train \(5 -> 3\)"):  # fewer: no
            gen.run(small_cfg(out, *base, "splits.train=3"), progress=False)

    def test_flight_views_share(self):
        cfg = small_cfg(Path("unused"), "splits.train=400", "training.flight_views=0")
        base = prepare(cfg).split_poses["train"]
        cfg["training"]["flight_views"] = 0.5
        mixed = prepare(cfg).split_poses["train"]
        kept = np.all(mixed == base, axis=(1, 2))
        assert kept.mean() == pytest.approx(0.5, abs=0.08), "the other frames are unchanged"
        heights = mixed[~kept, 2, 3]
        assert heights.min() >= 0.8 and heights.max() <= 1.7  # the flights' heights
        cfg["training"]["flight_views"] = 1.5
        with pytest.raises(ValueError, match="training.flight_views"):
            prepare(cfg)

    def test_missing_dataset_error(self, tmp_path):
        with pytest.raises(FileNotFoundError, match="python -m datagen"):
            Dataset(tmp_path / "nope")
