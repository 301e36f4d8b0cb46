"""The nearest-edge likelihood: score maps, line scores, the peak at the true pose, bad input."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core import classes as C
from core.classes import pair_code
from core.config import typed
from localize.config import VisibilityConfig
from localize.filter.likelihood import (
    FIT_EPS,
    EdgeLikelihood,
    LikelihoodConfig,
    distance_to,
    edge_normal_angle,
    frame_k,
    observe,
    run_all,
)
from localize.filter.projection import cam_from_world, sample_segments
from localize.filter.visibility import build_visibility
from localize.frontend.boundaries import label_edges
from localize.frontend.edge_image import EdgeImage

TRUE = np.array([0.2, 0.8, 1.2, np.deg2rad(80.0)])
OFFSETS = np.array([[0.1, 0, 0, 0], [-0.1, 0, 0, 0], [0, 0.2, 0, 0], [0, -0.2, 0, 0],
                    [0, 0, 0.1, 0], [0, 0, -0.1, 0], [0, 0, 0, np.deg2rad(3)],
                    [0, 0, 0, -np.deg2rad(3)]])


@pytest.fixture(scope="module")
def model(small_world):
    s = sample_segments(small_world.segments, 0.05)
    keep = small_world.segment_classes[:, 0] != small_world.segment_classes[:, 1]
    s, _ = s.select(keep)
    return s, build_visibility(small_world, s.points,
                               settings=VisibilityConfig(cell_xy=0.2, cell_z=0.3),
                               classes=small_world.segment_classes[s.segment],
                               normals=small_world.normals[s.segment])


@pytest.fixture(scope="module")
def rendered(renderer, camera):
    T = cam_from_world(TRUE[None], camera.body_from_cam)[0]
    labels, _ = renderer.render(np.linalg.inv(T))
    return labels


def _random_lines(rng: np.random.Generator, n: int = 25, shape=(120, 160)) -> np.ndarray:
    """(H, W) bool map of n random 1-px lines."""
    import cv2

    m = np.zeros(shape, np.uint8)
    H, W = shape
    for x0, y0, x1, y1 in zip(rng.integers(0, W, n), rng.integers(0, H, n),
                              rng.integers(0, W, n), rng.integers(0, H, n), strict=True):
        cv2.line(m, (int(x0), int(y0)), (int(x1), int(y1)), 1, 1)
    return m > 0


class TestObserve:
    def test_score_map_values(self):
        edges = np.zeros((20, 40), bool)
        edges[:, 10] = True
        known = np.ones_like(edges)
        known[:, 30:] = False
        p = LikelihoodConfig(sigma=0.3, search_px=10)
        obs = observe(EdgeImage(edges, known), p)
        g = obs.g[:-1].reshape(20, 40)
        np.testing.assert_allclose(g[:, 10], 1.0)
        np.testing.assert_allclose(g[5, 13], np.exp(-0.3 ** 2 / (2 * 0.3 ** 2)), rtol=1e-5)
        np.testing.assert_allclose(g[:, 35], obs.g0[0])  # unknown: chance
        assert obs.g[-1] == 0 and obs.fit[-1] == 0
        assert 0 < obs.chance < 1
        fit = obs.fit[:-1].reshape(20, 40)
        assert (fit[:, 30:] == 0).all() and (fit[:, :30] != 0).all()

    def test_no_edges_is_flat(self):
        obs = observe(EdgeImage(np.zeros((8, 8), bool), np.ones((8, 8), bool)),
                      LikelihoodConfig())
        np.testing.assert_allclose(obs.g[:-1], obs.g[0])
        assert np.isfinite(obs.g).all()

    def test_orientation_bins_split_edges(self):
        edges = np.zeros((40, 40), bool)
        edges[:, 10] = True  # vertical line: normal along x (angle 0)
        edges[30, :] = True  # horizontal line: normal along y (angle pi/2)
        theta = edge_normal_angle(edges)
        assert min(theta[15, 10], np.pi - theta[15, 10]) < 0.2
        assert abs(theta[30, 25] - np.pi / 2) < 0.2
        obs = observe(EdgeImage(edges, np.ones_like(edges)), LikelihoodConfig(orientation_bins=4))
        g = obs.g[:-1].reshape(4, 40, 40)
        assert g[0, 15, 10] == pytest.approx(1.0) and g[2, 15, 10] < 0.5
        assert g[2, 30, 25] == pytest.approx(1.0) and g[0, 30, 25] < 0.5

    def test_normal_angle_at_pixels_is_the_full_maps(self):
        """``at=`` gives the full map's angles at those pixels, exactly."""
        edges = _random_lines(np.random.default_rng(3))
        ys, xs = np.nonzero(edges)
        np.testing.assert_array_equal(edge_normal_angle(edges, at=(ys, xs)),
                                      edge_normal_angle(edges)[ys, xs])

    def test_distance_close_to_exact(self):
        """The chamfer distance stays within 0.05 px of the exact Euclidean one up to 4 px and
        within 2.5 % up to the 10-px reach."""
        from scipy.ndimage import distance_transform_edt

        rng = np.random.default_rng(4)
        for _ in range(5):
            edges = _random_lines(rng)
            exact = distance_transform_edt(~edges)
            d = distance_to(edges)
            near = exact <= 4
            assert np.abs(d - exact)[near].max() <= 0.05
            mid = (exact > 0) & (exact <= 10)
            assert (np.abs(d - exact)[mid] / exact[mid]).max() <= 0.025
        assert (distance_to(np.zeros((5, 5), bool)) >= 1e5).all()

    def test_all_known_maps(self):
        """Without unknown pixels (the shortcut): g from the distance, the chance level the
        mean of g, the fit map the log-ratio, nowhere exactly 0."""
        edges = _random_lines(np.random.default_rng(5))
        p = LikelihoodConfig(sigma=0.1, search_px=10)
        obs = observe(EdgeImage(edges, np.ones_like(edges)), p)
        g = np.exp(-(np.minimum(distance_to(edges), 10) / 10) ** 2 / (2 * 0.1 ** 2))
        np.testing.assert_allclose(obs.g[:-1].reshape(edges.shape), g, rtol=1e-5, atol=1e-30)
        assert obs.g0[0] == pytest.approx(g.mean(), rel=1e-5)
        fit = np.log(g + FIT_EPS) - np.log(g.mean() + FIT_EPS)
        np.testing.assert_allclose(obs.fit[:-1].reshape(edges.shape), fit, atol=1e-5)
        assert (obs.fit[:-1] != 0).all()

    def test_class_pairs_split_edges(self):
        """Two vertical boundaries, wall | door at column 10 and wall | window at 20: each pair
        gets its own map; the chance level is that of all edges together."""
        edges = np.zeros((20, 40), bool)
        edges[:, 10] = edges[:, 20] = True
        pairs = np.zeros((20, 40), np.uint8)
        pairs[:, 10] = pair_code(C.WALL, C.DOOR)
        pairs[:, 20] = pair_code(C.WALL, C.WINDOW)
        known = np.ones_like(edges)
        codes = np.array([pair_code(C.WALL, C.DOOR), pair_code(C.WALL, C.WINDOW)])
        p = LikelihoodConfig(class_pairs=True)
        obs = observe(EdgeImage(edges, known, pairs), p, codes)
        g = obs.g[:-1].reshape(2, 20, 40)
        assert obs.pairs == 2
        assert g[0, 5, 10] == pytest.approx(1.0) and g[0, 5, 20] < 0.01  # door map
        assert g[1, 5, 20] == pytest.approx(1.0) and g[1, 5, 10] < 0.01  # window map
        plain = observe(EdgeImage(edges, known, pairs), LikelihoodConfig(), codes)
        assert plain.pairs == 0 and plain.g0 == pytest.approx(obs.g0)
        # without classes (mode none) the maps are not split
        assert observe(EdgeImage(edges, known), p, codes).pairs == 0

    def test_bad_params(self):
        with pytest.raises(ValueError, match="sigma"):
            LikelihoodConfig(sigma=0.0)
        with pytest.raises(ValueError, match="filter.likelihood.kappa: Key 'kappa' not in"):
            typed(LikelihoodConfig, {"kappa": 1}, "filter.likelihood")


