"""``python -m localize`` end to end on the tiny dataset: every mode converges, the report's
shape, resuming, and clear errors for bad input."""

from __future__ import annotations

import json
import logging
import re
import shutil
from types import SimpleNamespace

import numpy as np
import pytest
from omegaconf import OmegaConf

from core.dataset import load_world
from core.occupancy import OccupancyMap
from core.poses import pose_from_xyzyaw, read_tum
from localize.filter.likelihood import LikelihoodConfig
from localize.filter.particle_filter import FilterConfig
from localize.offline.runner import RunSpec, check_resume, run, warn_outside_free_space
from tests.localize.conftest import QUICK, localize_cfg


@pytest.fixture(scope="module")
def report(flat_dataset, flat_segnet, tmp_path_factory):
    """All three modes, tracking and global init, on the flat-shaded tiny flights. The cnn
    mode uses the predicted boundaries themselves (refine=none): on flat class colours some
    class pairs have the same grey level, so Canny refinement (tested in test_localize_edges)
    would drop real boundaries here."""
    out = tmp_path_factory.mktemp("reports")
    cfg = localize_cfg([*QUICK, f"dataset={flat_dataset}", f"onnx_model={flat_segnet}",
                        f"out_root={out}", "name=t", "modes=[none,cnn,oracle]",
                        "inits=[tracking,global]", "edges.cnn.refine=none",
                        "filter.global_particles=6000", "filter.global_frames=8"])
    path = run(cfg)
    return cfg, path


def test_defaults_are_the_composed_configs():
    """LocalizerConfig() and LocalizeConfig() (library use) are what `python -m localize` runs with
    by default: the YAML holds no default of its own."""
    from localize.config import LocalizeConfig, LocalizerConfig
    from localize.context import settings_of

    full = settings_of(localize_cfg([]))
    assert full == LocalizeConfig()
    assert (LocalizerConfig(full.filter, full.edges, full.model_edges, full.visibility)
            == LocalizerConfig())


@pytest.mark.parametrize("preset", ["default", "paper"])
def test_presets_per_mode_k(preset):
    """The tuned preset gives the oracle its own sharper k; the paper's keeps k = 3 and
    sigma = 0.3 in every mode, though its mode_likelihood merges into the default's."""
    from hydra import compose, initialize_config_dir

    from core.config import CONF
    from localize.context import settings_of

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("localize", overrides=[f"filter={preset}"])
    settings = settings_of(cfg)
    fp, lp = settings.filter, settings.likelihood
    k = {m: fp.likelihood_for(m).k for m in ("none", "cnn", "oracle")}
    if preset == "paper":
        assert k == {"none": 3.0, "cnn": 3.0, "oracle": 3.0}
        assert {fp.likelihood_for(m).sigma for m in k} == {0.3}
        assert fp.global_likelihood_config() == lp
    else:
        assert k["oracle"] > k["none"] and k["oracle"] > k["cnn"]


