"""Tests of datagen.distractors: meshes, placement, walking people, presets."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from core.config import compose_config, typed
from core.occupancy import OccupancyMap
from datagen.config import DatagenConfig
from datagen.distractors.crowd import person_tracks
from datagen.distractors.meshes import (
    CLUTTER_KINDS,
    FURNISHED_KINDS,
    SMALL_HEIGHT,
    footprint_radius,
    make_clutter_mesh,
    make_person_mesh,
)
from datagen.distractors.placement import object_poses, place_objects
from datagen.distractors.presets import check_preset, preset_counts, sample_kinds

# the default corridor floor (x in [-1, 1], y in [0, 10]) with a side opening on the left
BOXES = np.array([[-1.0, 0.0, 1.0, 10.0], [-3.0, 5.4, -1.0, 7.0]])
FLOOR = OccupancyMap.from_boxes(BOXES, (0.5, 2.2), cell=0.05)  # where things stand
MAIN = OccupancyMap.from_boxes(BOXES[:1], (0.5, 2.2), cell=0.05)  # the corridor alone
WALL_MARGIN = 0.05


def circles_inside(xy: np.ndarray, r: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(K,) whether each circle lies entirely inside the union of the boxes (its rim, 64
    points, and its centre)."""
    a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    rim = xy[:, None] + r[:, None, None] * np.stack([np.cos(a), np.sin(a)], 1)[None]
    pts = np.concatenate([rim, xy[:, None]], axis=1)
    inside = ((pts[..., None, :] >= boxes[:, :2] - 1e-9)
              & (pts[..., None, :] <= boxes[:, 2:] + 1e-9)).all(-1).any(-1)
    return inside.all(1)


SMALL_KINDS = tuple(k for k in CLUTTER_KINDS if k not in FURNISHED_KINDS)


class TestMeshes:
    @pytest.mark.parametrize("kind", SMALL_KINDS)
    def test_clutter_bounds(self, kind):
        """The first ten kinds (the furnished ones: tests/datagen/test_furniture.py)."""
        for seed in range(8):
            mesh = make_clutter_mesh(kind, np.random.default_rng(seed))
            lo, hi = mesh.bounds
            assert isinstance(mesh, trimesh.Trimesh)
            assert abs(lo[2]) < 1e-9, "must stand on z = 0"
            assert 0.2 < hi[2] <= SMALL_HEIGHT + 1e-9
            np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9)  # centred
            assert footprint_radius(mesh) < 0.75  # fits in a 2 m corridor with room
            assert len(mesh.faces) < 2000
            assert np.isfinite(mesh.vertices).all()

    def test_person(self):
        for seed in range(8):
            mesh = make_person_mesh(np.random.default_rng(seed))
            lo, hi = mesh.bounds
            assert abs(lo[2]) < 1e-9
            assert 1.5 - 1e-9 <= hi[2] <= 1.95 + 1e-9
            assert len(mesh.faces) < 2000
            assert footprint_radius(mesh) < 0.6
            v = mesh.vertices
            feet = v[v[:, 2] < 0.05]
            assert abs(feet[:, 0].mean()) < 0.15  # origin between the feet
            head = v[v[:, 2] > 0.88 * hi[2]]
            assert head[:, 0].max() > -head[:, 0].min()  # the nose points to +x
            chest = mesh.section(plane_origin=[0, 0, 0.7 * hi[2]], plane_normal=[0, 0, 1])
            extent = np.ptp(chest.vertices, axis=0)
            assert extent[1] > 1.3 * extent[0]  # shoulders across y: facing +/-x

    def test_deterministic(self):
        a = make_clutter_mesh("chair", np.random.default_rng(3))
        b = make_clutter_mesh("chair", np.random.default_rng(3))
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.faces, b.faces)

    def test_unknown_kind(self):
        with pytest.raises(ValueError, match="unknown clutter kind"):
            make_clutter_mesh("piano", np.random.default_rng(0))

    def test_footprint_radius(self):
        box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
        assert footprint_radius(box) == pytest.approx(np.sqrt(0.5))


