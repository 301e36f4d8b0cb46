"""world=procedural: office floors drawn from a seed (datagen/worlds/procedural.py), built into a
site as an imported building is."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage

import datagen.generate as gen
from core import classes as C
from core.atomic import read_png
from core.config import compose_config
from core.dataset import Dataset
from core.occupancy import OccupancyMap
from datagen.config import ProceduralWorldConfig, world_config
from datagen.flights.routes import find_turns, plan_route, route_length
from datagen.worlds.__main__ import main
from datagen.worlds.procedural import build_floor, draw_plan
from datagen.worlds.site import build_site

#: A smaller floor than the default (a 3 x 2 or 2 x 2 corridor grid): fast.
SMALL = ProceduralWorldConfig(size=[26.0, 22.0], grid_spacing=[6.0, 7.0])


def floor(seed: int, **changes):
    return build_floor(replace(SMALL, seed=seed, **changes))


def junctions(plan) -> tuple[int, int]:
    """(L, T) junction counts of a plan: nodes where two perpendicular corridors meet, and
    nodes where three do."""
    degree = np.bincount(plan.edges.ravel(), minlength=len(plan.nodes))
    horizontal = plan.nodes[plan.edges[:, 0], 1] == plan.nodes[plan.edges[:, 1], 1]
    n_h = np.bincount(plan.edges[horizontal].ravel(), minlength=len(plan.nodes))
    ell = (degree == 2) & (n_h == 1)
    return int(ell.sum()), int((degree == 3).sum())


class TestPlan:
    def test_same_seed_same_mesh(self):
        (a, pa), (b, pb) = floor(4), floor(4)
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.faces, b.faces)
        np.testing.assert_array_equal(a.face_class, b.face_class)
        np.testing.assert_array_equal(pa.rects, pb.rects)

    def test_other_seeds_other_plans(self):
        plans = [floor(seed)[1] for seed in range(4)]
        keys = {(len(p.rects), round(float(p.rects.sum()), 3)) for p in plans}
        assert len(keys) == 4

    @pytest.mark.parametrize("seed", [0, 1, 2])
    def test_every_class_and_the_parts(self, seed):
        b, plan = floor(seed)
        present = set(np.unique(b.face_class))
        assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW} <= present
        assert present <= {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW}
        roles = set(plan.roles)
        assert {"corridor", "junction", "lobby", "room", "door"} <= roles
        assert plan.info["rooms"] == plan.info["doors"] >= 3
        assert junctions(plan)[0] >= 1  # an L at least (a ring's corners)
        assert b.info["floor_z"] == 0.0 and b.info["format"] == "procedural"
        area = b.info["class_shares"]
        assert sum(area.values()) == pytest.approx(1.0, abs=1e-3)

    def test_loops_and_features(self):
        """A 2 x 2 grid or larger has at least one loop; over seeds the drawn features
        (columns, recesses, glass walls) all appear."""
        plans = [floor(seed)[1] for seed in range(6)]
        assert all(p.loops >= 1 for p in plans)
        assert sum(junctions(p)[1] for p in plans) >= 2  # T junctions
        for key in ("columns", "recesses", "glass_walls"):
            assert sum(p.info[key] for p in plans) > 0, key
        none = floor(0, loops=0.0, columns=0.0, recesses=0.0, glass=0.0)[1]
        assert none.info["columns"] == none.info["recesses"] == none.info["glass_walls"] == 0
        assert none.loops == 1  # the one loop a 2 x 2 grid always gets

    @pytest.mark.parametrize("seed", [0, 5])
    def test_sizes_within_ranges(self, seed):
        s = replace(SMALL, seed=seed, corridor_width=[1.5, 2.5], height=[2.6, 3.2])
        b, plan = build_floor(s)
        assert np.all((plan.corridor_widths >= 1.5) & (plan.corridor_widths <= 2.5))
        assert 2.6 <= plan.height <= plan.lobby_height <= 3.2
        # the mesh: ceilings at the corridor / room height, the lobby's, or a door's head
        tri = b.vertices[b.faces]
        z = tri[b.face_class == C.CEILING][:, :, 2]
        assert set(np.unique(z.round(6))) <= {round(plan.height, 6),
                                              round(plan.lobby_height, 6)}
        door_z = plan.tops[plan.roles == "door"]
        assert np.all((door_z >= s.door_height[0]) & (door_z <= s.door_height[1]))
        assert b.vertices[:, 2].min() == 0.0 and b.vertices[:, 2].max() <= 3.2 + 1e-9
        # each corridor's free width across it on the mesh: the least over its middle part
        # (doors and recesses widen it; no columns below 2.8 m)
        occ = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class, (0.1, 1.5), 0.0, 0.02)
        lobby = plan.rects[plan.roles == "lobby"][0]
        measured = 0
        for (a, bb), w in zip(plan.edges, plan.corridor_widths, strict=True):
            axis = 0 if plan.nodes[a, 1] == plan.nodes[bb, 1] else 1
            across = []
            c = plan.nodes[a, 1 - axis]
            for f in np.linspace(0.3, 0.7, 15):
                p = plan.nodes[a] + f * (plan.nodes[bb] - plan.nodes[a])
                if (lobby[axis] < p[axis] < lobby[axis + 2]  # the lobby widens it here
                        and lobby[1 - axis] < c + w / 2 + 0.2
                        and lobby[3 - axis] > c - w / 2 - 0.2):
                    continue
                d = np.arange(-6.0, 6.0, 0.01)
                pts = np.repeat(p[None], len(d), axis=0)
                pts[:, 1 - axis] += d
                inside = occ.contains(pts)
                centre = len(d) // 2
                lo = centre - np.argmin(inside[centre::-1])
                hi = centre + np.argmin(inside[centre:])
                across.append((hi - lo) * 0.01)
            if across:
                assert min(across) == pytest.approx(w, abs=0.05)
                measured += 1
        assert measured >= len(plan.edges) - 2

    @pytest.mark.parametrize("settings,match", [
        ({"corridor_width": [3.0, 2.0]}, r"world\.corridor_width: \[3\.0, 2\.0\] must be"),
        ({"height": [-1.0, 3.0]}, r"world\.height"),
        ({"size": [-5.0, 20.0]}, r"world\.size"),
        ({"size": [8.0, 8.0]}, r"world\.size: .* too small"),
        ({"glass": 1.5}, r"world\.glass: 1\.5 must be a probability"),
        ({"wall_thickness": 0.0}, r"world\.wall_thickness"),
        ({"door_height": [2.0, 2.6], "height": [2.4, 3.0]}, r"world\.door_height"),
        ({"room_depth": [2.0]}, r"world\.room_depth"),
    ])
    def test_bad_settings(self, settings, match):
        with pytest.raises(ValueError, match=match):
            draw_plan(replace(SMALL, **settings), np.random.default_rng(0))
        with pytest.raises(ValueError, match=match):
            build_site({"kind": "procedural", **settings})


@pytest.fixture(scope="module")
def site():
    return build_site(replace(SMALL, seed=2))


class TestSite:
    def test_free_space_connected_and_a_route(self, site):
        w = site.world
        assert w.info["kind"] == "procedural" and w.info["plan"]["rooms"] >= 3
        free = w.free.free
        label, n = ndimage.label(free)
        largest = np.bincount(label.ravel())[1:].max()
        assert largest >= 0.9 * free.sum()  # rooms join the corridors through their doors
        route = plan_route(w.free, np.random.default_rng(0), {"min_turns": 1})
        assert route_length(route) >= 15.0 and len(find_turns(route)) >= 1
        assert w.free.contains(route).all()

    def test_same_structures_as_a_file(self, site):
        w = site.world
        assert site.route is None and site.corridor is None
        assert set(w.info["class_shares"]) == {"floor", "wall", "ceiling", "door", "window"}
        classes = {c for pair in w.segment_classes for c in pair}
        assert {C.FLOOR, C.WALL, C.CEILING, C.DOOR, C.WINDOW} <= classes
        assert site.floor.area > w.free.area
        assert site.scene.num_lights > 10

    def test_hydra_world_procedural(self):
        cfg = compose_config("datagen", ["world=procedural", "world.seed=3",
                                         "world.corridor_width=[1.4,2.0]"])
        spec = world_config(cfg["world"])
        assert isinstance(spec, ProceduralWorldConfig)
        assert spec.seed == 3 and spec.corridor_width == [1.4, 2.0]


def test_cli_plan(tmp_path, capsys):
    """``python -m datagen.worlds``: the plan image and the info of a floor."""
    assert main(["--seed", "1", "--size", "26", "22", "--out", str(tmp_path)]) == 0
    assert read_png(tmp_path / "procedural_1_plan.png").ndim == 3
    info = json.loads((tmp_path / "procedural_1.json").read_text())
    assert info["plan"]["rooms"] >= 3 and info["free_area_m2"] > 100 and info["route_m"] > 10
    assert main(["--size", "5", "5", "--out", str(tmp_path)]) == 2
    assert "world.size" in capsys.readouterr().err


def test_tiny_dataset(tmp_path):
    """``python -m datagen world=procedural flights=floor``, shrunk: a dataset renders."""
    out = tmp_path / "ds"
    cfg = compose_config("datagen", [
        "world=procedural", "world.seed=3", "world.size=[26,22]", "world.grid_spacing=[6,7]",
        "flights=floor", "camera.width=64", "camera.height=48", "splits.train=3",
        "splits.val=1", "splits.test=0", "render.spp=1", "training.chunk=2",
        "render_flights=[paper]", "flights.paper.num_frames=5", "val_flights=[]",
        f"out_dir={out}"])
    gen.run(cfg, progress=False)
    ds = Dataset(out)
    info = json.loads((out / "world" / "world.json").read_text())
    assert info["kind"] == "procedural" and info["plan"]["rooms"] >= 3
    assert len(list((out / "train" / "rgb").glob("*.png"))) == 3
    assert len(list((out / "flights" / "paper" / "rgb").glob("*.png"))) == 5
    assert ds.world().free.area == pytest.approx(info["free_space"]["area_m2"], abs=1e-3)


def test_generalist_recipe_composes():
    """datagen_experiment=generalist_floors: each floor of the sweep is its own dataset, with
    its own seed and a field of view that cycles through 60-100 deg; the training recipe reads
    them all through a glob pattern."""
    fovs = []
    for seed in range(6):
        cfg = compose_config("datagen",
                             ["datagen_experiment=generalist_floors", f"world.seed={seed}"])
        assert cfg["name"] == f"generalist/floor{seed}" and cfg["seed"] == seed
        assert cfg["world"]["kind"] == "procedural" and cfg["render_flights"] == []
        fovs.append(cfg["camera"]["hfov_deg"])
    assert fovs == [60, 70, 80, 90, 100, 60]
    train = compose_config("train", ["experiment=generalist"])
    assert train["dataset"] == "outputs/datasets/generalist/floor*"
