"""The pose estimate sent to a PX4 or ArduPilot autopilot over MAVLink, as external vision.

The estimate lives in the model's frame (REP 103: world x, y, z up; body x forward, y left,
z up). Both autopilots take an external vision pose as ``ODOMETRY`` with ``frame_id``
``MAV_FRAME_LOCAL_FRD`` (a world frame of arbitrary heading, z down) and ``child_frame_id``
``MAV_FRAME_BODY_FRD`` (body x forward, y right, z down); PX4 also takes
``MAV_FRAME_LOCAL_NED``, and both take ``VISION_POSITION_ESTIMATE`` (docs/autopilot.md).

The conversion is pure (``mavlink_pose``, ``rotate_covariance``, ``upper_triangle``):
``local_from_model`` (FRD: the model's axes with y and z flipped; NED: the model taken as
ENU, x east and y north) turns the world axes, ``BODY_FRD_FROM_FLU`` the body axes:
``R' = local_from_model @ R @ BODY_FRD_FROM_FLU.T``, ``p' = local_from_model @ p``. The
covariance's angular block is a small rotation about the world axes (as in ROS'
PoseWithCovariance) and turns with the same world rotation as the position.
``MavlinkSender`` owns the connection (pymavlink, the ``ros`` extra), the rate limit, the
reset counter, and a link thread that sends a ``HEARTBEAT`` each second and answers the
autopilot's ``TIMESYNC`` requests at once (PX4 maps ``time_usec`` onto its own clock once
they converge, and drops round trips that take long; ``clock`` must be the clock of the
capture times).
"""

from __future__ import annotations

import ipaddress
import logging
import math
import threading
import time
from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

log = logging.getLogger(__name__)

#: Body FLU (x forward, y left, z up) -> body FRD (x forward, y right, z down); also the
#: model's world axes -> a local FRD frame of the same heading.
BODY_FRD_FROM_FLU = np.diag([1.0, -1.0, -1.0])
#: ENU (x east, y north, z up) -> NED (x north, y east, z down).
NED_FROM_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: ``frame`` setting -> (MAV_FRAME id of the pose, local_from_model).
LOCAL_FRAMES = {"frd": (20, BODY_FRD_FROM_FLU), "ned": (1, NED_FROM_ENU)}
MAV_FRAME_BODY_FRD = 12
MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY = 197
MAV_ESTIMATOR_TYPE_VISION = 2
#: ``message`` setting choices.
MESSAGES = ("odometry", "vision_position_estimate")
#: Seconds between the HEARTBEATs the sender adds (MAVLink routers learn a component by them).
HEARTBEAT_PERIOD_S = 1.0
#: Seconds the link thread waits for a message before it looks at the heartbeat and the stop.
LINK_POLL_S = 0.05
#: A frame this fraction of the period early still goes (camera timestamps jitter).
RATE_SLACK = 0.05
#: pymavlink's network connections the sender takes, as ``SCHEME:HOST:PORT``.
NETWORK_SCHEMES = ("udpout", "udpin", "udp", "udpbcast", "tcp", "tcpin")
#: The forms of a connection url, for messages.
URL_FORMS = ("udpout:HOST:PORT (e.g. udpout:127.0.0.1:14550: to the autopilot or a MAVLink "
             "router), udpin:HOST:PORT, tcp:HOST:PORT or a serial device path (/dev/ttyUSB0)")


def check_url(url: str) -> str:
    """``url`` if it is a connection the sender opens: ``SCHEME:HOST:PORT`` with a scheme of
    ``NETWORK_SCHEMES``, a HOST (a name or an IPv4 address) and a PORT in 1-65535, or a
    serial device's absolute path (no ``:``; pymavlink would take it for UDP); else
    ValueError saying what is wrong and the form that works (the caller names the url).
    The host name is not resolved.
    """
    scheme, sep, rest = url.partition(":")
    if url.startswith("/"):
        if ":" in url:
            raise ValueError("a serial device path has no ':' (pymavlink would take it for "
                             "UDP): give the device alone, e.g. /dev/ttyUSB0")
        return url
    if not sep or scheme not in NETWORK_SCHEMES:
        raise ValueError(f"not a MAVLink connection: give {URL_FORMS}")
    parts = rest.split(":")
    if len(parts) != 2:
        raise ValueError(f"give {scheme}:HOST:PORT, e.g. {scheme}:127.0.0.1:14550")
    host, port = parts
    if not host:
        raise ValueError(f"no host: give {scheme}:HOST:PORT, e.g. {scheme}:127.0.0.1:{port}")
    if all(c.isdigit() or c == "." for c in host):
        try:
            ipaddress.IPv4Address(host)
        except ValueError:
            raise ValueError(f"host {host} is not an IPv4 address: four numbers 0-255, e.g. "
                             f"{scheme}:127.0.0.1:{port}") from None
    if not (port.isdigit() and 1 <= int(port) <= 65535):
        raise ValueError(f"port {port} is not in 1-65535: give e.g. {scheme}:{host}:14550")
    return url


