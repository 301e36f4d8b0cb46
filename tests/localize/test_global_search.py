"""The global search (localize.search.global_search, localize.search.ray_table) on the small
corridor, with labels rendered from the structural model."""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from core import classes as C
from core.poses import odometry_increment, pose_from_xyzyaw, wrap_angle
from localize.config import FilterConfig, LocalizerConfig
from localize.edge_model import EdgeModel
from localize.filter.start_hint import StartHint
from localize.localizer import Localizer
from localize.search.config import GlobalSearchConfig
from localize.search.global_search import GlobalSearch, ray_table_for
from localize.search.ray_table import STANDING, RayTable, SearchUnavailable, floor_boundary

#: A path through the small corridor (free x in [-1.9, 0.7], y in [0.3, 3.7]), low enough to
#: see the floor meet the side walls (a 70 deg camera): along it,
#: turning a little, 0.06 m per frame.
FRAMES = 30
#: Coarser and quicker to hand over than the defaults: the corridor is 5.5 m2 and 30 frames.
SMALL = {"headings": 36, "max_hypotheses": 30000, "evidence": 8.0, "frame_floor": 6.0,
         "handover_mass": 0.99, "handover_frames": 5}
PARAMS = GlobalSearchConfig(**SMALL)


def path() -> np.ndarray:
    """(FRAMES, 4) body x, y, z, yaw."""
    t = np.arange(FRAMES)
    return np.column_stack([-0.6 + 0.3 * np.sin(t / 10), 0.8 + 0.06 * t, 0.7 + 0.005 * t,
                            np.pi / 2 + 0.3 * np.sin(t / 8)])


@pytest.fixture(scope="module")
def rendered(renderer, camera):
    """(poses (FRAMES, 4, 4), labels (FRAMES, H, W)) along ``path``."""
    poses = pose_from_xyzyaw(path())
    labels = np.stack([renderer.render(T @ camera.body_from_cam)[0] for T in poses])
    return poses, labels


@pytest.fixture(scope="module")
def table(small_world):
    return RayTable.build(small_world, PARAMS.cell, PARAMS.rays)


def test_table_matches_the_rendered_floor_boundary(table, rendered, camera):
    """From the true pose the frame's floor boundary lies where the table says: tan = h / D
    in most azimuth bins."""
    _, labels = rendered
    diffs = []
    for lab, st in zip(labels[::5], path()[::5], strict=True):
        fb = floor_boundary(lab, camera, None, table.rays)
        assert len(fb) >= 6
        c, sn = np.cos(st[3]), np.sin(st[3])
        cxy = st[:2] + [c * fb.camera[0] - sn * fb.camera[1], sn * fb.camera[0] + c * fb.camera[1]]
        cell = table.cells(cxy[None])[0]
        assert cell >= 0
        bins = np.rint((st[3] + fb.offsets) / (2 * np.pi / table.rays)).astype(int) % table.rays
        D = table.dist.reshape(-1, table.rays)[cell, bins].astype(np.float64)
        pred = np.arctan((st[2] + fb.camera[2]) / D)
        diffs.append(np.abs(np.arctan(fb.tan) - pred))
    d = np.degrees(np.concatenate(diffs))
    assert np.median(d) < 1.5 and np.mean(d < 5.0) > 0.8


def run_search(table, small_world, camera, rendered, seed):
    """Top hypotheses (FRAMES, 4), the search, the first frame it converged (None: never) and
    200 particles sampled then (the Localizer's handover)."""
    poses, labels = rendered
    search = GlobalSearch(table, camera, small_world.free, PARAMS, np.random.default_rng(seed))
    search.reset()
    tops, first, particles = [], None, None
    for t in range(FRAMES):
        if t:
            search.predict(odometry_increment(poses[t - 1], poses[t]))
        search.update(labels[t], None)
        tops.append(search.hypotheses(3)[0][0])
        if first is None and search.converged:
            first, particles = t, search.sample(200)
    return np.array(tops), search, first, particles


