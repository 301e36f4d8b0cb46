"""A training-only dataset (no flights; the generalist's floors) skips its world's model edges:
the same frames as a build with edges, world/ without edges.npz until
``python -m datagen.mesh.rebuild_edges`` makes them."""

from __future__ import annotations

import json

import numpy as np
import pytest

import datagen.generate as gen
import datagen.job as datagen_job
from core.atomic import read_png
from core.config import compose_config, typed
from core.dataset import load_world
from datagen.config import DatagenConfig
from datagen.mesh.rebuild_edges import main as rebuild_main
from datagen.worlds.site import NO_EDGES

SMALL_FLOOR = ["world=procedural", "world.seed=3", "world.size=[26,22]",
               "world.grid_spacing=[6,7]", "camera.width=64", "camera.height=48",
               "splits.train=3", "splits.val=0", "splits.test=0", "training.chunk=3",
               "render_flights=[]", "val_flights=[]"]


def test_needs_edges():
    cfg = typed(DatagenConfig, compose_config("datagen", SMALL_FLOOR), "datagen")
    assert not datagen_job.needs_edges(cfg, map_active=False)
    assert datagen_job.needs_edges(cfg, map_active=True)
    cfg.val_flights = ["paper"]
    assert datagen_job.needs_edges(cfg, map_active=False)
    cfg.val_flights, cfg.render_flights = [], ["paper"]
    assert datagen_job.needs_edges(cfg, map_active=False)


def test_training_only_floor_same_frames_without_edges(tmp_path, monkeypatch):
    """Rendered without edges, then with (``needs_edges`` forced): labels byte for byte the
    same, RGB within the LLVM variant's rare one-level differences; the edges rebuilt
    afterwards are the ones the build with edges saved."""
    without, with_edges = tmp_path / "without", tmp_path / "with"
    gen.run(compose_config("datagen", SMALL_FLOOR + [f"out_dir={without}"]), progress=False)
    monkeypatch.setattr(datagen_job, "needs_edges", lambda cfg, map_active: True)
    gen.run(compose_config("datagen", SMALL_FLOOR + [f"out_dir={with_edges}"]), progress=False)

    info = json.loads((without / "world" / "world.json").read_text())
    assert info["num_edges"] is None and info["edges"] == NO_EDGES
    assert not (without / "world" / "edges.npz").exists()
    with pytest.raises(FileNotFoundError, match="rebuild_edges"):
        load_world(without / "world")
    assert json.loads((with_edges / "world" / "world.json").read_text())["num_edges"] > 100

    for i in range(3):
        name = f"{i:06d}.png"
        assert (without / "train" / "label" / name).read_bytes() == \
            (with_edges / "train" / "label" / name).read_bytes()
        a = read_png(without / "train" / "rgb" / name).astype(int)
        b = read_png(with_edges / "train" / "rgb" / name).astype(int)
        assert np.abs(a - b).max() <= 1 and (a != b).mean() < 0.01

    assert rebuild_main([str(without)]) == 0
    built, saved = load_world(without / "world"), load_world(with_edges / "world")
    np.testing.assert_array_equal(built.segments, saved.segments)
    np.testing.assert_array_equal(built.segment_classes, saved.segment_classes)
    info = json.loads((without / "world" / "world.json").read_text())
    assert info["num_edges"] == len(saved.segments) and "edges" not in info