@pytest.mark.slow
class TestEndToEnd:
    def test_each_mode_converges_tracking(self, report):
        # Label modes must track both tiny flights tightly. `none` (Canny on flat-shaded
        # images with distractors, 200 particles) only has to stay near the truth on one of
        # them: on 30 frames a person crossing the 128x96 view, or a recovery particle landing
        # on clutter edges, decides a flight by luck (moving where the people walk flips it).
        cfg, path = report
        m = json.loads((path.parent / "metrics.json").read_text())
        last = {}
        for flight in ("paper", "cluttered"):
            for mode in ("none", "cnn", "oracle"):
                rec = json.loads(RunSpec(flight, mode, "tracking", 0).paths(path.parent)[1]
                                 .read_text())
                last[flight, mode] = np.mean(rec["position_error_m"][-10:])
        for flight in ("paper", "cluttered"):
            for mode in ("cnn", "oracle"):
                assert last[flight, mode] < 0.1, (flight, mode, last[flight, mode])
                assert m["flights"][flight][mode]["mean_position_error_m"] < 0.1
        assert min(last["paper", "none"], last["cluttered", "none"]) < 0.4, last
        for flight in ("paper", "cluttered"):
            for mode in ("none", "cnn", "oracle"):
                assert m["flights"][flight][mode]["failure_rate"] < 0.5, (flight, mode)

    def test_oracle_global_converges(self, report):
        cfg, path = report
        m = json.loads((path.parent / "metrics.json").read_text())
        conv = [m["flights"][f]["oracle"]["global"]["convergence_frames"][0]
                for f in ("paper", "cluttered")]
        assert any(c is not None and c <= 25 for c in conv), conv

    def test_metrics_shape(self, report, flat_dataset):
        cfg, path = report
        m = json.loads((path.parent / "metrics.json").read_text())
        assert set(m) >= {"flights", "timing_ms", "dataset", "realism"}
        assert m["dataset"] == str(flat_dataset)
        assert m["realism"] == "ideal"
        entry = m["flights"]["paper"]["cnn"]
        for key in ("mean_position_error_m", "median_m", "rmse_m", "p95_m",
                    "mean_yaw_error_deg"):
            assert isinstance(entry[key], float)
        assert set(m["timing_ms"]) == {"acquisition", "segmentation", "preprocessing",
                                       "filter", "total"}
        for v in m["timing_ms"].values():
            assert v["min"] <= v["avg"] <= v["max"]
        assert m["timing_mode"] == "cnn"
        assert {t["target"].split(":")[0] for t in m["targets"]}
        outside = entry["truth_outside_free"]  # the flight flies inside its free space
        assert outside["frames"] == 0 and outside["max_m"] == 0.0
        cal = entry["calibration"]
        assert cal["within_m"] == cfg.metrics.calibration_within_m
        assert sum(b["frame_share"] for b in cal["bins"]) == pytest.approx(1.0)
        assert "calibration" in entry["global"]

    def test_files(self, report):
        cfg, path = report
        d = path.parent
        text = path.read_text()
        assert "0.32" in text and "177" in text
        assert "mode cnn: k = 40.0" in text  # conf/filter/default.yaml's mode_likelihood
        assert "mode cnn: [0.01, 0.005, 0.2]" in text  # and its mode_motion_std
        assert "fewer than 15 lines" in text  # and its likelihood.lines_ref
        assert "## Confidence calibration" in text
        for png in ("paper_xy", "paper_topdown", "paper_error", "paper_frame",
                    "paper_calibration"):
            assert (d / "plots" / f"{png}.png").stat().st_size > 1000
            assert f"plots/{png}.png" in text
        t, poses = read_tum(d / "trajectories" / "paper" / "cnn_seed0.txt")
        assert poses.shape == (30, 4, 4) and np.isfinite(poses).all()
        assert (d / "trajectories" / "paper" / "oracle_global_seed0.txt").is_file()

    def test_resume_skips_finished_runs(self, report):
        cfg, path = report
        traj = path.parent / "trajectories" / "paper" / "none_seed0.txt"
        before = traj.stat().st_mtime_ns
        again = run(cfg)
        assert again == path and traj.stat().st_mtime_ns == before
        assert RunSpec("paper", "none", "tracking", 0).done(path.parent)

    def test_resume_refuses_other_settings(self, report):
        """Finished runs made with other filter settings are not mixed into a new report."""
        cfg, path = report
        stored = (path.parent / "config.json").read_text()
        other = OmegaConf.merge(cfg, {"filter": {"likelihood": {"k": 7.0}}})
        with pytest.raises(RuntimeError, match=r"likelihood.k \(.* -> 7.0\).*overwrite=true"):
            run(other)
        assert (path.parent / "config.json").read_text() == stored

    def test_resume_refuses_rebuilt_edges(self, report, tmp_path):
        """Runs made against a dataset's edges are not resumed once its edges.npz changed
        (``python -m datagen.mesh.rebuild_edges``)."""
        cfg, _ = report
        edges = tmp_path / "ds" / "world" / "edges.npz"
        edges.parent.mkdir(parents=True)
        edges.write_bytes(b"old edges")
        other = OmegaConf.merge(cfg, {"dataset": str(tmp_path / "ds")})
        check_resume(tmp_path / "out", other)
        run_file = tmp_path / "out" / "runs" / "paper" / "none_seed0.json"
        run_file.parent.mkdir(parents=True)
        run_file.write_text("{}")  # a finished run
        check_resume(tmp_path / "out", other)  # the same edges: it resumes
        edges.write_bytes(b"rebuilt edges")
        with pytest.raises(RuntimeError, match=r"edges_sha256.*overwrite=true"):
            check_resume(tmp_path / "out", other)

    def test_resume_ignores_speed_only_settings(self, report):
        """Threads and block size change no result: a report resumes across them."""
        cfg, path = report
        traj = path.parent / "trajectories" / "paper" / "none_seed0.txt"
        before = traj.stat().st_mtime_ns
        faster = OmegaConf.merge(cfg, {"filter": {"likelihood": {"workers": 1, "chunk": 17}}})
        assert run(faster) == path and traj.stat().st_mtime_ns == before