def test_search_finds_the_true_pose_and_is_deterministic(table, small_world, camera, rendered):
    tops, search, first, particles = run_search(table, small_world, camera, rendered, 0)
    truth = path()
    err = np.hypot(*(tops[:, :2] - truth[:, :2]).T)
    yaw = np.abs(wrap_angle(tops[:, 3] - truth[:, 3]))
    assert (err[20:] < 0.3).all() and (yaw[20:] < np.deg2rad(10)).all(), err
    _, mass = search.hypotheses(3)
    assert mass[0] > 0.9
    # one cluster held handover_mass for handover_frames frames: the handover, at the truth
    assert first is not None and first <= 20, first
    assert particles.shape == (200, 4)
    assert err[first] < PARAMS.cluster_radius, err[first]  # the tracking filter refines it
    # drawn from the dominant cluster's hypotheses (its radius, and a copy's jitter)
    assert np.hypot(*(particles[:, :2] - tops[first, :2]).T).max() <= PARAMS.cluster_radius + 0.1
    again, *_ = run_search(table, small_world, camera, rendered, 0)
    np.testing.assert_array_equal(tops, again)


def test_several_places_are_handed_over_evenly(table, small_world, camera):
    """With ``handover_places`` k the search converges once k clusters hold the mass together
    (one alone never does here) and ``sample`` splits the particles evenly between them."""
    centres = np.array([[-0.6, 0.8], [-0.6, 3.0]])

    def two_places(s):
        d = np.hypot(s[:, 0, None] - centres[:, 0], s[:, 1, None] - centres[:, 1]).min(1)
        return np.where((d < 0.2) & (np.abs(wrap_angle(s[:, 3] - np.pi / 2)) < 0.2), 0.0,
                        -np.inf)

    wall = np.full((camera.height, camera.width), C.WALL, np.uint8)  # nothing to weigh
    for places in (1, 3):
        params = dataclasses.replace(PARAMS, handover_places=places)
        search = GlobalSearch(table, camera, small_world.free, params, np.random.default_rng(0))
        search.reset(two_places)
        for _ in range(params.handover_frames):
            assert not search.update(wall, None)
        assert search.converged is (places == 3)
        assert search.places == (0 if places == 1 else 2)
    particles = search.sample(201)
    near = [np.hypot(*(particles[:, :2] - c).T) < 0.5 for c in centres]
    assert sorted([near[0].sum(), near[1].sum()]) == [100, 101]


def test_a_fresh_injection_does_not_hold_a_handover_back(table, small_world, camera):
    """Hypotheses injected this frame (1 % of the weight, far from the one place that holds
    the rest) do not count against ``handover_mass`` until they have been weighed for
    ``handover_frames`` frames; the mass reported (``hypotheses``) still includes them."""
    centre = np.array([-0.6, 0.8, 0.7, np.pi / 2])

    def one_place(s):
        near = (np.hypot(s[:, 0] - centre[0], s[:, 1] - centre[1]) < 0.2) \
            & (np.abs(wrap_angle(s[:, 3] - centre[3])) < 0.2)
        return np.where(near, 0.0, -np.inf)

    params = dataclasses.replace(PARAMS, handover_mass=0.999)
    search = GlobalSearch(table, camera, small_world.free, params, np.random.default_rng(0))
    search.reset(one_place)
    search._frames = 50  # as after 50 weighed frames
    far = np.tile([-0.6, 3.2, 0.7, -np.pi / 2], (20, 1))
    n = len(search.states)
    search.states = np.concatenate([search.states, far])
    search.logw = np.concatenate([search.logw + np.log(0.99), np.full(20, np.log(0.01 / 20))])
    search._born = np.concatenate([search._born, np.full(20, 50)])
    search._version += 1
    assert search.hypotheses(1)[1][0] == pytest.approx(0.99)
    np.testing.assert_allclose(search._cluster_list(1)[4], [1.0])  # the settled mass
    for _ in range(params.handover_frames):
        search._track_dominant()
    assert search.converged and search.places == 1
    search._born[n:] = 50 - params.handover_frames  # weighed long enough: they count
    search._version += 1
    np.testing.assert_allclose(search._cluster_list(1)[4], [0.99])
    search._track_dominant()
    assert not search.converged


def test_a_hint_limits_the_start(table, small_world, camera):
    search = GlobalSearch(table, camera, small_world.free, PARAMS, np.random.default_rng(0))
    search.reset(lambda s: np.where(s[:, 1] < 1.0, 0.0, -np.inf))
    assert (search.states[:, 1] < 1.0).all() and len(search.states) > 0
    with pytest.raises(ValueError, match="leaves no pose"):
        search.reset(lambda s: np.full(len(s), -np.inf))


