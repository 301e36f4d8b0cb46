"""Pose hypotheses of a weighted set, the ambiguous status, start hints, false convergence."""

from __future__ import annotations

import numpy as np
import pytest

from core.occupancy import OccupancyMap
from core.poses import pose_from_xyzyaw, wrap_angle
from localize.config import FilterConfig, HintConfig
from localize.filter.hypotheses import Dominance, top_hypotheses
from localize.filter.particle_filter import ParticleFilter
from localize.filter.start_hint import (
    START_MAX_OUTSIDE_M,
    StartHint,
    as_polygon,
    hint_from_settings,
    named_space,
    polygon_contains,
    start_of_settings,
)
from localize.offline.metrics import false_convergence

BOXES = np.array([[-0.7, 0.3, 0.7, 9.7], [-2.7, 5.7, -0.7, 6.7]])
FREE = OccupancyMap.from_boxes(BOXES, np.array([0.5, 2.2]), 0.05, margin=0.3)

#: The tracking start's noise of the filter's defaults (x, y, z m, yaw deg).
INIT_STD = FilterConfig().init_std
#: The pose kernel of the filter's defaults: (k, radius_m, yaw_deg).
KERNEL = (FilterConfig().hypotheses, FilterConfig().hypothesis_radius_m,
          FilterConfig().hypothesis_yaw_deg)


def cloud(rng, centre, n, std=(0.1, 0.1, 0.02, 0.05)):
    p = np.asarray(centre, float)[None] + rng.normal(0, 1, (n, 4)) * np.asarray(std)
    p[:, 3] = wrap_angle(p[:, 3])
    return p


class TestTopHypotheses:
    def test_two_clusters_two_hypotheses_with_their_masses(self):
        rng = np.random.default_rng(0)
        a, b = np.array([0.0, 2.0, 1.2, 0.5]), np.array([0.0, 8.0, 1.2, -2.5])
        p = np.concatenate([cloud(rng, a, 3000), cloud(rng, b, 1000)])
        logw = np.log(np.r_[np.full(3000, 1.0), np.full(1000, 2.0)])  # masses 0.6, 0.4
        h = top_hypotheses(p, logw, *KERNEL)
        assert len(h) == 2  # nothing is left for a third
        np.testing.assert_allclose([h[0].mass, h[1].mass], [0.6, 0.4], atol=0.01)
        assert np.linalg.norm(h[0].state[:2] - a[:2]) < 0.02
        assert np.linalg.norm(h[1].state[:2] - b[:2]) < 0.03
        assert abs(wrap_angle(h[1].state[3] - b[3])) < 0.02
        assert h[0].position_std == pytest.approx(0.14, abs=0.02)  # sqrt(2) x 0.1
        thinned = top_hypotheses(p, logw, *KERNEL, max_poses=1000)  # a large set's shortcut
        np.testing.assert_allclose([t.mass for t in thinned], [0.6, 0.4], atol=0.01)

    def test_a_cluster_across_the_yaw_seam_is_one(self):
        rng = np.random.default_rng(1)
        p = cloud(rng, [1.0, 1.0, 1.0, np.pi], 2000)
        h = top_hypotheses(p, np.zeros(len(p)), *KERNEL)
        assert h[0].mass > 0.99 and abs(wrap_angle(h[0].state[3] - np.pi)) < 0.01

    def test_uniform_set_has_no_heavy_hypothesis(self):
        rng = np.random.default_rng(2)
        p = np.column_stack([FREE.sample(rng, 20000), np.full(20000, 1.2),
                             rng.uniform(-np.pi, np.pi, 20000)])
        h = top_hypotheses(p, np.zeros(len(p)), *KERNEL)
        assert 1 <= len(h) <= 3 and h[0].mass < 0.05

    def test_bad_shapes(self):
        with pytest.raises(ValueError, match="poses must be"):
            top_hypotheses(np.zeros((3, 3)), np.zeros(3), *KERNEL)


