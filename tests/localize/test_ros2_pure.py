"""The live node's pure parts, without a middleware: the odometry at frame times, the
newest-frame slot, message conversions (bad poses refused), the covariance of the particles
and of a global search's hypotheses, the settings."""

from __future__ import annotations

import threading
import time
from array import array
from types import SimpleNamespace

import numpy as np
import pytest

from core.config import typed
from core.poses import interpolate_poses, pose_from_xyzyaw
from localize.filter.hypotheses import Hypothesis
from localize.filter.start_hint import StartHint
from localize.live.sync import LatencyWindow, LatestSlot, OdometryBuffer, Throttle, wait_until
from localize.ros2.config import Ros2Config
from localize.ros2.convert import (
    hypotheses_covariance,
    image_of,
    initial_pose_start,
    live_status,
    particle_covariance,
    pose_of,
    position_quaternion,
    shown_particles,
    stamp_parts,
    yaw_quaternions,
)
from localize.ros2.loopback import loopback_env


def poses(n: int) -> np.ndarray:
    return pose_from_xyzyaw(np.column_stack([np.arange(n) * 0.1, np.zeros(n), np.ones(n),
                                             np.linspace(0, 1, n)]))


class TestOdometryBuffer:
    def test_interpolates_as_recordings_do(self):
        buf, T = OdometryBuffer(10.0), poses(5)
        t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
        for ti, Ti in zip(t, T, strict=True):
            assert buf.add(ti, Ti) is None
        np.testing.assert_allclose(buf.at(0.25), interpolate_poses([0.25], t, T)[0],
                                   atol=1e-12)
        np.testing.assert_allclose(buf.at(0.4), T[4], atol=1e-12)
        assert buf.at(0.41) is None and buf.at(-0.01) is None  # never extrapolated

    def test_stamps_going_backwards_are_refused(self):
        buf = OdometryBuffer(10.0)
        buf.add(1.0, np.eye(4))
        why = buf.add(0.5, np.eye(4))
        assert "backwards" in why and len(buf) == 1
        assert "finite" in buf.add(2.0, np.full((4, 4), np.nan))

    def test_keeps_only_the_last_seconds(self):
        buf, T = OdometryBuffer(1.0), poses(40)
        for i, Ti in enumerate(T):
            buf.add(0.1 * i, Ti)
        assert len(buf) <= 12 and buf.at(0.5) is None and buf.at(3.85) is not None

    def test_waits_for_the_odometry_to_reach_the_frame(self):
        buf = OdometryBuffer(10.0)
        buf.add(0.0, np.eye(4))
        threading.Timer(0.05, buf.add, (1.0, np.eye(4))).start()
        pose, why = buf.wait_for(0.5, 2.0)
        assert pose is not None and why == ""
        pose, why = buf.wait_for(2.0, 0.05)
        assert pose is None and "did not reach" in why and "clock" in why
        assert "no odometry" in OdometryBuffer(1.0).wait_for(0.0, 0.01)[1]
        assert "before the odometry" in buf.wait_for(-1.0, 0.01)[1]


def test_latest_slot_keeps_the_newest():
    slot = LatestSlot()
    assert slot.put(1) is None
    assert slot.put(2) == 1  # 1 was not taken: dropped
    assert slot.take(0.01) == 2 and slot.take(0.01) is None
    t0 = time.monotonic()
    threading.Timer(0.05, slot.put, (3,)).start()
    assert slot.take(2.0) == 3 and time.monotonic() - t0 < 1.0


def test_wait_until_a_condition_or_the_timeout():
    assert wait_until(lambda: True, 0.0)
    flag = threading.Event()
    threading.Timer(0.05, flag.set).start()
    assert wait_until(flag.is_set, 5.0, poll_s=0.01)
    start = time.monotonic()
    assert not wait_until(lambda: False, 0.1, poll_s=0.01)
    assert time.monotonic() - start >= 0.1


def test_latency_window_and_throttle():
    w = LatencyWindow(3)
    assert np.isnan(w.percentile(50))
    for v in (1.0, 2.0, 3.0, 4.0):
        w.add(v)
    assert w.percentile(50) == 3.0 and len(w) == 3
    th = Throttle(60.0)
    assert th("a") and not th("a") and th("b")


def test_stamps_and_quaternions():
    assert stamp_parts(12.5) == (12, 500_000_000)
    sec, ns = stamp_parts(1796176277.430581)
    assert sec == 1796176277 and abs(ns - 430581000) < 1000  # float64: ~0.2 us at 2026
    T = pose_from_xyzyaw([1.0, 2.0, 3.0, 0.7])[0]
    p, q = position_quaternion(T)
    np.testing.assert_allclose(p, [1, 2, 3])
    np.testing.assert_allclose(q, yaw_quaternions(np.array([0.7]))[0], atol=1e-12)


