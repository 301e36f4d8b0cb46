"""The live node over the real middleware (rclpy, Fast DDS), on loopback only: the tiny
dataset's flight played through ``localize.ros2.play`` into ``localize.ros2``'s node tracks as
the offline run of the same frames; bad input is logged clearly, without a crash or a backlog.

Every participant runs with ``localize.ros2.loopback.loopback_env`` (UDPv4 on 127.0.0.1 only,
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a random domain), set before ``rclpy.init``.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402

from core.config import CONF, typed  # noqa: E402
from core.dataset import Dataset  # noqa: E402
from core.poses import xyzyaw_from_pose  # noqa: E402
from localize.live import sync  # noqa: E402
from localize.live.loop import load_context, offline_estimates  # noqa: E402
from localize.ros2.config import Ros2Config  # noqa: E402
from localize.ros2.convert import stamp_parts, stamp_seconds  # noqa: E402
from localize.ros2.play import PlayConfig, Player, open_playback  # noqa: E402
from tests.localize.conftest import QUICK  # noqa: E402

FLIGHT = "paper"


@pytest.fixture(scope="module")
def setup(tiny_dataset, tmp_path_factory):
    """The node's config (mode none, quick filter, tracking from the flight's first true
    pose), its loaded context and the flight's playback."""
    flight_dir = tiny_dataset / "flights" / FLIGHT
    pb = open_playback(flight_dir)
    s = xyzyaw_from_pose(pb.groundtruth[0])[0]
    start = [float(s[0]), float(s[1]), float(s[2]), float(np.degrees(s[3]))]
    overrides = [o for o in QUICK if not o.startswith(("seeds", "progress"))]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="ros2", overrides=[
            *overrides, f"dataset={tiny_dataset}", "mode=none",
            f"out_root={tmp_path_factory.mktemp('out')}", f"hint.pose={start}",
            "realtime.max_age_s=2.0"])
    return cfg, load_context(cfg), pb


def start(context, cfg, ctx):
    """(node, listener, executor, player node, listener node): the node with its worker and
    a listener of the pose and the status, spinning on a thread."""
    from rclpy.executors import SingleThreadedExecutor

    from localize.ros2.listen import Listener
    from localize.ros2.node import LocalizerNode

    node = LocalizerNode(cfg, ctx, context=context)
    listener_node = rclpy.create_node("listener", context=context)
    got = Listener(listener_node, node.topics)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(listener_node)
    player_node = rclpy.create_node("player", context=context)
    executor.add_node(player_node)  # its service calls' answers
    threading.Thread(target=executor.spin, daemon=True).start()
    return node, got, executor, player_node, listener_node


def stop(node, executor, *others):
    executor.shutdown(timeout_sec=2.0)
    node.destroy_node()
    for n in others:
        n.destroy_node()


def wait_until(cond, timeout_s: float = 10.0) -> bool:
    """``localize.live.sync.wait_until`` with the tests' default timeout."""
    return sync.wait_until(cond, timeout_s)


def test_camera_info_makes_no_model_edges(setup, monkeypatch):
    """The mode's model edges (seconds on a large building) are made when the node starts,
    not in the CameraInfo callback: that callback runs on the receiving thread, and while it
    ran no frame was received (the sensor QoS kept the last few, the rest were lost)."""
    import dataclasses

    from localize.edge_model import EdgeModel
    from localize.live.loop import LiveLocalizer

    cfg, ctx, pb = setup
    fresh = dataclasses.replace(ctx, _models={})
    made = []
    for_mode = EdgeModel.for_mode
    monkeypatch.setattr(EdgeModel, "for_mode",
                        lambda self, *a, **k: made.append(1) or for_mode(self, *a, **k))
    live = LiveLocalizer(cfg, fresh, publish=lambda out: None)
    before = len(made)
    live.camera_info(pb.camera, "test camera_info")
    assert live.localizer is not None
    assert len(made) == before, "the CameraInfo callback made the model edges"
    live.stop()


