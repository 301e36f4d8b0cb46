"""The furnished-room kinds (datagen/distractors/furniture.py): their meshes, their parts'
colours, their placement as chains of circles, the furnished preset, and a render that labels
them clutter."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from core import classes as C
from core.config import compose_config, typed
from core.occupancy import OccupancyMap
from datagen.appearance.materials import (
    BODY,
    DARK,
    ITEM,
    TONES,
    object_colours,
    part_colours,
    part_palettes,
)
from datagen.config import DatagenConfig
from datagen.distractors.meshes import (
    FURNISHED_KINDS,
    MAX_FACES,
    footprint_circles,
    make_clutter_mesh,
)
from datagen.distractors.placement import place_objects, placed_circles
from datagen.distractors.presets import check_preset
from datagen.rendering.split import _slot_meshes

HEIGHTS = {"shelf": (1.8, 2.4), "shelf_rows": (1.8, 2.4), "desk": (0.72, 1.4),
           "counter": (0.9, 1.65), "bed": (0.8, 2.05)}  # m, the tallest point
ROOM = np.array([0.0, 0.0, 8.0, 6.0])  # a room's floor, x0, y0, x1, y1 (m)
FLOOR = OccupancyMap.from_boxes(ROOM[None], (0.05, 2.45), cell=0.05)
MARGIN = 0.05  # m, the wall margin


def covered(xy: np.ndarray, circles: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """(N,) whether each point (N, 2) lies in one of the circles (C, 3)."""
    d = np.linalg.norm(xy[:, None, :] - circles[None, :, :2], axis=-1)
    return np.any(d <= circles[None, :, 2] + tol, axis=1)


def placed_vertices(mesh, pose: np.ndarray) -> np.ndarray:
    """(V, 2) m the mesh's vertices in the world for a placement pose (3,) x, y, yaw."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    v = np.asarray(mesh.vertices)[:, :2]
    return v @ np.array([[c, s], [-s, c]]) + pose[:2]


class TestKinds:
    @pytest.mark.parametrize("kind", FURNISHED_KINDS)
    def test_mesh_on_the_floor_inside_its_footprint(self, kind):
        for seed in range(6):
            mesh = make_clutter_mesh(kind, np.random.default_rng(seed))
            lo, hi = mesh.bounds
            v = np.asarray(mesh.vertices)
            assert np.isfinite(v).all() and len(mesh.faces) <= MAX_FACES
            assert mesh.faces.max() < len(v) and (mesh.area_faces > 1e-10).all()
            assert abs(lo[2]) < 1e-9  # on the floor, and standing: what touches it spans
            feet = v[v[:, 2] < 0.005, :2]  # a good part of the footprint
            assert ConvexHull(feet).volume > 0.15 * np.prod(hi[:2] - lo[:2])
            assert HEIGHTS[kind][0] <= hi[2] <= HEIGHTS[kind][1]
            np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9)  # centred
            circles = footprint_circles(mesh)
            assert covered(v[:, :2], circles).all()  # the footprint holds the mesh
            parts, tones = mesh.metadata["parts"], mesh.metadata["tones"]
            assert parts.shape == (len(v),) and parts.min() == 0
            assert parts.max() == len(tones) - 1 and set(tones) <= set(range(len(TONES)))

    def test_deterministic(self):
        for kind in FURNISHED_KINDS:
            a = make_clutter_mesh(kind, np.random.default_rng(7))
            b = make_clutter_mesh(kind, np.random.default_rng(7))
            np.testing.assert_array_equal(a.vertices, b.vertices)
            np.testing.assert_array_equal(a.metadata["parts"], b.metadata["parts"])

    def test_shelves_hold_many_books_within_the_carcass(self):
        for seed in range(6):
            mesh = make_clutter_mesh("shelf", np.random.default_rng(seed))
            tones, parts = mesh.metadata["tones"], mesh.metadata["parts"]
            assert (tones == ITEM).sum() >= 25  # books and boxes, each its own part
            v = np.asarray(mesh.vertices)
            books = v[tones[parts] == ITEM]
            lo, hi = mesh.bounds
            assert (books[:, :2] >= lo[:2] - 1e-9).all()
            assert (books[:, :2] <= hi[:2] + 1e-9).all()
            assert books[:, 2].max() < hi[2] - 0.01  # under the top board

    def test_rows_leave_aisles(self):
        """Each run is a chain of circles of its own, with 0.8 m or more of free floor between
        neighbouring runs: a camera may stand in an aisle."""
        for seed in range(6):
            mesh = make_clutter_mesh("shelf_rows", np.random.default_rng(seed))
            circles = footprint_circles(mesh)
            xs = np.unique(np.round(circles[:, 0], 6))
            assert len(xs) >= 2
            r = circles[:, 2].max()
            assert np.diff(xs).min() - 2 * r >= 0.8

    def test_bed_head_at_the_back_and_desk_screens_at_the_back(self):
        for seed in range(6):
            bed = make_clutter_mesh("bed", np.random.default_rng(seed))
            v = np.asarray(bed.vertices)
            lo, hi = bed.bounds
            head, foot = v[v[:, 0] < lo[0] + 0.06], v[v[:, 0] > hi[0] - 0.06]
            assert head[:, 2].max() > foot[:, 2].max() + 0.1  # head board at -x, the wall
            desk = make_clutter_mesh("desk", np.random.default_rng(seed))
            v, tones = np.asarray(desk.vertices), desk.metadata["tones"][desk.metadata["parts"]]
            screens = v[(tones == DARK) & (v[:, 2] > 0.9)]
            assert len(screens) and screens[:, 0].max() < 0.0  # behind the desk's middle


