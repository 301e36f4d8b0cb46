"""Training views of many heights and handheld tilts (``training.z_range``, ``handheld``): the
headroom above the free space (``Site.camera_top``), where tall objects stand
(``Site.floor_for``), and the poses a generalist floor draws."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from core import classes as C
from core.config import compose_config, typed
from core.occupancy import OccupancyMap
from datagen import job as J
from datagen.config import DatagenConfig, ProceduralWorldConfig, TrainingConfig
from datagen.flights import training_views as TV
from datagen.worlds.site import STANDING_BAND, TALL_BAND, build_site, corridor_site

BOXES = np.array([[-0.7, 0.3, 0.7, 9.7]])
Z = np.array([0.5, 2.2])
FREE = OccupancyMap.from_boxes(BOXES, Z, cell=0.05, margin=0.3)
SMALL = ProceduralWorldConfig(size=[26.0, 22.0], grid_spacing=[6.0, 7.0], seed=2)


def tilts_deg(T: np.ndarray) -> np.ndarray:
    """(N, 2) roll, pitch of body poses (N, 4, 4), degrees."""
    return np.rad2deg(Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz"))[:, :2]


class TestPoses:
    def test_handheld_tilts(self):
        """A share of handheld poses pitch up and down to 20 deg and roll to 15; the rest
        keep max_roll_pitch_deg; none drawn when the share is 0."""
        T = TV.sample_training_poses(np.random.default_rng(0), 4000, FREE, Z, 5.0,
                                     handheld=0.5, handheld_deg=(20.0, 15.0))
        roll, pitch = tilts_deg(T).T
        assert np.abs(pitch).max() <= 20 + 1e-6 and np.abs(roll).max() <= 15 + 1e-6
        assert (np.abs(pitch) > 5.01).mean() == pytest.approx(0.5 * 15 / 20, abs=0.03)
        assert (pitch > 10).mean() > 0.1 and (pitch < -10).mean() > 0.1  # up and down
        assert (np.abs(roll) > 10).mean() > 0.08
        np.testing.assert_array_equal(
            TV.sample_training_poses(np.random.default_rng(1), 50, FREE, Z, handheld=0.0),
            TV.sample_training_poses(np.random.default_rng(1), 50, FREE, Z))
        with pytest.raises(ValueError, match="training.handheld"):
            TV.sample_training_poses(np.random.default_rng(0), 3, FREE, Z, handheld=2.0)

    def test_heights_under_the_top(self):
        """Heights are uniform up to the z range's max where the top allows, under the top
        elsewhere, and never capped below the free space's band."""
        def top(xy):
            return np.where(xy[:, 1] < 5.0, 2.0, 2.45)
        T = TV.sample_training_poses(np.random.default_rng(2), 4000, FREE, [0.5, 2.5], top=top)
        p = T[:, :3, 3]
        low = p[:, 1] < 5.0
        assert (p[:, 2] >= 0.5).all()
        assert p[low, 2].max() <= 2.2 + 1e-9  # the band's top (2.2) over a lower top (2.0)
        assert p[~low, 2].max() <= 2.45 + 1e-9 and p[~low, 2].max() > 2.4
        assert (p[~low, 2] > 2.2).mean() == pytest.approx(0.25 / 1.95, abs=0.03)

    def test_defaults_unchanged(self):
        """The flights' and the corridor's conventions stay: training heights are the world's
        band and tilts 5 deg unless a recipe asks (the generalist's)."""
        tr = TrainingConfig()
        assert tr.z_range is None and tr.handheld == 0.0 and tr.max_roll_pitch_deg == 5.0
        cfg = typed(DatagenConfig, compose_config("datagen"), "datagen")
        assert cfg.world.z_range == [0.5, 2.2] and cfg.training.z_range is None


@pytest.fixture(scope="module")
def floor_site():
    return build_site(SMALL)


