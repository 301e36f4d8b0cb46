"""One rendered frame: a renderer for the job's scene (``new_renderer``), a frame traced at a
pose and finished (denoised, developed, written) on the pipeline's worker (``render_frame``,
``render_optics_frame`` through a lens). Training splits (``datagen.rendering.split``) and
flights (``datagen.rendering.flight``) both render with these."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from core.dataset import Camera
from datagen.dataset_writer import write_frame
from datagen.job import NEAR_LIGHTS_FROM, Job
from datagen.realism import optics
from datagen.rendering.pipeline import Pipeline
from datagen.worlds.scene import Scene

log = logging.getLogger(__name__)


def new_renderer(job: Job, textures, clutter, people, camera: Camera | None = None,
                  scene: Scene | None = None):
    """The renderer of the site's scene (or ``scene``), with ``camera`` (None: the job's);
    with more than ``NEAR_LIGHTS_FROM`` lights (a floor, most lights out of view) it samples
    lights by radiance / distance^2 (``near_lights``); a floor that can be glossy where
    ``appearance.prob.glossy_floor`` > 0."""
    from datagen.rendering.render import Renderer

    scene = job.site.scene if scene is None else scene
    return Renderer(scene, job.camera if camera is None else camera, textures, clutter, people,
                    max_depth=job.cfg.render.max_depth,
                    near_lights=scene.num_lights > NEAR_LIGHTS_FROM,
                    glossy_floor=job.cfg.appearance.prob.glossy_floor > 0)


def render_frame(job: Job, renderer, d: Path, i: int, body_pose: np.ndarray, seed: int,
                  pipe: Pipeline, effect: Callable[[np.ndarray], np.ndarray] | None = None
                  ) -> None:
    """Trace frame i here; develop and write it on the pipeline's worker (``effect``, if
    given, maps the developed (H, W, 3) uint8 rgb to the one written; the label is kept)."""
    r = job.cfg.render
    renderer.set_camera(body_pose @ job.camera.body_from_cam)
    sigma = r.denoise_sigma_px
    traced = renderer.trace(r.spp, seed, albedo=sigma > 0)
    # The worker gets the renderer's numpy-only developer, never the renderer: the last
    # reference to a Mitsuba scene must not be dropped on the worker
    # (datagen.rendering.render.Renderer.trace).
    pipe.submit(_finish_frame, renderer.developer, traced, d, i,
                r.exposure, sigma, r.depth, effect)


def _finish_frame(developer, traced, d: Path, i: int, exposure: float, sigma: float,
                  depth: bool, effect: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
    rgb, label, z = developer.develop(traced, exposure, sigma)
    if effect is not None:
        rgb = effect(rgb)
    write_frame(d, i, rgb, label, z if depth else None)


def render_optics_frame(job: Job, renderer, d: Path, i: int, fo: optics.FlightOptics,
                         seeds: np.random.Generator, pipe: Pipeline,
                         effect: Callable[[np.ndarray], np.ndarray] | None) -> None:
    """Trace frame i's sub-frames here (``optics.FlightOptics``; render seeds drawn one by
    one from ``seeds``, the frame's generator); assemble, develop and write them on the
    pipeline's worker."""
    r = job.cfg.render
    sigma = r.denoise_sigma_px
    plan, poses = fo.subframes(i)
    traced = []
    for pose in poses:
        renderer.set_camera(pose @ job.camera.body_from_cam)
        traced.append(renderer.trace(r.spp, int(seeds.integers(2**31)), albedo=sigma > 0))
    pipe.submit(_finish_optics_frame, fo, renderer.developer, traced, plan, d, i, r.exposure,
                sigma, r.depth, effect)


def _finish_optics_frame(fo: optics.FlightOptics, developer, traced, plan, d: Path, i: int,
                         exposure: float, sigma: float, depth: bool,
                         effect: Callable[[np.ndarray], np.ndarray] | None) -> None:
    rgb, label, z = fo.finish(developer, traced, plan, exposure, sigma)
    if effect is not None:
        rgb = effect(rgb)
    write_frame(d, i, rgb, label, z if depth else None)
