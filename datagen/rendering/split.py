"""Rendering a training split: each chunk of frames a renderer with its own textures,
lights, clutter and people; each frame from its own random stream."""

from __future__ import annotations

import logging

import numpy as np
from tqdm import tqdm

from core import classes as C
from datagen.appearance.lights import sample_lights
from datagen.appearance.materials import object_colours, part_palettes, sample_floor_gloss
from datagen.appearance.textures import sample_textures
from datagen.config import DistractorPreset
from datagen.dataset_writer import frame_done
from datagen.distractors.meshes import footprint_circles, make_clutter_mesh, make_person_mesh
from datagen.distractors.placement import place_objects
from datagen.distractors.presets import preset_counts, sample_kinds
from datagen.job import SPLIT_STREAM, Job, rng_for, shard_range
from datagen.rendering.frame import new_renderer, render_frame
from datagen.rendering.pipeline import Pipeline

log = logging.getLogger(__name__)

NEAR_WIDEN_DEG = 30.0  # deg the view objects stand in (near_camera_m) reaches past the camera's
# field of view on each side: objects reaching in from its edges


def _slot_meshes(chunk_rng: np.random.Generator, presets: list[DistractorPreset]
                 ) -> tuple[list, list, list[list[int]]]:
    """Distractor meshes for one scene load: for each list of kinds the presets draw from
    (the presets of one list share its slots) enough of those kinds for its busiest preset,
    then enough people for the busiest.

    Returns:
        clutter meshes, people meshes, and per preset the indices of the clutter slots its
        images draw from (a preset without clutter: all of them).
    """
    groups: dict[tuple[str, ...], list[int]] = {}
    for k, p in enumerate(presets):
        if p.clutter.max:
            groups.setdefault(tuple(p.kinds), []).append(k)
    clutter: list = []
    slots_of: list[list[int]] = [[] for _ in presets]
    for members in groups.values():
        n = max(presets[k].clutter.max for k in members)
        ids = list(range(len(clutter), len(clutter) + n))
        clutter += [make_clutter_mesh(kind, chunk_rng)
                    for kind in sample_kinds(chunk_rng, n, presets[members[0]])]
        for k in members:
            slots_of[k] = ids
    slots_of = [ids or list(range(len(clutter))) for ids in slots_of]
    people = [make_person_mesh(chunk_rng) for _ in range(max(p.people.max for p in presets))]
    return clutter, people, slots_of


def _dress(job: Job, renderer, rng: np.random.Generator, preset: DistractorPreset,
           body_pose: np.ndarray, clutter_ids: list[int]) -> None:
    """Randomize textures, lights and distractors of one training image (its clutter drawn
    from the slots ``clutter_ids``)."""
    look = job.cfg.appearance
    renderer.set_textures(sample_textures(rng, None, look))
    renderer.set_lights(sample_lights(rng, renderer.num_lights, look)[1])
    gloss = sample_floor_gloss(rng, look)  # None (and no draw) when never glossy
    if gloss is not None:
        renderer.set_floor_gloss(*gloss)
    n_clutter, n_people = preset_counts(rng, preset)
    slots = renderer.slots
    people_ids = [i for i, (_, c) in enumerate(slots) if c == C.PERSON]
    use = (list(rng.permutation(clutter_ids)[:n_clutter])
           + list(rng.permutation(people_ids)[:n_people]))
    poses = np.full((len(slots), 3), np.nan)
    if use:
        meshes = [slots[i][0] for i in use]
        cam = (body_pose @ job.camera.body_from_cam)[:3, 3]
        keep = np.array([[cam[0], cam[1], preset.camera_keepout_m]])
        view = None
        if preset.near_camera_m > 0:  # in sight, in the field of view widened 30 deg a side
            K, ahead = job.camera.K, body_pose[:2, 0]
            half = np.arctan(job.camera.width / 2 / K[0, 0]) + np.deg2rad(NEAR_WIDEN_DEG)
            view = np.array([cam[0], cam[1], np.arctan2(ahead[1], ahead[0]), half,
                             preset.near_camera_m])
        xy_yaw, _ = place_objects(
            rng, [footprint_circles(m) for m in meshes],
            [job.site.floor_for(m.bounds[1][2]) for m in meshes], keep,
            against_walls=preset.against_walls, wall_margin=preset.wall_margin,
            aligned=preset.aligned, view=view)
        poses[use] = xy_yaw
    colours = object_colours(rng, len(slots))
    renderer.set_objects(poses, part_palettes(rng, colours,
                                              [m.metadata.get("tones") for m, _ in slots]))


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
                clutter, people, slots_of = _slot_meshes(crng, presets)
                tex = sample_textures(crng, None, cfg.appearance)
                renderer, loaded = new_renderer(job, tex, clutter, people), c
            rng = rng_for(cfg.seed, stream, i, 2)
            k = rng.choice(len(presets), p=weights / weights.sum())
            _dress(job, renderer, rng, presets[k], poses[i], slots_of[k])
            render_frame(job, renderer, d, i, poses[i], int(rng.integers(2**31)), pipe)
    return len(todo)
