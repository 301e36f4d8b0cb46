"""The live loop without a middleware (``localize.live.loop.LiveLocalizer``), fed by hand on
the synthetic copy of the tiny dataset with the palette SegNet (mode cnn): a global start
publishes every frame of its search; a re-localization that is not a pose is refused and the
track goes on; refused odometry is counted."""

from __future__ import annotations

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from core.config import CONF, typed
from core.poses import xyzyaw_from_pose
from localize.live.loop import LiveLocalizer, load_context
from localize.ros2.config import Ros2Config
from localize.ros2.play import open_playback
from tests.localize.conftest import QUICK

FLIGHT = "paper"
#: Capture time of the first frame, seconds; frames follow at 10 Hz.
T0 = 1000.0


@pytest.fixture(scope="module")
def setup(flat_dataset, flat_segnet, tmp_path_factory):
    """The node's config (mode cnn, the default unknown start), its context, the playback."""
    overrides = [o for o in QUICK if not o.startswith(("seeds", "progress"))]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="ros2", overrides=[
            *overrides, f"dataset={flat_dataset}", "mode=cnn", f"onnx_model={flat_segnet}",
            f"out_root={tmp_path_factory.mktemp('out')}"])
    assert cfg.hint.pose is None
    return cfg, load_context(cfg), open_playback(flat_dataset / "flights" / FLIGHT)


class Feed:
    """A ``LiveLocalizer`` on a clock that reads each frame's capture time when it is taken,
    and its outputs."""

    def __init__(self, cfg, ctx, pb):
        self.now, self.pb, self.outputs = T0, pb, []
        self.live = LiveLocalizer(cfg, ctx, self.outputs.append, clock=lambda: self.now)
        self.live.camera_info(pb.camera, "test camera_info")
        self.frames = iter(enumerate(pb.frames()))

    def step(self):
        """The next frame with its odometry: the worker's ``step_once``'s output or None."""
        i, image = next(self.frames)
        self.now = T0 + 0.1 * i
        self.live.odometry(self.now, self.pb.odometry[i], "test odometry")
        self.live.image(self.now, lambda: image, f"test frame {i}")
        return self.live.step_once(1.0)


def test_a_global_start_publishes_every_frame_of_its_search(setup):
    """While the global search runs (the particle filter holds no particles yet), each frame
    publishes its status, the heaviest hypothesis as the pose and a covariance around it as
    wide as the hypotheses: at least each one's mass times its offset, squared."""
    feed = Feed(*setup)
    try:
        for _ in range(4):
            assert feed.live.localizer.search is not None, "the search ended: test fewer frames"
            out = feed.step()
            assert out is not None, "the frame failed"
            est = out.estimate
            assert out.status == est.status == "ambiguous"
            np.testing.assert_allclose(out.pose[:3, 3], est.state[:3])
            cov = out.covariance
            assert cov.shape == (6, 6) and np.isfinite(cov).all() and np.allclose(cov, cov.T)
            assert np.linalg.eigvalsh(cov).min() >= -1e-9
            assert len(est.hypotheses) >= 2
            for axis in (0, 1):
                reach = sum(h.mass * (h.state[axis] - est.state[axis]) ** 2
                            for h in est.hypotheses)
                assert cov[axis, axis] >= reach > 0
            assert 0 < len(out.particles) <= 200 and np.isfinite(out.particles).all()
        assert feed.live.counts.processed == 4 and len(feed.outputs) == 4
        assert feed.live.status()[0] == "ambiguous"
    finally:
        feed.live.stop()


def tracking(cfg, pb):
    """``cfg`` tracking from the flight's first true pose."""
    x, y, z, yaw = xyzyaw_from_pose(pb.groundtruth[0])[0]
    return OmegaConf.merge(cfg, {"hint": {"pose": [float(x), float(y), float(z),
                                                   float(np.degrees(yaw))]}})


