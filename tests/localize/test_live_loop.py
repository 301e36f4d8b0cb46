"""The live loop without a middleware (``localize.live.loop.LiveLocalizer``), fed by hand on
the synthetic copy of the tiny dataset with the palette SegNet (mode cnn): a global start
publishes every frame of its search; a re-localization that is not a pose is refused and the
track goes on; refused odometry is counted."""

from __future__ import annotations

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from core.config import CONF
from core.poses import xyzyaw_from_pose
from localize.live.loop import LiveLocalizer, load_context
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