def test_image_decoding_names_the_encoding():
    msg = SimpleNamespace(encoding="bgr8", height=2, width=3, step=9,
                          data=array("B", range(18)))
    rgb = image_of(msg, "raw", "topic /cam frame 1")
    assert rgb.shape == (2, 3, 3) and rgb[0, 0].tolist() == [2, 1, 0]
    bad = SimpleNamespace(encoding="16UC1", height=2, width=3, step=6, data=array("B", bytes(12)))
    with pytest.raises(ValueError, match=r"/cam frame 1: image encoding '16UC1' is not "
                                         r"supported; use one of"):
        image_of(bad, "raw", "/cam frame 1")


def test_covariance_of_the_particles():
    rng = np.random.default_rng(0)
    n = 20000
    std = np.array([0.3, 0.1, 0.05, 0.02, 0.01, 0.2])
    d = rng.normal(size=(n, 6)) * std
    mean = np.array([1.0, 2.0, 1.0, np.pi - 0.05])  # yaw near the wrap
    particles = mean + d[:, [0, 1, 2, 5]]
    particles[:, 3] = (particles[:, 3] + np.pi) % (2 * np.pi) - np.pi
    cov = particle_covariance(particles, np.full(n, -np.log(n)), d[:, 3:5], mean)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), std, rtol=0.03)
    assert np.allclose(cov, cov.T) and abs(cov[0, 1]) < 1e-3
    shown = shown_particles(particles, 100, rng)
    assert shown.shape == (100, 4)


def pose_message(position=(1.0, 2.0, 0.5), orientation=(0.0, 0.0, 0.0, 1.0),
                 covariance=(0.0,) * 36) -> SimpleNamespace:
    """A PoseWithCovarianceStamped- or Odometry-like message (``msg.pose.pose``)."""
    x, y, z = position
    qx, qy, qz, qw = orientation
    pose = SimpleNamespace(position=SimpleNamespace(x=x, y=y, z=z),
                           orientation=SimpleNamespace(x=qx, y=qy, z=qz, w=qw))
    return SimpleNamespace(pose=SimpleNamespace(pose=pose, covariance=list(covariance)))


class TestBadPoseMessages:
    """A pose that is not one is refused with a ValueError naming the topic and the field
    (the node drops and counts the message), never a scipy error or a NaN pose."""

    NAN = float("nan")

    @pytest.mark.parametrize("orientation", [(0.0, 0.0, 0.0, 0.0), (NAN, 0.0, 0.0, 1.0),
                                             (0.0, 0.0, 0.0, float("inf"))])
    def test_an_orientation_that_is_not_a_rotation(self, orientation):
        with pytest.raises(ValueError, match=r"^/odom: pose.orientation .* is not a rotation"):
            pose_of(pose_message(orientation=orientation), "odometry", "/odom")

    def test_a_position_that_is_not_finite(self):
        with pytest.raises(ValueError, match=r"^/odom: pose.position .* is not finite"):
            pose_of(pose_message(position=(self.NAN, 0.0, 0.0)), "odometry", "/odom")

    def test_a_good_pose(self):
        T = pose_of(pose_message(orientation=(0.0, 0.0, np.sin(0.35), np.cos(0.35))),
                    "odometry", "/odom")
        np.testing.assert_allclose(T, pose_from_xyzyaw([1.0, 2.0, 0.5, 0.7])[0], atol=1e-12)

    @pytest.mark.parametrize("bad, field", [
        ({"position": (NAN, 2.0, 0.5)}, "pose.position"),
        ({"orientation": (NAN, 0.0, 0.0, 1.0)}, "pose.orientation"),
        ({"orientation": (0.0, 0.0, 0.0, 0.0)}, "pose.orientation"),
        ({"covariance": (NAN,) * 36}, "pose.covariance"),
        ({"covariance": (0.25,) * 35}, "pose.covariance"),
        ({"covariance": -np.eye(6).ravel()}, "pose.covariance"),  # not semi-definite
    ])
    def test_an_initial_pose_that_is_not_one(self, bad, field):
        with pytest.raises(ValueError, match=rf"^/initialpose: {field}"):
            initial_pose_start(pose_message(**bad), [0.1, 0.1, 0.05, 5.0], "/initialpose")

    def test_an_initial_pose(self):
        init_std = [0.1, 0.1, 0.05, 5.0]
        start = initial_pose_start(pose_message(), init_std, "/initialpose")
        np.testing.assert_allclose(start, [1.0, 2.0, 0.5, 0.0])  # no covariance: tracking
        wide = np.diag([0.25, 0.25, 0.0, 0.0, 0.0, 0.07]).ravel()
        hint = initial_pose_start(pose_message(covariance=wide), init_std, "/initialpose")
        assert isinstance(hint, StartHint) and hint.covariance[0, 0] == 0.25


def hypothesis(x: float, y: float, yaw: float, mass: float, position_std: float = 0.1,
               yaw_std: float = 0.05) -> Hypothesis:
    return Hypothesis(np.array([x, y, 1.0, yaw]), mass, position_std, yaw_std, 10)


