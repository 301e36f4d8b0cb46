"""``python -m datagen.importers FILE --out DIR``: summary and plan image."""

from __future__ import annotations

import json

import cv2
import numpy as np

from core import classes as C
from datagen.importers import load_building
from datagen.importers.__main__ import main
from datagen.mesh.plan import plan_labels
from tests.datagen.building_files import open_room


def test_cli_and_plan(tmp_path, capsys):
    path = tmp_path / "room.ply"
    open_room().export(path)
    assert main([str(path), "--out", str(tmp_path / "out"), "--px", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "floor" in out and "wall" in out and "ceiling added" in out
    image = cv2.imread(str(tmp_path / "out" / "room_plan.png"))
    assert image is not None and image.shape[0] >= (3 + 1) / 0.05
    info = json.loads((tmp_path / "out" / "room_import.json").read_text())
    assert info["free_area_m2"] > 0 and info["route_m"] >= 40.0  # laps around the one room
    assert cv2.imread(str(tmp_path / "out" / "room_free.png")) is not None
    summary = json.loads((tmp_path / "out" / "room_summary.json").read_text())
    assert summary["up_axis"]["axis"] == "+z" and summary["wall_height_m"] == 2.5
    assert summary["vertical_edges"] >= 4 and "up axis +z (auto" in out
    assert main([str(tmp_path / "none.obj"), "--out", str(tmp_path)]) == 2
    assert "no such file" in capsys.readouterr().err


def test_plan_labels_walls_over_floor(tmp_path):
    path = tmp_path / "room.ply"
    open_room().export(path)
    labels, origin, res = plan_labels(load_building(path), metres_per_px=0.05)
    np.testing.assert_allclose(origin, [-0.5, -0.5])
    rows, cols = labels.shape
    assert (rows, cols) == (80, 100)
    centre = labels[rows // 2, cols // 2]
    assert centre == C.FLOOR
    # the wall x = 0 at column 10 (0.5 m margin), the outside left of it is empty
    assert labels[rows // 2, 10] == C.WALL and labels[rows // 2, 5] == 255
