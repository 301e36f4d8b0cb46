"""Flights rendered through a distorting lens (realism.lens): the localizer undistorts each
frame (and the oracle's true labels) back to the pinhole K with the calibration in
flight.json, and a recording exported from such a flight carries the lens in camera.yaml."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from core.atomic import read_png
from core.config import compose_config
from core.dataset import Dataset
from datagen import generate as gen
from localize.frontend.sources import LabelFunction
from localize.offline.runner import run
from localize.recordings.export import export_folder
from localize.recordings.read import read_recording
from tests.core.test_lens import EUROC, LENS
from tests.localize.conftest import QUICK, localize_cfg

FRAMES = 12
SMALL = ["camera.width=128", "camera.height=96", "splits.train=0", "splits.val=0",
         "splits.test=0", "render.spp=1", "render_flights=[paper]",
         f"flights.paper.num_frames={FRAMES}"]


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    d = tmp_path_factory.mktemp("lens")
    return {name: gen.run(compose_config("datagen", [*SMALL, *extra, f"out_dir={d / name}"]),
                          progress=False)
            for name, extra in (("ideal", []), ("lens", LENS))}


def test_localizer_undistorts_the_frames(datasets, tmp_path):
    """python -m localize on the lens's flight: the oracle's edge source is given each frame's
    image and true labels undistorted (Flight.image / Flight.labels, the pinhole render's
    geometry), and the filter tracks."""
    seen = []

    def capture(rgb, labels):
        seen.append((rgb, labels))
        return labels

    wrap = {"oracle": lambda own: LabelFunction(capture, "oracle", needs_truth=True)}
    cfg = localize_cfg([*QUICK, f"dataset={datasets['lens']}", f"out_root={tmp_path}",
                        "name=lens", "modes=[oracle]", "inits=[tracking]"])
    run(cfg, source_wrappers=wrap)
    lens, ideal = (Dataset(datasets[k]).flight("paper") for k in ("lens", "ideal"))
    assert len(seen) >= FRAMES  # the run's frames, then the report's figure's
    for t, (rgb, labels) in enumerate(seen[:FRAMES]):
        np.testing.assert_array_equal(rgb, lens.image(t))
        np.testing.assert_array_equal(labels, lens.labels(t))
        raw = read_png(lens.label[t], rgb=False)
        inner = (slice(6, -6), slice(6, -6))
        assert (labels[inner] == ideal.labels(t)[inner]).mean() > 0.97
        assert (raw[inner] == ideal.labels(t)[inner]).mean() < 0.95
    run_file = tmp_path / "lens" / "runs" / "paper" / "oracle_seed0.json"
    assert np.mean(json.loads(run_file.read_text())["position_error_m"]) < 0.15


def test_recording_of_a_lens_flight(datasets, tmp_path):
    """Exported as a folder, a lens flight's frames are its PNGs and camera.yaml holds the
    flight's plumb_bob lens; read back, each frame is undistorted as the dataset reader does."""
    ds = Dataset(datasets["lens"])
    flight = ds.flight("paper")
    out = export_folder(datasets["lens"], "paper", tmp_path / "rec", jpeg_quality=0)
    cam = yaml.safe_load((out / "camera.yaml").read_text())
    np.testing.assert_allclose(cam["distortion_coefficients"]["data"], EUROC)
    rec = read_recording(out, ds.camera)
    np.testing.assert_allclose(rec.camera.K, ds.camera.K, atol=1e-9)
    for t in (0, FRAMES - 1):
        np.testing.assert_array_equal(read_png(sorted((out / "images").iterdir())[t]),
                                      read_png(flight.rgb[t]))
        diff = np.abs(rec.image(t).astype(int) - flight.image(t).astype(int))
        assert diff.max() <= 1
