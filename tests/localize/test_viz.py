"""The viewer: a Viewer logs what a run shows into a readable .rrd, an offline run with
viz=rerun writes one per pass and viz=none writes none and runs the same."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from core.poses import read_tum
from localize.config import LocalizerConfig
from localize.context import settings_of
from localize.localizer import Localizer
from localize.offline.runner import run
from localize.viewers.viz import open_viewer
from tests.localize.conftest import QUICK, localize_cfg


def rrd_entities(path) -> set[str] | None:
    """The entity paths of an .rrd file, read by rerun's own reader; None where that reader
    is not there (the file's rerun header is checked then)."""
    assert path.is_file() and path.stat().st_size > 0
    assert path.read_bytes()[:3] == b"RRF", "not a rerun .rrd file"
    try:
        from rerun_bindings import RrdReaderInternal
    except ImportError:
        return None
    reader = RrdReaderInternal(str(path))
    (entry,) = [e for e in reader.store_entries() if str(e.kind) == "recording"]
    summary = str(reader.store(entry).summary())
    return {line.split()[0] for line in summary.splitlines() if line.startswith("/")}


def test_none_is_no_viewer(small_world, tmp_path):
    assert open_viewer("none", small_world, tmp_path / "x.rrd") is None
    with pytest.raises(ValueError, match="viz='matplotlib'"):
        open_viewer("matplotlib", small_world, tmp_path / "x.rrd")
    with pytest.raises(ValueError, match="viz='web'"):
        settings_of(localize_cfg(["viz=web"]))


def test_viewer_logs_a_run(small_world, camera, renderer, tmp_path):
    pytest.importorskip("rerun")
    start = np.array([0.6, 0.0, 1.2, 0.0])
    loc = Localizer(small_world, camera, "oracle", LocalizerConfig(), np.random.default_rng(0))
    loc.reset(start)
    out = tmp_path / "viz" / "run.rrd"
    with open_viewer("rerun", small_world, out, camera=camera) as viewer:
        for k in range(3):
            truth = np.eye(4)
            truth[:3, 3] = start[:3] + [0.1 * k, 0.0, 0.0]
            labels, _ = renderer.render(truth @ camera.body_from_cam)
            est = loc.step(None, None if k == 0 else np.array([0.1, 0, 0, 0]), None, 0.1 * k,
                           labels=labels)
            viewer.log_step(0.1 * k, C.colorize(labels), labels, est, loc.filter.particles,
                            attitude=truth, truth=truth)
        assert not out.exists()  # written under a temporary name until closed
        with pytest.raises(ValueError, match=r"\(H, W, 3\) uint8"):
            viewer.log_step(1.0, labels, labels, est, None)
    entities = rrd_entities(out)
    assert list(out.parent.iterdir()) == [out]
    if entities is not None:
        assert {"/world/model/mesh", "/world/model/edges", "/world/camera/image",
                "/world/camera/labels", "/world/camera/edges", "/world/particles",
                "/world/trajectory/estimate", "/world/trajectory/truth",
                "/status/confidence", "/status/log"} <= entities


def test_viewer_discards_a_failed_pass(small_world, tmp_path):
    pytest.importorskip("rerun")
    out = tmp_path / "run.rrd"
    with pytest.raises(RuntimeError), open_viewer("rerun", small_world, out):
        raise RuntimeError("the pass failed")
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_unreachable_viewer_is_a_warning(small_world, tmp_path, caplog):
    """viz_connect to a viewer that is not running (a closed port on 127.0.0.1): a warning
    at close, no file, no error."""
    pytest.importorskip("rerun")
    with open_viewer("rerun", small_world, tmp_path / "x.rrd",
                     connect="rerun+http://127.0.0.1:9/proxy"):
        pass
    assert "was not reached" in caplog.text
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_offline_run_writes_one_rrd_per_pass(flat_dataset, flat_segnet, tmp_path):
    """viz=rerun: <report>/viz/<flight>_<mode>.rrd per pass; viz=none: no viz folder and
    the same trajectories."""
    pytest.importorskip("rerun")
    base = [*QUICK, f"dataset={flat_dataset}", f"onnx_model={flat_segnet}",
            f"out_root={tmp_path}", "modes=[cnn]", "inits=[tracking]", "max_frames=4",
            "flight_names=[paper]", "edges.cnn.refine=none"]
    shown = run(localize_cfg([*base, "name=shown", "viz=rerun"])).parent
    plain = run(localize_cfg([*base, "name=plain"])).parent
    assert not (plain / "viz").exists()
    entities = rrd_entities(shown / "viz" / "paper_cnn.rrd")
    if entities is not None:
        assert {"/world/camera/image", "/world/camera/labels", "/world/particles"} <= entities
    traj = "trajectories/paper/cnn_seed0.txt"
    np.testing.assert_array_equal(read_tum(shown / traj)[1], read_tum(plain / traj)[1])
