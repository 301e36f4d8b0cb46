"""Open a recording, a folder or a ROS 1 / ROS 2 bag, as a ``Recording``
(``localize.recordings.recording``; docs/recording.md)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from core.dataset import Camera
from localize.recordings.folder import read_folder
from localize.recordings.recording import Recording


def read_recording(path: str | Path, target: Camera | None = None, *,
                   topics: Mapping | None = None, body_from_cam: np.ndarray | None = None,
                   name: str | None = None) -> Recording:
    """Read a recording: a folder, a ROS 1 ``.bag`` or a ROS 2 bag folder.

    Args:
        path: the recording.
        target: camera the frames are delivered for (size; default body_from_cam), usually the
            dataset's; None keeps the recorded size (frames are still undistorted).
        topics: bag topics (``localize.recordings.bag.BagTopicsConfig`` keys: image, camera_info,
            odometry, groundtruth); ignored for folders.
        body_from_cam: (4, 4) camera mount overriding the recording's own.
        name: recording name (default: the file or folder name without suffix).

    Returns:
        The recording (frames not read yet).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"recording not found: {path}")
    if path.suffix == ".bag" or (path / "metadata.yaml").is_file():
        from localize.recordings.bag import read_bag  # rosbags only where a bag is read

        return read_bag(path, target, topics=topics, body_from_cam=body_from_cam, name=name)
    if path.is_dir() and ((path / "images").is_dir() or (path / "images.txt").is_file()):
        return read_folder(path, target, body_from_cam, name)
    raise ValueError(f"{path}: not a recording: expected a folder with images/ and camera.yaml, "
                     f"a ROS 1 .bag file or a ROS 2 bag folder with metadata.yaml "
                     f"(docs/recording.md)")
