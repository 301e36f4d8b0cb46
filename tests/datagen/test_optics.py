"""The flights' optics (datagen/realism/optics.py): sub-frame times and poses, motion blur and a
rolling shutter assembled from sub-frames, their checks, rendered frames (the lens itself:
tests/core/test_lens.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.atomic import read_png
from core.config import compose_config
from core.imaging.realism import RealismConfig
from datagen import generate as gen
from datagen.job import prepare
from datagen.realism import optics
from datagen.rendering.flight import flight_scene
from datagen.rendering.frame import new_renderer
from tests.core.test_lens import EUROC, LENS, SMALL, camera


class TestTime:
    def test_frame_plan(self):
        """Global shutter: every row the same weights, over [t - exposure, t]; rolling: row r
        ends at t + (r / H - 0.5) readout; labels from the sub-frame nearest mid-exposure."""
        p = optics.frame_plan(1.0, 8, 0.01, 0.0, 4)
        np.testing.assert_allclose(p.times, [0.99125, 0.99375, 0.99625, 0.99875])
        np.testing.assert_allclose(p.weights, 0.25)
        assert set(p.nearest) <= {1, 2}
        np.testing.assert_allclose(optics.row_times(1.0, 4, 0.02), [0.99, 0.995, 1.0, 1.005])
        p = optics.frame_plan(1.0, 4, 0.0, 0.02, 3)
        assert optics.frame_span(1.0, 4, 0.0, 0.02) == pytest.approx((0.99, 1.005))
        np.testing.assert_array_equal(p.weights.argmax(1), [0, 1, 2, 2])
        np.testing.assert_array_equal(p.nearest, [0, 1, 2, 2])
        p = optics.frame_plan(1.0, 96, 0.01, 0.02, 7)
        np.testing.assert_allclose(p.weights.sum(1), 1.0, rtol=1e-6)
        first, last = (np.flatnonzero(p.weights[r] > 0) for r in (0, 95))
        assert first[0] == 0 and last[-1] == 6 and first[-1] < last[0]  # bottom rows later

    def test_subframe_count(self):
        a = np.eye(4)
        b = np.eye(4)
        b[:3, :3] = Rotation.from_euler("y", 1.0, degrees=True).as_matrix()
        f = 229.0  # px: 1 degree is 4 px
        assert optics.subframe_count(np.stack([a, b]), f, 1.0, 16) == 4
        assert optics.subframe_count(np.stack([a, b]), f, 0.5, 16) == 8
        assert optics.subframe_count(np.stack([a, b]), f, 0.5, 5) == 5
        assert optics.subframe_count(np.stack([a, a]), f, 1.0, 16) == 1
        b = np.eye(4)
        b[0, 3] = 0.01  # 1 cm at NEAR_M = 1 m: 2.3 px
        assert optics.subframe_count(np.stack([a, b]), f, 1.0, 16) == 3

    def test_rolling_shutter_slants_a_vertical_edge(self):
        """Sub-frames of a camera yawing right (a vertical edge moving left in the image at
        400 px/s): the rolling-shutter frame's edge is further left in lower rows (read
        later), by the motion over each row's time; the motion-blurred global-shutter frame is
        the same in every row, a ramp as wide as the motion over the exposure (16 px)."""
        H, W, S = 40, 80, 9
        cols = np.arange(W)[None, :]

        def sub_frames(times):  # (S, H, W, 1): dark left of the edge, bright right
            img = np.clip(cols - (50.0 - 400.0 * times)[:, None] + 0.5, 0, 1)
            return np.repeat(img.astype(np.float32)[:, None, :, None], H, axis=1)

        plan = optics.frame_plan(0.02, H, 0.0, 0.04, S)
        rs = optics.assemble(sub_frames(plan.times), plan.weights)
        x = (1.0 - rs[..., 0]).sum(axis=1)  # per row: the edge's column
        assert x[0] > x[-1] + 10 and np.all(np.diff(x) <= 1e-6)  # slanted: bottom further left
        row = optics.row_times(0.02, H, 0.04)
        np.testing.assert_allclose(x, 50.0 - 400.0 * row, atol=400.0 * 0.04 / S)
        labels = optics.pick_rows(np.arange(S)[:, None, None] * np.ones((S, H, W)), plan.nearest)
        np.testing.assert_array_equal(labels[:, 0], plan.nearest)

        plan = optics.frame_plan(0.04, H, 0.04, 0.0, S)
        gs = optics.assemble(sub_frames(plan.times), plan.weights)
        np.testing.assert_allclose(gs, gs[:1].repeat(H, 0))
        ramp = np.flatnonzero((gs[0, :, 0] > 0.02) & (gs[0, :, 0] < 0.98))
        assert 13 <= len(ramp) <= 18


class TestChecks:
    @pytest.mark.parametrize(("settings", "match"), [
        ({"lens": {"k1": -0.5}}, r"realism.lens: k1 = -0.5, k2 = 0, k3 = 0 fold the image"),
        ({"lens": {"k1": -0.35, "k2": 0.05}}, "realism.lens: .* stops increasing at r = 1.208"),
        ({"motion_blur": {"exposure_s": 0.1}},
         r"realism.motion_blur.exposure_s = 0.1 s is not shorter than flights.paper's frame "
         r"interval 1 / fps = 0.1 s"),
        ({"motion_blur": {"exposure_s": -0.01}}, "realism.motion_blur.exposure_s = -0.01"),
        ({"rolling_shutter": {"readout_s": 0.2}}, "realism.rolling_shutter.readout_s = 0.2"),
        ({"subframes": {"step_px": 0.0}}, "realism.subframes.step_px"),
        ({"subframes": {"max_count": 0}}, "realism.subframes.max_count"),
    ])
    def test_bad_settings(self, settings, match):
        with pytest.raises(ValueError, match=match):
            optics.check_settings(settings, camera(), {"paper": 10.0})

    def test_defaults_off(self):
        assert not optics.is_active(RealismConfig())
        real = prepare(compose_config("datagen", [*SMALL, "realism=real",
                                                      "realism.dropout.per_min=0"])).cfg.realism
        assert optics.is_active(real)
        np.testing.assert_allclose(optics.lens_coefficients(real), EUROC)
        assert real.motion_blur.exposure_s == 0.01 and real.rolling_shutter.readout_s == 0.02

    def test_bad_settings_stop_before_anything(self, tmp_path):
        out = tmp_path / "bad"
        for override, match in (("realism.lens.k1=-0.6", "realism.lens"),
                                ("realism.motion_blur.exposure_s=0.25",
                                 "realism.motion_blur.exposure_s")):
            cfg = compose_config("datagen", [*SMALL, override, f"out_dir={out}"])
            with pytest.raises(ValueError, match=match):
                gen.run(cfg, progress=False)
            assert not out.exists()


class TestRender:
    def test_blur_and_rolling_shutter_frames_are_their_own(self, tmp_path):
        """Lens, blur and rolling shutter on: a frame re-rendered alone after it was lost is
        the same (its sub-frames and seeds are its own); the blurred frame differs from the
        sharp one but keeps its labels close (rows from the nearest sub-frame)."""
        fx = [*LENS, "realism.motion_blur.exposure_s=0.02",
              "realism.rolling_shutter.readout_s=0.03", "realism.subframes.max_count=4"]
        sharp, out = tmp_path / "sharp", tmp_path / "fx"
        gen.run(compose_config("datagen", [*SMALL, *LENS, f"out_dir={sharp}"]), progress=False)
        cfg = compose_config("datagen", [*SMALL, *fx, f"out_dir={out}"])
        gen.run(cfg, progress=False)
        job = prepare(cfg)
        fo = optics.FlightOptics.build(job.cfg.realism, job.camera,
                                       job.flights["paper"]["groundtruth"], 10.0)
        assert [len(fo.subframes(i)[0].times) for i in range(3)] != [1, 1, 1]
        d = out / "flights" / "paper"
        written = {s: read_png(d / s / "000002.png", rgb=s == "rgb") for s in ("rgb", "label")}
        for s in ("rgb", "label"):
            (d / s / "000002.png").unlink()
        gen.run(cfg, progress=False)
        assert (read_png(d / "rgb" / "000002.png") == written["rgb"]).mean() > 0.99  # LLVM
        np.testing.assert_array_equal(read_png(d / "label" / "000002.png", rgb=False),
                                      written["label"])
        flight = json.loads((d / "flight.json").read_text())
        assert flight["realism"]["motion_blur"]["exposure_s"] == 0.02
        s = sharp / "flights" / "paper"
        for i in (1, 2):
            name = f"{i:06d}.png"
            assert not np.array_equal(read_png(d / "rgb" / name), read_png(s / "rgb" / name))
            same = read_png(d / "label" / name, rgb=False) == read_png(s / "label" / name,
                                                                        rgb=False)
            assert same.mean() > 0.9

    def test_rolling_shutter_of_a_yawing_camera(self):
        """Rendered: a camera yawing left at 90 deg/s (the scene moves right in the image) with
        a 60 ms readout. Against the global-shutter frame at t, each row's labels are shifted
        right by about f * yaw rate * (t_r - t): top rows (read early) to the left, bottom rows
        to the right, so vertical edges slant."""
        from core.imaging.variant import choose_variant

        choose_variant("auto")
        cfg = compose_config("datagen", [*SMALL, "realism.rolling_shutter.readout_s=0.06",
                                         "realism.subframes.step_px=0.5"])
        job = prepare(cfg)
        scene = flight_scene(job, "paper")
        rate = np.radians(90.0)  # rad/s, positive: to the left (z up)
        mid = job.flights["paper"]["groundtruth"][1]
        gt = np.stack([mid.copy() for _ in range(3)])
        for k in range(3):
            gt[k, :3, :3] = Rotation.from_rotvec([0, 0, rate * (k - 1) / 10.0]).as_matrix() \
                @ mid[:3, :3]
        fo = optics.FlightOptics.build(job.cfg.realism, job.camera, gt, 10.0)
        renderer = new_renderer(job, scene.textures, scene.clutter, scene.people)
        renderer.set_lights(scene.lights)
        renderer.set_objects(np.concatenate([scene.placed, scene.tracks[:, 1]], axis=0),
                             scene.colours)
        plan, poses = fo.subframes(1)
        traced = []
        for pose in poses:
            renderer.set_camera(pose @ job.camera.body_from_cam)
            traced.append(renderer.trace(1, 0, albedo=True))
        _, rolled, _ = fo.finish(renderer.developer, traced, plan, 1.6, 4.0)
        renderer.set_camera(mid @ job.camera.body_from_cam)
        _, still, _ = renderer.render(1, 0)
        H = still.shape[0]
        f = job.camera.K[0, 0]
        shifts = np.arange(-12, 13)
        agree = np.stack([(rolled == np.roll(still, s, axis=1))[:, 12:-12].mean(axis=1)
                          for s in shifts])  # (shifts, H)
        best = shifts[agree.argmax(axis=0)]
        expect = f * rate * (optics.row_times(0.1, H, 0.06) - 0.1)  # px, +: right
        assert best[:10].mean() < -2.5 and best[-10:].mean() > 2.5  # expected: -4.2, +4.1
        assert np.median(np.abs(best - expect)) <= 1.5
