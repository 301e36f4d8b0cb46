"""``python -m datagen.mesh.rebuild_edges``: a dataset's edges.npz rebuilt from its model.npz."""

from __future__ import annotations

import json

import numpy as np

from core.dataset import load_world
from datagen.mesh.rebuild_edges import dataset_crease_deg, main
from datagen.worlds.corridor import build_world
from datagen.worlds.save import save_world


def _dataset(tmp_path, crease=20.0):
    w = build_world().world
    save_world(tmp_path / "world", w)
    (tmp_path / "dataset.json").write_text(json.dumps(
        {"generator": {"world": {"crease_deg": crease}}}))
    return w


def test_rebuild_writes_the_current_edges(tmp_path, capsys):
    w = _dataset(tmp_path)
    np.savez(tmp_path / "world" / "edges.npz", segments=w.segments[:3],
             classes=w.segment_classes[:3], crease_deg=w.crease_deg[:3])
    assert main([str(tmp_path)]) == 0
    assert "3 -> 132 model edge segments" in capsys.readouterr().out
    got = load_world(tmp_path / "world")
    assert np.array_equal(got.segments, w.segments)
    assert np.array_equal(got.segment_classes, w.segment_classes)
    assert got.info["num_edges"] == 132
    assert sorted(p.name for p in (tmp_path / "world").iterdir() if p.name.startswith("."))\
        == []  # no temporary file left


def test_the_dataset_crease_threshold_is_used(tmp_path):
    _dataset(tmp_path, crease=95.0)  # no crease of the corridor is above 95 degrees
    assert dataset_crease_deg(tmp_path) == 95.0
    assert main([str(tmp_path)]) == 0
    w = load_world(tmp_path / "world")
    assert (w.segment_classes[:, 0] != w.segment_classes[:, 1]).all()  # class changes only
    assert main([str(tmp_path), "--crease-deg", "20"]) == 0
    assert len(load_world(tmp_path / "world").segments) == 132


def test_a_folder_without_a_model_is_an_error(tmp_path, capsys):
    assert main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "model.npz" in err and "dataset folder" in err
