"""A listener of the node's outputs (rclpy): every pose and status message with the wall-clock
time it arrived, for the tests and benchmarks/live.py."""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped

from localize.ros2.config import NodeTopics
from localize.ros2.convert import stamp_seconds


class Listener:
    """Subscribes the node's pose and status topics on ``node`` (reliable, depth 100).

    Attributes:
        poses: the PoseWithCovarianceStamped messages, in arrival order.
        arrivals: (wall-clock seconds) when each pose arrived.
        statuses: the DiagnosticArray messages.
    """

    def __init__(self, node, topics: NodeTopics):
        self.poses: list = []
        self.arrivals: list[float] = []
        self.statuses: list = []
        node.create_subscription(PoseWithCovarianceStamped, topics.pose, self._on_pose, 100)
        node.create_subscription(DiagnosticArray, topics.status, self.statuses.append, 100)

    def _on_pose(self, msg) -> None:
        self.arrivals.append(time.time())
        self.poses.append(msg)

    def stamps(self) -> np.ndarray:
        """(N,) the poses' stamps (the frames' capture times), seconds."""
        return np.array([stamp_seconds(m.header.stamp) for m in self.poses])

    def positions(self) -> np.ndarray:
        """(N, 3) the poses' x, y, z, metres."""
        return np.array([[m.pose.pose.position.x, m.pose.pose.position.y,
                          m.pose.pose.position.z] for m in self.poses])

    def status_values(self) -> dict[str, str]:
        """The key-value pairs of the last status (empty before one came), and ``status``."""
        if not self.statuses:
            return {}
        s = self.statuses[-1].status[0]
        return {"status": s.message, **{kv.key: kv.value for kv in s.values}}

    def clear(self) -> None:
        self.poses.clear()
        self.arrivals.clear()
        self.statuses.clear()
