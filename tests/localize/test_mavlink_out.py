"""The estimate to the autopilot: the frame conversion (exact, on hand-made poses) and the
MAVLink messages a loopback UDP receiver decodes (frames, pose, covariance, time_usec,
reset counter, rate limit). Only 127.0.0.1 is used."""

from __future__ import annotations

import math
import socket

import numpy as np
import pytest

from localize.live.mavlink import (
    MAV_FRAME_BODY_FRD,
    check_url,
    due,
    euler_rpy,
    mavlink_pose,
    quality_of,
    quaternion_wxyz,
    rotate_covariance,
    time_usec,
    upper_triangle,
)

S = math.sqrt(0.5)


def pose(yaw_deg: float, xyz=(1.0, 2.0, 3.0)) -> np.ndarray:
    """(4, 4) model-frame world_from_body with a yaw about z up."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = xyz
    return T


class TestConversion:
    def test_identity_frd(self):
        p, R = mavlink_pose(pose(0.0), "frd")
        np.testing.assert_allclose(p, [1.0, -2.0, -3.0])
        np.testing.assert_allclose(R, np.eye(3), atol=1e-15)
        np.testing.assert_allclose(quaternion_wxyz(R), [1.0, 0.0, 0.0, 0.0], atol=1e-15)

    def test_yaw_90_enu_is_north_in_ned(self):
        """Facing the model's +y (north, when the model is ENU) is NED yaw 0; position
        (x east, y north, z up) = (1, 2, 3) is (2, 1, -3) north, east, down."""
        p, R = mavlink_pose(pose(90.0), "ned")
        np.testing.assert_allclose(p, [2.0, 1.0, -3.0])
        np.testing.assert_allclose(R, np.eye(3), atol=1e-15)
        np.testing.assert_allclose(quaternion_wxyz(R), [1.0, 0.0, 0.0, 0.0], atol=1e-15)

    def test_yaw_90_left_is_minus_90_in_frd(self):
        """A left turn (FLU yaw +90 deg) is an FRD yaw of -90 deg (z down)."""
        _, R = mavlink_pose(pose(90.0), "frd")
        np.testing.assert_allclose(quaternion_wxyz(R), [S, 0.0, 0.0, -S], atol=1e-15)
        np.testing.assert_allclose(euler_rpy(R), [0.0, 0.0, -math.pi / 2], atol=1e-15)

    def test_yaw_0_enu_is_east_in_ned(self):
        """Facing east (ENU yaw 0) is NED yaw +90 deg."""
        _, R = mavlink_pose(pose(0.0), "ned")
        np.testing.assert_allclose(quaternion_wxyz(R), [S, 0.0, 0.0, S], atol=1e-15)

    def test_roll_right_wing_down(self):
        """A FLU body rolled by +10 deg about x (left side up, right wing down) is an FRD
        roll of +10 deg."""
        a = math.radians(10.0)
        T = np.eye(4)
        T[:3, :3] = [[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]]
        _, R = mavlink_pose(T, "frd")
        np.testing.assert_allclose(euler_rpy(R), [a, 0.0, 0.0], atol=1e-15)

    def test_covariance_turns_with_the_world(self):
        C = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        C[0, 1] = C[1, 0] = 0.5  # x-y correlation
        ned = rotate_covariance(C, "ned")
        np.testing.assert_allclose(np.diag(ned), [2.0, 1.0, 3.0, 5.0, 4.0, 6.0])
        assert ned[0, 1] == 0.5
        frd = rotate_covariance(C, "frd")
        np.testing.assert_allclose(np.diag(frd), np.diag(C))
        assert frd[0, 1] == -0.5  # y flips

    def test_upper_triangle_packing(self):
        C = np.arange(36, dtype=np.float64).reshape(6, 6)
        C = C + C.T
        packed = upper_triangle(C)
        assert packed.shape == (21,) and packed.dtype == np.float32
        np.testing.assert_array_equal(packed[:6], C[0])
        np.testing.assert_array_equal(packed[6:11], C[1, 1:])
        # the diagonal at 0, 6, 11, 15, 18, 20 (what ArduPilot reads)
        np.testing.assert_array_equal(packed[[0, 6, 11, 15, 18, 20]], np.diag(C))
        unknown = upper_triangle(None)
        assert np.isnan(unknown[0]) and not unknown[1:].any()

    def test_time_and_quality(self):
        assert time_usec(12.3456789) == 12345679
        assert time_usec(1.7e9) == 1_700_000_000_000_000
        assert quality_of(0.5, "tracking") == 50
        assert quality_of(0.0, "coasting") == 1
        assert quality_of(0.9, "lost") == -1 and quality_of(0.9, "ambiguous") == -1

    def test_rate_limit(self):
        assert due(None, 0.0, 10.0)
        assert not due(1.0, 1.05, 10.0) and due(1.0, 1.1, 10.0)
        assert due(1.0, 1.0 + 0.097, 10.0)  # within the jitter slack
        assert not due(1.0, 1.0, 0.0) and due(1.0, 1.001, 0.0)
        assert not due(1.0, 0.5, 10.0)  # going backwards

    def test_bad_input(self):
        with pytest.raises(ValueError, match="frame 'enu'"):
            mavlink_pose(np.eye(4), "enu")
        with pytest.raises(ValueError, match=r"\(4, 4\)"):
            mavlink_pose(np.eye(3))
        with pytest.raises(ValueError, match=r"\(6, 6\)"):
            rotate_covariance(np.eye(3))
        with pytest.raises(ValueError, match="capture_time_s"):
            time_usec(float("nan"))


class TestUrl:
    """A connection pymavlink would open but the sender could not use (a port out of range
    killed the link thread after the node reported ready) or would misread is refused, with
    what is wrong and the form that works."""

    @pytest.mark.parametrize("url, why", [
        ("udpout:127.0.0.1:99999", "port 99999 is not in 1-65535: give e.g. "
                                   "udpout:127.0.0.1:14550"),
        ("udpout:127.0.0.1:0", "port 0 is not in 1-65535"),
        ("udpin:127.0.0.1:-1", "port -1 is not in 1-65535"),
        ("tcp:127.0.0.1:abc", "port abc is not in 1-65535"),
        ("udpout:127.0.0.1", "give udpout:HOST:PORT, e.g. udpout:127.0.0.1:14550"),
        ("udpout:127.0.0.1:14550:7", "give udpout:HOST:PORT"),
        ("udpout::14550", "no host: give udpout:HOST:PORT, e.g. udpout:127.0.0.1:14550"),
        ("udpout:256.1.1.1:14550", "host 256.1.1.1 is not an IPv4 address"),
        ("udpot:127.0.0.1:14550", "not a MAVLink connection: give udpout:HOST:PORT"),
        (" udpout:127.0.0.1:14550", "not a MAVLink connection"),
        ("127.0.0.1:14550", "not a MAVLink connection"),
        ("/dev/ttyUSB0:57600", "a serial device path has no ':'"),
    ])
    def test_malformed(self, url, why):
        with pytest.raises(ValueError, match=why):
            check_url(url)

    @pytest.mark.parametrize("url", ["udpout:127.0.0.1:14550", "udpin:0.0.0.0:14550",
                                     "tcp:localhost:5760", "udpbcast:127.255.255.255:14550",
                                     "/dev/ttyUSB0"])
    def test_well_formed(self, url):
        assert check_url(url) == url


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def link():
    """(receiver, url of a sender to it) on the loopback interface."""
    mavutil = pytest.importorskip("pymavlink.mavutil")
    port = free_port()
    rx = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}")
    yield rx, f"udpout:127.0.0.1:{port}"
    rx.close()


def receive(rx, kind: str, n: int = 1) -> list:
    out = []
    for _ in range(n):
        m = rx.recv_match(type=kind, blocking=True, timeout=5)
        assert m is not None, f"no {kind} received"
        out.append(m)
    return out


class TestSender:
    def test_odometry(self, link):
        from localize.live.mavlink import MavlinkSender

        rx, url = link
        tx = MavlinkSender(url, rate_hz=10.0)
        C = np.diag([0.01, 0.02, 0.03, 0.001, 0.002, 0.004])
        assert tx.send(100.25, pose(90.0), C, 80)
        tx.reset()
        assert tx.send(100.35, pose(0.0, (0.5, 0.0, 1.0)), None, 0)
        tx.close()
        a, b = receive(rx, "ODOMETRY", 2)
        assert a.get_srcSystem() == 1 and a.get_srcComponent() == 197
        assert (a.frame_id, a.child_frame_id) == (20, MAV_FRAME_BODY_FRD)
        assert a.time_usec == 100_250_000 and b.time_usec == 100_350_000
        np.testing.assert_allclose([a.x, a.y, a.z], [1.0, -2.0, -3.0])
        np.testing.assert_allclose(a.q, [S, 0.0, 0.0, -S], atol=1e-7)
        np.testing.assert_allclose(np.asarray(a.pose_covariance)[[0, 6, 11, 15, 18, 20]],
                                   np.diag(C), rtol=1e-6)
        assert np.isnan(a.vx) and np.isnan(a.velocity_covariance[0])
        assert (a.reset_counter, b.reset_counter) == (0, 1)
        assert (a.quality, b.quality) == (80, 0)
        assert a.estimator_type == 2  # MAV_ESTIMATOR_TYPE_VISION
        assert np.isnan(b.pose_covariance[0])
        np.testing.assert_allclose([b.x, b.y, b.z], [0.5, 0.0, -1.0])

    def test_ned_and_vision_position_estimate(self, link):
        from localize.live.mavlink import MavlinkSender

        rx, url = link
        C = np.diag([0.01, 0.02, 0.03, 0.001, 0.002, 0.004])
        with MavlinkSender(url, rate_hz=0.0, message="vision_position_estimate",
                           frame="ned") as tx:
            assert not tx.send(6.0, pose(0.0), C, -1)  # failed: the message cannot say so
            assert tx.send(7.0, pose(0.0), C, 50)
        (m,) = receive(rx, "VISION_POSITION_ESTIMATE")
        assert m.usec == 7_000_000 and m.reset_counter == 0
        np.testing.assert_allclose([m.x, m.y, m.z], [2.0, 1.0, -3.0])
        np.testing.assert_allclose([m.roll, m.pitch, m.yaw], [0.0, 0.0, math.pi / 2],
                                   atol=1e-7)
        np.testing.assert_allclose(np.asarray(m.covariance)[[0, 6, 11, 15, 18, 20]],
                                   [0.02, 0.01, 0.03, 0.002, 0.001, 0.004], rtol=1e-6)

    def test_rate_limit_and_reset_counter_wraps(self, link):
        from localize.live.mavlink import MavlinkSender

        rx, url = link
        tx = MavlinkSender(url, rate_hz=10.0)
        stamps = np.arange(30) / 30.0  # a 30 Hz camera
        sent = [tx.send(t, pose(0.0), None, 0) for t in stamps]
        assert sum(sent) == 10 and sent[0] and sent[3] and not sent[1]
        assert not tx.send(stamps[-1], pose(0.0), None, 0)  # not after the last sent
        for _ in range(256):
            tx.reset()
        assert tx.reset_counter == 0
        tx.close()
        got = receive(rx, "ODOMETRY", 10)
        np.testing.assert_array_equal([m.time_usec for m in got],
                                      [time_usec(t) for t in stamps[::3]])

    def test_answers_timesync(self, link):
        """The autopilot's TIMESYNC request (tc1 = 0) gets the capture clock's time in ns
        and its own ts1 back, from the link thread; a HEARTBEAT comes with the first send."""
        from localize.live.mavlink import MavlinkSender

        rx, url = link
        tx = MavlinkSender(url, rate_hz=0.0, clock=lambda: 1000.5)
        assert tx.send(1.0, pose(0.0), None, 0)  # the receiver learns the sender's address
        receive(rx, "ODOMETRY")
        (hb,) = receive(rx, "HEARTBEAT")
        assert hb.type == 18  # MAV_TYPE_ONBOARD_CONTROLLER
        rx.mav.timesync_send(0, 123456789)
        (m,) = receive(rx, "TIMESYNC")
        assert (m.tc1, m.ts1) == (1_000_500_000_000, 123456789)
        tx.close()
        assert not tx._thread.is_alive()

    def test_ids_are_the_dialects(self):
        m = pytest.importorskip("pymavlink.dialects.v20.common")
        from localize.live import mavlink as mo

        assert mo.LOCAL_FRAMES["frd"][0] == m.MAV_FRAME_LOCAL_FRD
        assert mo.LOCAL_FRAMES["ned"][0] == m.MAV_FRAME_LOCAL_NED
        assert mo.MAV_FRAME_BODY_FRD == m.MAV_FRAME_BODY_FRD
        assert mo.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY == m.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY
        assert mo.MAV_ESTIMATOR_TYPE_VISION == m.MAV_ESTIMATOR_TYPE_VISION

    def test_bad_settings(self):
        pytest.importorskip("pymavlink")
        from localize.live.mavlink import MavlinkSender

        with pytest.raises(ValueError, match="message 'pose'"):
            MavlinkSender("udpout:127.0.0.1:9", 10.0, message="pose")
        with pytest.raises(ValueError, match="rate_hz"):
            MavlinkSender("udpout:127.0.0.1:9", -1.0)
        with pytest.raises(ValueError, match="mavlink url 'udpout:127.0.0.1:99999': port 99999 "
                                             "is not in 1-65535"):
            MavlinkSender("udpout:127.0.0.1:99999", 10.0)
        tx = MavlinkSender("udpout:127.0.0.1:9", 10.0)
        with pytest.raises(ValueError, match="quality"):
            tx.send(1.0, pose(0.0), None, 101)
        tx.close()