def test_the_flight_through_the_node_tracks_as_offline(ros, setup):
    cfg, ctx, pb = setup
    node, got, executor, player_node, listener = start(ros, cfg, ctx)
    try:
        player = Player(player_node, PlayConfig(rate=0.5))  # 5 Hz: room on a busy machine
        assert player.wait_for_subscriber()
        stamps = player.play(pb)
        assert wait_until(lambda: node.live.counts.processed + node.live.counts.dropped
                          >= len(stamps))
        wait_until(lambda: len(got.poses) >= node.live.counts.processed, 3.0)
        wait_until(lambda: got.status_values().get("frames_processed")
                   == str(node.live.counts.processed), 3.0)
    finally:
        stop(node, executor, player_node, listener)
    counts = node.live.counts
    assert counts.received == len(pb) and counts.processed >= 0.8 * len(pb), counts
    sent = np.array(stamps)
    got_stamps = got.stamps()
    rows = [int(np.argmin(abs(sent - s))) for s in got_stamps]
    # stamped with the capture times (to the float64 rounding of a 2026 stamp, ~0.2 us)
    assert np.all(abs(sent[rows] - got_stamps) < 1e-6)
    assert rows == sorted(rows) and len(rows) == counts.processed
    live = got.positions()
    assert all(m.header.frame_id == "map" for m in got.poses)
    # the played stamps (5 Hz) as the node reads them from the messages: the motion noise
    # follows the time between frames, and the filter amplifies a rounding's difference
    received = np.array([stamp_seconds(Time(sec=sec, nanosec=ns))
                         for sec, ns in map(stamp_parts, sent)])
    offline = offline_estimates(ctx, cfg, Dataset(cfg.dataset).flight(FLIGHT),
                                stamps=received)[rows, :3]
    gap = np.linalg.norm(live - offline, axis=1)
    # every frame processed: the same frames, pixels and odometry (to quaternion rounding)
    assert gap.mean() < (1e-6 if counts.dropped == 0 else 0.05), gap
    cov = np.array(got.poses[-1].pose.covariance).reshape(6, 6)
    assert np.all(np.diag(cov) > 0) and np.allclose(cov, cov.T)
    values = got.status_values()
    assert values["status"] in ("tracking", "ambiguous")
    assert int(values["frames_processed"]) == counts.processed
    assert float(values["latency_median_ms"]) > 0


def publish_frames(player, pb, n, stamps, encoding=None, info=True, crop=0):
    """Frames 0..n-1 of the playback at the given stamps (odometry, CameraInfo, image;
    the CameraInfo once before them too)."""
    if info:
        player.info_pub.publish(player.camera_info(pb.camera, stamps[0]))
        time.sleep(0.3)
    for i, (image, stamp) in enumerate(zip(pb.frames(), stamps, strict=False)):
        if i >= n:
            break
        time.sleep(max(0.0, stamp - time.time()))  # at its capture time
        player.odometry_pub.publish(player.odometry_message(pb.odometry[i], stamp))
        if info:
            player.info_pub.publish(player.camera_info(pb.camera, stamp))
        msg = player.image_message(image[crop:], stamp)
        if encoding is not None:
            msg.encoding = encoding
        player.image_pub.publish(msg)


def test_plays_a_bag(setup, tmp_path):
    """A ROS 2 bag plays with its own calibration and frames as recorded."""
    from localize.recordings.export import export_bag

    cfg, ctx, pb = setup
    bag = export_bag(cfg.dataset, FLIGHT, tmp_path / "bag")
    played = open_playback(bag)
    assert len(played) == len(pb) and played.camera.width == pb.camera.width
    np.testing.assert_allclose(played.odometry[:, :3, 3], pb.odometry[:, :3, 3], atol=1e-6)
    assert next(iter(played.frames())).shape == (pb.camera.height, pb.camera.width, 3)


def run_node(ros, setup, feed, settings=None, **topics):
    """Start the node (``settings`` and ``topics`` over the config's), ``feed(player,
    playback, node, listener)``, stop it; (node, listener)."""
    cfg, ctx, pb = setup
    if settings or topics:
        cfg = OmegaConf.merge(cfg, settings or {}, {"topics": topics})
    node, got, executor, player_node, listener = start(ros, cfg, ctx)
    try:
        player = Player(player_node, PlayConfig(topics=node.topics))
        assert player.wait_for_subscriber()
        feed(player, pb, node, got)
    finally:
        stop(node, executor, player_node, listener)
    return node, got


