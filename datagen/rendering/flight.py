"""Rendering an evaluation flight: its scene (textures, lights, distractors, crowd), each
frame with the flight's camera effects and optics."""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from core.imaging import camera_effects
from datagen.appearance.lights import sample_lights
from datagen.appearance.materials import object_colours, part_palettes, sample_floor_gloss
from datagen.appearance.textures import sample_textures
from datagen.dataset_writer import frame_done
from datagen.distractors.crowd import person_tracks
from datagen.distractors.meshes import footprint_circles, make_clutter_mesh, make_person_mesh
from datagen.distractors.placement import place_objects, placed_circles
from datagen.distractors.presets import preset_counts, sample_kinds
from datagen.job import Job, flight_stream, rng_for, shard_range
from datagen.realism import optics
from datagen.rendering.frame import new_renderer, render_frame, render_optics_frame
from datagen.rendering.pipeline import Pipeline

log = logging.getLogger(__name__)


def flight_effect(job: Job, name: str, i: int) -> Callable[[np.ndarray], np.ndarray] | None:
    """What the drone's camera does to frame i of a flight (``camera_effects.apply_effects``
    with the frame's own generator, ``rng_for(seed, flight stream, 5, i)``, its exposure
    offset and dropout kind); None when realism has no image effect."""
    cfg, f = job.cfg, job.flights[name]
    if not camera_effects.is_active(cfg.realism):
        return None
    return functools.partial(camera_effects.apply_effects,
                             rng=rng_for(cfg.seed, flight_stream(name, f["preset"].seed), 5, i),
                             settings=cfg.realism, ev=float(f["exposure_ev"][i]),
                             dropout=camera_effects.dropout_kind(f["dropout"], i),
                             where="realism")


@dataclass
class FlightScene:
    """A flight's fixed dressing: drawn once, in this order, from the flight's generator.

    placed: (C, 3) clutter x, y, yaw (NaN: not placed); tracks: (P, N, 3) people x, y, yaw
    per frame; colours: C + P linear RGB colours of the distractors, (3,) each or (parts, 3)
    for a mesh whose parts have tones (drawn last, ``part_palettes``).
    """

    clutter: list
    people: list
    textures: dict[str, np.ndarray]
    lights: np.ndarray
    colours: list
    placed: np.ndarray
    tracks: np.ndarray
    gloss: tuple[float, float] | None = None  # the floor's (weight, alpha), drawn last


def flight_scene(job: Job, name: str) -> FlightScene:
    """One appearance, fixed clutter placed off the flight path, and people walking."""
    cfg, f = job.cfg, job.flights[name]
    gt, preset = f["groundtruth"], f["preset"]
    rng = rng_for(cfg.seed, flight_stream(name, preset.seed), 1)
    dp = cfg.distractor_presets[preset.distractors]
    n_clutter, n_people = preset_counts(rng, dp)
    clutter = [make_clutter_mesh(k, rng)
               for k in sample_kinds(rng, n_clutter, dp)]
    people = [make_person_mesh(rng) for _ in range(n_people)]
    textures = sample_textures(rng, None, cfg.appearance)
    lights = sample_lights(rng, job.site.scene.num_lights, cfg.appearance)[1]
    colours = object_colours(rng, n_clutter + n_people)
    cam_xy = (gt @ job.camera.body_from_cam)[:, :2, 3]
    flown = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(cam_xy, axis=0), axis=1))])
    step = max(dp.camera_keepout_m / 2, 0.05)  # keep-out circles along the path, overlapping
    path = cam_xy[np.unique(np.floor(flown / step), return_index=True)[1]]
    keep = np.concatenate([path, np.full((len(path), 1), dp.camera_keepout_m)], axis=1)
    builtins = np.array([b.footprint_circle() for b in job.builtins]).reshape(-1, 3)
    if len(builtins):
        keep = np.concatenate([keep, builtins])
    shapes = [footprint_circles(m) for m in clutter]
    floor = job.site.floor
    placed = place_objects(rng, shapes, [job.site.floor_for(m.bounds[1][2]) for m in clutter],
                           keep, against_walls=dp.against_walls, wall_margin=dp.wall_margin,
                           aligned=dp.aligned)[0]
    obstacles = placed_circles(shapes, placed)
    if len(builtins):
        obstacles = np.concatenate([obstacles, builtins])
    tracks = person_tracks(
        rng, n_people, len(gt), preset.fps, floor, speed=tuple(dp.person_speed),
        radius=dp.person_radius, obstacles=obstacles, avoid=cam_xy,
        avoid_radius=dp.person_camera_keepout, max_turn_deg_s=dp.person_max_turn_deg_s,
        patience_s=dp.person_patience_s,
    ) if n_people else np.zeros((0, len(gt), 3))
    gloss = sample_floor_gloss(rng, cfg.appearance)
    colours = part_palettes(rng, colours, [m.metadata.get("tones") for m in clutter + people])
    return FlightScene(clutter, people, textures, lights, colours, placed, tracks, gloss)


def render_flight(job: Job, name: str, progress: bool = True) -> int:
    """Render this shard's frames of a flight (``flight_scene``); returns their number."""
    cfg, gt = job.cfg, job.flights[name]["groundtruth"]
    delivered = job.flights[name]["delivered"]
    frames = shard_range(len(gt), cfg.shard, cfg.num_shards)
    d = job.out / "flights" / name
    todo = [i for i in frames if delivered[i] and not frame_done(d, i, cfg.render.depth)]
    if not todo:
        return 0
    scene = flight_scene(job, name)
    fo = (optics.FlightOptics.build(cfg.realism, job.camera, gt, job.flights[name]["preset"].fps)
          if optics.is_active(cfg.realism) else None)
    renderer = new_renderer(job, scene.textures, scene.clutter, scene.people,
                             None if fo is None else fo.render_camera, job.flight_render_scene)
    renderer.set_lights(scene.lights)
    if scene.gloss is not None:
        renderer.set_floor_gloss(*scene.gloss)
    with Pipeline() as pipe:
        for i in tqdm(todo, desc=f"flight {name}", unit="img", disable=not progress):
            renderer.set_objects(np.concatenate([scene.placed, scene.tracks[:, i]], axis=0),
                                 scene.colours)
            seeds = rng_for(cfg.seed, flight_stream(name, job.flights[name]["preset"].seed), 2, i)
            if fo is None:
                render_frame(job, renderer, d, i, gt[i], int(seeds.integers(2**31)), pipe,
                              flight_effect(job, name, i))
            else:
                render_optics_frame(job, renderer, d, i, fo, seeds, pipe,
                                     flight_effect(job, name, i))
    return len(todo)