@pytest.mark.parametrize("bins", [0, 4])
def test_peaks_at_true_pose(model, camera, rendered, bins):
    s, vis = model
    paper = {"k": 3.0, "sigma": 0.3, "lines_ref": 0}  # the paper's likelihood
    lik = EdgeLikelihood(s, camera, LikelihoodConfig(orientation_bins=bins, min_lines=1, chunk=3,
                                                     **paper), vis)
    obs = lik.observe(label_edges(rendered, dilate_px=0))
    states = np.vstack([TRUE, TRUE + OFFSETS])
    score, quality = lik.scores(states, obs)
    assert np.argmax(score) == 0
    assert (score[0] > score[1:] + 1e-3).all()
    assert quality[0] > 0.9
    logw, q = lik.log_likelihood(states, obs)
    np.testing.assert_allclose(logw, np.log(1.0) + 3.0 * score)


def test_frame_k():
    assert frame_k(25.0, np.array([4, 4, 10]), 15) == pytest.approx(25.0 * 4 / 15)
    assert frame_k(25.0, np.array([40, 3, 41]), 15) == 25.0  # enough lines: k itself
    assert frame_k(25.0, np.array([4]), 0) == 25.0  # off
    assert frame_k(25.0, np.array([], int), 15) == 25.0
    with pytest.raises(ValueError, match="lines_ref"):
        LikelihoodConfig(lines_ref=-1)