class TestBadInput:
    def test_unsupported_encoding(self, ros, setup, caplog):
        def feed(player, pb, node, got):
            stamps = time.time() + 0.1 * np.arange(4)
            publish_frames(player, pb, 3, stamps[:3], encoding="16UC1")
            wait_until(lambda: node.live.counts.rejected >= 1)
            publish_frames(player, pb, 1, stamps[3:])  # a good frame still goes through
            wait_until(lambda: node.live.counts.processed >= 1)

        with caplog.at_level(logging.WARNING):
            node, got = run_node(ros, setup, feed)
        assert "image encoding '16UC1' is not supported; use one of" in caplog.text
        assert "(or a CompressedImage topic)" in caplog.text
        assert node.live.counts.rejected >= 1 and node.live.counts.processed >= 1

    def test_image_of_another_size(self, ros, setup, caplog):
        def feed(player, pb, node, got):
            publish_frames(player, pb, 2, time.time() + 0.1 * np.arange(2), crop=8)
            wait_until(lambda: node.live.counts.rejected >= 1)

        with caplog.at_level(logging.WARNING):
            node, got = run_node(ros, setup, feed)
        assert "the CameraInfo (/camera/camera_info) says 128x96" in caplog.text
        assert node.live.counts.processed == 0

    def test_no_camera_info(self, ros, setup, caplog):
        def feed(player, pb, node, got):
            now = time.time()
            publish_frames(player, pb, 3, now + 0.05 * np.arange(3), info=False)
            wait_until(lambda: node.live.counts.received >= 3)

        with caplog.at_level(logging.WARNING):
            node, got = run_node(ros, setup, feed)
        assert "no CameraInfo received yet on /camera/camera_info" in caplog.text
        assert node.live.counts.processed == 0 and not got.poses
        assert node.live.counts.rejected == node.live.counts.received >= 1

    def test_odometry_going_backwards(self, ros, setup, caplog):
        def feed(player, pb, node, got):
            now = time.time()
            publish_frames(player, pb, 2, [now, now + 0.1])
            odo = player._types["odometry"]()
            player._header(odo, now - 1.0, "odom")  # back in time
            odo.pose.pose.orientation.w = 1.0
            player.odometry_pub.publish(odo)
            wait_until(lambda: node.live.counts.processed >= 1)
            wait_until(lambda: "backwards" in caplog.text, 3.0)

        with caplog.at_level(logging.WARNING):
            node, got = run_node(ros, setup, feed)
        assert "stamps went backwards or repeat; sample ignored" in caplog.text
        assert node.live.counts.processed >= 1

    def test_bad_pose_messages_are_dropped_and_counted(self, ros, setup, caplog):
        """An odometry with a zero quaternion and initial poses with a NaN or zero
        quaternion, a NaN covariance or a NaN position are each dropped with a warning and
        counted; the node goes on spinning and tracks the next frames from its own state."""
        from geometry_msgs.msg import PoseWithCovarianceStamped

        from localize.ros2.play import _set_pose

        nan = float("nan")

        def feed(player, pb, node, got):
            now = time.time()
            odo = player.odometry_message(pb.odometry[0], now - 0.5)
            odo.pose.pose.orientation.x = odo.pose.pose.orientation.y = 0.0
            odo.pose.pose.orientation.z = odo.pose.pose.orientation.w = 0.0
            player.odometry_pub.publish(odo)
            assert wait_until(lambda: node.live.counts.messages_rejected == 1, 5.0)
            pub = player.node.create_publisher(PoseWithCovarianceStamped,
                                               node.topics.initial_pose, 1)
            assert wait_until(lambda: pub.get_subscription_count() > 0, 5.0)
            for n, bad in enumerate(("nan quaternion", "zero quaternion", "nan covariance",
                                     "nan position"), start=2):
                msg = PoseWithCovarianceStamped()
                msg.header.frame_id = "map"
                _set_pose(msg.pose.pose, pb.groundtruth[0])
                q, p = msg.pose.pose.orientation, msg.pose.pose.position
                if bad == "nan quaternion":
                    q.x = nan
                elif bad == "zero quaternion":
                    q.x = q.y = q.z = q.w = 0.0
                elif bad == "nan covariance":
                    msg.pose.covariance[0] = nan
                else:
                    p.x = nan
                pub.publish(msg)
                assert wait_until(lambda n=n: node.live.counts.messages_rejected == n, 5.0), bad
            publish_frames(player, pb, 2, time.time() + 0.3 + 0.1 * np.arange(2))
            wait_until(lambda: node.live.counts.processed >= 2)

        with caplog.at_level(logging.WARNING):
            node, got = run_node(ros, setup, feed)
        c = node.live.counts
        assert c.messages_rejected == 5 and c.resets == 0, c
        assert c.processed == 2 and len(got.poses) == 2, c
        assert "/odom: pose.orientation (x, y, z, w) = [0.0, 0.0, 0.0, 0.0] is not a rotation" \
            in caplog.text
        assert "/initialpose: pose.orientation" in caplog.text  # once per 5 s: the first
        assert "/odom: /odom" not in caplog.text
        assert got.status_values()["messages_rejected"] == "5"
        truth = xyzyaw_from_pose(setup[2].groundtruth[:2])
        assert np.linalg.norm(got.positions()[-1] - truth[-1, :3]) < 0.5

    def test_a_burst_of_frames_builds_no_backlog(self, ros, setup):
        """30 frames at 30 Hz, then 30 as fast as they go, then, after a pause, one more: the
        node takes the newest, counts the others as dropped, and the last frame is processed
        soon after it came, not behind a backlog (the sensor QoS, best effort with a depth of
        5, may lose frames of the burst before the node sees them)."""
        def feed(player, pb, node, got):
            now = time.time()
            stamps = now + np.arange(30) / 30.0
            for i in range(0, 30, 10):  # 30 Hz for a third of a second, three times over
                publish_frames(player, pb, 10, stamps[i:i + 10])
            burst = max(time.time(), stamps[-1] + 0.01) + 1e-4 * np.arange(30)
            publish_frames(player, pb, 30, burst)  # as fast as they go
            time.sleep(0.3)
            self.last = max(time.time(), burst[-1] + 0.01)
            publish_frames(player, pb, 1, np.array([self.last]))
            wait_until(lambda: len(got.poses) and got.stamps().max() >= self.last - 1e-6)
            time.sleep(0.3)

        node, got = run_node(ros, setup, feed)
        c = node.live.counts
        # (frames the sensor QoS lost before the node saw them are not the node's to count)
        assert 20 <= c.received <= 61 and c.processed < c.received and c.superseded > 0, c
        assert c.processed + c.dropped == c.received, c
        # the last frame was processed, not a backlog of old ones
        assert got.stamps().max() >= self.last - 1e-6
        assert node.live.latency.percentile(100) < 2.0


