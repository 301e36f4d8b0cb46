"""A sequence of frames as the localizer consumes it: the one contract of a frame source.

A rendered flight (``core.dataset.Flight``), a recording (a folder or a bag,
``localize.recordings.recording.Recording``) and a live stream are each a ``FrameSource``: per frame
its image, its true labels if any, the odometry increment since the previous delivered
frame, the attitude (roll and pitch of the odometry pose) and the timestamp, and the true
pose if any (``FrameSource.steps``). ``delivered_frames``, behind each source's ``steps``,
turns a source's arrays and images into those frames, with the one odometry increment
(``core.poses.odometry_increment``).

A frame whose image cannot be read (``None`` from the image iterator) is dropped, as a
camera's dropped frame: the next delivered frame's increment spans from the last one
delivered.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple, Protocol

import numpy as np

from core.poses import odometry_increment


class Frame(NamedTuple):
    """One delivered frame with what ``Localizer.step`` takes.

    Attributes:
        index: the frame's index in its source (0..len-1).
        timestamp: seconds.
        image: (H, W, 3) uint8 RGB of the source's camera, or None when not read.
        labels: (H, W) uint8 true class ids, or None (not read, or no truth).
        odometry_increment: (4,) forward, left, up (metres), yaw change (radians) since the
            previous delivered frame, in its heading frame; None for the first frame.
        attitude: (4, 4) world_from_body odometry pose of the frame (its roll and pitch).
        truth: (4, 4) true world_from_body, or None without ground truth.
    """

    index: int
    timestamp: float
    image: np.ndarray | None
    labels: np.ndarray | None
    odometry_increment: np.ndarray | None
    attitude: np.ndarray
    truth: np.ndarray | None


class FrameSource(Protocol):
    """A sequence of frames (a rendered flight, a recording, a live stream).

    Attributes:
        name: the sequence's name (the run's name in a report).
        timestamps: (N,) frame times, seconds, increasing.
        odometry: (N, 4, 4) world_from_body in the odometry's own frame at the frame times.
        groundtruth: (N, 4, 4) true world_from_body in the model's frame, or None.
    """

    name: str
    timestamps: np.ndarray
    odometry: np.ndarray
    groundtruth: np.ndarray | None

    def __len__(self) -> int: ...

    def image(self, index: int) -> np.ndarray:
        """Frame ``index``'s (H, W, 3) uint8 RGB."""
        ...

    def steps(self, limit: int | None = None, *, images: bool = True,
               labels: bool = False) -> Iterator[Frame]:
        """The delivered frames of the first ``limit`` (all: None), in order; ``images`` /
        ``labels``: read the image / the true labels (a source without labels gives None)."""
        ...


def frame_count(source: FrameSource, limit: int | None) -> int:
    """How many of the source's frames a run of ``limit`` frames (``max_frames``) covers."""
    return len(source) if limit is None else min(int(limit), len(source))


def delivered_frames(source: FrameSource, limit: int | None,
                     images: Iterable[np.ndarray | None] | None,
                     labels: Iterable[np.ndarray | None] | None = None) -> Iterator[Frame]:
    """The frames of a source from its arrays and its images, in order.

    Args:
        source: timestamps, odometry and ground truth of the frames.
        limit: frames 0..limit-1 (``frame_count``).
        images: per frame its (H, W, 3) uint8 image, None for one that cannot be read (the
            frame is dropped); or None: no image read (every frame delivered, image None).
        labels: per frame its (H, W) uint8 true labels; or None: no labels.

    Yields:
        ``Frame`` of each delivered frame; the increment is from the last delivered frame.
    """
    n = frame_count(source, limit)
    gt = source.groundtruth
    image_it = iter(images) if images is not None else None
    label_it = iter(labels) if labels is not None else None
    last = None
    for i in range(n):
        image = next(image_it) if image_it is not None else None
        label = next(label_it) if label_it is not None else None
        if image_it is not None and image is None:
            continue
        inc = None if last is None else odometry_increment(source.odometry[last],
                                                           source.odometry[i])
        yield Frame(i, float(source.timestamps[i]), image, label, inc, source.odometry[i],
                    None if gt is None else gt[i])
        last = i