class TestPartColours:
    def test_tones(self):
        mesh = make_clutter_mesh("shelf", np.random.default_rng(0))
        tones = mesh.metadata["tones"]
        body = np.array([0.1, 0.2, 0.3], np.float32)
        a = part_colours(np.random.default_rng(1), tones, body)
        assert a.shape == (len(tones), 3) and a.dtype == np.float32
        assert (a >= 0.02 - 1e-6).all() and (a <= 0.8 + 1e-6).all()
        items = a[tones == ITEM]
        assert len(np.unique(np.round(items, 3), axis=0)) > 0.9 * len(items)  # many colours
        np.testing.assert_array_equal(a, part_colours(np.random.default_rng(1), tones, body))
        np.testing.assert_array_equal(part_colours(np.random.default_rng(2), [BODY], body)[0],
                                      body)
        with pytest.raises(ValueError, match="tones"):
            part_colours(np.random.default_rng(0), [len(TONES)], body)

    def test_no_draw_without_tones(self):
        """Objects without parts keep their colour and draw nothing: the ten first kinds'
        scenes are drawn as they always were."""
        rng, ref = np.random.default_rng(3), np.random.default_rng(3)
        colours = object_colours(np.random.default_rng(0), 3)
        out = part_palettes(rng, colours, [None, None, None])
        np.testing.assert_array_equal(np.stack(out), colours)
        assert rng.random() == ref.random()


