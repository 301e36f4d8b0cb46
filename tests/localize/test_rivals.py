"""Rival hypotheses kept beside the track (localize.search.rivals): a teleport into a place
that still fits is declared lost by them, with the fit gate off; a steady track is never."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core.poses import xyzyaw_from_pose
from core.spliced import kidnapped
from localize.config import FilterConfig
from localize.edge_model import EdgeModel
from localize.localizer import Localizer
from localize.offline.metrics import false_convergence
from localize.search.config import RivalsConfig
from localize.search.rivals import Check, doubt_after
from tests.localize.test_global_search import PARAMS
from tests.localize.test_kidnapped import rendered_flight, walk
from tests.localize.test_localize_localizer import SETTINGS

#: The gate never declares a loss (``lost_frames`` 0): only the rivals can.
NO_GATE = replace(SETTINGS, filter=FilterConfig(
    num_particles=300, global_method="table", global_search=PARAMS, lost_frames=0,
    tracking_quality=0.0, rivals=RivalsConfig(enabled=True)))


def run(flight, world, camera, settings, seed=0):
    """Track ``flight`` from its first true pose: (statuses, horizontal errors (m), the
    localizer)."""
    model = EdgeModel.build(world, settings).for_mode(world, "oracle")
    loc = Localizer(world, camera, "oracle", settings, np.random.default_rng(seed), model=model)
    truth = xyzyaw_from_pose(flight.groundtruth)
    loc.reset(truth[0])
    status, err = [], []
    for f in flight.steps(images=False, labels=True):
        est = loc.step(None, f.odometry_increment, f.attitude, f.timestamp, labels=f.labels)
        status.append(est.status)
        err.append(float(np.linalg.norm(est.state[:2] - truth[f.index, :2])))
    return status, np.array(err), loc


@pytest.fixture(scope="module")
def flights(small_world, camera, renderer, tmp_path_factory):
    """(steady, kidnapped): a 40-frame walk up the small corridor; 12 frames of it, then the
    truth teleported 2.6 m to the far end, facing back, for 30 frames (the odometry does not
    feel the jump)."""
    folder = tmp_path_factory.mktemp("rivals")
    steady = rendered_flight(folder, "s", walk([0.2, 0.6, 1.2, np.deg2rad(80.0)], 40),
                             renderer, camera, np.eye(4))
    a = rendered_flight(folder, "a", walk([0.2, 0.6, 1.2, np.deg2rad(80.0)], 12), renderer,
                        camera, np.eye(4))
    b = rendered_flight(folder, "b", walk([-0.1, 3.2, 1.2, np.deg2rad(-95.0)], 30), renderer,
                        camera, np.eye(4))
    return steady, kidnapped(a, b)


@pytest.mark.slow
def test_a_kidnapping_the_gate_misses_is_caught_by_the_rivals(flights, small_world, camera):
    """With the fit gate off, the teleport is declared ``lost`` within 15 frames, the
    background search re-localizes (``ambiguous``; its heaviest place within 1 m: the
    corridor's two ends look alike to its floor-boundary table, so it does not hand over in
    the 15 frames left), and ``tracking`` is never reported > 1 m off for > 1 s; without the
    rivals the loss is never declared."""
    _, flight = flights
    at = flight.info["kidnapped_at"]
    status, err, loc = run(flight, small_world, camera, NO_GATE)
    assert "lost" not in status[:at]
    assert "lost" in status[at:at + 15], status[at:]
    lost = at + status[at:].index("lost")
    assert loc.search is not None and set(status[lost + 1:]) == {"ambiguous"}, status[lost:]
    assert (err[-5:] < 1.0).all(), err[at:]
    assert not false_convergence(err, flight.timestamps, status, 1.0, 1.0)
    off = replace(NO_GATE, filter=replace(NO_GATE.filter, rivals=RivalsConfig(enabled=False)))
    status, err, loc = run(flight, small_world, camera, off)
    assert loc.rivals is None and "lost" not in status
    assert err[at:].min() > 0.5  # the teleport goes unnoticed: the rivals are what caught it


@pytest.mark.slow
def test_a_steady_track_is_never_declared_lost(flights, small_world, camera):
    """40 frames along the corridor from the truth: the rivals are checked (13 times) and
    never outweigh the track."""
    steady, _ = flights
    status, err, loc = run(steady, small_world, camera, NO_GATE)
    assert loc.rivals is not None and loc.rivals._checks >= 10
    assert "lost" not in status and (err < 0.2).all(), err


def test_after_a_loss_the_track_is_doubted_until_it_leads_every_rival():
    """A loss starts the doubt; a check where a rival comes within the margin of the track
    (the copy of the place the filter jumped to) resets it; ``checks`` leads in a row by
    more than the margin end it; no check (or no doubt) leaves it as it is."""
    p = RivalsConfig(margin=3.0, checks=3)

    def chk(track, rival, lost=False):
        return Check(track, rival, None, 0, lost)

    assert doubt_after(None, chk(0.0, 9.0, lost=True), p) == 0
    assert doubt_after(None, chk(0.0, 2.0), p) is None
    doubt = 0
    for track, rival in ((9.0, 1.0), (9.0, 1.0), (9.0, 7.0), (9.0, 1.0), (9.0, float("-inf"))):
        doubt = doubt_after(doubt, chk(track, rival), p)
        assert doubt is not None  # the third lead in a row has not come yet
        doubt = doubt_after(doubt, None, p)
    assert doubt_after(doubt, chk(9.0, 1.0), p) is None


def test_rivals_settings_are_checked():
    with pytest.raises(ValueError, match="filter.rivals.every"):
        RivalsConfig(every=0)
    with pytest.raises(ValueError, match="filter.rivals.margin"):
        RivalsConfig(margin=-1.0)