def test_likelihood_for_mode():
    lp = LikelihoodConfig(k=25.0)
    fp = FilterConfig(likelihood=lp, mode_likelihood={"cnn": {"k": 5.0, "orientation_bins": 8}})
    cnn = fp.likelihood_for("cnn")
    assert (cnn.k, cnn.orientation_bins, cnn.sigma) == (5.0, 8, lp.sigma)
    assert fp.likelihood_for("oracle") is lp
    # a typo in an override fails when the settings are made, at start-up
    with pytest.raises(ValueError, match=r"filter.mode_likelihood.cnn.kk: Key 'kk' not in"):
        FilterConfig(mode_likelihood={"cnn": {"kk": 1}})
    with pytest.raises(ValueError, match=r"filter.global_likelihood.sigmaa: Key 'sigmaa'"):
        FilterConfig(global_likelihood={"sigmaa": 1})


class TestBadInput:
    def test_missing_dataset(self, tmp_path):
        cfg = localize_cfg([*QUICK, f"dataset={tmp_path / 'nope'}", f"out_root={tmp_path}"])
        with pytest.raises(FileNotFoundError, match="python -m datagen"):
            run(cfg)

    def test_dataset_without_flights(self, tiny_dataset, tmp_path):
        ds = tmp_path / "ds"
        shutil.copytree(tiny_dataset, ds, ignore=shutil.ignore_patterns("flights"))
        cfg = localize_cfg([*QUICK, f"dataset={ds}", f"out_root={tmp_path}",
                            "modes=[oracle]"])
        with pytest.raises(ValueError, match="has no flights"):
            run(cfg)

    def test_unknown_flight_and_mode(self, tiny_dataset, tmp_path):
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "modes=[oracle]", "flight_names=[loop]"])
        with pytest.raises(ValueError, match="available"):
            run(cfg)
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "modes=[sobel]"])
        with pytest.raises(ValueError, match="unknown edge mode"):
            run(cfg)

    @pytest.mark.parametrize("override,match", [
        ("seeds=[]", "seeds is empty"),
        ("modes=[]", "modes is empty"),
        ("seeds=[0,0]", "repeats an entry"),
        ("seeds=[-1]", "not a non-negative integer"),
        ("max_frames=0", "max_frames=0: a run needs at least one frame"),
    ])
    def test_bad_lists(self, tiny_dataset, tmp_path, override, match):
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "modes=[oracle]", override])
        with pytest.raises(ValueError, match=re.escape(match)):
            run(cfg)
        assert not (tmp_path / str(cfg.name)).exists()  # nothing written

    def test_missing_model(self, tiny_dataset, tmp_path):
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "modes=[cnn]", f"onnx_model={tmp_path / 'segnet.onnx'}"])
        with pytest.raises(FileNotFoundError, match="segmentation model not found"):
            run(cfg)

    def test_model_classes_mismatch(self, tiny_dataset, tmp_path):
        from core import classes as C
        from tests.localize.conftest import palette_segnet

        other = C.as_json()  # same count, one class renamed: a model of another dataset
        other[6] = {**other[6], "name": "furniture"}
        onnx_path = palette_segnet(tmp_path / "segnet.onnx", 96, 128, classes=other)
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "modes=[cnn]", f"onnx_model={onnx_path}"])
        with pytest.raises(ValueError, match="do not match the dataset"):
            run(cfg)

    def test_missing_world(self, tiny_dataset, tmp_path):
        ds = tmp_path / "ds"
        shutil.copytree(tiny_dataset, ds)
        (ds / "world" / "edges.npz").unlink()
        cfg = localize_cfg([*QUICK, f"dataset={ds}", f"out_root={tmp_path}", "modes=[oracle]"])
        with pytest.raises(FileNotFoundError, match="edges.npz"):
            run(cfg)

    def test_model_without_structural_edges(self, tiny_dataset, tmp_path):
        """No edge segment with a structural class on a side: refused before any run, naming
        the world, its edges file and the fix."""
        from core import classes as C

        ds = tmp_path / "ds"
        shutil.copytree(tiny_dataset, ds)
        w = load_world(ds / "world")
        np.savez(ds / "world" / "edges.npz", segments=w.segments,
                 classes=np.full_like(w.segment_classes, C.CLUTTER), crease_deg=w.crease_deg)
        cfg = localize_cfg([*QUICK, f"dataset={ds}", f"out_root={tmp_path}", "modes=[oracle]"])
        with pytest.raises(ValueError, match=r"world '.*': no edge segment of world/edges.npz "
                           r"has a floor.*world.name_rules.*model_edges.min_length"):
            run(cfg)


