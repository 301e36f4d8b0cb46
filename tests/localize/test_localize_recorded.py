"""``python -m localize recording=PATH``: a recording made from a rendered flight localizes as
the flight does through the dataset path."""

from __future__ import annotations

import numpy as np
import pytest

from core.poses import pose_from_xyzyaw, read_tum, xyzyaw_from_pose
from localize.offline.recorded import run_recording
from localize.offline.runner import run
from localize.recordings.export import export_bag, export_folder
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
    _, truth = read_tum(flat_dataset / "flights" / FLIGHT / "groundtruth.txt")
    out = {"dataset": dataset_path, "truth": truth[:len(dataset_path)]}
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
        filter draws other numbers, so the two runs part by centimetres; the JPEG run is as
        near the truth as the dataset path's, within 2 cm."""
        truth = runs["truth"][:, :3, 3]
        err = {k: np.linalg.norm(runs[k][:, :3, 3] - truth, axis=1) for k in ("dataset", "jpeg")}
        assert err["jpeg"].mean() < err["dataset"].mean() + 0.02, err
        assert err["jpeg"].mean() < 0.1, err

    def test_outputs(self, runs):
        folder = runs["bag_report"].parent
        for name in ("trajectory.txt", "trajectory.json", "trajectories/cnn.txt",
                     "trajectories/cnn.json", "metrics.json", "overlay.png"):
            assert (folder / name).is_file(), name
        text = runs["bag_report"].read_text()
        assert "## Accuracy, tracking init" in text and f"| {FLIGHT} | cnn | " in text
        # the companion: one entry per trajectory line, the filter's own status and confidence
        import json

        health = json.loads((folder / "trajectory.json").read_text())
        t, _ = read_tum(folder / "trajectory.txt")
        np.testing.assert_allclose(health["timestamp"], t, atol=1e-6)
        assert set(health["status"]) <= {"tracking", "ambiguous", "coasting", "lost"}
        c = np.array(health["confidence"])
        assert len(c) == len(t) and ((c >= 0) & (c <= 1)).all() and c[-1] > 0
        m = json.loads((folder / "metrics.json").read_text())["flights"][FLIGHT]["cnn"]
        assert m["mean_confidence"] == pytest.approx(c.mean())


def test_oracle_alone_is_refused(flat_dataset, tmp_path):
    cfg = localize_cfg([*QUICK, f"dataset={flat_dataset}", "modes=[oracle]",
                        f"recording={tmp_path}", f"out_root={tmp_path}"])
    with pytest.raises(ValueError, match="oracle"):
        run_recording(cfg)


@pytest.fixture(scope="module")
def folder_recording(flat_dataset, tmp_path_factory):
    """The flight exported as a PNG folder recording (exact pixels)."""
    d = tmp_path_factory.mktemp("recording")
    return export_folder(flat_dataset, FLIGHT, d / FLIGHT, jpeg_quality=0)


def recording_cfg(flat_dataset, recording, out_root, *extra):
    return localize_cfg([*QUICK, f"dataset={flat_dataset}", f"recording={recording}",
                         f"out_root={out_root}", "name=r1", "modes=[none]", "inits=[tracking]",
                         *extra])


class TestRecordingOutputPolicy:
    """A recording's folder goes through the flight's claim / resume / refuse policy."""

    def test_other_settings_are_refused_then_overwritten(self, flat_dataset, folder_recording,
                                                         tmp_path):
        from core.outputs import OutputFolderError

        report = run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path,
                                             "max_frames=4"))
        folder = report.parent
        with pytest.raises(OutputFolderError, match="max_frames"):
            run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path,
                                        "max_frames=5"))
        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=5",
                                    "overwrite=true"))
        for name in ("trajectory.txt", "trajectories/none.txt"):
            assert len(read_tum(folder / name)[0]) == 5, name

    def test_more_seeds_resume_a_recording_another_first_seed_is_refused(
            self, flat_dataset, folder_recording, tmp_path):
        """A recording runs its first seed alone: ``seeds=[0,1]`` resumes a ``seeds=[0]``
        folder; ``seeds=[1]`` is another run."""
        from core.outputs import OutputFolderError

        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=4",
                                    "seeds=[0]"))
        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=4",
                                    "seeds=[0,1]"))
        with pytest.raises(OutputFolderError, match="seeds"):
            run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path,
                                        "max_frames=4", "seeds=[1]"))

    def test_other_modes_join_the_report(self, flat_dataset, folder_recording, flat_segnet,
                                         tmp_path):
        import json

        model = f"onnx_model={flat_segnet}"
        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=4",
                                    model))
        report = run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path,
                                             "max_frames=4", "modes=[cnn]", model))
        folder = report.parent
        m = json.loads((folder / "metrics.json").read_text())
        assert list(m["flights"][FLIGHT]) == ["cnn", "none"]
        assert m["dataset"] == str(flat_dataset)
        assert m["model"]["onnx_model"] == str(flat_segnet) and m["model"]["onnx_sha256"]
        assert ((folder / "trajectory.txt").read_text()
                == (folder / "trajectories" / "cnn.txt").read_text())

    def test_a_second_run_at_once_is_refused(self, flat_dataset, folder_recording, tmp_path,
                                            monkeypatch):
        from core import outputs

        folder = tmp_path / "r1" / "recordings" / FLIGHT
        held = outputs.claim_output(folder, {}, outputs.FolderPolicy())
        monkeypatch.setattr(outputs, "RUN_WAIT_S", 0.2)
        try:
            # the holder's record differs from this run's: refused naming the keys (the same
            # record: FolderBusy); either way nothing of this run is written
            with pytest.raises(outputs.OutputFolderError, match="another run"):
                run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path))
        finally:
            held.release()
        assert not (folder / "trajectory.txt").exists()


