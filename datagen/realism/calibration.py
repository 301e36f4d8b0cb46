"""The camera the localizer is told: the rendering's camera with a calibration error
(``realism.calibration``, ``CalibrationConfig``).

A real drone's intrinsics come from a checkerboard calibration and its camera mount from a
CAD drawing or a hand-eye calibration; both are off by a little. Datagen renders with the true
camera and writes the told one as dataset.json's ``camera`` (what ``core.dataset.Dataset``
hands the localizer), the truth as ``camera_truth`` and the drawn error as
``calibration_error``. The error is drawn once per dataset from its own generator, every
component whatever the stds, so one std changed leaves the others' draws as they were.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import cv2
import numpy as np

from core.config import as_config
from core.dataset import Camera
from core.imaging.realism import CalibrationConfig

WHERE = "realism.calibration"


def check_settings(settings: CalibrationConfig | Mapping | None,
                   where: str = WHERE) -> CalibrationConfig:
    """The settings typed and checked: every std finite and >= 0, the focal error below 20 %.

    Raises:
        ValueError: a bad setting, naming ``where.<key>`` and the fix.
    """
    c = as_config(CalibrationConfig, settings, where)
    for key in ("focal_std", "principal_std_px", "rotation_std_deg", "translation_std_m"):
        v = float(getattr(c, key))
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{where}.{key} = {v} must be a finite std >= 0; 0 turns this "
                             "calibration error off")
    if c.focal_std >= 0.2:
        raise ValueError(f"{where}.focal_std = {c.focal_std} is a relative std (0.01 = 1 %); "
                         "give it below 0.2")
    if c.rotation_std_deg >= 30:
        raise ValueError(f"{where}.rotation_std_deg = {c.rotation_std_deg} is in degrees; give "
                         "it below 30")
    return c


def is_active(c: CalibrationConfig) -> bool:
    """Whether the told camera differs from the rendering's."""
    return any(getattr(c, k) > 0 for k in ("focal_std", "principal_std_px", "rotation_std_deg",
                                           "translation_std_m"))


def told_camera(camera: Camera, c: CalibrationConfig,
                rng: np.random.Generator) -> tuple[Camera, dict]:
    """The camera as calibrated: the true one with a drawn error.

    K's focal lengths are scaled by one factor ``1 + N(0, focal_std)`` and its principal
    point moved by ``N(0, principal_std_px)`` px per axis; body_from_cam is turned by an
    angle ``N(0, rotation_std_deg)`` about a uniformly random axis of the camera frame
    (``body_from_cam @ R``) and its translation moved by ``N(0, translation_std_m)`` m per
    axis.

    Args:
        camera: the rendering's camera (K (3, 3) px, body_from_cam (4, 4) m).
        c: the settings (``check_settings``).
        rng: the dataset's calibration generator.

    Returns:
        The told camera, and the error as a JSON-ready dict: focal_scale, principal_px (2,),
        rotation_deg, rotation_axis (3,) unit in the camera frame, translation_m (3,).
    """
    scale = 1.0 + c.focal_std * rng.standard_normal()
    dpp = c.principal_std_px * rng.standard_normal(2)
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    angle = c.rotation_std_deg * rng.standard_normal()
    dt = c.translation_std_m * rng.standard_normal(3)
    K = camera.K.astype(np.float64).copy()
    K[0, 0] *= scale
    K[1, 1] *= scale
    K[:2, 2] += dpp
    R = cv2.Rodrigues(axis * math.radians(angle))[0]
    body_from_cam = camera.body_from_cam.astype(np.float64).copy()
    body_from_cam[:3, :3] = body_from_cam[:3, :3] @ R
    body_from_cam[:3, 3] += dt
    error = {"focal_scale": float(scale), "principal_px": dpp.tolist(),
             "rotation_deg": float(angle), "rotation_axis": axis.tolist(),
             "translation_m": dt.tolist()}
    return Camera(K, camera.width, camera.height, body_from_cam), error


def camera_json(camera: Camera, hfov_deg: float) -> dict:
    """dataset.json's form of a camera (K, size, hfov_deg, body_from_cam)."""
    return {"K": camera.K.tolist(), "width": camera.width, "height": camera.height,
            "hfov_deg": float(hfov_deg), "body_from_cam": camera.body_from_cam.tolist()}
