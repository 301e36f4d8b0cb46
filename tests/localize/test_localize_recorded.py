"""``python -m localize recording=PATH``: a recording made from a rendered flight localizes as
the flight does through the dataset path."""

from __future__ import annotations

import numpy as np
import pytest

from core.poses import pose_from_xyzyaw, read_tum, xyzyaw_from_pose
from localize.recorded import run_recording
from localize.recording_export import export_bag, export_folder
from localize.runner import run
from tests.localize.conftest import QUICK, localize_cfg

FLIGHT = "paper"


@pytest.fixture(scope="module")
def runs(flat_dataset, flat_segnet, tmp_path_factory):
    """The flight through the dataset path, and as a ROS 2 bag and a JPEG folder recording."""
    d = tmp_path_factory.mktemp("recorded")
    base = [*QUICK, f"dataset={flat_dataset}", f"onnx_model={flat_segnet}", f"out_root={d}",
            "name=t", "modes=[cnn]", "inits=[tracking]", "edges.cnn.refine=none"]
    run(localize_cfg([*base, f"flight_names=[{FLIGHT}]"]))
    _, dataset_path = read_tum(d / "t" / "trajectories" / FLIGHT / "cnn_seed0.txt")
    out = {"dataset": dataset_path}
    recordings = {"bag": export_bag(flat_dataset, FLIGHT, d / "bag" / FLIGHT),
                  "jpeg": export_folder(flat_dataset, FLIGHT, d / "jpeg" / FLIGHT,
                                        odometry_frame=pose_from_xyzyaw([3.0, -2.0, 0.5, 0.7])[0])}
    for key, path in recordings.items():
        report = run_recording(localize_cfg([*base, f"recording={path}", f"name={key}",
                                             "recording_topics.groundtruth=/groundtruth"]))
        _, out[key] = read_tum(report.parent / "trajectory.txt")
        out[f"{key}_report"] = report
    return out


@pytest.mark.slow
class TestRecordedFlight:
    def test_bag_tracks_as_the_dataset_path(self, runs):
        """A bag holds the same pixels and float64 poses: the same run, to rounding (the
        odometry passes through an interpolation at its own stamps)."""
        a, b = xyzyaw_from_pose(runs["dataset"]), xyzyaw_from_pose(runs["bag"])
        np.testing.assert_allclose(b[:, :3], a[:, :3], atol=1e-6)

    def test_jpeg_folder_tracks_as_the_dataset_path(self, runs):
        """JPEG moves edge pixels and the odometry is in another frame (TUM's 9 decimals): the
        filter draws other numbers: measured 7 mm apart on average, 19 mm at most."""
        a, b = xyzyaw_from_pose(runs["dataset"]), xyzyaw_from_pose(runs["jpeg"])
        gap = np.linalg.norm(b[:, :3] - a[:, :3], axis=1)
        assert gap.mean() < 0.03, gap

    def test_outputs(self, runs):
        folder = runs["bag_report"].parent
        for name in ("trajectory.txt", "trajectory.json", "trajectories/cnn.txt",
                     "trajectories/cnn.json", "metrics.json", "overlay.png"):
            assert (folder / name).is_file(), name
        assert "mean error" in runs["bag_report"].read_text()
        # the companion: one entry per trajectory line, the filter's own status and confidence
        import json

        health = json.loads((folder / "trajectory.json").read_text())
        t, _ = read_tum(folder / "trajectory.txt")
        np.testing.assert_allclose(health["timestamp"], t, atol=1e-6)
        assert set(health["status"]) <= {"tracking", "coasting", "lost", "global"}
        c = np.array(health["confidence"])
        assert len(c) == len(t) and ((c >= 0) & (c <= 1)).all() and c[-1] > 0
        m = json.loads((folder / "metrics.json").read_text())["modes"]["cnn"]
        assert m["mean_confidence"] == pytest.approx(c.mean())


def test_oracle_alone_is_refused(flat_dataset, tmp_path):
    cfg = localize_cfg([*QUICK, f"dataset={flat_dataset}", "modes=[oracle]",
                        f"recording={tmp_path}", f"out_root={tmp_path}"])
    with pytest.raises(ValueError, match="oracle"):
        run_recording(cfg)
