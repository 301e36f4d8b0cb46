"""realism.map and realism.calibration: what the localizer is told differs from what is rendered."""

from __future__ import annotations

import filecmp
import json

import cv2
import numpy as np
import pytest

import datagen.generate as gen
from core import classes as C
from core.atomic import read_png
from core.config import compose_config
from core.dataset import Dataset
from core.imaging.realism import CalibrationConfig, MapErrorConfig
from datagen.job import CALIBRATION_STREAM, MAP_STREAM, make_camera, prepare, rng_for
from datagen.realism import builtin_objects as B
from datagen.realism import calibration as CAL
from datagen.realism import map_error as M
from datagen.worlds.site import build_site
from tests.datagen.test_site import write_ring_glb

MAP = ["realism.map.wall_std_m=0.03", "realism.map.ceiling_std_m=0.03",
       "realism.map.missing_openings=1", "realism.map.extra_openings=1"]
CAL_ON = ["realism.calibration.focal_std=0.015", "realism.calibration.principal_std_px=3",
          "realism.calibration.rotation_std_deg=1"]
SMALL = ["camera.width=64", "camera.height=48", "splits.train=0", "splits.val=0",
         "splits.test=0", "render.spp=1", "render_flights=[paper]", "flights.paper.num_frames=3"]


@pytest.fixture(scope="module")
def corridor():
    return build_site(None)