class TestDominance:
    def test_needs_a_stretch(self):
        d = Dominance(0.9, 3)
        assert [d.update(m) for m in (0.95, 0.95, 0.5, 0.95, 0.95, 0.95, 0.97)] == [
            "ambiguous", "ambiguous", "ambiguous", "ambiguous", "ambiguous", "tracking",
            "tracking"]
        assert d.update(0.6) == "ambiguous"

    def test_two_equal_modes_stay_ambiguous(self):
        """A filter whose likelihood has two equal modes never declares tracking."""
        params = FilterConfig(num_particles=2000, global_particles=20000, global_frames=15,
                              recovery=False)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_global()
        a, b = np.array([0.0, 2.0, 1.2, 0.5]), np.array([0.0, 8.0, 1.2, 0.5])

        def two_peaks(states, tilt=None):  # two equal plateaus: both fit equally well
            near = [(np.hypot(*(states[:, :2] - t[:2]).T) < 0.3)
                    & (np.abs(wrap_angle(states[:, 3] - t[3])) < 0.3) for t in (a, b)]
            inside = near[0] | near[1]
            return np.where(inside, 0.0, -30.0), np.where(inside, 0.8, 0.1)

        infos = [pf.update(two_peaks) for _ in range(40)]
        assert {i.status for i in infos} == {"ambiguous"}
        last = infos[-1]
        assert len(last.hypotheses) >= 2
        masses = [h.mass for h in last.hypotheses[:2]]
        assert min(masses) > 0.25 and sum(masses) > 0.8
        # the estimate is a hypothesis's pose, not the mean between the two
        assert min(np.linalg.norm(last.estimate[:2] - t[:2]) for t in (a, b)) < 0.3
        assert last.confidence == 0.0

    def test_one_mode_becomes_tracking(self):
        params = FilterConfig(num_particles=500, global_particles=20000, global_frames=15)
        pf = ParticleFilter(params, FREE, np.random.default_rng(0))
        pf.init_global()
        target = np.array([0.0, 2.0, 1.2, 0.5])

        def one(states, tilt=None):
            d = ((states[:, :3] - target[:3]) ** 2).sum(1) + wrap_angle(
                states[:, 3] - target[3]) ** 2
            return -20 * d, np.exp(-d)

        status = [pf.update(one).status for _ in range(40)]
        first = status.index("tracking")
        assert first >= params.dominant_frames - 1 and status[-1] == "tracking"

    def test_a_tracking_start_is_dominant_at_once(self):
        pf = ParticleFilter(FilterConfig(), FREE, np.random.default_rng(0))
        pf.init_tracking(np.array([0.0, 2.0, 1.2, 0.5]))
        flat = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.5))  # noqa: E731
        assert pf.update(flat).status == "tracking"