def test_a_building_without_floor_boundary_runs(flat_dataset, tmp_path, caplog):
    """Walls on a slab of their own (no floor-to-wall edge segment): the default global start
    (the table search) falls back to the uniform particle set with one warning for the whole
    run (both flights' localizers), and the run writes its report."""
    from tests.localize.test_global_search import without_floor_boundary

    ds = tmp_path / "slab"
    shutil.copytree(flat_dataset, ds)
    w = without_floor_boundary(load_world(ds / "world"))
    np.savez(ds / "world" / "edges.npz", segments=w.segments, classes=w.segment_classes,
             crease_deg=w.crease_deg)
    cfg = localize_cfg([*QUICK, f"dataset={ds}", f"out_root={tmp_path}", "name=slab",
                        "modes=[oracle]", "inits=[global]", "max_frames=4"])
    assert cfg.filter.global_method == "table"
    with caplog.at_level(logging.WARNING):
        path = run(cfg)
    assert path.is_file()
    warned = [r.getMessage() for r in caplog.records if "falls back" in r.getMessage()]
    assert len(warned) == 1 and "filter.global_method=particles" in warned[0], warned


class TestFlightSets:
    def test_validation_run_and_report_name_the_set(self, tiny_dataset, tmp_path):
        """flight_set=val runs only the validation flights; metrics.json and report.md say
        which flights were used and what the set is for."""
        cfg = localize_cfg([*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}",
                            "name=v", "modes=[oracle]", "inits=[tracking]", "max_frames=3",
                            "flight_set=val"])
        path = run(cfg)
        m = json.loads((path.parent / "metrics.json").read_text())
        assert m["flight_set"] == "val" and m["flights_used"] == ["paper_val"]
        assert set(m["flights"]) == {"paper_val"}
        assert "tuned" in m["flight_set_note"]
        text = path.read_text()
        assert "Flights: paper_val, the validation flights" in text

    def test_default_is_the_test_set(self):
        assert localize_cfg([]).flight_set == "test"

    def test_bad_flight_set(self, tiny_dataset, tmp_path):
        base = [*QUICK, f"dataset={tiny_dataset}", f"out_root={tmp_path}", "modes=[oracle]"]
        with pytest.raises(ValueError, match="flight_set='train'"):
            run(localize_cfg([*base, "flight_set=train"]))
        with pytest.raises(ValueError, match=r"flight_names: \['paper'\] are not val flights"):
            run(localize_cfg([*base, "flight_set=val", "flight_names=[paper]"]))


def test_pose_outside_free_space_is_warned(caplog):
    """A start or a true pose outside the free space: a warning with the distance and the
    keys of the map; none inside."""
    free = OccupancyMap.from_boxes(np.array([[0.0, 0.0, 2.0, 4.0]]), (0.5, 2.2), 0.05)
    truth = pose_from_xyzyaw(np.array([[1.0, 1.0, 1.0, 0.0], [3.0, 1.0, 1.0, 0.0],
                                       [1.0, 2.0, 1.2, 0.0]]))
    inside = SimpleNamespace(name="walk", groundtruth=truth[[0, 2]])
    source = SimpleNamespace(name="walk", groundtruth=truth)
    with caplog.at_level(logging.WARNING, logger="localize.offline.runner"):
        warn_outside_free_space(inside, free, 2, np.array([1.0, 1.0, 1.0, 0.0]), 0.25)
        assert not caplog.records
        warn_outside_free_space(source, free, 3, np.array([1.0, 1.0, 2.6, 0.0]), 0.25)
    start, poses = (r.getMessage() for r in caplog.records)
    assert "start pose [1.0, 1.0, 2.6] lies 0.40 m outside" in start
    assert "walk: 1 of 3 true poses lie outside the free space, up to 0.98 m (frame 1" in poses
    for text in (start, poses):
        assert "world.z_range" in text and "world.camera_margin" in text
        assert "filter.free_space_slack" in text


def test_full_disk_names_the_folder_and_the_key(flat_dataset, tmp_path, monkeypatch):
    """ENOSPC on a write (simulated) ends in a DiskFullError naming the file, the report
    folder, ``out_root=`` and that finished runs are kept."""
    import errno

    from core import atomic

    def full(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "replace", full)
    cfg = localize_cfg([*QUICK, f"dataset={flat_dataset}", f"out_root={tmp_path}", "name=full",
                        "modes=[oracle]", "inits=[tracking]", "max_frames=2",
                        "flight_names=[cluttered]"])
    with pytest.raises(atomic.DiskFullError, match=rf"into {tmp_path / 'full'}\S* failed: the "
                       r"disk is full .* out_root= .* the finished runs are kept"):
        run(cfg)