def test_lines_ref_scales_the_frame_not_the_particles(model, camera, rendered):
    """With lines_ref above the lines in view every particle's log-weight is the same
    fraction of k times its score (the ranking is kept); with lines_ref 1 it is k itself."""
    s, vis = model
    states = np.vstack([TRUE, TRUE + OFFSETS])
    edge = label_edges(rendered, dilate_px=0)
    base = LikelihoodConfig(k=25.0, min_lines=1)
    for ref, lo, hi in ((1, 25.0, 25.0), (10_000, 1e-6, 0.5)):
        lik = EdgeLikelihood(s, camera, replace(base, lines_ref=ref), vis)
        obs = lik.observe(edge)
        score, _ = lik.scores(states, obs)
        logw, _ = lik.log_likelihood(states, obs)
        scale = logw / score
        np.testing.assert_allclose(scale, scale[0], rtol=1e-9)
        assert lo - 1e-9 <= scale[0] <= hi + 1e-9
        assert np.argmax(logw) == 0


def test_class_pairs_peak_and_need_sample_pairs(model, camera, rendered, small_world):
    """Matching by class pair keeps the peak at the true pose, and a model line matched
    against another pair's boundaries loses its score."""
    s, vis = model
    sc = small_world.segment_classes[s.segment]
    pairs = pair_code(sc[:, 0], sc[:, 1])
    p = LikelihoodConfig(orientation_bins=4, class_pairs=True)
    lik = EdgeLikelihood(s, camera, p, vis, pairs)
    edge = label_edges(rendered, dilate_px=0)
    states = np.vstack([TRUE, TRUE + OFFSETS])
    score, _ = lik.scores(states, lik.observe(edge))
    assert np.argmax(score) == 0 and (score[0] > score[1:] + 1e-3).all()
    # the same edges with every pair code swapped for one the model lacks: nothing matches
    wrong = EdgeImage(edge.edges, edge.known, np.where(edge.edges, np.uint8(255), np.uint8(0)))
    assert lik.scores(TRUE[None], lik.observe(wrong))[0][0] < 1e-3 * score[0]
    with pytest.raises(ValueError, match="class pair of every model sample"):
        EdgeLikelihood(s, camera, p, vis)


def test_peaks_on_a_really_rendered_frame(tiny_dataset):
    """Oracle edges of a flight frame of the tiny dataset: the true pose beats its neighbours."""
    from core.atomic import read_png
    from core.dataset import Dataset
    from core.poses import xyzyaw_from_pose
    from localize.filter.projection import tilt_from_pose

    ds = Dataset(tiny_dataset)
    world, cam = ds.world(), ds.camera
    fl = ds.flight("paper")
    s = sample_segments(world.segments, 0.1)
    keep = world.segment_classes[:, 0] != world.segment_classes[:, 1]
    s, _ = s.select(keep)
    vis = build_visibility(world, s.points, settings=VisibilityConfig(cell_xy=0.4, cell_z=0.5))
    lik = EdgeLikelihood(s, cam, LikelihoodConfig(), vis)
    wins = 0
    for t in (5, 15, 25):
        obs = lik.observe(label_edges(read_png(fl.label[t], rgb=False)))
        truth = xyzyaw_from_pose(fl.groundtruth[t])[0]
        score, _ = lik.scores(np.vstack([truth, truth + OFFSETS]), obs,
                              tilt_from_pose(fl.odometry[t]))
        wins += int(np.argmax(score) == 0)
    assert wins >= 2


def test_per_particle_tilts_correct_an_imu_error(model, camera, renderer):
    """A frame rendered at roll 1.5, pitch -2 deg while the IMU says 0.5, -1: the particle
    whose correction undoes the error scores best; zero corrections equal the shared tilt."""
    from core.poses import pose_from_xyz_rpy
    from localize.filter.projection import corrected_tilts, tilt_from_pose

    s, vis = model

    def tilt(roll, pitch):
        return tilt_from_pose(pose_from_xyz_rpy(np.zeros((1, 3)),
                                                np.deg2rad([[roll, pitch, 0.0]]))[0])

    T = cam_from_world(TRUE[None], camera.body_from_cam, tilt(1.5, -2.0))[0]
    labels, _ = renderer.render(np.linalg.inv(T))
    lik = EdgeLikelihood(s, camera, LikelihoodConfig(), vis)
    obs = lik.observe(label_edges(labels))
    imu = tilt(0.5, -1.0)
    corr = np.deg2rad([[0.0, 0.0], [1.0, -1.0], [-1.0, 1.0], [1.0, 0.0], [0.0, -1.0]])
    states = np.repeat(TRUE[None], len(corr), axis=0)
    score, _ = lik.scores(states, obs, corrected_tilts(imu, corr))
    assert np.argmax(score) == 1 and score[1] > score[0] + 0.05
    shared, _ = lik.scores(states[:1], obs, imu)
    assert score[0] == pytest.approx(shared[0], abs=1e-6)
    with pytest.raises(ValueError, match="tilts for"):
        lik.scores(states, obs, corrected_tilts(imu, corr[:2]))


