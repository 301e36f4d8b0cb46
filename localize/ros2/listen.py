"""A listener of the node's outputs (rclpy): every pose, hypotheses and status message (the
poses with the wall-clock time they arrived), for the tests and benchmarks/live.py;
``Session``: rclpy in a process with such a listener."""

from __future__ import annotations

import threading
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped

from localize.ros2.config import NodeTopicsConfig
from localize.ros2.convert import position_quaternion, stamp_seconds


class Listener:
    """Subscribes the node's pose, hypotheses and status topics on ``node`` (reliable, depth
    100).

    Attributes:
        poses: the PoseWithCovarianceStamped messages, in arrival order.
        arrivals: (wall-clock seconds) when each pose arrived.
        hypotheses: the PoseArray messages of the pose hypotheses.
        statuses: the DiagnosticArray messages.
    """

    def __init__(self, node, topics: NodeTopicsConfig):
        self.poses: list = []
        self.arrivals: list[float] = []
        self.hypotheses: list = []
        self.statuses: list = []
        node.create_subscription(PoseWithCovarianceStamped, topics.pose, self._on_pose, 100)
        node.create_subscription(PoseArray, topics.hypotheses, self.hypotheses.append, 100)
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
        self.hypotheses.clear()
        self.statuses.clear()


class Session:
    """rclpy started in this process with one node holding a ``Listener`` and an initial-pose
    publisher, spinning on a thread (benchmarks/live.py; a player can publish on ``node``).
    Set the DDS environment (``localize.ros2.loopback``) before making one."""

    def __init__(self, topics: NodeTopicsConfig, name: str = "edgeloc_listener"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init()
        self.node = rclpy.create_node(name)
        self.listener = Listener(self.node, topics)
        self._initial_pose = self.node.create_publisher(PoseWithCovarianceStamped,
                                                        topics.initial_pose, 1)
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        threading.Thread(target=self._executor.spin, daemon=True).start()

    def initial_pose(self, world_from_body: np.ndarray, frame: str = "map") -> None:
        """Publish an initial pose (4, 4) in ``frame``."""
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = frame
        p, q = position_quaternion(world_from_body)
        pose = msg.pose.pose
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p)
        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
         pose.orientation.w) = (float(v) for v in q)
        self._initial_pose.publish(msg)

    def close(self) -> None:
        import rclpy

        self._executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