class TestPlaceObjects:
    def test_no_overlaps_inside_and_clear_of_keepouts(self):
        keep = np.array([[0.0, 5.0, 0.6], [0.3, 2.0, 0.4]])
        for seed in range(20):
            rng = np.random.default_rng(seed)
            radii = rng.uniform(0.15, 0.6, 10)
            xy_yaw, placed = place_objects(rng, radii, FLOOR, keep, wall_margin=WALL_MARGIN)
            assert xy_yaw.shape == (10, 3) and placed.shape == (10,)
            assert placed.sum() >= 6
            assert np.isnan(xy_yaw[~placed]).all()
            xy, r = xy_yaw[placed, :2], radii[placed]
            d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
            gap = d - r[:, None] - r[None]
            assert np.all(gap[~np.eye(len(r), dtype=bool)] >= -1e-9)
            assert circles_inside(xy, r + WALL_MARGIN, BOXES).all()
            dk = np.linalg.norm(xy[:, None] - keep[None, :, :2], axis=-1)
            assert np.all(dk >= r[:, None] + keep[None, :, 2] - 1e-9)
            assert np.all(np.abs(xy_yaw[placed, 2]) <= np.pi)

    def test_too_big_is_unplaced(self):
        xy_yaw, placed = place_objects(np.random.default_rng(0), np.array([0.3, 1.2]), FLOOR)
        np.testing.assert_array_equal(placed, [True, False])

    def test_against_walls(self):
        rng = np.random.default_rng(1)
        radii = np.full(12, 0.3)
        xy_yaw, placed = place_objects(rng, radii, MAIN, against_walls=1.0,
                                         wall_margin=WALL_MARGIN)
        assert placed.all()
        x, y, yaw = xy_yaw.T
        gaps = np.stack([1 - x, 1 + x, 10 - y, y], 1)  # to the walls +x, -x, +y, -y
        nearest = gaps.min(1)
        assert np.all(nearest >= 0.3 + WALL_MARGIN - 1e-9)
        assert np.all(nearest <= 0.3 + WALL_MARGIN + 0.05 + 1e-9)  # touching, within a cell
        away = np.array([[-1, 0], [1, 0], [0, -1], [0, 1]])[gaps.argmin(1)]
        facing = np.cos(yaw) * away[:, 0] + np.sin(yaw) * away[:, 1]
        assert np.all(facing > np.cos(np.deg2rad(46)))  # +x away from the wall (corners: 45)

    def test_deterministic(self):
        radii = np.array([0.4, 0.3, 0.2])
        a = place_objects(np.random.default_rng(5), radii, FLOOR)
        b = place_objects(np.random.default_rng(5), radii, FLOOR)
        np.testing.assert_array_equal(a[0], b[0])

    def test_bad_floor(self):
        with pytest.raises(TypeError, match="OccupancyMap"):
            place_objects(np.random.default_rng(0), [0.2], np.array([[1.0, 0.0, 0.0, 1.0]]))

    def test_object_poses(self):
        T = object_poses(np.array([[1.0, 2.0, np.pi / 2]]))
        np.testing.assert_allclose(T[0] @ [1, 0, 0, 1], [1, 3, 0, 1], atol=1e-12)


