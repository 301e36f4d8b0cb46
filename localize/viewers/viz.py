"""The viewer (``viz=rerun``): a run's frames, labels, model edges, particles and trajectory
with the model in 3D, logged to rerun (rerun-sdk, the ``viz`` extra).

``open_viewer(kind, world, out_path)`` gives None for ``none`` and a ``Viewer`` for
``rerun``, which saves an .rrd file at ``out_path`` (written under a temporary name and
renamed by ``close``) or, given ``connect``, streams to a running viewer
(``rerun+http://HOST:9876/proxy``). ``Viewer.log_step`` logs one frame on the ``time``
timeline (seconds). Entities:

- ``world``: the model (z up): ``world/model/mesh`` (faces in class colours, the ceiling
  left out so the inside shows from above) and ``world/model/edges`` (the edge segments),
  logged once; ``world/particles``; ``world/trajectory/estimate`` and ``.../truth``.
- ``world/camera``: the camera at the estimate (a pinhole, with the camera given):
  ``image``, ``labels`` (class colours of ``core.classes``) and ``edges``, the model's edges
  projected at the estimate (``overlay.project_segments``). Without a camera the image and
  labels go to ``camera/`` alone.
- ``status/confidence``, ``status/position_std``: the estimate's, over time;
  ``status/log``: the filter's status (tracking, ambiguous, coasting, lost) when it changes.

The core never imports rerun: only ``open_viewer("rerun", ...)`` does.
"""

from __future__ import annotations

import logging
import os
import uuid
from pathlib import Path

import cv2
import numpy as np

from core import classes as C
from core.dataset import Camera, World
from localize.config import VIZ_KINDS
from localize.filter.projection import cam_from_world, tilt_from_pose
from localize.localizer import Estimate
from localize.viewers.overlay import project_segments

#: Colours (RGB) of the estimate and the truth: the report's overlay colours.
ESTIMATE_RGB = (0, 255, 0)
TRUTH_RGB = (255, 0, 255)
EDGE_RGB = (160, 160, 160)
PARTICLE_RGB = (255, 160, 0)
#: JPEG quality of the logged camera frames (640 x 480: about 25 kB a frame instead of 920 kB
#: raw; the labels compress losslessly in the file by themselves).
JPEG_QUALITY = 85
#: Seconds ``close`` waits for the logged data to reach the file or the viewer.
FLUSH_TIMEOUT_S = 10.0

log = logging.getLogger(__name__)


def open_viewer(kind: str, world: World, out_path: str | Path, *, camera: Camera | None = None,
                connect: str | None = None) -> Viewer | None:
    """The viewer a ``viz`` setting names.

    Args:
        kind: ``none`` (None is returned) or ``rerun``.
        world: the model, logged once in 3D.
        out_path: the .rrd file to write (when not connecting).
        camera: the frames' camera: the pinhole the image, labels and projected edges are
            shown in; None: the image and labels alone.
        connect: a running rerun viewer to stream to (``viz_connect``), instead of the file.
    """
    if kind not in VIZ_KINDS:
        raise ValueError(f"viz={kind!r}: use one of {', '.join(VIZ_KINDS)}")
    if kind == "none":
        return None
    return Viewer(world, Path(out_path), camera=camera, connect=connect)


