"""During a global search the live node speaks, over the real middleware (rclpy, Fast DDS on
loopback only, as test_ros2_node.py): every frame gives a pose (the heaviest hypothesis) with
a covariance as wide as the hypotheses' spread, the hypotheses as a PoseArray, and a status
``ambiguous`` (WARN) whose values carry the calibrated quality; no frame fails.

The synthetic copy of the tiny dataset with the palette SegNet (mode cnn; the search needs a
label mode), started from nowhere."""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from hydra import compose, initialize_config_dir  # noqa: E402

from core.config import CONF  # noqa: E402
from localize.live.loop import load_context  # noqa: E402
from localize.ros2.play import PlayConfig, Player, open_playback  # noqa: E402
from tests.localize.conftest import QUICK  # noqa: E402
from tests.localize.test_ros2_node import publish_frames, start, stop, wait_until  # noqa: E402

FLIGHT = "paper"
FRAMES = 5  # fewer than the search's handover takes (filter.global_search.handover_frames)


@pytest.fixture(scope="module")
def search_setup(flat_dataset, flat_segnet, tmp_path_factory):
    """The node's config (mode cnn, no start: a global search), its context, the playback."""
    overrides = [o for o in QUICK if not o.startswith(("seeds", "progress"))]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="ros2", overrides=[
            *overrides, f"dataset={flat_dataset}", "mode=cnn", f"onnx_model={flat_segnet}",
            f"out_root={tmp_path_factory.mktemp('out')}", "realtime.max_age_s=2.0"])
    assert cfg.hint.pose is None
    return cfg, load_context(cfg), open_playback(flat_dataset / "flights" / FLIGHT)


def test_the_node_speaks_during_a_search(ros, search_setup, caplog):
    cfg, ctx, pb = search_setup
    node, got, executor, player_node, listener = start(ros, cfg, ctx)
    try:
        with caplog.at_level(logging.WARNING):
            player = Player(player_node, PlayConfig(topics=node.topics))
            assert player.wait_for_subscriber()
            publish_frames(player, pb, FRAMES, time.time() + 0.3 + 0.25 * np.arange(FRAMES))
            assert wait_until(lambda: node.live.counts.processed + node.live.counts.dropped
                              >= FRAMES, 20.0)
            n = node.live.counts.processed
            assert wait_until(lambda: len(got.poses) >= n and len(got.hypotheses) >= n
                              and len(got.statuses) >= n, 5.0)
            searching = node.live.localizer.search is not None
    finally:
        stop(node, executor, player_node, listener)
    assert searching, "the search handed over: test fewer frames"
    assert "frame failed" not in caplog.text
    c = node.live.counts
    assert c.processed >= FRAMES - 1 and c.processed + c.dropped == c.received == FRAMES, c
    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in got.hypotheses}
    for pose in got.poses:
        hyps = by_stamp[(pose.header.stamp.sec, pose.header.stamp.nanosec)]
        assert hyps.header.frame_id == pose.header.frame_id == "map"
        assert 2 <= len(hyps.poses) <= cfg.filter.hypotheses
        p = pose.pose.pose.position
        top = hyps.poses[0].position  # the pose is the heaviest place
        assert (p.x, p.y, p.z) == pytest.approx((top.x, top.y, top.z), abs=1e-9)
        cov = np.array(pose.pose.covariance).reshape(6, 6)
        assert np.isfinite(cov).all() and np.allclose(cov, cov.T)
        assert np.linalg.eigvalsh(cov).min() >= -1e-9 and cov[0, 0] + cov[1, 1] > 0
    values = got.status_values()
    status = got.statuses[-1].status[0]
    assert values["status"] == "ambiguous" and status.level == b"\x01"
    masses = np.array(values["hypothesis_masses"].split(), dtype=float)
    assert len(masses) == int(values["hypotheses"]) == len(got.hypotheses[-1].poses)
    assert np.all(np.diff(masses) <= 0) and 0 < masses.sum() <= 1 + 1e-6
    last = got.poses[-1]
    cov = np.array(last.pose.covariance).reshape(6, 6)
    xy = np.array([[h.position.x, h.position.y] for h in got.hypotheses[-1].poses])
    p = last.pose.pose.position
    d2 = ((xy - [p.x, p.y]) ** 2).sum(axis=1)
    # as wide as the hypotheses' spread: at least each one's mass times its offset from the
    # pose, squared (the masses this frame's status gives)
    assert cov[0, 0] + cov[1, 1] >= (masses * d2).sum() - 1e-6 > 0
    assert 0.0 <= float(values["quality"]) <= 1.0 or values["quality"] == "nan"
    assert values["filter_status"] == "ambiguous"