def test_localizer_global_start_hands_over_to_tracking(small_world, camera, rendered):
    """``reset(None)`` in a label mode runs the search (status ``ambiguous``, its pose
    hypotheses reported), then the tracking filter takes over near the truth."""
    poses, labels = rendered
    # the handover, not the quality's gate (test_quality.py): frames of this corridor that
    # show too little to score say `ambiguous` under the floors' calibration
    settings = LocalizerConfig(filter=FilterConfig(num_particles=150, global_search=PARAMS,
                                                   tracking_quality=0.0))
    model = EdgeModel.build(small_world, settings, occlusion=False).for_mode(small_world,
                                                                             "oracle")
    loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                    model=model)
    loc.reset(None)
    assert loc.search is not None
    statuses, est = [], []
    for t in range(FRAMES):
        delta = odometry_increment(poses[t - 1], poses[t]) if t else None
        e = loc.step(None, delta, poses[t], 0.1 * t, labels=labels[t])
        statuses.append(e.status)
        est.append(e.state)
        assert e.hypotheses and e.hypotheses[0].mass <= 1.0 + 1e-9
    assert statuses[0] == "ambiguous" and statuses[-1] == "tracking"
    assert loc.search is None
    err = np.hypot(*(np.array(est)[-5:, :2] - path()[-5:, :2]).T)
    assert (err < 0.3).all(), err
    assert ray_table_for(small_world, GlobalSearchConfig(headings=36)) is ray_table_for(
        small_world, GlobalSearchConfig(headings=36))


@pytest.mark.parametrize("tracking_quality", [0.0, 1.0])
def test_an_unconfirmed_handover_searches_again(small_world, camera, rendered, tracking_quality):
    """``global_search.confirm_within``: a handover whose track is not reported ``tracking``
    within that many frames (here: a quality gate no estimate passes) is declared lost and a
    fresh search starts; a confirmed one is kept."""
    poses, labels = rendered
    params = dataclasses.replace(PARAMS, confirm_within=12)
    settings = LocalizerConfig(filter=FilterConfig(num_particles=150, global_search=params,
                                                   tracking_quality=tracking_quality))
    model = EdgeModel.build(small_world, settings, occlusion=False).for_mode(small_world,
                                                                             "oracle")
    loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                    model=model)
    loc.reset(None)
    statuses, searching = [], []
    for t in range(FRAMES):
        delta = odometry_increment(poses[t - 1], poses[t]) if t else None
        statuses.append(loc.step(None, delta, poses[t], 0.1 * t, labels=labels[t]).status)
        searching.append(loc.search is not None)
    handover = searching.index(False)  # the frame the filter took over at
    if tracking_quality == 0.0:
        assert "lost" not in statuses and statuses[-1] == "tracking"
    else:
        assert "tracking" not in statuses
        lost = statuses.index("lost")
        assert lost == handover + params.confirm_within, (handover, lost)
        assert searching[lost]


def test_localizer_hint_weighs_the_search(small_world, camera):
    """A ``StartHint`` given to ``Localizer.reset`` restricts the search's start: a region
    keeps only its poses, a pose with covariance weighs them by its Gaussian."""
    settings = LocalizerConfig(filter=FilterConfig(num_particles=150, global_search=PARAMS))
    model = EdgeModel.build(small_world, settings, occlusion=False).for_mode(small_world,
                                                                             "oracle")
    loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                    model=model)
    loc.reset(StartHint(region=[-5.0, 0.0, 5.0, 1.0], heading=(0.0, np.pi / 2)))
    s = loc.search.states
    assert len(s) and (s[:, 1] <= 1.0 + 1e-9).all()
    assert ((s[:, 3] >= -1e-6) & (s[:, 3] <= np.pi / 2 + 1e-6)).all()
    centre = np.array([-0.6, 1.5, 0.7, 0.0])
    loc.reset(StartHint(pose=centre, covariance=np.diag([0.04, 0.04, 0.01, 0.05])))
    s, w = loc.search.states, np.exp(loc.search.logw)
    near = np.hypot(*(s[:, :2] - centre[:2]).T) < 0.5
    assert w[near].sum() > 0.9


def test_floor_boundary_only_above_the_horizon_is_none(camera):
    """Floor under a wall only in the image's top rows (rays going up: labels no real floor
    shows, a poorly trained SegNet's): no boundary bin, not an IndexError."""
    lab = np.full((camera.height, camera.width), C.CEILING, np.uint8)
    lab[0], lab[1] = C.WALL, C.FLOOR
    fb = floor_boundary(lab, camera, None, 180)
    assert len(fb.offsets) == 0