class TestDegenerate:
    """Black image, no edges, everything clutter: finite, equal scores."""

    @pytest.mark.parametrize("case", ["no_edges", "all_unknown", "black_canny"])
    def test_finite_and_flat(self, model, camera, case):
        from localize.frontend.canny import canny_edges

        s, vis = model
        H, W = camera.height, camera.width
        if case == "no_edges":
            edge = EdgeImage(np.zeros((H, W), bool), np.ones((H, W), bool))
        elif case == "all_unknown":
            edge = label_edges(np.full((H, W), C.CLUTTER, np.uint8))
        else:
            edge = canny_edges(np.zeros((H, W, 3), np.uint8))
        lik = EdgeLikelihood(s, camera, LikelihoodConfig(), vis)
        obs = lik.observe(edge)
        states = np.vstack([TRUE, TRUE + OFFSETS])
        logw, quality = lik.log_likelihood(states, obs)
        assert np.isfinite(logw).all()
        np.testing.assert_allclose(logw, logw[0], atol=1e-6)

    def test_nothing_in_view(self, model, camera):
        s, vis = model
        lik = EdgeLikelihood(s, camera, LikelihoodConfig(), vis)
        edges = np.zeros((camera.height, camera.width), bool)
        edges[60] = True
        obs = lik.observe(EdgeImage(edges, np.ones_like(edges)))
        far = np.array([[100.0, 100.0, 50.0, 0.0]])  # far outside, looking away
        score, quality = lik.scores(far, obs)
        assert score[0] == pytest.approx(obs.chance) and np.isnan(quality[0])

    def test_shape_checks(self, model, camera):
        s, vis = model
        lik = EdgeLikelihood(s, camera, LikelihoodConfig(), vis)
        with pytest.raises(ValueError, match="does not match the camera"):
            lik.observe(EdgeImage(np.zeros((4, 4), bool), np.ones((4, 4), bool)))
        obs = lik.observe(EdgeImage(np.zeros((camera.height, camera.width), bool),
                                    np.ones((camera.height, camera.width), bool)))
        with pytest.raises(ValueError, match=r"\(N, 4\)"):
            lik.scores(np.zeros((3, 3)), obs)


@pytest.mark.parametrize("class_pairs", [False, True])
def test_workers_do_not_change_results(model, camera, rendered, small_world, class_pairs):
    """Scoring on 2 threads (bins' maps and particle blocks) gives the same maps and scores,
    to the bit, as the calling thread alone, and so does another block size; with unknown
    pixels and several blocks."""
    s, vis = model
    sc = small_world.segment_classes[s.segment]
    pairs = pair_code(sc[:, 0], sc[:, 1])
    edge = label_edges(rendered, dilate_px=0)
    known = edge.known.copy()
    known[:, : known.shape[1] // 4] = False  # an object hides a quarter of the view
    edge = EdgeImage(edge.edges, known, edge.pairs)
    states = np.vstack([TRUE, TRUE + OFFSETS, TRUE + 0.5 * OFFSETS])
    out = []
    for workers, chunk in ((1, 2), (2, 2), (2, 64)):
        p = LikelihoodConfig(orientation_bins=4, class_pairs=class_pairs, chunk=chunk,
                             workers=workers)
        lik = EdgeLikelihood(s, camera, p, vis, pairs)
        obs = lik.observe(edge)
        out.append((obs.g, obs.fit, obs.g0, *lik.scores(states, obs)))
    for other in out[1:]:
        for a, b in zip(out[0], other, strict=True):
            np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="workers"):
        LikelihoodConfig(workers=0)


def _child_run_all(queue) -> None:
    queue.put(run_all(lambda x: x * x, range(5), 2))


def test_run_all_in_a_forked_child():
    """A process forked after the pool was made gets its own threads (the parent's do not
    exist in it) instead of waiting on them forever."""
    import multiprocessing as mp

    assert run_all(lambda x: x + 1, range(5), 2) == [1, 2, 3, 4, 5]  # the parent's pool
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child_run_all, args=(queue,))
    child.start()
    child.join(timeout=60)
    if child.is_alive():
        child.kill()
        pytest.fail("run_all hung in a forked child")
    assert queue.get(timeout=5) == [0, 1, 4, 9, 16]
