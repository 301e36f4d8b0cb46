"""Rendering a training split: each chunk of frames a renderer with its own textures,
lights, clutter and people; each frame from its own random stream."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from core import classes as C
from core.dataset import Camera
from datagen.appearance.lights import sample_lights
from datagen.appearance.materials import object_colours, sample_floor_gloss
from datagen.appearance.textures import sample_textures
from datagen.config import DistractorPreset
from datagen.dataset_writer import frame_done, write_frame
from datagen.distractors.meshes import footprint_radius, make_clutter_mesh, make_person_mesh
from datagen.distractors.placement import place_objects
from datagen.distractors.presets import preset_counts, sample_kinds
from datagen.job import NEAR_LIGHTS_FROM, SPLIT_STREAM, Job, rng_for, shard_range
from datagen.pipeline import Pipeline
from datagen.realism import optics
from datagen.scene import Scene

log = logging.getLogger(__name__)


def _slot_meshes(chunk_rng: np.random.Generator, presets: list[DistractorPreset]):
    """Distractor meshes for one scene load: enough slots for the busiest preset used."""
    n_clutter = max(p.clutter.max for p in presets)
    n_people = max(p.people.max for p in presets)
    kinds_from = next((p for p in presets if p.clutter.max), presets[0])
    kinds = sample_kinds(chunk_rng, n_clutter, kinds_from)
    clutter = [make_clutter_mesh(k, chunk_rng) for k in kinds]
    people = [make_person_mesh(chunk_rng) for _ in range(n_people)]
    return clutter, people


def new_renderer(job: Job, textures, clutter, people, camera: Camera | None = None,
                  scene: Scene | None = None):
    """The renderer of the site's scene (or ``scene``), with ``camera`` (None: the job's);
    with more than ``NEAR_LIGHTS_FROM`` lights (a floor, most lights out of view) it samples
    lights by radiance / distance^2 (``near_lights``); a floor that can be glossy where
    ``appearance.prob.glossy_floor`` > 0."""
    from datagen.render import Renderer

    scene = job.site.scene if scene is None else scene
    return Renderer(scene, job.camera if camera is None else camera, textures, clutter, people,
                    max_depth=job.cfg.render.max_depth,
                    near_lights=scene.num_lights > NEAR_LIGHTS_FROM,
                    glossy_floor=job.cfg.appearance.prob.glossy_floor > 0)


def _dress(job: Job, renderer, rng: np.random.Generator, preset: DistractorPreset,
           body_pose: np.ndarray) -> None:
    """Randomize textures, lights and distractors of one training image."""
    look = job.cfg.appearance
    renderer.set_textures(sample_textures(rng, None, look))
    renderer.set_lights(sample_lights(rng, renderer.num_lights, look)[1])
    gloss = sample_floor_gloss(rng, look)  # None (and no draw) when never glossy
    if gloss is not None:
        renderer.set_floor_gloss(*gloss)
    n_clutter, n_people = preset_counts(rng, preset)
    slots = renderer.slots
    clutter_ids = [i for i, (_, c) in enumerate(slots) if c == C.CLUTTER]
    people_ids = [i for i, (_, c) in enumerate(slots) if c == C.PERSON]
    use = (list(rng.permutation(clutter_ids)[:n_clutter])
           + list(rng.permutation(people_ids)[:n_people]))
    poses = np.full((len(slots), 3), np.nan)
    if use:
        radii = np.array([footprint_radius(slots[i][0]) for i in use])
        cam = (body_pose @ job.camera.body_from_cam)[:3, 3]
        keep = np.array([[cam[0], cam[1], preset.camera_keepout_m]])
        xy_yaw, _ = place_objects(
            rng, radii, job.site.floor, keep, against_walls=preset.against_walls,
            wall_margin=preset.wall_margin)
        poses[use] = xy_yaw
    renderer.set_objects(poses, object_colours(rng, len(slots)))


def render_split(job: Job, split: str, progress: bool = True) -> int:
    """Render this shard's frames of a split; returns the number of frames rendered."""
    cfg, poses = job.cfg, job.split_poses[split]
    frames = shard_range(len(poses), cfg.shard, cfg.num_shards)
    depth = cfg.render.depth
    d = job.out / split
    todo = [i for i in frames if not frame_done(d, i, depth)]
    if not todo:
        return 0
    names = list(cfg.training.distractors)
    weights = np.array([float(cfg.training.distractors[n]) for n in names])
    presets = [cfg.distractor_presets[n] for n in names]
    chunk = cfg.training.chunk
    renderer, loaded = None, None
    stream = SPLIT_STREAM[split]
    with Pipeline() as pipe:
        for i in tqdm(todo, desc=f"{split:>5}", unit="img", disable=not progress):
            c = i // chunk
            if loaded != c:
                crng = rng_for(cfg.seed, stream, c, 1)
                clutter, people = _slot_meshes(crng, presets)
                tex = sample_textures(crng, None, cfg.appearance)
                renderer, loaded = new_renderer(job, tex, clutter, people), c
            rng = rng_for(cfg.seed, stream, i, 2)
            preset = presets[rng.choice(len(presets), p=weights / weights.sum())]
            _dress(job, renderer, rng, preset, poses[i])
            render_frame(job, renderer, d, i, poses[i], int(rng.integers(2**31)), pipe)
    return len(todo)


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
    # reference to a Mitsuba scene must not be dropped on the worker (datagen.render.trace).
    pipe.submit(_finish_frame, renderer.developer, traced, d, i, r.exposure, sigma, r.depth,
                effect)


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