def test_a_relocalization_that_is_not_a_pose_is_refused(setup):
    """A start that is not finite (an ``/initialpose`` with a NaN position) is refused where
    it is requested; the next frame is processed from the current state, not failed."""
    cfg, ctx, pb = setup
    feed = Feed(tracking(cfg, pb), ctx, pb)
    try:
        assert feed.step() is not None
        nan_pose = np.eye(4)
        nan_pose[0, 3] = np.nan
        for start in (np.array([np.nan, 0.0, 1.0, 0.0]), nan_pose):
            with pytest.raises(ValueError, match="re-localization from .* refused: give a "
                                                 "finite"):
                feed.live.request_reset(start)
        assert feed.step() is not None
        assert feed.live.counts.processed == 2 and feed.live.counts.resets == 0
    finally:
        feed.live.stop()


def test_frames_not_processed_still_move_the_filter(setup):
    """Every other frame superseded (the worker busy, as at 30 Hz): each superseded frame's
    odometry moves the particles (``Localizer.predict`` at its capture time, counted
    ``predicted``) before the next frame's step; the estimates are those of a ``Localizer``
    that predicts at the odd frames and steps at the even ones, to float rounding."""
    from core.poses import odometry_increment
    from localize.filter.start_hint import start_of_settings
    from localize.localizer import Localizer

    cfg, ctx, pb = setup
    cfg = tracking(cfg, pb)
    feed = Feed(cfg, ctx, pb)
    n = 12
    frames = [image for _, image in zip(range(n), pb.frames(), strict=False)]
    try:
        live = feed.live
        for i in range(n):
            feed.now = T0 + 0.1 * i
            live.odometry(feed.now, pb.odometry[i], "test odometry")
            live.image(feed.now, lambda i=i: frames[i], f"test frame {i}")
            if i % 2:
                assert live.step_once(1.0) is not None
        c = live.counts
        assert c.processed == n // 2 and c.superseded == n // 2, c
        # each superseded frame moved the filter, but the first: the odometry starts there
        # (and the first step moves from it)
        assert c.predicted == n // 2 - 1, c
        assert live.status()[1]["frames_predicted"] == str(n // 2 - 1)
    finally:
        feed.live.stop()
    s = typed(Ros2Config, cfg, "ros2 config")
    loc = Localizer(ctx.world, ctx.camera, ctx.front_end(cfg.mode), ctx.settings,
                    np.random.default_rng(int(cfg.seed)), model=ctx.model_for(cfg.mode))
    loc.reset(start_of_settings(s.hint, ctx.world.info, ctx.world.free, s.filter.init_std))
    want = []
    for i in range(1, n, 2):
        t, odo = T0 + 0.1 * i, pb.odometry
        if i > 1:
            loc.predict(odometry_increment(odo[i - 2], odo[i - 1]), t - 0.1)
        want.append(loc.step(frames[i], odometry_increment(odo[i - 1], odo[i]), odo[i], t).state)
    got = np.array([o.estimate.state for o in feed.outputs])
    truth = xyzyaw_from_pose(pb.groundtruth[1:n:2])
    assert np.linalg.norm(got[:, :2] - truth[:, :2], axis=1).max() < 0.3
    np.testing.assert_allclose(got, np.array(want), atol=1e-5)


def test_refused_odometry_is_counted(setup):
    cfg, ctx, pb = setup
    feed = Feed(tracking(cfg, pb), ctx, pb)
    try:
        live = feed.live
        live.odometry(T0, np.eye(4), "test odometry")
        live.odometry(T0 + 0.1, np.full((4, 4), np.nan), "test odometry")  # not finite
        live.odometry(T0 - 1.0, np.eye(4), "test odometry")  # back in time
        live.reject_message("/initialpose", ValueError("test: a bad message"))
        assert live.counts.messages_rejected == 3
        assert live.status()[1]["messages_rejected"] == "3"
    finally:
        feed.live.stop()
