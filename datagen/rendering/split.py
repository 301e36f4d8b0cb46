"""Rendering a training split: each chunk of frames a renderer with its own textures,
lights, clutter and people; each frame from its own random stream."""

from __future__ import annotations

import logging

import numpy as np
from tqdm import tqdm

from core import classes as C
from datagen.appearance.lights import sample_lights
from datagen.appearance.materials import object_colours, sample_floor_gloss
from datagen.appearance.textures import sample_textures
from datagen.config import DistractorPreset
from datagen.dataset_writer import frame_done
from datagen.distractors.meshes import footprint_radius, make_clutter_mesh, make_person_mesh
from datagen.distractors.placement import place_objects
from datagen.distractors.presets import preset_counts, sample_kinds
from datagen.job import SPLIT_STREAM, Job, rng_for, shard_range
from datagen.rendering.frame import new_renderer, render_frame
from datagen.rendering.pipeline import Pipeline

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