def distance_to(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    return trimesh.proximity.closest_point(mesh, points)[1]


class TestHeadroom:
    def test_corridor(self):
        """The corridor's ceiling is 2.8 m high: a camera may rise to 2.5 m (door and window
        heads within the margin of the walls keep it to the band's top there)."""
        site = corridor_site(typed(DatagenConfig, compose_config("datagen"), "datagen").world)
        free = site.world.free
        xy = free.sample(np.random.default_rng(0), 2000)
        top = site.camera_top(xy)
        assert (top >= free.band[1] - 1e-9).all() and (top <= 2.5 + 1e-9).all()
        assert np.median(top) == pytest.approx(2.5, abs=1e-6)
        assert site.floor_for(1.0) is site.floor and site.floor_for(2.4) is site.floor
        assert site.floor_for(TALL_BAND[1] + 0.1) is None

    def test_floor_clear_of_every_surface(self, floor_site):
        """At its top a camera is the margin from the model (its ceilings, the heads of its
        doors), and the top is no lower than it must be: 0.15 m higher, a surface is within
        the margin for a good share of the points."""
        w = floor_site.world
        mesh = trimesh.Trimesh(w.vertices, w.faces, process=False)
        xy = w.free.sample(np.random.default_rng(1), 300)
        top = floor_site.camera_top(xy)
        above = top > w.free.band[1] + 1e-6
        assert above.mean() > 0.8 and np.median(top) > 2.1  # ceilings of 2.4 m and more
        pts = np.column_stack([xy, top])[above]
        assert (distance_to(mesh, pts) >= w.free.margin - w.free.cell).all()
        higher = distance_to(mesh, pts + [0, 0, 0.15])
        assert (higher < w.free.margin).mean() > 0.9
        doors = w.vertices[w.faces[w.face_class == C.DOOR]].reshape(-1, 3)
        head = doors[:, 2].max()
        near_door = np.linalg.norm(xy[:, None] - doors[None, :, :2], axis=-1).min(1) < 0.1
        assert near_door.any() and (top[near_door] <= max(head - w.free.margin,
                                                           w.free.band[1]) + 1e-6).all()

    def test_tall_objects_stand_clear_of_door_heads(self, floor_site):
        tall = floor_site.floor_for(2.3)
        assert tall is not None and tall is not floor_site.floor
        assert floor_site.floor_for(STANDING_BAND[1]) is floor_site.floor
        assert tall.area < floor_site.floor.area  # no doorway: door heads are lower
        w = floor_site.world
        doors = w.vertices[w.faces[w.face_class == C.DOOR]].reshape(-1, 3)
        assert not tall.contains(doors[:, :2]).any()
        assert floor_site.floor.contains(doors[:, :2]).mean() < 1.0  # (walls at the jambs)


def test_generalist_poses_span_heights_and_tilts(tmp_path):
    """A floor of the generalist's recipe (small): spread-out poses reach 0.5-2.5 m where the
    ceiling allows and a share are handheld; every pose passes the free-space check; the
    flights' band is the world's."""
    cfg = compose_config("datagen", [
        "datagen_experiment=generalist_floors", "world.seed=2", "world.size=[26,22]",
        "world.grid_spacing=[6,7]", "splits.train=300", "splits.val=0", "splits.test=0",
        f"out_dir={tmp_path / 'ds'}"])
    job = J.prepare(cfg)
    poses = job.split_poses["train"]
    z = (poses @ job.camera.body_from_cam)[:, 2, 3]
    assert job.site.world.free.band == (0.5, 1.9)
    assert z.min() < 0.6 and z.max() > 2.3 and (z > 1.9).mean() > 0.05
    roll, pitch = tilts_deg(poses).T
    assert (pitch > 10).mean() > 0.03 and (pitch < -10).mean() > 0.03
    assert np.abs(pitch).max() <= 20 + 1e-6
    J.check_inside(job.site, job.camera, poses, "splits.train")
    bad = typed(DatagenConfig, cfg, "datagen")
    bad.training.z_range = [0.3, 2.5]
    with pytest.raises(ValueError, match="training.z_range"):
        J.poses_of_split(bad, job.site, job.camera, "train")
    with pytest.raises(ValueError, match="training.z_range"):
        J.prepare(replace(bad, training=replace(bad.training, z_range=[2.0, 1.0])))


def test_a_camera_ahead_of_its_body_stays_under_a_door_head(tmp_path):
    """Generalist floor 15's training frame 136 drew a body at 2.27 m under a room's 3.2 m
    ceiling whose camera, 0.1 m ahead, sat under a door's head (1.9 m at most there): the
    whole floor failed its free-space check. Such a draw is drawn again."""
    cfg = compose_config("datagen", [
        "datagen_experiment=generalist_floors", "world.seed=15", "splits.train=137",
        "splits.val=0", "splits.test=0", f"out_dir={tmp_path / 'ds'}"])
    job = J.prepare(cfg)  # raised ValueError "splits.train: camera 136 ... outside"
    poses = job.split_poses["train"]
    assert J.outside_by(job.site, job.camera, poses).max() < job.site.world.free.margin