def search_estimate(hyps: list[Hypothesis], position_std: float, yaw_std: float):
    """A global search's estimate: the heaviest hypothesis's pose, the whole set's spread."""
    return SimpleNamespace(state=hyps[0].state, hypotheses=tuple(hyps),
                           position_std=position_std, yaw_std=yaw_std)


class TestCovarianceOfAGlobalSearch:
    def test_one_hypothesis_holding_the_mass(self):
        cov = hypotheses_covariance(search_estimate([hypothesis(1.0, 2.0, 0.3, 1.0, 0.2, 0.1)],
                                                    5.0, 2.0))
        np.testing.assert_allclose(np.diag(cov), [0.04, 0.04, 0.0, 0.0, 0.0, 0.01])

    def test_as_wide_as_the_hypotheses_around_the_best(self):
        """Two places 4 m apart and headings across the wrap: the covariance around the
        heaviest reaches the other (its mass times its offset, squared, at least), and the
        yaw offset is the short way round."""
        hyps = [hypothesis(0.0, 0.0, np.pi - 0.1, 0.5), hypothesis(0.0, 4.0, -np.pi + 0.1, 0.4)]
        cov = hypotheses_covariance(search_estimate(hyps, 2.0, 0.2))
        assert cov[1, 1] >= 0.4 * 4.0 ** 2 and cov[0, 0] < cov[1, 1]
        assert 0.4 * 0.2 ** 2 <= cov[5, 5] < 0.5  # not (2 pi - 0.2) squared
        assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() >= -1e-12

    def test_the_mass_outside_the_hypotheses_has_the_whole_sets_spread(self):
        """A search just started: hypotheses of tiny mass, the pose anywhere on the floor."""
        hyps = [hypothesis(0.0, 0.0, 0.0, 0.01), hypothesis(0.3, 0.0, 0.0, 0.01)]
        cov = hypotheses_covariance(search_estimate(hyps, 3.0, 1.5))
        assert np.all(np.sqrt(np.diag(cov)[[0, 1]]) > 0.9 * 3.0)
        assert np.sqrt(cov[5, 5]) > 0.9 * 1.5
        assert np.isfinite(cov).all()


def test_status_of_an_estimate():
    e = SimpleNamespace(status="tracking", position_std=0.1)
    assert live_status(e, 0.5) == "tracking"
    assert live_status(SimpleNamespace(status="coasting", position_std=0.8), 0.5) == "ambiguous"
    assert live_status(SimpleNamespace(status="ambiguous", position_std=3.0), 0.5) == "ambiguous"


def test_settings_name_the_key():
    cfg = typed(Ros2Config, {}, "ros2 config")
    assert cfg.frames.map == "map" and cfg.topics.initial_pose == "/initialpose"
    with pytest.raises(ValueError, match="mode"):
        typed(Ros2Config, {"mode": "oracle"}, "ros2 config")
    with pytest.raises(ValueError, match="image_transport"):
        typed(Ros2Config, {"topics": {"image_transport": "theora"}}, "ros2 config")
    with pytest.raises(ValueError, match="topics.imgae"):
        typed(Ros2Config, {"topics": {"imgae": "/x"}}, "ros2 config")


def test_the_node_faces_only_the_settings_it_reads():
    """The offline app's keys (its flights, seeds, recordings, report) are not the node's: a
    user giving one is told, not ignored."""
    from dataclasses import fields

    from localize.config import LocalizeConfig

    node = {f.name for f in fields(Ros2Config)}
    offline_only = {f.name for f in fields(LocalizeConfig)} - node
    assert {"modes", "seeds", "inits", "recording", "metrics", "report", "max_frames",
            "flight_set", "progress", "overwrite"} <= offline_only
    with pytest.raises(ValueError, match="seeds"):
        typed(Ros2Config, {"seeds": [0, 1]}, "ros2 config")


@pytest.mark.parametrize("url, why", [
    ("udpout:127.0.0.1:99999", "port 99999 is not in 1-65535: give e.g. "
                               "udpout:127.0.0.1:14550"),
    ("udpout:127.0.0.1", "give udpout:HOST:PORT"),
    ("udpot:127.0.0.1:14550", "not a MAVLink connection: give udpout:HOST:PORT"),
])
def test_a_malformed_mavlink_setting_fails_at_start_up(url, why):
    """The settings are checked first at start-up (``load_context``), before the node is
    made or reports ready: the message names the ``mavlink`` setting and the fix."""
    with pytest.raises(ValueError, match=f"mavlink={url}: {why}"):
        typed(Ros2Config, {"mavlink": url}, "ros2 config")
    assert typed(Ros2Config, {"mavlink": "udpout:127.0.0.1:14550"}, "ros2 config").mavlink


def test_loopback_profile(tmp_path):
    env = loopback_env(tmp_path, 42)
    xml = (tmp_path / "fastdds_loopback.xml").read_text()
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"] == "42"
    assert "<address>127.0.0.1</address>" in xml
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in xml