def meshes_of(kinds: list[str], seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    return [make_clutter_mesh(k, rng) for k in kinds]


class TestPlacement:
    KINDS = ["shelf_rows", "counter", "bed", "desk", "shelf", "shelf", "desk", "bed"]

    def test_clear_of_walls_each_other_and_the_camera(self):
        keep = np.array([[4.0, 3.0, 0.45]])
        for seed in range(6):
            meshes = meshes_of(self.KINDS, seed)
            shapes = [footprint_circles(m) for m in meshes]
            xy_yaw, placed = place_objects(np.random.default_rng(seed), shapes, FLOOR, keep,
                                           against_walls=0.6, wall_margin=MARGIN, aligned=0.8)
            assert placed.sum() >= 5
            for k in np.flatnonzero(placed):  # the meshes themselves stay inside the room
                v = placed_vertices(meshes[k], xy_yaw[k])
                assert (v >= ROOM[:2] + MARGIN - 0.01).all()
                assert (v <= ROOM[2:] - MARGIN + 0.01).all()
                assert np.linalg.norm(v - keep[0, :2], axis=1).min() >= 0.45 - 0.01
            world = [placed_circles([s], xy_yaw[k:k + 1]) for k, s in enumerate(shapes)
                     if placed[k]]
            for i in range(len(world)):
                for j in range(i):
                    d = np.linalg.norm(world[i][:, None, :2] - world[j][None, :, :2], axis=-1)
                    assert (d >= world[i][:, None, 2] + world[j][None, :, 2] - 1e-9).all()

    def test_against_walls_back_first_and_square(self):
        """A shelf against a wall has its back at the wall and faces the room; free-standing
        objects aligned turn square to the walls (the room's axes)."""
        meshes = meshes_of(["shelf"] * 6, 1)
        shapes = [footprint_circles(m) for m in meshes]
        xy_yaw, placed = place_objects(np.random.default_rng(2), shapes, FLOOR,
                                       against_walls=1.0, wall_margin=MARGIN)
        assert placed.all()
        for m, pose in zip(meshes, xy_yaw, strict=True):
            v = placed_vertices(m, pose)
            gaps = np.stack([v[:, 0] - ROOM[0], v[:, 1] - ROOM[1], ROOM[2] - v[:, 0],
                             ROOM[3] - v[:, 1]], 1).min(0)
            assert gaps.min() >= MARGIN - 1e-6 and gaps.min() <= MARGIN + 0.1  # at a wall
            side = int(np.argmin(gaps))
            away = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])[side]
            assert np.cos(pose[2]) * away[0] + np.sin(pose[2]) * away[1] > 0.99  # faces in
        xy_yaw, placed = place_objects(np.random.default_rng(3), shapes, FLOOR,
                                       wall_margin=MARGIN, aligned=1.0)
        quarter = np.abs(np.angle(np.exp(4j * xy_yaw[placed, 2]))) / 4  # off the axes
        assert (quarter < np.deg2rad(1)).mean() >= 0.8  # (a corner's normal is diagonal)

    def test_in_sight_of_the_camera(self):
        """With a view, objects stand ahead of the camera within the reach, none behind a
        wall: a wall across the room at x = 4 hides its far half."""
        halves = OccupancyMap.from_boxes(np.array([[0.0, 0.0, 3.9, 6.0], [4.1, 0.0, 8.0, 6.0],
                                                   [3.9, 4.5, 4.1, 6.0]]), (0.05, 2.45), 0.05)
        view = np.array([1.0, 1.0, 0.0, np.deg2rad(80), 5.0])  # looking +x from (1, 1)
        shapes = [np.array([[0.0, 0.0, 0.15]])] * 12
        xy, placed = place_objects(np.random.default_rng(0), shapes, halves, view=view)
        assert placed.sum() >= 8
        rel = xy[placed, :2] - view[:2]
        assert (np.linalg.norm(rel, axis=1) <= 5.0 + 0.05).all()
        assert (np.abs(np.arctan2(rel[:, 1], rel[:, 0])) <= view[3] + 0.02).all()
        assert (xy[placed, 0] < 4.0).all()  # the door at y > 4.5 is out of sight

    def test_radii_as_before_and_no_map(self):
        """Radii place as one circle each would; an object without a map is not placed."""
        radii = np.array([0.4, 0.3, 0.2])
        a = place_objects(np.random.default_rng(5), radii, FLOOR, against_walls=0.5)
        b = place_objects(np.random.default_rng(5), [np.array([[0.0, 0.0, r]]) for r in radii],
                          FLOOR, against_walls=0.5)
        np.testing.assert_array_equal(a[0], b[0])
        _, placed = place_objects(np.random.default_rng(5), radii, [FLOOR, None, FLOOR])
        np.testing.assert_array_equal(placed, [True, False, True])
        with pytest.raises(ValueError, match="footprint 1"):
            place_objects(np.random.default_rng(0), [np.zeros((1, 3)), np.array([[0, 0, -1]])],
                          FLOOR)


@pytest.fixture(scope="module")
def generalist() -> DatagenConfig:
    return typed(DatagenConfig, compose_config(
        "datagen", ["datagen_experiment=generalist_floors", "world.seed=0"]), "datagen")