class TestInputsAndResets:
    def test_compressed_images_and_pose_odometry(self, ros, setup):
        def feed(player, pb, node, got):
            publish_frames(player, pb, 4, time.time() + 0.3 + 0.1 * np.arange(4))
            wait_until(lambda: node.live.counts.processed >= 2)

        node, got = run_node(ros, setup, feed, image_transport="compressed",
                                     odometry_type="pose")
        assert node.live.counts.processed >= 2 and len(got.poses) >= 2

    def test_initial_pose_and_global_localization(self, ros, setup, caplog):
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from std_srvs.srv import Empty

        from localize.ros2.play import _set_pose

        def feed(player, pb, node, got):
            client = player.node.create_client(Empty, node.topics.global_localization)
            assert client.wait_for_service(timeout_sec=5.0)
            future = client.call_async(Empty.Request())
            assert wait_until(future.done, 5.0)
            publish_frames(player, pb, 1, [time.time() + 0.3])
            wait_until(lambda: node.live.counts.processed >= 1)
            assert got.status_values().get("status") in (None, "ambiguous")
            pub = player.node.create_publisher(PoseWithCovarianceStamped,
                                               node.topics.initial_pose, 1)
            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = "map"
            _set_pose(msg.pose.pose, pb.groundtruth[1])
            assert wait_until(lambda: pub.get_subscription_count() > 0, 5.0)
            # RViz's 2D Pose Estimate covariance: a search around the pose
            msg.pose.covariance = np.diag([0.25, 0.25, 0, 0, 0, 0.0685]).ravel().tolist()
            pub.publish(msg)
            time.sleep(0.3)
            publish_frames(player, pb, 1, [time.time() + 0.3])
            wait_until(lambda: node.live.counts.processed >= 2)
            msg.pose.covariance = [0.0] * 36  # no covariance: tracking from the pose
            pub.publish(msg)
            time.sleep(0.3)
            now = time.time() + 0.3
            publish_frames(player, pb, 2, [now, now + 0.1])
            wait_until(lambda: node.live.counts.processed >= 4)

        with caplog.at_level(logging.INFO):
            node, got = run_node(ros, setup, feed)
        assert node.live.counts.resets == 3
        assert "re-localization (global start): reset counter 1" in caplog.text
        assert "searching around x" in caplog.text
        assert "re-localization (initial pose search): reset counter 2" in caplog.text
        assert "re-localization (initial pose): reset counter 3" in caplog.text
        truth = xyzyaw_from_pose(setup[2].groundtruth[:3])
        assert np.linalg.norm(got.positions()[-1] - truth[:, :3], axis=1).min() < 0.5

    def test_estimates_reach_the_autopilot(self, ros, setup):
        """With ``mavlink=udpout:...`` each estimate goes out as MAVLink ODOMETRY stamped
        with its frame's capture time, and ``/initialpose`` increments its reset counter."""
        from geometry_msgs.msg import PoseWithCovarianceStamped

        from localize.live.mavlink import MAV_FRAME_BODY_FRD
        from localize.ros2.play import _set_pose

        mavutil = pytest.importorskip("pymavlink.mavutil")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        rx = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}")
        sent = []

        def feed(player, pb, node, got):
            now = time.time() + 0.3
            sent.extend([now, now + 0.1])
            publish_frames(player, pb, 2, sent[:2])
            wait_until(lambda: node.live.counts.processed >= 2)
            pub = player.node.create_publisher(PoseWithCovarianceStamped,
                                               node.topics.initial_pose, 1)
            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = "map"
            _set_pose(msg.pose.pose, pb.groundtruth[2])
            assert wait_until(lambda: pub.get_subscription_count() > 0, 5.0)
            pub.publish(msg)
            wait_until(lambda: node.live.counts.resets >= 1, 5.0)
            later = time.time() + 0.3
            sent.append(later)
            publish_frames(player, pb, 1, [later])
            wait_until(lambda: node.live.counts.processed >= 3)

        try:
            node, got = run_node(ros, setup, feed,
                                 settings={"mavlink": f"udpout:127.0.0.1:{port}"})
            out = []
            while (m := rx.recv_match(type="ODOMETRY", blocking=True, timeout=2)) is not None:
                out.append(m)
        finally:
            rx.close()
        assert len(out) == node.live.counts.processed == 3
        assert all(m.child_frame_id == MAV_FRAME_BODY_FRD for m in out)
        # the capture stamps, to the microsecond (a float second's nanoseconds round either way)
        np.testing.assert_allclose([m.time_usec for m in out], [t * 1e6 for t in sent],
                                   rtol=0, atol=1.0)
        assert [m.reset_counter for m in out] == [0, 0, 1]