class TestPersonTracks:
    def test_inside_walking_and_apart(self):
        fps, radius = 10.0, 0.3
        for seed in range(4):
            rng = np.random.default_rng(seed)
            tracks = person_tracks(rng, 3, 200, fps, MAIN, radius=radius)
            assert tracks.shape == (3, 200, 3)
            xy = tracks[..., :2]
            assert circles_inside(xy.reshape(-1, 2), np.full(600, radius), BOXES[:1]).all()
            step = np.diff(xy, axis=1)
            speed = np.linalg.norm(step, axis=-1) * fps
            assert speed.max() <= 1.4 + 1e-6
            assert np.all(speed.mean(axis=1) > 0.3)  # they walk
            assert np.abs(step[..., 1]).sum() > 3 * np.abs(step[..., 0]).sum()  # along Y
            moving = speed > 0.2
            walk_dir = np.arctan2(step[..., 1], step[..., 0])
            yaw_err = np.abs(np.angle(np.exp(1j * (walk_dir - tracks[:, 1:, 2]))))
            assert np.median(yaw_err[moving]) < np.deg2rad(5)  # yaw is the walking direction
            d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)[np.triu_indices(3, 1)]
            assert (d < 2 * radius - 0.05).mean() < 0.02  # rarely walk through each other

    def test_avoid_obstacles_and_camera(self):
        rng = np.random.default_rng(2)
        obstacles = np.array([[0.6, 3.0, 0.3], [-0.6, 7.0, 0.3]])
        camera = np.column_stack([np.zeros(150), np.linspace(1, 9, 150)])
        tracks = person_tracks(rng, 2, 150, 10.0, MAIN, obstacles=obstacles,
                                 avoid=camera, avoid_radius=0.4)
        xy = tracks[..., :2]
        d_obs = np.linalg.norm(xy[:, :, None] - obstacles[None, None, :, :2], axis=-1)
        assert d_obs.min() >= 0.3 + 0.3 - 1e-6
        d_cam = np.linalg.norm(xy - camera[None], axis=-1)
        assert (d_cam < 0.3 + 0.4 - 0.05).mean() < 0.02

    def test_deterministic_and_empty(self):
        a = person_tracks(np.random.default_rng(9), 2, 50, 10.0, FLOOR)
        b = person_tracks(np.random.default_rng(9), 2, 50, 10.0, FLOOR)
        np.testing.assert_array_equal(a, b)
        assert person_tracks(np.random.default_rng(0), 0, 50, 10.0, FLOOR).shape == (0, 50, 3)


@pytest.fixture(scope="module")
def presets():
    """The composed config's distractor presets (``DistractorPreset``)."""
    return typed(DatagenConfig, compose_config("datagen"), "datagen").distractor_presets


class TestPresets:
    @pytest.mark.parametrize("name", ["none", "paper", "cluttered"])
    def test_presets(self, name, presets):
        cfg = presets[name]
        rng = np.random.default_rng(0)
        for _ in range(20):
            n_clutter, n_people = preset_counts(rng, cfg)
            assert cfg.clutter.min <= n_clutter <= cfg.clutter.max
            assert cfg.people.min <= n_people <= cfg.people.max
            assert set(sample_kinds(rng, n_clutter, cfg)) <= set(cfg.kinds)
        if name == "none":
            assert preset_counts(rng, cfg) == (0, 0)

    def test_new_kinds_only_where_listed(self, presets):
        """The default presets draw today's five kinds; conf/distractors/varied.yaml, added
        as a fourth preset, draws the ten that are not the furnished rooms' kinds."""
        for name in ("none", "paper", "cluttered"):
            assert list(presets[name].kinds) == ["box", "cabinet", "chair", "table", "plant"]
        cfg = typed(DatagenConfig, compose_config(
            "datagen", ["+distractors@distractor_presets.varied=varied",
                        "+training.distractors.varied=0.3"]), "datagen")
        varied = cfg.distractor_presets["varied"]
        assert set(varied.kinds) == set(SMALL_KINDS)
        check_preset(varied)
        drawn = set(sample_kinds(np.random.default_rng(0), 200, varied))
        assert drawn == set(SMALL_KINDS)

    def test_presets_grow(self, presets):
        load = [presets[n] for n in ("none", "paper", "cluttered")]
        assert load[0].clutter.max < load[1].clutter.max < load[2].clutter.min + 1
        assert load[0].people.max < load[1].people.max <= load[2].people.max

    def test_bad_preset(self):
        with pytest.raises(ValueError, match="clutter"):
            preset_counts(np.random.default_rng(0), {"clutter": {"min": 3, "max": 1}})
        with pytest.raises(ValueError, match="kinds"):
            sample_kinds(np.random.default_rng(0), 2, {"kinds": ["piano"]})