def test_unreadable_frame_is_dropped(flat_dataset, folder_recording, tmp_path):
    """One broken image costs one frame, not the run: it counts as a dropped frame."""
    import json
    import shutil

    rec = tmp_path / FLIGHT
    shutil.copytree(folder_recording, rec)
    broken = sorted((rec / "images").iterdir())[2]
    broken.write_bytes(b"not an image")
    report = run_recording(recording_cfg(flat_dataset, rec, tmp_path / "out", "max_frames=6"))
    m = json.loads((report.parent / "metrics.json").read_text())["flights"][FLIGHT]["none"]
    assert m["num_frames"] == 5 and m["dropped_frames"] == 1
    assert len(read_tum(report.parent / "trajectory.txt")[0]) == 5
    assert "1 frames could not be read" in report.read_text()


def test_cut_short_jpeg_is_dropped(flat_dataset, tmp_path):
    """A JPEG cut short is not fed to the filter: it counts as a dropped frame."""
    import json

    rec = export_folder(flat_dataset, FLIGHT, tmp_path / FLIGHT)
    cut = sorted((rec / "images").iterdir())[2]
    cut.write_bytes(cut.read_bytes()[:-400])
    report = run_recording(recording_cfg(flat_dataset, rec, tmp_path / "out", "max_frames=6"))
    m = json.loads((report.parent / "metrics.json").read_text())["flights"][FLIGHT]["none"]
    assert m["num_frames"] == 5 and m["dropped_frames"] == 1
    assert "1 frames could not be read" in report.read_text()


@pytest.mark.parametrize("setting, match", [
    ("hint.pose=[140,0,1.2,0]", r"^hint\.pose=\[140\.0, 0\.0, 1\.2, 0\.0\]: the position lies "
                                r"\d+\.\d+ m outside the map's free space \(x .* m, y .* m, "
                                r"heights"),
    ("hint.region=[100,100,110,110]", r"^hint\.region=\[100, 100, 110, 110\]: the region does "
                                      r"not overlap the map's free space \(x .* m, y .* m"),
])
def test_start_off_the_map_is_refused(flat_dataset, folder_recording, tmp_path, setting, match):
    """A start pose or a hint region off the map is refused before any run."""
    with pytest.raises(ValueError, match=match):
        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, setting))
    assert not list(tmp_path.glob("**/trajectory.txt"))


def test_report_names_dataset_model_and_frames_run(flat_dataset, flat_segnet, folder_recording,
                                                   tmp_path):
    """report.md names the dataset and the SegNet and counts the frames run, not the
    recording's."""
    report = run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=4",
                                         "modes=[cnn]", f"onnx_model={flat_segnet}"))
    text = report.read_text()
    assert "its first 4 of 30 frames (max_frames=4)" in text, text
    assert f"Dataset `{flat_dataset}`" in text and f"SegNet `{flat_segnet}` (sha256 " in text
    report = run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path / "none",
                                         "max_frames=4"))
    assert "no SegNet (no cnn mode run)" in report.read_text()


def test_max_frames_zero_names_the_key(flat_dataset, folder_recording, tmp_path):
    with pytest.raises(ValueError, match=r"max_frames=0: .*max_frames=null"):
        run_recording(recording_cfg(flat_dataset, folder_recording, tmp_path, "max_frames=0"))


def test_recording_without_truth_reports_no_errors(flat_dataset, folder_recording, tmp_path):
    """The same report without truth: the filter's health and timings, no errors."""
    import json
    import shutil

    rec = tmp_path / FLIGHT
    shutil.copytree(folder_recording, rec)
    (rec / "groundtruth.txt").unlink()
    report = run_recording(recording_cfg(flat_dataset, rec, tmp_path / "out", "max_frames=4"))
    m = json.loads((report.parent / "metrics.json").read_text())
    entry = m["flights"][FLIGHT]["none"]["global"]
    assert entry["num_frames"] == 4 and "mean_position_error_m" not in entry
    assert 0 <= entry["mean_confidence"] <= 1 and m["timing_ms_by_mode"]["none"]
    assert "No ground truth" in report.read_text()