def test_a_search_hands_over_its_poses():
    pf = ParticleFilter(FilterConfig(num_particles=400), FREE, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    a, b = np.array([0.0, 2.0, 1.2, 0.5]), np.array([0.0, 8.0, 1.2, -2.5])
    pf.init_particles(cloud(rng, a, 400))
    assert pf.particles.shape == (400, 4) and not pf.in_global_phase
    assert pf.dominance.confirmed
    pf.init_particles(np.concatenate([cloud(rng, a, 300), cloud(rng, b, 100)]))  # 0.75, 0.25
    flat = lambda s, t: (np.zeros(len(s)), np.full(len(s), 0.5))  # noqa: E731
    assert pf.update(flat).status == "ambiguous"


def test_a_handover_of_several_places_is_ambiguous_until_one_dominates():
    """``init_particles(dominant=False)``: the edge likelihood chooses between the places; the
    status is ``tracking`` only after the chosen one has held ``dominant_mass`` for
    ``dominant_frames``."""
    params = FilterConfig(num_particles=400)
    pf = ParticleFilter(params, FREE, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    a, b = np.array([0.0, 2.0, 1.2, 0.5]), np.array([0.0, 8.0, 1.2, -2.5])
    pf.init_particles(np.concatenate([cloud(rng, a, 200), cloud(rng, b, 200)]), dominant=False)

    def near_a(states, tilt=None):
        d = np.hypot(*(states[:, :2] - a[:2]).T)
        return -5.0 * d, np.exp(-d)

    status = [pf.update(near_a).status for _ in range(20)]
    first = status.index("tracking")
    assert first == params.dominant_frames - 1 and status[-1] == "tracking", status
    assert np.hypot(*(pf.particles[:, :2] - a[:2]).T).max() < 1.0


class TestStartHint:
    def test_region_restricts_the_particles(self):
        region = [-0.7, 4.0, 0.7, 6.0]
        pf = ParticleFilter(FilterConfig(global_particles=4000), FREE,
                            np.random.default_rng(0))
        pf.init_global(StartHint(region=region, heading=(0.0, np.pi / 2)))
        p = pf.particles
        assert polygon_contains(as_polygon(region), p[:, :2]).all()
        assert FREE.contains(p[:, :2]).all()
        assert (p[:, 3] >= 0).all() and (p[:, 3] <= np.pi / 2 + 1e-9).all()
        assert len(p) == 4000  # a small area: the minimum count

    def test_region_outside_free_space_is_drawn_in_the_polygon(self):
        poly = [[5.0, 5.0], [6.0, 5.0], [6.0, 6.0]]
        p = StartHint(region=poly).draw(np.random.default_rng(0), FREE, 500)
        assert polygon_contains(as_polygon(poly), p[:, :2]).all()

    def test_pose_with_covariance(self):
        hint = StartHint(pose=np.array([0.0, 3.0, 1.2, 1.0]),
                         covariance=np.diag([0.2, 0.3, 0.05, 0.1]) ** 2)
        p = hint.draw(np.random.default_rng(0), FREE, 20000)
        np.testing.assert_allclose(p[:, :3].std(0), [0.2, 0.3, 0.05], rtol=0.05)
        assert abs(np.mean(wrap_angle(p[:, 3] - 1.0))) < 0.01

    def test_initial_pose_keeps_x_y_z_yaw_of_the_ros_covariance(self):
        cov6 = np.diag([0.25, 0.16, 0.01, 99.0, 99.0, 0.04])
        T = pose_from_xyzyaw(np.array([[0.0, 3.0, 1.2, 0.3]]))[0]
        hint = StartHint.from_initial_pose(T, cov6.ravel())
        np.testing.assert_allclose(hint.pose, [0.0, 3.0, 1.2, 0.3], atol=1e-12)
        np.testing.assert_allclose(np.diag(hint.covariance), [0.25, 0.16, 0.01, 0.04])

    def test_initial_pose_tracks_or_searches_by_its_covariance(self):
        """No wider than the tracking start's noise (zero included): track from the pose;
        RViz's 2D Pose Estimate (0.5 m, 15 deg): a search inside its Gaussian."""
        T = pose_from_xyzyaw(np.array([[0.0, 3.0, 1.2, 0.3]]))[0]
        init_std = [0.1, 0.1, 0.05, 3.0]
        for cov6 in (np.zeros(36), np.diag([0.01, 0.005, 0, 0, 0, 0.002]).ravel()):
            start = StartHint.start_of_initial_pose(T, cov6, init_std)
            assert not isinstance(start, StartHint)
            np.testing.assert_allclose(start, [0.0, 3.0, 1.2, 0.3], atol=1e-12)
        rviz = np.diag([0.25, 0.25, 0, 0, 0, 0.06853892]).ravel()
        start = StartHint.start_of_initial_pose(T, rviz, init_std)
        assert isinstance(start, StartHint)
        np.testing.assert_allclose(np.diag(start.covariance), [0.25, 0.25, 0, 0.06853892])
        yaw_only = np.diag([0.0, 0.0, 0, 0, 0, 0.01]).ravel()  # 5.7 deg > 3 deg
        assert isinstance(StartHint.start_of_initial_pose(T, yaw_only, init_std), StartHint)

    def test_heading_range_across_the_seam(self):
        hint = StartHint(heading=(np.deg2rad(170), np.deg2rad(-170)))
        p = hint.draw(np.random.default_rng(0), FREE, 2000)
        assert (np.abs(p[:, 3]) >= np.deg2rad(170) - 1e-9).all()
        assert hint.heading_span == pytest.approx(np.deg2rad(20))

    def test_settings_and_named_spaces(self):
        assert hint_from_settings(HintConfig(), {}, FREE, INIT_STD) is None
        info = {"spaces": {"Lobby": [[-0.7, 0.3], [0.7, 0.3], [0.7, 2.0], [-0.7, 2.0]]}}
        hint = hint_from_settings(HintConfig(space="lobby", heading_deg=[0, 90]), info, FREE,
                                  INIT_STD)
        assert hint.region.shape == (4, 2) and hint.heading_span == pytest.approx(np.pi / 2)
        with pytest.raises(ValueError, match="its spaces: Lobby"):
            named_space(info, "kitchen")
        with pytest.raises(ValueError, match="no 'spaces'"):
            named_space({}, "kitchen")
        with pytest.raises(ValueError, match=r"xmax > xmin"):
            hint_from_settings(HintConfig(region=[1, 0, 0, 1]), {}, FREE, INIT_STD)
        pose = hint_from_settings(HintConfig(pose=[0, 3, 1.2, 90]), {}, FREE, INIT_STD)
        assert pose.pose[3] == pytest.approx(np.pi / 2)

    @pytest.mark.parametrize("region", [[100.0, 100.0, 110.0, 110.0],
                                        [[5.0, 5.0], [6.0, 5.0], [6.0, 6.0]],
                                        [0.8, 0.0, 3.0, 12.0]])  # beside the corridor
    def test_region_off_the_free_space_is_refused(self, region):
        """A region that does not overlap the free space is an error naming hint.region, the
        region and the free space's extent."""
        with pytest.raises(ValueError, match=r"^hint\.region=\[.*\]: the region does not "
                                             r"overlap the map's free space \(x -2\.7\d to 0\.7\d "
                                             r"m, y 0\.\d+ to 9\.7\d m, heights 0\.50 to 2\.20 m"):
            hint_from_settings(HintConfig(region=region), {}, FREE, INIT_STD)

    @pytest.mark.parametrize("region", [[0.5, 9.0, 3.0, 12.0],  # a corner of it in the corridor
                                        [0.01, 5.01, 0.02, 5.02],  # inside one cell
                                        [[0.69, 1.0], [0.9, 0.9], [0.9, 1.1]]])  # a tip in it
    def test_region_overlapping_the_free_space_is_taken(self, region):
        hint = hint_from_settings(HintConfig(region=region), {}, FREE, INIT_STD)
        p = hint.draw(np.random.default_rng(0), FREE, 200)
        assert polygon_contains(hint.region, p[:, :2]).all()

    def test_named_space_and_pose_off_the_free_space_are_refused(self):
        info = {"spaces": {"Annex": [[50.0, 50.0], [60.0, 50.0], [60.0, 60.0]]}}
        with pytest.raises(ValueError, match=r"^hint\.space='annex' .*does not overlap"):
            hint_from_settings(HintConfig(space="annex"), info, FREE, INIT_STD)
        with pytest.raises(ValueError, match=r"^hint\.pose=\[140\.0, 0\.0, 1\.2, 0\.0\]: the "
                                             r"position lies 139\.\d+ m outside"):
            hint_from_settings(HintConfig(pose=[140.0, 0.0, 1.2, 0.0]), {}, FREE, INIT_STD)


class TestStartSetting:
    """``hint.pose`` alone: tracking from it; with a wider ``pose_std``: a search around it."""

    def test_pose_far_off_the_free_space_is_refused(self):
        with pytest.raises(ValueError, match=r"^hint\.pose=\[140\.0, 5\.0, 1\.2, 90\.0\]: the "
                                             r"position lies 139\.\d+ m outside the map's free "
                                             r"space \(x -2\.7\d to 0\.7\d m, "
                                             r"y 0\.\d+ to 9\.7\d m"):
            start_of_settings(HintConfig(pose=[140.0, 5.0, 1.2, 90.0]), {}, FREE, INIT_STD)
        with pytest.raises(ValueError, match=r"^hint\.pose=\[0\.0, 5\.0, 4\.0, 0\.0\]: .* 1\.80 m "
                                             r"outside"):  # above the band
            start_of_settings(HintConfig(pose=[0.0, 5.0, 4.0, 0.0]), {}, FREE, INIT_STD)

    def test_pose_alone_tracks_from_it(self):
        """Within START_MAX_OUTSIDE_M (a start measured by hand beside a wall, a drone on the
        floor): taken, in radians, as a tracking start."""
        assert START_MAX_OUTSIDE_M == 1.0
        np.testing.assert_allclose(
            start_of_settings(HintConfig(pose=[1.5, 5.0, 1.2, 90.0]), {}, FREE, INIT_STD),
            [1.5, 5.0, 1.2, np.pi / 2])
        below = start_of_settings(HintConfig(pose=[0.0, 5.0, 0.0, 0.0]), {}, FREE, INIT_STD)
        assert isinstance(below, np.ndarray)  # 0.5 m below the band
        assert start_of_settings(HintConfig(), {}, FREE, INIT_STD) is None

    def test_pose_with_a_wide_spread_is_a_search(self):
        hint = start_of_settings(HintConfig(pose=[0.0, 5.0, 1.2, 90.0],
                                            pose_std=[0.5, 0.5, 0.1, 15.0]), {}, FREE, INIT_STD)
        assert isinstance(hint, StartHint) and hint.covariance[0, 0] == pytest.approx(0.25)
        narrow = start_of_settings(HintConfig(pose=[0.0, 5.0, 1.2, 90.0], pose_std=INIT_STD),
                                   {}, FREE, INIT_STD)
        assert isinstance(narrow, np.ndarray)

    def test_pose_not_four_numbers(self):
        with pytest.raises(ValueError, match=r"^hint\.pose is \[x, y, z, yaw_deg\]"):
            start_of_settings(HintConfig(pose=[1.0, 2.0]), {}, FREE, INIT_STD)


def test_false_convergence():
    t = np.arange(30) * 0.1
    err = np.r_[np.full(10, 5.0), np.full(20, 0.1)]
    ambiguous_then_right = ["ambiguous"] * 10 + ["tracking"] * 20
    assert not false_convergence(err, t, ambiguous_then_right, 1.0, 1.0)
    confident_and_wrong = ["tracking"] * 30
    assert false_convergence(np.full(30, 2.0), t, confident_and_wrong, 1.0, 1.0)
    assert not false_convergence(err, t, confident_and_wrong, 1.0, 1.0)  # 0.9 s only
