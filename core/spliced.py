"""Flights cut and spliced: a start from the middle of a flight, and the kidnapped robot.

``flight_segment`` is a stretch of a flight as a flight of its own (a global start from
anywhere along its route). ``kidnapped`` splices two stretches: the frames of the first, then
those of the second, with the truth teleported between them and the odometry continuing as if
nothing happened (the robot does not feel the teleport: the second stretch's odometry is
re-anchored, by a yaw and a shift about z, at the first stretch's last odometry pose). Both
are ``core.dataset.Flight``, so every ``core.frames.FrameSource`` consumer runs them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.dataset import Flight
from core.poses import pose_from_xyzyaw, xyzyaw_from_pose


def flight_segment(flight: Flight, start: int, count: int | None = None,
                   name: str | None = None) -> Flight:
    """Frames ``start`` .. ``start + count - 1`` of ``flight`` (to its end: None), timestamps
    from 0.

    Raises:
        ValueError: the stretch is empty or leaves the flight (naming both).
    """
    n = len(flight)
    stop = n if count is None else int(start) + int(count)
    if not 0 <= int(start) < stop <= n:
        raise ValueError(f"flight {flight.name}: frames {start}..{stop - 1} are not within its "
                         f"{n} frames")
    sel = slice(int(start), stop)
    frames = np.arange(n) if flight.frames is None else np.asarray(flight.frames)
    t = np.asarray(flight.timestamps, dtype=np.float64)[sel]
    return replace(flight, name=name or f"{flight.name}@{start}", rgb=flight.rgb[sel],
                   label=flight.label[sel], timestamps=t - t[0],
                   groundtruth=flight.groundtruth[sel], odometry=flight.odometry[sel],
                   frames=frames[sel])


def kidnapped(first: Flight, second: Flight, name: str | None = None) -> Flight:
    """``first``'s frames, then ``second``'s, the truth teleported between them.

    The second's timestamps follow the first's at its frame period; its odometry is moved
    rigidly (yaw and shift, so gravity stays vertical) to start at the first's last
    odometry pose, so the increment across the splice is zero (the odometry felt nothing).
    Both must be of one dataset (one camera).

    Returns:
        A ``Flight`` of ``len(first) + len(second)`` frames; ``info["kidnapped_at"]`` is the
        index of the first frame after the teleport.
    """
    if len(first) < 2 or len(second) < 1:
        raise ValueError(f"kidnapped: the first stretch needs >= 2 frames and the second >= 1, "
                         f"got {len(first)} and {len(second)}")
    t1 = np.asarray(first.timestamps, dtype=np.float64)
    t2 = np.asarray(second.timestamps, dtype=np.float64)
    period = float(np.median(np.diff(t1)))
    t = np.concatenate([t1, t1[-1] + period + (t2 - t2[0])])
    a = pose_from_xyzyaw(xyzyaw_from_pose(first.odometry[-1:]))[0]
    b = pose_from_xyzyaw(xyzyaw_from_pose(second.odometry[:1]))[0]
    anchor = a @ np.linalg.inv(b)  # a rotation about z and a shift
    odo = np.concatenate([first.odometry, anchor[None] @ second.odometry])
    f1 = np.arange(len(first)) if first.frames is None else np.asarray(first.frames)
    f2 = np.arange(len(second)) if second.frames is None else np.asarray(second.frames)
    info = {**first.info, "kidnapped_at": len(first), "kidnapped_from": first.name,
            "kidnapped_to": second.name}
    return Flight(name or f"{first.name}+{second.name}", [*first.rgb, *second.rgb],
                  [*first.label, *second.label], t,
                  np.concatenate([first.groundtruth, second.groundtruth]), odo, info,
                  np.concatenate([f1, f2]))