def without_floor_boundary(world):
    """``world`` with its edge segments between the floor and a wall, door or window dropped:
    walls standing on a slab of their own, sharing no vertex with the floor."""
    sc = np.asarray(world.segment_classes)
    standing = np.isin(sc, STANDING)
    pair = ((sc[:, 0] == C.FLOOR) & standing[:, 1]) | ((sc[:, 1] == C.FLOOR) & standing[:, 0])
    assert pair.any() and not pair.all()
    keep = ~pair
    return dataclasses.replace(world, segments=world.segments[keep], segment_classes=sc[keep],
                               crease_deg=world.crease_deg[keep],
                               info={**world.info, "name": "slab"})


def test_no_floor_boundary_falls_back_to_the_uniform_spread(small_world, camera, rendered,
                                                            caplog):
    """A model without floor-to-wall segments: the default global start (``table``) warns
    once, naming the reason and the setting, and starts the uniform particle set over the free
    space (as ``global_method: particles``) instead of raising; later starts on the world (a
    re-localization, another localizer) warn no more, and the filter steps."""
    world = without_floor_boundary(small_world)
    with pytest.raises(SearchUnavailable, match="no edge segment between the floor"):
        ray_table_for(world, PARAMS)
    settings = LocalizerConfig(filter=FilterConfig(num_particles=150, global_particles=2000,
                                                   global_search=PARAMS))
    assert settings.filter.global_method == "table"
    model = EdgeModel.build(world, settings, occlusion=False).for_mode(world, "oracle")
    locs = [Localizer(world, camera, "oracle", settings, np.random.default_rng(i), model=model)
            for i in range(2)]
    with caplog.at_level(logging.WARNING):
        for loc in locs + locs:
            loc.reset(None)
    warned = [r.getMessage() for r in caplog.records if "falls back" in r.getMessage()]
    assert len(warned) == 1, warned
    assert "'slab' has no edge segment between the floor" in warned[0]
    assert "filter.global_method=particles" in warned[0]
    loc = locs[0]
    assert loc.search is None
    P = loc.filter.particles
    free = world.free
    assert P.shape == (settings.filter.global_count(free.area), 4)
    assert free.contains(P[:, :2]).all()
    assert ((P[:, 2] >= free.band[0]) & (P[:, 2] <= free.band[1])).all()
    # spread over the whole free space and every heading, not around one pose
    x0, y0, x1, y1 = free.free_bounds
    assert np.ptp(P[:, 0]) > 0.8 * (x1 - x0) and np.ptp(P[:, 1]) > 0.8 * (y1 - y0)
    assert np.histogram(P[:, 3], 8, (-np.pi, np.pi))[0].min() > 0.08 * len(P)
    poses, labels = rendered
    e = loc.step(None, None, poses[0], 0.0, labels=labels[0])
    assert e.status == "ambiguous" and np.isfinite(e.state).all()


def test_a_hint_the_grid_misses_falls_back_to_the_hint_spread(small_world, camera, caplog):
    """A hint region inside the free space that no pose of the search's grid (cell centres
    jittered within their cell) falls in: the particles drawn inside the hint, with a warning,
    instead of raising."""
    settings = LocalizerConfig(filter=FilterConfig(num_particles=150, global_particles=500,
                                                   global_search=PARAMS))
    model = EdgeModel.build(small_world, settings, occlusion=False).for_mode(small_world,
                                                                             "oracle")
    loc = Localizer(small_world, camera, "oracle", settings, np.random.default_rng(0),
                    model=model)
    table = ray_table_for(small_world, PARAMS)
    corner = table.origin + np.floor((np.array([-0.6, 2.0]) - table.origin) / table.cell) \
        * table.cell  # a cell corner: the grid's centres are half a cell away in x and y
    region = [*(corner - 0.001), *(corner + 0.001)]
    with caplog.at_level(logging.WARNING):
        loc.reset(StartHint(region=region))
    assert loc.search is None
    assert any("leaves no pose" in r.getMessage() for r in caplog.records)
    P = loc.filter.particles
    assert len(P) and (np.abs(P[:, :2] - corner) <= 0.001 + 1e-9).all()