class TestFurnishedPreset:
    def test_in_the_generalist_mix(self, generalist):
        p = generalist.distractor_presets["furnished"]
        check_preset(p, "distractor_presets.furnished")
        assert set(FURNISHED_KINDS) <= set(p.kinds)
        assert p.clutter.min >= 6 and p.near_camera_m > 0 and p.aligned > 0
        mix = generalist.training.distractors
        assert mix["furnished"] > 0 and mix["none"] > 0  # some images with none at all
        for key, value in (("aligned", 1.5), ("near_camera_m", -1.0)):
            with pytest.raises(ValueError, match=f"furnished.{key}"):
                check_preset(replace(p, **{key: value}), "distractor_presets.furnished")

    def test_each_kind_list_its_own_slots(self, generalist):
        """Presets of one kind list share slots (paper, cluttered: today's five kinds), the
        varied and furnished presets have theirs, so their kinds are drawn; a preset
        without clutter sees all."""
        names = list(generalist.training.distractors)
        presets = [generalist.distractor_presets[n] for n in names]
        clutter, people, slots_of = _slot_meshes(np.random.default_rng(0), presets)
        of = dict(zip(names, slots_of, strict=True))
        assert of["paper"] == of["cluttered"] and len(of["paper"]) == 10
        assert not set(of["varied"]) & set(of["paper"])
        assert len(of["furnished"]) == presets[names.index("furnished")].clutter.max
        assert of["none"] == list(range(len(clutter)))
        kinds = {len(clutter[i].metadata.get("tones", [])) > 0 for i in of["furnished"]}
        assert True in kinds  # furnished kinds among them
        assert len(people) == max(p.people.max for p in presets)


def test_furniture_labelled_clutter_in_a_render():
    """Shelves, a counter and a desk against the corridor's walls render as clutter:
    every pixel whose label they change is clutter, they fill a good part of the view, and
    the shelf's books show many colours."""
    from core.imaging.variant import choose_variant
    from core.poses import pose_from_xyz_rpy
    from datagen.appearance.textures import sample_textures
    from datagen.job import make_camera
    from datagen.rendering.render import Renderer
    from datagen.worlds.site import corridor_site

    choose_variant()
    cfg = compose_config("datagen", ["camera.width=160", "camera.height=120"])
    site = corridor_site(typed(DatagenConfig, cfg, "datagen").world)
    camera = make_camera(cfg["camera"])
    meshes = meshes_of(["shelf", "counter", "desk", "shelf"], 3)
    tex = sample_textures(np.random.default_rng(0), 32, cfg["appearance"])
    r = Renderer(site.scene, camera, tex, clutter=meshes)
    r.set_lights(np.full((r.num_lights, 3), 6.0))
    body = pose_from_xyz_rpy([0.0, 0.6, 1.4], [0.0, 0.15, np.pi / 2])[0]
    cam = (body @ camera.body_from_cam)[:3, 3]
    rng = np.random.default_rng(1)
    xy_yaw, placed = place_objects(rng, [footprint_circles(m) for m in meshes],
                                   [site.floor_for(m.bounds[1][2]) for m in meshes],
                                   np.array([[cam[0], cam[1], 0.45]]), against_walls=1.0,
                                   wall_margin=0.05, view=np.array([*cam[:2], np.pi / 2,
                                                                    0.6, 6.0]))
    assert placed[0] and placed.sum() >= 3
    colours = part_palettes(rng, object_colours(rng, len(meshes)),
                            [m.metadata["tones"] for m in meshes])
    r.set_camera(body @ camera.body_from_cam)
    r.set_objects(np.full((len(meshes), 3), np.nan), colours)
    _, empty, _ = r.render(spp=1, seed=0)
    r.set_objects(xy_yaw, colours)
    rgb, label, _ = r.render(spp=1, seed=0)
    changed = label != empty
    assert changed.mean() > 0.1
    assert (label[changed] == C.CLUTTER).all()
    shelf = np.zeros(len(meshes), bool)
    shelf[0] = True
    r.set_objects(np.where(shelf[:, None], xy_yaw, np.nan), colours)
    _, only_shelf, _ = r.render(spp=1, seed=0)
    pixels = rgb[(only_shelf == C.CLUTTER) & (label == C.CLUTTER)].astype(float)
    hue = np.arctan2(pixels[:, 1] - pixels[:, 2], 2 * pixels[:, 0] - pixels[:, 1] - pixels[:, 2])
    assert len(pixels) > 200 and np.std(hue) > 0.5  # books of many colours