def local_from_model(frame: str) -> np.ndarray:
    """(3, 3) rotation from the model's world axes to the MAVLink local frame ``frame``
    (``frd`` or ``ned``; ``LOCAL_FRAMES``)."""
    if frame not in LOCAL_FRAMES:
        raise ValueError(f"mavlink frame {frame!r}: use one of {sorted(LOCAL_FRAMES)} (frd: "
                         "the model's heading, z down; ned: the model is ENU, x east, y north)")
    return LOCAL_FRAMES[frame][1]


def mavlink_pose(world_from_body: np.ndarray, frame: str = "frd"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """A model-frame body pose in a MAVLink local frame with an FRD body.

    Args:
        world_from_body: (4, 4) pose in the model frame (body FLU), metres.
        frame: ``frd`` or ``ned`` (``local_from_model``).

    Returns:
        position (3,) metres and rotation (3, 3) local_from_body_frd.
    """
    T = np.asarray(world_from_body, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise ValueError(f"world_from_body must be a finite (4, 4) pose, got {T.shape}")
    A = local_from_model(frame)
    return A @ T[:3, 3], A @ T[:3, :3] @ BODY_FRD_FROM_FLU.T


def quaternion_wxyz(rotation: np.ndarray) -> np.ndarray:
    """(4,) w, x, y, z unit quaternion of a (3, 3) rotation, w >= 0 (MAVLink's order)."""
    q = Rotation.from_matrix(np.asarray(rotation, dtype=np.float64)).as_quat()  # x, y, z, w
    q = np.roll(q, 1)
    return -q if q[0] < 0 else q


def euler_rpy(rotation: np.ndarray) -> np.ndarray:
    """(3,) roll, pitch, yaw (radians; the z-y-x Tait-Bryan angles MAVLink uses) of a
    (3, 3) rotation."""
    yaw, pitch, roll = Rotation.from_matrix(np.asarray(rotation, dtype=np.float64)).as_euler(
        "ZYX")
    return np.array([roll, pitch, yaw])


def rotate_covariance(covariance: np.ndarray, frame: str = "frd") -> np.ndarray:
    """The (6, 6) covariance over x, y, z, roll, pitch, yaw of a model-frame pose in the
    MAVLink local frame: ``J C J.T`` with ``J = blockdiag(A, A)``, ``A = local_from_model``
    (the angles: small rotations about the world axes)."""
    C = np.asarray(covariance, dtype=np.float64)
    if C.shape != (6, 6):
        raise ValueError(f"covariance must be (6, 6) over x, y, z, roll, pitch, yaw, got "
                         f"{C.shape}")
    J = np.zeros((6, 6))
    J[:3, :3] = J[3:, 3:] = local_from_model(frame)
    return J @ C @ J.T


def upper_triangle(covariance: np.ndarray | None) -> np.ndarray:
    """(21,) float32 row-major upper triangle of a (6, 6) covariance (MAVLink's
    ``pose_covariance``: row 0's six entries, then row 1's five, ...); None (unknown): NaN
    first, zeros after."""
    if covariance is None:
        out = np.zeros(21, dtype=np.float32)
        out[0] = np.nan
        return out
    C = np.asarray(covariance, dtype=np.float64)
    if C.shape != (6, 6):
        raise ValueError(f"covariance must be (6, 6), got {C.shape}")
    return C[np.triu_indices(6)].astype(np.float32)


def time_usec(capture_time_s: float) -> int:
    """MAVLink ``time_usec`` (integer microseconds) of a capture time in seconds."""
    t = float(capture_time_s)
    if not math.isfinite(t) or t < 0:
        raise ValueError(f"capture_time_s must be a finite time >= 0 s, got {capture_time_s}")
    return int(round(t * 1e6))


def check_quality(quality: int) -> int:
    """``quality`` as MAVLink's int8 percentage: -1 failed, 0 unknown, 1 worst .. 100 best."""
    q = int(quality)
    if q != quality or not -1 <= q <= 100:
        raise ValueError(f"quality must be an integer in [-1, 100] (-1: failed, 0: unknown, "
                         f"1..100: worst..best), got {quality!r}")
    return q


def quality_of(confidence: float, status: str) -> int:
    """MAVLink quality of an estimate (``localizer.Estimate``): -1 when ``lost`` or in the
    ``ambiguous`` (no hypothesis dominates yet: no pose to fuse), else
    ``round(100 * confidence)`` in 1..100."""
    if status in ("lost", "ambiguous"):
        return -1
    return int(np.clip(round(100.0 * float(confidence)), 1, 100))


def due(last_sent_s: float | None, capture_time_s: float, rate_hz: float) -> bool:
    """Whether a frame captured at ``capture_time_s`` goes out at ``rate_hz`` (0: every
    frame) after one sent at ``last_sent_s`` (None: nothing sent yet): strictly later, and
    at least one period (less ``RATE_SLACK`` of it) later."""
    if last_sent_s is None:
        return True
    if capture_time_s <= last_sent_s:
        return False
    return rate_hz <= 0 or capture_time_s - last_sent_s >= (1.0 - RATE_SLACK) / rate_hz


class MavlinkSender:
    """Sends pose estimates to an autopilot as external vision (pymavlink, MAVLink 2).

    Args:
        url: a pymavlink connection, e.g. ``udpout:127.0.0.1:14550`` or ``/dev/ttyUSB0``
            (``check_url``).
        rate_hz: most messages per second of capture time (0: every frame).
        message: ``odometry`` (``ODOMETRY``) or ``vision_position_estimate``.
        frame: ``frd`` (``MAV_FRAME_LOCAL_FRD``, the model's heading: PX4 and ArduPilot) or
            ``ned`` (``MAV_FRAME_LOCAL_NED``, the model taken as ENU: PX4 only).
        system_id: MAVLink system id of the sender (the vehicle's, usually 1).
        component_id: its component id (``MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY``).
        clock: seconds now on the clock of the capture times (``time.time``: ROS wall time);
            the ``TIMESYNC`` answers carry it.
        link_thread: run the link thread (heartbeat, ``TIMESYNC`` answers); False: none
            (``poll`` answers the waiting requests when called).
    """

    def __init__(self, url: str, rate_hz: float, *, message: str = "odometry",
                 frame: str = "frd", system_id: int = 1,
                 component_id: int = MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY,
                 clock: Callable[[], float] = time.time, link_thread: bool = True):
        if message not in MESSAGES:
            raise ValueError(f"mavlink message {message!r}: use one of {MESSAGES}")
        local_from_model(frame)
        if not rate_hz >= 0:
            raise ValueError(f"mavlink rate_hz must be >= 0 (0: every frame), got {rate_hz}")
        try:
            check_url(url)
        except ValueError as err:
            raise ValueError(f"mavlink url {url!r}: {err}") from None
        try:
            from pymavlink import mavutil
            from pymavlink.dialects.v20 import common as mavlink2
        except ImportError:
            raise ImportError("the MAVLink sender needs pymavlink: pip install -e '.[ros]'"
                              ) from None

        self.url, self.rate_hz, self.message, self.frame = url, float(rate_hz), message, frame
        try:
            self._conn = mavutil.mavlink_connection(url, source_system=system_id,
                                                    source_component=component_id)
        except Exception as err:
            raise ValueError(f"mavlink url {url!r}: cannot open it ({err}); give e.g. "
                             "udpout:127.0.0.1:14550 or a serial device") from err
        # ODOMETRY needs MAVLink 2 (message id 331); pymavlink starts with MAVLink 1
        self._mav = mavlink2.MAVLink(self._conn, srcSystem=system_id, srcComponent=component_id)
        self._mavlink2 = mavlink2
        self._clock = clock
        self.reset_counter = 0
        self.sent = 0
        self._last_sent: float | None = None
        self._last_heartbeat = -math.inf
        self._lock = threading.Lock()  # one sender at a time on the MAVLink object
        self._stop = threading.Event()
        self._thread = None
        if link_thread:
            self._thread = threading.Thread(target=self._link, name="mavlink-link",
                                            daemon=True)
            self._thread.start()

    def reset(self) -> None:
        """Count a jump of the estimate (a re-localization): the autopilot resets its fused
        position to the next message instead of rejecting it (``reset_counter``, mod 256)."""
        self.reset_counter = (self.reset_counter + 1) % 256

    def send(self, capture_time_s: float, world_from_body: np.ndarray,
             covariance: np.ndarray | None, quality: int) -> bool:
        """Send one estimate; False (nothing sent) when the rate limit holds it back, its
        capture time is not after the last one sent, or (``VISION_POSITION_ESTIMATE``, which
        has no quality field) its quality is -1.

        Args:
            capture_time_s: the frame's capture time, seconds (``time_usec``).
            world_from_body: (4, 4) model-frame pose (body FLU).
            covariance: (6, 6) over x, y, z, roll, pitch, yaw in the model frame (metres^2,
                radians^2), or None (unknown).
            quality: -1 (failed), 0 (unknown), 1..100 (worst..best) (``quality_of``).
        """
        usec = time_usec(capture_time_s)
        quality = check_quality(quality)
        if not due(self._last_sent, float(capture_time_s), self.rate_hz):
            return False
        if quality < 0 and self.message == "vision_position_estimate":
            return False
        position, rotation = mavlink_pose(world_from_body, self.frame)
        cov = upper_triangle(None if covariance is None
                             else rotate_covariance(covariance, self.frame))
        x, y, z = (float(v) for v in position)
        if self.message == "odometry":
            nan = float("nan")
            unknown = upper_triangle(None).tolist()
            with self._lock:
                self._mav.odometry_send(usec, LOCAL_FRAMES[self.frame][0], MAV_FRAME_BODY_FRD,
                                        x, y, z, quaternion_wxyz(rotation).tolist(),
                                        nan, nan, nan, nan, nan, nan, cov.tolist(), unknown,
                                        self.reset_counter, MAV_ESTIMATOR_TYPE_VISION, quality)
        else:
            roll, pitch, yaw = (float(v) for v in euler_rpy(rotation))
            with self._lock:
                self._mav.vision_position_estimate_send(usec, x, y, z, roll, pitch, yaw,
                                                        cov.tolist(), self.reset_counter)
        self._last_sent = float(capture_time_s)
        self.sent += 1
        return True

    def poll(self, timeout_s: float = 0.0) -> int:
        """Answer the ``TIMESYNC`` requests on the link, waiting up to ``timeout_s`` for the
        first: ``tc1`` = ``clock()`` in ns, ``ts1`` echoed. Returns how many were answered."""
        answered = 0
        m = self._conn.recv_match(type="TIMESYNC", blocking=timeout_s > 0, timeout=timeout_s)
        while m is not None:
            if m.tc1 == 0:
                with self._lock:
                    self._mav.timesync_send(int(round(self._clock() * 1e9)), m.ts1)
                answered += 1
            m = self._conn.recv_match(type="TIMESYNC", blocking=False)
        return answered

    def heartbeat(self) -> None:
        """A HEARTBEAT, at most once per ``HEARTBEAT_PERIOD_S`` of wall time."""
        now = time.monotonic()
        if now - self._last_heartbeat >= HEARTBEAT_PERIOD_S:
            m = self._mavlink2
            with self._lock:
                self._mav.heartbeat_send(m.MAV_TYPE_ONBOARD_CONTROLLER,
                                         m.MAV_AUTOPILOT_INVALID, 0, 0, m.MAV_STATE_ACTIVE)
            self._last_heartbeat = now

    def _link(self) -> None:
        """The link thread: heartbeats and ``TIMESYNC`` answers until ``close``."""
        while not self._stop.is_set():
            try:
                self.heartbeat()
                self.poll(LINK_POLL_S)
            except (OSError, ValueError) as err:  # the link closed under us
                if not self._stop.is_set():
                    log.warning("mavlink %s: the link thread stops: %s", self.url, err)
                return

    def close(self) -> None:
        """Stop the link thread and close the connection."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._conn.close()

    def __enter__(self) -> MavlinkSender:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()