class Viewer:
    """A rerun recording of one pass (one frame source, one edge mode); see the module."""

    def __init__(self, world: World, out_path: Path, *, camera: Camera | None = None,
                 connect: str | None = None):
        try:
            import rerun as rr
        except ImportError:
            raise ImportError("viz=rerun needs rerun-sdk: pip install -e '.[viz]' (or "
                              "viz=none)") from None
        self._rr, self.camera, self.world = rr, camera, world
        self.out_path = Path(out_path)
        self._part = None
        self._connect = connect
        self._status: str | None = None
        rec = rr.RecordingStream("localize", recording_id=str(uuid.uuid4()))
        if connect:
            rec.connect_grpc(connect)
        else:
            self.out_path.parent.mkdir(parents=True, exist_ok=True)
            self._part = self.out_path.with_name(self.out_path.name + ".part")
            rec.save(self._part)
        self._rec = rec
        self._estimate: list[np.ndarray] = []
        self._truth: list[np.ndarray] = []
        self._log_static()

    def _log_static(self) -> None:
        """The model in 3D, the class colours and the pinhole, once."""
        rr, rec, w = self._rr, self._rec, self.world
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        faces = np.asarray(w.faces)[np.asarray(w.face_class) != C.CEILING]
        shown = np.asarray(w.face_class)[np.asarray(w.face_class) != C.CEILING]
        if len(faces):
            rec.log("world/model/mesh", rr.Mesh3D(
                vertex_positions=np.asarray(w.vertices, dtype=np.float32)[faces].reshape(-1, 3),
                triangle_indices=np.arange(3 * len(faces), dtype=np.uint32).reshape(-1, 3),
                vertex_colors=np.repeat(C.palette()[shown], 3, axis=0)), static=True)
        seg = np.asarray(w.segments, dtype=np.float32).reshape(-1, 2, 3)
        rec.log("world/model/edges", rr.LineStrips3D(seg, colors=EDGE_RGB, radii=0.01),
                static=True)
        context = rr.AnnotationContext([(i, name, colour) for i, name, colour in C.CLASSES])
        for path in ("world/camera/labels", "camera/labels"):
            rec.log(path, context, static=True)
        if self.camera is not None:
            cam = self.camera
            rec.log("world/camera", rr.Pinhole(image_from_camera=np.asarray(cam.K),
                                               resolution=[cam.width, cam.height],
                                               camera_xyz=rr.ViewCoordinates.RDF,
                                               image_plane_distance=0.3), static=True)

    def log_step(self, t_s: float, image: np.ndarray | None, labels: np.ndarray | None,
                 estimate: Estimate, particles: np.ndarray | None, *,
                 attitude: np.ndarray | None = None, truth: np.ndarray | None = None) -> None:
        """Log one frame.

        Args:
            t_s: the frame's time, seconds (the ``time`` timeline).
            image: (H, W, 3) uint8 RGB, or None (a source that reads no image).
            labels: (H, W) uint8 class ids the edges were made of (the SegNet's), or None.
            estimate: the frame's estimate (``Localizer.step``).
            particles: (N, >= 3) the filter's particles (x, y, z first), or None.
            attitude: (4, 4) odometry pose of the frame: the roll and pitch the camera is
                drawn with (None: level).
            truth: (4, 4) true world_from_body, or None.
        """
        rr, rec = self._rr, self._rec
        if rec is None:
            raise RuntimeError(f"Viewer.log_step after close ({self.out_path})")
        if image is not None and (image.ndim != 3 or image.shape[2] != 3
                                  or image.dtype != np.uint8):
            raise ValueError(f"image must be (H, W, 3) uint8 RGB, got {image.shape} "
                             f"{image.dtype}")
        rec.set_time("time", duration=float(t_s))
        state = np.asarray(estimate.state, dtype=np.float64)
        self._estimate.append(state[:3])
        root = "camera"
        if self.camera is not None:
            root = "world/camera"
            tilt = None if attitude is None else tilt_from_pose(np.asarray(attitude))
            cfw = cam_from_world(state[None], self.camera.body_from_cam, tilt)[0]
            wfc = np.linalg.inv(cfw)
            rec.log(root, rr.Transform3D(translation=wfc[:3, 3], mat3x3=wfc[:3, :3]))
            lines = project_segments(self.camera, cfw, self.world.segments)
            rec.log(f"{root}/edges", rr.LineStrips2D(lines.astype(np.float32),
                                                     colors=ESTIMATE_RGB))
        if image is not None:
            _, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(image[..., ::-1]),
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            rec.log(f"{root}/image", rr.EncodedImage(contents=jpeg.tobytes(),
                                                     media_type="image/jpeg"))
        if labels is not None:
            rec.log(f"{root}/labels", rr.SegmentationImage(np.asarray(labels)))
        if particles is not None:
            p = np.asarray(particles)
            if p.ndim != 2 or p.shape[1] < 3:
                raise ValueError(f"particles must be (N, >= 3) x, y, z, ..., got {p.shape}")
            rec.log("world/particles", rr.Points3D(p[:, :3].astype(np.float32),
                                                   colors=PARTICLE_RGB, radii=0.02))
        rec.log("world/trajectory/estimate",
                rr.LineStrips3D([np.asarray(self._estimate, dtype=np.float32)],
                                colors=ESTIMATE_RGB, radii=0.02))
        if truth is not None:
            self._truth.append(np.asarray(truth, dtype=np.float64)[:3, 3])
            rec.log("world/trajectory/truth",
                    rr.LineStrips3D([np.asarray(self._truth, dtype=np.float32)],
                                    colors=TRUTH_RGB, radii=0.02))
        rec.log("status/confidence", rr.Scalars(float(estimate.confidence)))
        rec.log("status/position_std", rr.Scalars(float(estimate.position_std)))
        if estimate.status != self._status:
            self._status = estimate.status
            rec.log("status/log", rr.TextLog(f"{estimate.status} (confidence "
                                             f"{estimate.confidence:.2f})"))

    def close(self, keep: bool = True) -> None:
        """Flush and end the recording: the .rrd gets its name (``keep``) or is deleted.
        Closing twice does nothing."""
        if self._rec is None:
            return
        rec, self._rec = self._rec, None
        try:
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except RuntimeError as err:  # a viewer that cannot be reached: the run goes on
            if self._part is None:
                log.warning("viz_connect=%s: the viewer was not reached (%s); start it "
                            "(`rerun`) or log to a file (viz_connect=null)", self._connect,
                            err)
            else:
                keep = False
                log.warning("viz: %s could not be written (%s)", self.out_path, err)
        rec.disconnect()
        if self._part is not None:
            if keep:
                os.replace(self._part, self.out_path)
            else:
                self._part.unlink(missing_ok=True)

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(keep=exc_type is None)