def face_planes(world, normal):
    """Offsets (normal . centre) of the world's faces along ``normal`` (either way)."""
    tri = world.vertices[world.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    mine = np.abs(n @ np.asarray(normal)) > 0.999
    return tri[mine].mean(axis=1) @ np.asarray(normal), mine


class TestMap:
    def test_walls_and_ceiling_move_as_recorded(self, corridor):
        truth = corridor.world
        c = MapErrorConfig(wall_std_m=0.03, ceiling_std_m=0.03)
        m, rec = M.make_map(truth, c, 20.0, rng_for(3, MAP_STREAM))
        assert len(rec["walls"]) >= 6 and len(rec["ceilings"]) == 1
        for w in rec["walls"]:
            want = np.dot(w["normal"], w["point"]) + w["shift_m"]
            offsets, _ = face_planes(m, w["normal"])
            assert np.min(np.abs(offsets - want)) < 1e-4, w
        (ceil,) = rec["ceilings"]
        offsets, mine = face_planes(m, [0, 0, 1])
        ceiling = mine & (m.face_class == C.CEILING)
        z = m.vertices[m.faces[ceiling]][..., 2]
        np.testing.assert_allclose(z, 2.8 + ceil["dz_m"], atol=1e-6)
        # the map's free space and edges come from the moved mesh
        left = next(w for w in rec["walls"] if w["normal"] == [1.0, 0.0, 0.0]
                    and w["point"][0] == -1.0 and w["area_m2"] > 10)
        assert m.segments[..., 0].min() < -1.0 + 1e-9 or left["shift_m"] > 0
        assert not np.array_equal(m.free.free, truth.free.free) or abs(left["shift_m"]) < 0.05
        assert m.free.band == truth.free.band and m.free.margin == truth.free.margin

    def test_shift_magnitudes(self, corridor):
        shifts, dz = [], []
        c = MapErrorConfig(wall_std_m=0.03, ceiling_std_m=0.02)
        for seed in range(25):
            _, walls, ceilings = M.shift_planes(corridor.world.vertices, corridor.world.faces,
                                                corridor.world.face_class, c.wall_std_m,
                                                c.ceiling_std_m, rng_for(seed, 10), 2.2)
            shifts += [w["shift_m"] for w in walls]
            dz += [x["dz_m"] for x in ceilings]
        assert len(shifts) >= 150 and len(dz) == 25
        assert np.std(shifts) == pytest.approx(0.03, rel=0.15)
        assert np.sqrt(np.mean(np.square(dz))) == pytest.approx(0.02, rel=0.35)

    def test_openings_missing_and_added(self, corridor):
        truth = corridor.world
        c = MapErrorConfig(missing_openings=2, extra_openings=2)
        m, rec = M.make_map(truth, c, 20.0, rng_for(0, MAP_STREAM))
        assert len(rec["missing_openings"]) == 2 and len(rec["extra_openings"]) == 2

        def classes_at(world, centre, reach=0.05):
            tri = world.vertices[world.faces]
            near = np.all(np.abs(tri.mean(axis=1) - centre) < [reach + 0.6, reach + 0.6, 1.1],
                          axis=1)
            return set(world.face_class[near].tolist())

        def outline(world, centre, cls):
            """Model edges of class ``cls`` within 0.7 m (x, y) and 1.2 m (z) of centre."""
            near = np.all(np.abs(world.segments - centre) < [0.7, 0.7, 1.2], axis=(1, 2))
            return int(np.sum(near & np.any(world.segment_classes == cls, axis=1)))

        for gone in rec["missing_openings"]:
            cls = {"door": C.DOOR, "window": C.WINDOW}[gone["kind"]]
            assert cls in classes_at(truth, gone["centre"])
            assert cls not in classes_at(m, gone["centre"])
            # its outline is no model edge of the map any more
            assert outline(truth, gone["centre"], cls) >= 3
            assert outline(m, gone["centre"], cls) == 0
        for new in rec["extra_openings"]:
            cls = {"door": C.DOOR, "window": C.WINDOW}[new["kind"]]
            assert cls not in classes_at(truth, new["centre"], reach=0.0)
            assert cls in classes_at(m, new["centre"], reach=0.0)
            near = np.linalg.norm(m.segments.mean(axis=1) - new["centre"], axis=1) < 1.2
            assert np.any(near & np.any(m.segment_classes == cls, axis=1))

    def test_seeded(self, corridor):
        c = MapErrorConfig(wall_std_m=0.03, ceiling_std_m=0.03, missing_openings=1,
                           extra_openings=1)
        a = M.make_map(corridor.world, c, 20.0, rng_for(0, 10))
        b = M.make_map(corridor.world, c, 20.0, rng_for(0, 10))
        other = M.make_map(corridor.world, c, 20.0, rng_for(1, 10))
        assert a[1] == b[1] and a[1] != other[1]
        np.testing.assert_array_equal(a[0].segments, b[0].segments)

    def test_file_world(self, tmp_path):
        site = build_site({"kind": "file", "path": write_ring_glb(tmp_path / "ring.glb"),
                           "free_cell": 0.05})
        truth = site.world
        c = MapErrorConfig(wall_std_m=0.03, ceiling_std_m=0.03, extra_openings=1, builtins=1)
        m, rec = M.make_map(truth, c, 20.0, rng_for(0, 10))
        assert len(rec["walls"]) >= 8 and len(rec["ceilings"]) == 1
        assert rec["missing_openings"] == []  # the ring has none to leave out
        (new,) = rec["extra_openings"]
        assert site.world.free.outside_distance(
            np.asarray(new["centre"])[None, :2] + 0.35 * np.asarray(new["normal"])[:2])[0] < 0.1
        assert m.free.area == pytest.approx(truth.free.area, rel=0.05)
        for w in rec["walls"]:
            offsets, _ = face_planes(m, w["normal"])
            assert np.min(np.abs(offsets - np.dot(w["normal"], w["point"]) - w["shift_m"])) < 1e-4
        path = np.array([[1.0, 1.0], [1.0, 9.0], [9.0, 9.0]])
        (b,) = B.place_builtins(c, site.floor, [path], truth.vertices, truth.faces,
                                truth.face_class, 0.0, rng_for(0, 10, 1))
        self.check_builtin(b, site.floor, path, c.builtin_clearance_m)

    @staticmethod
    def check_builtin(b, floor, path, clearance):
        xy = b.corners()
        assert floor.contains(np.array([xy[1], xy[2]])).all()  # its front stands on the floor
        back = (xy[0] + xy[3]) / 2
        assert floor.distance(back[None] - 0.06 * np.array([np.cos(b.yaw), np.sin(b.yaw)]))[0] \
            == 0  # its back is at a wall
        edge = np.concatenate([xy, (xy + np.roll(xy, -1, 0)) / 2])
        assert B._segment_distance(edge, path[:-1], path[1:]).min() >= clearance

    def test_builtins_in_the_corridor(self, corridor):
        c = MapErrorConfig(builtins=3, builtin_kinds=["pillar", "cabinet"])
        path = np.array([[0.0, 0.3], [0.0, 9.7]])
        w = corridor.world
        bs = B.place_builtins(c, corridor.floor, [path], w.vertices, w.faces, w.face_class,
                              0.0, rng_for(0, 10, 1))
        assert len(bs) == 3
        opening = np.isin(w.face_class, [C.DOOR, C.WINDOW])
        at_openings = w.vertices[w.faces[opening]].mean(axis=1)
        for b in bs:
            self.check_builtin(b, corridor.floor, path, c.builtin_clearance_m)
            # not in front of a door or window
            low = at_openings[at_openings[:, 2] < b.size[2], :2]
            assert not B._inside(low, b.corners(behind=0.15, inset=0.01)).any()
            if b.kind == "pillar":
                assert b.size[2] == pytest.approx(2.8)  # floor to ceiling
        for i, a in enumerate(bs):
            assert not any(B._overlap(a.corners(), o.corners()) for o in bs[i + 1:])
        world = B.with_builtins(corridor.world, bs, 20.0)
        assert len(world.faces) == len(corridor.world.faces) + 12 * len(bs)
        assert len(world.segments) == len(corridor.world.segments) + 12 * len(bs)

    @pytest.mark.parametrize("key,value,match", [
        ("wall_std_m", -0.01, "realism.map.wall_std_m"),
        ("ceiling_std_m", float("nan"), "realism.map.ceiling_std_m"),
        ("wall_std_m", 2.0, "realism.map.wall_std_m"),
        ("missing_openings", -1, "realism.map.missing_openings"),
        ("extra_kinds", ["door", "skylight"], "realism.map.extra_kinds"),
        ("builtin_kinds", [], "realism.map.builtin_kinds"),
        ("builtin_cabinet_m", [1.0, -0.4, 2.0], "realism.map.builtin_cabinet_m"),
    ])
    def test_bad_settings(self, key, value, match):
        with pytest.raises(ValueError, match=match):
            M.check_settings({key: value})


class TestCalibration:
    def test_magnitudes(self):
        cam = make_camera({})
        c = CalibrationConfig(focal_std=0.015, principal_std_px=3.0, rotation_std_deg=1.0,
                              translation_std_m=0.005)
        scale, pp, angle, dt = [], [], [], []
        for seed in range(400):
            told, err = CAL.told_camera(cam, c, rng_for(seed, CALIBRATION_STREAM))
            scale.append(told.K[0, 0] / cam.K[0, 0])
            assert told.K[1, 1] / cam.K[1, 1] == pytest.approx(scale[-1])
            assert scale[-1] == pytest.approx(err["focal_scale"])
            pp.append(told.K[:2, 2] - cam.K[:2, 2])
            R = cam.body_from_cam[:3, :3].T @ told.body_from_cam[:3, :3]
            angle.append(np.degrees(np.linalg.norm(cv2.Rodrigues(R)[0])))
            assert angle[-1] == pytest.approx(abs(err["rotation_deg"]), abs=1e-9)
            dt.append(told.body_from_cam[:3, 3] - cam.body_from_cam[:3, 3])
        assert np.std(scale) == pytest.approx(0.015, rel=0.15)
        assert np.std(pp) == pytest.approx(3.0, rel=0.15)
        assert np.sqrt(np.mean(np.square(angle))) == pytest.approx(1.0, rel=0.15)
        assert np.std(dt) == pytest.approx(0.005, rel=0.15)

    def test_off_is_the_truth(self):
        cam = make_camera({})
        told, _ = CAL.told_camera(cam, CalibrationConfig(), rng_for(0, 11))
        np.testing.assert_array_equal(told.K, cam.K)
        np.testing.assert_array_equal(told.body_from_cam, cam.body_from_cam)
        assert not CAL.is_active(CalibrationConfig())

    @pytest.mark.parametrize("key,value", [("focal_std", -0.01), ("focal_std", 0.5),
                                           ("principal_std_px", float("inf")),
                                           ("rotation_std_deg", -1.0),
                                           ("translation_std_m", -0.1)])
    def test_bad_settings(self, key, value):
        with pytest.raises(ValueError, match=f"realism.calibration.{key}"):
            CAL.check_settings({key: value})


class TestDatagen:
    def test_presets(self):
        ideal = prepare(compose_config("datagen", SMALL))
        assert ideal.map_world is None and ideal.told_camera is None and not ideal.builtins
        real = compose_config("datagen", ["realism=real"])["realism"]
        assert M.is_active(M.check_settings(real["map"]))
        assert CAL.is_active(CAL.check_settings(real["calibration"]))

    def test_realism_name_says_what_was_changed(self):
        """A preset edited on the command line is recorded as such, not as the preset."""
        assert prepare(compose_config("datagen", SMALL)).cfg.realism.name == "ideal"
        edited = prepare(compose_config("datagen", [*SMALL, *MAP]))
        assert edited.cfg.realism.name == ("ideal + map.wall_std_m, map.ceiling_std_m, "
                                           "map.missing_openings, map.extra_openings")
        named = prepare(compose_config("datagen", [*SMALL, *MAP, "realism.name=my_map"]))
        assert named.cfg.realism.name == "my_map"

    def test_bad_settings_stop_before_anything(self, tmp_path):
        out = tmp_path / "bad"
        for override, match in (("realism.map.wall_std_m=-0.1", "realism.map.wall_std_m"),
                                ("realism.calibration.rotation_std_deg=-1",
                                 "realism.calibration.rotation_std_deg")):
            with pytest.raises(ValueError, match=match):
                gen.run(compose_config("datagen", [*SMALL, override, f"out_dir={out}"]),
                        progress=False)
            assert not out.exists()

    def test_told_map_and_camera_render_the_truth(self, tmp_path):
        """With the map and calibration errors the flights' images, labels and poses are the
        ideal's to the byte; world/ is the map and world_truth/ the ideal's world; the told
        camera is dataset.json's camera, the truth camera_truth."""
        ideal, told = tmp_path / "ideal", tmp_path / "told"
        gen.run(compose_config("datagen", [*SMALL, f"out_dir={ideal}"]), progress=False)
        gen.run(compose_config("datagen", [*SMALL, *MAP, *CAL_ON, f"out_dir={told}"]),
                progress=False)
        a, b = ideal / "flights" / "paper", told / "flights" / "paper"
        names = [f"{sub}/{i:06d}.png" for sub in ("rgb", "label") for i in range(3)]
        names += ["groundtruth.txt", "odometry.txt"]
        match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
        assert mismatch == [] and errors == []
        assert not (ideal / "world_truth").exists()
        for f in ("model.npz", "edges.npz", "free.npz", "world.json", "model.ply"):
            assert filecmp.cmp(ideal / "world" / f, told / "world_truth" / f, shallow=False)
        ds, ds_ideal = Dataset(told), Dataset(ideal)
        meta = ds.meta
        assert "map_error" not in ds_ideal.meta and "camera_truth" not in ds_ideal.meta
        assert meta["camera_truth"] == ds_ideal.meta["camera"]
        assert len(meta["map_error"]["missing_openings"]) == 1
        assert len(meta["map_error"]["extra_openings"]) == 1
        assert meta["map_error"]["builtins"] == []
        assert not np.allclose(ds.camera.K, ds_ideal.camera.K)
        np.testing.assert_array_equal(ds.camera_truth.K, ds_ideal.camera.K)
        err = meta["calibration_error"]
        assert ds.camera.K[0, 0] == pytest.approx(ds_ideal.camera.K[0, 0] * err["focal_scale"])
        world, truth = ds.world(), ds.world_truth()
        assert world.info["map_of"].startswith("world_truth")
        assert len(world.segments) != len(truth.segments) or not np.allclose(world.segments,
                                                                             truth.segments)
        np.testing.assert_array_equal(truth.segments, ds_ideal.world().segments)

    def test_builtins_are_rendered_not_mapped(self, tmp_path):
        """A pillar: in world_truth/ and in the flight's images (labelled wall where the
        ideal flight saw something else), not in the map."""
        ideal, told = tmp_path / "ideal", tmp_path / "told"
        small = [*SMALL, "flights.paper.distractors=none"]
        gen.run(compose_config("datagen", [*small, f"out_dir={ideal}"]), progress=False)
        gen.run(compose_config("datagen", [*small, "realism.map.builtins=1",
                                           "realism.map.builtin_kinds=[pillar]",
                                           f"out_dir={told}"]), progress=False)
        meta = json.loads((told / "dataset.json").read_text())
        (b,) = meta["map_error"]["builtins"]
        assert b["kind"] == "pillar"
        ds, ds_ideal = Dataset(told), Dataset(ideal)
        assert len(ds.world_truth().faces) == len(ds_ideal.world().faces) + 12
        np.testing.assert_array_equal(ds.world().faces, ds_ideal.world().faces)
        f, g = ds.flight("paper"), ds_ideal.flight("paper")
        changed = [(read_png(p, rgb=False) != read_png(q, rgb=False))
                   for p, q in zip(f.label, g.label, strict=True)]
        assert any(c.any() for c in changed)
        for p, c in zip(f.label, changed, strict=True):
            assert np.all(read_png(p, rgb=False)[c] == C.WALL)