@pytest.mark.slow
def test_python_m_localize_ros2(ros, setup, tmp_path):
    """``python -m localize.ros2`` starts from the command line (Hydra's overrides, then a ROS
    params file after ``--ros-args`` giving the start pose), reports its status on the
    loopback DDS of this test, tracks the frames played to it and stops cleanly on Ctrl-C."""
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from localize.ros2.listen import Listener

    cfg, ctx, pb = setup
    root = Path(__file__).resolve().parents[2]
    params = tmp_path / "params.yaml"
    params.write_text("edgeloc:\n  ros__parameters:\n    hint:\n"
                      f"      pose: {[float(v) for v in cfg.hint.pose]}\n")
    args = [f"dataset={cfg.dataset}", "mode=none", f"out_root={cfg.out_root}",
            f"hydra.run.dir={tmp_path}",
            *[o for o in QUICK if not o.startswith(("seeds", "progress"))],
            "--ros-args", "--params-file", str(params)]
    proc = subprocess.Popen([sys.executable, "-m", "localize.ros2", *args], cwd=root,
                            env=os.environ.copy(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node("cli_listener", context=ros)
    from rclpy.executors import SingleThreadedExecutor

    got = Listener(node, typed(Ros2Config, cfg, "ros2 config").topics)
    executor = SingleThreadedExecutor(context=ros)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    try:
        assert wait_until(lambda: got.statuses or proc.poll() is not None, 120.0)
        assert proc.poll() is None, proc.stdout.read()
        assert got.status_values()["status"] == "waiting"
        player = Player(node, PlayConfig(max_frames=5))
        assert player.wait_for_subscriber()
        player.play(pb)
        assert wait_until(lambda: len(got.poses) >= 3, 20.0)
        truth = xyzyaw_from_pose(pb.groundtruth[:5])[:, :3]
        assert np.linalg.norm(got.positions()[0] - truth[0]) < 0.3  # the params file's start
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, _ = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
    assert proc.returncode == 0, out
    assert "hint.pose=" in out and "node edgeloc active" in out, out


def test_the_player_prints_its_usage(capsys):
    """``--help`` prints the usage (not "recording not found: --help"); no recording: usage."""
    from localize.ros2.play import main

    main(["--help"])
    assert "usage: python -m localize.ros2.play" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="usage"):
        main([])
