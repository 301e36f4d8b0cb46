"""Real-time plumbing of the live node, free of any middleware: the odometry at a frame's
capture time, the single-slot newest-frame buffer, latency figures and throttled warnings.

The camera and the odometry come on their own threads and clocks' stamps; ``OdometryBuffer``
keeps the last seconds of odometry and gives the pose at a frame's stamp, interpolated as a
recording's is (``core.poses.interpolate_poses``: linear translation, slerp rotation; never
extrapolated), waiting a little for the odometry to reach it. ``LatestSlot`` holds one frame:
a new frame replaces the one not taken yet (that one is dropped and counted), so the worker
always takes the newest and no backlog builds. ``wait_until`` polls a condition another thread
makes true (the player waiting for subscribers, tests and benchmarks for the node's output).
"""

from __future__ import annotations

import bisect
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from core.poses import interpolate_poses
from localize.recordings.recording import SPAN_SLACK


def wait_until(cond: Callable[[], Any], timeout_s: float, poll_s: float = 0.05) -> bool:
    """Poll ``cond()`` every ``poll_s`` seconds until it is true (True) or ``timeout_s``
    seconds have passed (False)."""
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(poll_s)
    return True


class OdometryBuffer:
    """The last ``keep_s`` seconds of odometry, (stamp, world_from_body), thread-safe.

    Args:
        keep_s: seconds of samples kept behind the newest one.
    """

    def __init__(self, keep_s: float):
        self.keep_s = float(keep_s)
        self._t: deque[float] = deque()
        self._T: deque[np.ndarray] = deque()
        self._cond = threading.Condition()

    def __len__(self) -> int:
        return len(self._t)

    def add(self, stamp: float, pose: np.ndarray) -> str | None:
        """Add a sample; None, or why it was refused (a stamp not after the newest one, a
        non-finite pose), for the caller's warning."""
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            return f"odometry at {stamp:.6f} s is not a finite pose; sample ignored"
        with self._cond:
            if self._t and stamp <= self._t[-1]:
                return (f"odometry stamp {stamp:.6f} s is not after the previous one "
                        f"({self._t[-1]:.6f} s): stamps went backwards or repeat; sample "
                        "ignored")
            self._t.append(float(stamp))
            self._T.append(pose)
            while len(self._t) > 2 and self._t[1] < stamp - self.keep_s:
                self._t.popleft()
                self._T.popleft()
            self._cond.notify_all()
        return None

    def clear(self) -> None:
        with self._cond:
            self._t.clear()
            self._T.clear()

    def at(self, t: float) -> np.ndarray | None:
        """(4, 4) world_from_body at time ``t`` (seconds), interpolated between the two samples
        around it; None when ``t`` is outside the samples' span (``SPAN_SLACK`` beyond the
        ends counts as inside)."""
        with self._cond:
            return self._at(t)

    def _at(self, t: float) -> np.ndarray | None:
        if not self._t or t < self._t[0] - SPAN_SLACK or t > self._t[-1] + SPAN_SLACK:
            return None
        if len(self._t) == 1:
            return self._T[0].copy()
        k = min(max(bisect.bisect_right(self._t, t) - 1, 0), len(self._t) - 2)
        stamps = np.array([self._t[k], self._t[k + 1]])
        return interpolate_poses(np.array([t]), stamps, np.stack([self._T[k], self._T[k + 1]]))[0]

    def wait_for(self, t: float, timeout_s: float) -> tuple[np.ndarray | None, str]:
        """The pose at ``t`` once the odometry reaches it, waiting up to ``timeout_s``.

        Returns:
            (pose or None, "" or why there is none: no odometry yet, ``t`` before the kept
            span, the odometry not reaching ``t`` in time).
        """
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                pose = self._at(t)
                if pose is not None:
                    return pose, ""
                if self._t and t < self._t[0]:
                    return None, (f"the frame at {t:.6f} s is before the odometry kept "
                                  f"({self._t[0]:.6f} .. {self._t[-1]:.6f} s)")
                left = deadline - time.monotonic()
                if left <= 0:
                    if not self._t:
                        return None, "no odometry received yet"
                    return None, (f"the odometry ({self._t[-1]:.6f} s) did not reach the "
                                  f"frame's stamp {t:.6f} s within {timeout_s:.3f} s; do the "
                                  "camera and the odometry share one clock?")
                self._cond.wait(left)


class LatestSlot:
    """A single-slot buffer: ``put`` replaces what was not taken yet; ``take`` waits for an
    item. Thread-safe."""

    def __init__(self):
        self._item: Any = None
        self._cond = threading.Condition()
        self._closed = False

    def put(self, item: Any) -> Any:
        """Put ``item``; the item it replaced, not taken (dropped), or None."""
        with self._cond:
            replaced, self._item = self._item, item
            self._cond.notify()
            return replaced

    def take(self, timeout_s: float) -> Any:
        """The item, or None after ``timeout_s`` or once closed."""
        with self._cond:
            if self._item is None and not self._closed:
                self._cond.wait(timeout_s)
            item, self._item = self._item, None
            return item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class LatencyWindow:
    """The last ``size`` latencies, seconds: their median and 95th percentile."""

    def __init__(self, size: int = 200):
        self._values: deque[float] = deque(maxlen=size)

    def add(self, seconds: float) -> None:
        self._values.append(float(seconds))

    def __len__(self) -> int:
        return len(self._values)

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile, seconds (NaN before any value)."""
        return float(np.percentile(self._values, q)) if self._values else float("nan")


class Throttle:
    """Says yes to a key at most once per ``period_s`` (repeated warnings of a live stream)."""

    def __init__(self, period_s: float = 5.0):
        self.period_s = float(period_s)
        self._last: dict[str, float] = {}

    def __call__(self, key: str) -> bool:
        now = time.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            return False
        self._last[key] = now
        return True
