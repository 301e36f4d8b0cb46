"""The kidnapped robot: two flights spliced (``core.spliced``), the teleport detected, the
status honest after it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core.atomic import write_png
from core.dataset import Flight
from core.poses import odometry_increment, pose_from_xyzyaw, xyzyaw_from_pose
from core.spliced import flight_segment, kidnapped
from localize.config import FilterConfig
from localize.edge_model import EdgeModel
from localize.filter.particle_filter import apply_increment
from localize.filter.projection import cam_from_world
from localize.localizer import Localizer
from localize.offline.metrics import false_convergence
from tests.localize.test_localize_localizer import SETTINGS

STEP = np.array([0.03, 0.0, 0.0, 0.0])  # forward 3 cm a frame


def walk(start: np.ndarray, n: int) -> np.ndarray:
    """(n, 4) states from ``start``, ``STEP`` each frame."""
    out = [np.asarray(start, dtype=np.float64)]
    for _ in range(n - 1):
        out.append(apply_increment(out[-1][None], STEP)[0])
    return np.array(out)


def rendered_flight(folder, name, truth, renderer, camera, odometry_from_world) -> Flight:
    """A flight along ``truth`` (n, 4) with the model's labels rendered at each pose and its
    odometry in its own frame (``odometry_from_world`` (4, 4) applied to the truth)."""
    rgb, label = [], []
    for i, s in enumerate(truth):
        lab, _ = renderer.render(np.linalg.inv(cam_from_world(s[None], camera.body_from_cam)[0]))
        label.append(folder / f"{name}_l{i:03d}.png")
        rgb.append(folder / f"{name}_r{i:03d}.png")
        write_png(label[-1], lab)
        write_png(rgb[-1], np.repeat(lab[..., None], 3, axis=2))
    gt = pose_from_xyzyaw(truth)
    return Flight(name, rgb, label, np.arange(len(truth)) * 0.1, gt, odometry_from_world @ gt,
                  {})


def test_segment_and_splice_keep_the_odometry_continuous():
    truth_a, truth_b = walk([0.0, 0.0, 1.0, 0.3], 6), walk([5.0, 2.0, 1.2, -2.0], 4)
    other = pose_from_xyzyaw(np.array([[10.0, -3.0, 0.0, 1.1]]))[0]  # b's odometry frame
    a = Flight("a", [f"a{i}" for i in range(6)], [f"la{i}" for i in range(6)],
               np.arange(6) * 0.1, pose_from_xyzyaw(truth_a), pose_from_xyzyaw(truth_a), {})
    b = Flight("b", [f"b{i}" for i in range(4)], [f"lb{i}" for i in range(4)],
               np.arange(4) * 0.1 + 7.0, pose_from_xyzyaw(truth_b),
               other @ pose_from_xyzyaw(truth_b), {})
    seg = flight_segment(a, 2, 3)
    assert len(seg) == 3 and seg.rgb == ["a2", "a3", "a4"] and seg.timestamps[0] == 0.0
    with pytest.raises(ValueError, match="not within its 6 frames"):
        flight_segment(a, 4, 5)
    k = kidnapped(a, b)
    assert len(k) == 10 and k.info["kidnapped_at"] == 6
    np.testing.assert_allclose(np.diff(k.timestamps), 0.1, atol=1e-9)
    inc = [odometry_increment(k.odometry[i - 1], k.odometry[i]) for i in range(1, 10)]
    np.testing.assert_allclose(inc[5], 0.0, atol=1e-9)  # the teleport is not felt
    for i in (0, 6, 8):
        np.testing.assert_allclose(inc[i], STEP, atol=1e-9)  # b's own motion is kept
    jump = np.linalg.norm(xyzyaw_from_pose(k.groundtruth[6])[0, :2] - truth_a[-1, :2])
    assert jump > 5.0  # the truth teleports


@pytest.mark.slow
def test_a_kidnapping_is_detected_and_never_tracked_falsely(small_world, camera, renderer,
                                                             tmp_path):
    """Oracle labels of the small corridor: 12 frames tracked, then the truth teleported 2 m
    to the far end, facing back. The loss is declared within 10 frames, a global set drawn
    again, and the filter never reports ``tracking`` while more than 1 m off for over 1 s."""
    settings = replace(SETTINGS, filter=FilterConfig(num_particles=300, global_particles=4000,
                                                     global_frames=15, lost_frames=5))
    model = EdgeModel.build(small_world, settings).for_mode(small_world, "oracle")
    odo_b = pose_from_xyzyaw(np.array([[3.0, -1.0, 0.0, 0.7]]))[0]
    a = rendered_flight(tmp_path, "a", walk([0.2, 0.6, 1.2, np.deg2rad(80.0)], 12), renderer,
                        camera, np.eye(4))
    b = rendered_flight(tmp_path, "b", walk([-0.1, 3.2, 1.3, np.deg2rad(-95.0)], 30), renderer,
                        camera, odo_b)
    flight = kidnapped(a, b)
    loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                    model=model)
    loc.reset(xyzyaw_from_pose(flight.groundtruth[0])[0])
    status, err, count = [], [], []
    truth = xyzyaw_from_pose(flight.groundtruth)
    for f in flight.steps(images=False, labels=True):
        est = loc.step(None, f.odometry_increment, f.attitude, f.timestamp, labels=f.labels)
        status.append(est.status)
        err.append(float(np.linalg.norm(est.state[:2] - truth[f.index, :2])))
        count.append(est.num_particles)
    at = flight.info["kidnapped_at"]
    assert set(status[:at]) == {"tracking"} and max(err[:at]) < 0.1
    assert "lost" in status[at:at + 10]
    lost = at + status[at:].index("lost")
    assert count[lost + 1] > count[lost]  # a global set over the free space again
    assert not false_convergence(np.array(err), flight.timestamps, status, 1.0, 1.0)
