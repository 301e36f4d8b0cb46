"""The datagen job: render the training splits and the evaluation flights of one world.

Every frame draws its randomness from its own stream, ``SeedSequence([seed, stream, index])``,
so a frame's bytes do not depend on which shard renders it or on what was rendered before:
a stopped run re-run with the same config skips finished frames and ends byte-identical to an
uninterrupted run (up to rare one-level pixel differences from the LLVM variant's multithreaded
kernels; docs/datagen.md).
"""

from __future__ import annotations

import copy
import hashlib
import json
import logging
import math
import platform
import time
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from core import classes as C
from core.atomic import atomic_write_json, png_complete, remove_temp_files, write_png
from core.camera import intrinsics
from core.dataset import SCHEMA_VERSION, SPLITS, Camera, frame_name
from core.outputs import Claim, FolderPolicy, claim_output
from core.poses import pose_from_xyz_rpy, write_tum
from datagen import appearance, distractors, trajectories
from datagen.pipeline import Pipeline
from datagen.world import MAIN, OPENING, CorridorModel, build_world, recess_mouths

log = logging.getLogger(__name__)

SPLIT_STREAM = {"train": 0, "val": 1, "test": 2}
# Keys that do not change the dataset's content (left out of the config hash).
NON_CONTENT_KEYS = ("shard", "num_shards", "overwrite", "out_dir", "pipeline", "progress")
#: A dataset folder belongs to its ``generator`` config (core.outputs). Split counts and the
#: rendered flights may grow: a frame depends only on (seed, split, index) and a flight on
#: (seed, name), so the frames there are the ones the larger config renders. A flight's
#: ``num_frames`` may not: its trajectory spans the flight's whole duration. Shards of one
#: config render side by side.
DATASET_POLICY = FolderPolicy(record="dataset.json", section="generator",
                              grow=("splits", "render_flights"),
                              results=("*/rgb", "flights/*/rgb"), concurrent=True)


def rng_for(seed: int, *keys: int) -> np.random.Generator:
    """An independent generator for (seed, keys...)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), *map(int, keys)]))


def flight_stream(name: str) -> int:
    return 1000 + zlib.crc32(name.encode()) % 1_000_000


def content_config(cfg: Mapping) -> dict:
    """The keys of cfg that decide the dataset's content (dataset.json's ``generator``): all
    but ``NON_CONTENT_KEYS`` (a copy; cfg is not changed)."""
    return copy.deepcopy({k: v for k, v in cfg.items() if k not in NON_CONTENT_KEYS})


def config_hash(cfg: Mapping) -> str:
    return hashlib.sha256(json.dumps(content_config(cfg), sort_keys=True).encode()).hexdigest()[:16]


def make_camera(cam_cfg: Mapping) -> Camera:
    """Camera from config: K and body_from_cam for a forward camera (OpenCV axes)."""
    W, H = int(cam_cfg["width"]), int(cam_cfg["height"])
    K = intrinsics(W, H, float(cam_cfg["hfov_deg"]))
    # Columns: the camera's x (right), y (down), z (forward) axes in the body frame (FLU).
    base = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    pitch = math.radians(float(cam_cfg["mount"]["pitch_deg"]))
    tilt = pose_from_xyz_rpy(np.zeros(3), np.array([0.0, pitch, 0.0]))[0, :3, :3]
    xyz = np.asarray(cam_cfg["mount"]["xyz"], dtype=np.float64)
    if np.linalg.norm(xyz) > 0.5:
        raise ValueError(f"camera.mount.xyz {xyz.tolist()} puts the camera more than 0.5 m from "
                         "the body centre; give it in metres in the body frame")
    body_from_cam = np.eye(4)
    body_from_cam[:3, :3] = tilt @ base
    body_from_cam[:3, 3] = xyz
    return Camera(K, W, H, body_from_cam)


def floor_boxes(model: CorridorModel, margin: float) -> np.ndarray:
    """(B, 4) floor regions of the corridor and its openings, shrunk by margin (m)."""
    out = [[b.lo[0] + margin, b.lo[1] + margin, b.hi[0] - margin, b.hi[1] - margin]
           for b in model.boxes if b.kind in (MAIN, OPENING)]
    return np.array(out)


@dataclass
class Job:
    """Everything a shard needs, resolved and checked before any rendering."""

    cfg: dict
    out: Path
    model: CorridorModel
    camera: Camera
    split_poses: dict[str, np.ndarray]  # split -> (N, 4, 4) world_from_body
    flights: dict[str, dict[str, Any]]  # name -> preset, groundtruth, odometry, timestamps


def _check_counts(cfg: Mapping) -> None:
    for split, n in cfg["splits"].items():
        if split not in SPLITS:
            raise ValueError(f"splits.{split}: unknown split; use {list(SPLITS)}")
        if int(n) < 0:
            raise ValueError(f"splits.{split} = {n} must be >= 0")
    for key in ("width", "height"):
        if int(cfg["camera"][key]) <= 0:
            raise ValueError(f"camera.{key} = {cfg['camera'][key]} must be positive")
    if int(cfg["render"]["spp"]) <= 0 or int(cfg["render"]["max_depth"]) <= 0:
        raise ValueError("render.spp and render.max_depth must be positive")
    if not 0 <= int(cfg["shard"]) < int(cfg["num_shards"]):
        raise ValueError(f"shard={cfg['shard']} must be in [0, num_shards={cfg['num_shards']})")
    if int(cfg["training"]["chunk"]) <= 0:
        raise ValueError("training.chunk must be positive")
    presets = cfg["distractor_presets"]
    for name in cfg["training"]["distractors"]:
        if name not in presets:
            raise ValueError(f"training.distractors: unknown preset {name!r}; "
                             f"known: {sorted(presets)}")
    for name, preset in cfg["flights"].items():  # every preset: flight_views samples them all
        if int(preset["num_frames"]) <= 0 or float(preset["fps"]) <= 0:
            raise ValueError(f"flights.{name}: num_frames ({preset['num_frames']}) and fps "
                             f"({preset['fps']}) must be positive")
    for name in cfg["render_flights"]:
        if name not in cfg["flights"]:
            raise ValueError(f"render_flights: unknown flight preset {name!r}; "
                             f"known: {sorted(cfg['flights'])}")
        dp = cfg["flights"][name].get("distractors", "none")
        if dp not in presets:
            raise ValueError(f"flights.{name}.distractors: unknown preset {dp!r}; "
                             f"known: {sorted(presets)}")


def _check_inside(model: CorridorModel, camera: Camera, poses: np.ndarray, where: str) -> None:
    """Every camera centre must lie inside the corridor's free space."""
    centres = (poses @ camera.body_from_cam)[:, :3, 3]
    inside = np.zeros(len(centres), dtype=bool)
    for b in model.boxes:
        inside |= np.all((centres > np.array(b.lo)) & (centres < np.array(b.hi)), axis=1)
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        raise ValueError(f"{where}: camera {i} at {np.round(centres[i], 3).tolist()} is outside "
                         "the corridor; check world.camera_margin, world.z_range, camera.mount "
                         "and the flight preset's trajectory")


def poses_of_split(cfg: Mapping, model: CorridorModel, split: str) -> np.ndarray:
    """(N, 4, 4) body poses of a split's frames; frame i's depends only on (seed, split, i).

    A share ``training.opening_views`` of them (decided per frame by its own generator) face
    a door or window from close by (``trajectories.sample_opening_views``); of the others, a
    share ``training.flight_views`` are posed as the flights fly
    (``trajectories.sample_flight_views``) and the rest spread over the free space
    (``trajectories.sample_training_poses``).
    """
    tr, world = cfg["training"], model.world
    share, close = float(tr["flight_views"]), float(tr["opening_views"])
    for key, v in (("flight_views", share), ("opening_views", close)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"training.{key}={v} must be a share in [0, 1]")
    distance = tuple(tr["opening_distance"])
    mouths = recess_mouths(model.boxes)
    presets = list(cfg["flights"].values())
    stream = SPLIT_STREAM[split]
    poses = np.zeros((int(cfg["splits"].get(split, 0)), 4, 4))
    for i in range(len(poses)):
        if close > 0 and rng_for(cfg["seed"], stream, i, 5).random() < close:
            poses[i] = trajectories.sample_opening_views(
                rng_for(cfg["seed"], stream, i, 6), 1, *mouths, world.free_boxes,
                world.z_range, distance, max_roll_pitch_deg=tr["max_roll_pitch_deg"])[0]
        elif share > 0 and rng_for(cfg["seed"], stream, i, 3).random() < share:
            poses[i] = trajectories.sample_flight_views(
                rng_for(cfg["seed"], stream, i, 4), 1, world.free_boxes, world.z_range,
                presets)[0]
        else:
            poses[i] = trajectories.sample_training_poses(
                rng_for(cfg["seed"], stream, i, 0), 1, world.free_boxes, world.z_range,
                tr["max_roll_pitch_deg"], float(tr.get("yaw_along_corridor", 0.0)),
                float(tr.get("yaw_spread_deg", 50.0)))[0]
    return poses


def prepare(cfg: Mapping) -> Job:
    """Resolve and validate a datagen config; build the world and every pose. No rendering."""
    cfg = dict(cfg)
    _check_counts(cfg)
    model = build_world(cfg["world"])
    camera = make_camera(cfg["camera"])
    w = model.world
    split_poses = {}
    for split in SPLITS:
        poses = poses_of_split(cfg, model, split)
        _check_inside(model, camera, poses, f"splits.{split}")
        split_poses[split] = poses
    flights = {}
    for name in cfg["render_flights"]:
        preset = cfg["flights"][name]
        r = rng_for(cfg["seed"], flight_stream(name), 0)
        n, fps = int(preset["num_frames"]), float(preset["fps"])  # checked in _check_counts
        gt = trajectories.flight_trajectory(r, n, fps, w.free_boxes, w.z_range, preset)
        odo = trajectories.noisy_odometry(r, gt, preset, fps=fps)
        _check_inside(model, camera, gt, f"flights.{name}")
        flights[name] = {"preset": preset, "groundtruth": gt, "odometry": odo,
                         "timestamps": trajectories.timestamps(n, fps)}
    return Job(cfg, Path(cfg["out_dir"]), model, camera, split_poses, flights)


def shard_range(n: int, shard: int, num_shards: int) -> range:
    """Frames [start, stop) of one shard of n frames."""
    return range(n * shard // num_shards, n * (shard + 1) // num_shards)


def software_versions(variant: str) -> dict[str, str]:
    import drjit
    import mitsuba
    import trimesh

    return {"python": platform.python_version(), "numpy": np.__version__,
            "mitsuba": mitsuba.__version__, "drjit": drjit.__version__,
            "trimesh": trimesh.__version__, "mitsuba_variant": variant}


def write_metadata(job: Job, variant: str) -> None:
    """dataset.json, world/ and the pose files (identical bytes from every shard)."""
    from datagen.save import save_world

    cfg, out, cam = job.cfg, job.out, job.camera
    meta = {
        "schema_version": SCHEMA_VERSION,
        "name": cfg["name"],
        "classes": C.as_json(),
        "structural_classes": list(C.STRUCTURAL),
        "ignore_index": C.IGNORE,
        "camera": {"K": cam.K.tolist(), "width": cam.width, "height": cam.height,
                   "hfov_deg": float(cfg["camera"]["hfov_deg"]),
                   "body_from_cam": cam.body_from_cam.tolist()},
        "seed": int(cfg["seed"]),
        "config_hash": config_hash(cfg),
        "counts": {**{s: int(cfg["splits"].get(s, 0)) for s in SPLITS},
                   "flights": {k: int(v["groundtruth"].shape[0]) for k, v in job.flights.items()}},
        "generator": content_config(cfg),
        "command": datagen_command(),
        "software": software_versions(variant),
    }
    save_world(out / "world", job.model)
    for split, poses in job.split_poses.items():
        if len(poses):
            write_tum(out / split / "poses.txt", np.arange(len(poses), dtype=float), poses)
    for name, f in job.flights.items():
        d = out / "flights" / name
        write_tum(d / "groundtruth.txt", f["timestamps"], f["groundtruth"])
        write_tum(d / "odometry.txt", f["timestamps"], f["odometry"])
        atomic_write_json(d / "flight.json", {
            "name": name, "fps": float(f["preset"]["fps"]),
            "num_frames": int(len(f["timestamps"])),
            "distractors": f["preset"].get("distractors", "none"), "preset": f["preset"],
            "seed_stream": flight_stream(name)})
    atomic_write_json(out / "dataset.json", meta)


def datagen_command() -> str | None:
    """``python -m datagen <overrides>`` of this Hydra run without the per-run keys (shard,
    num_shards, overwrite, pipeline, progress); None outside Hydra."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    per_run = set(NON_CONTENT_KEYS) - {"out_dir"}
    keep = [o for o in HydraConfig.get().overrides.task
            if o.lstrip("+~").split("=")[0] not in per_run]
    return " ".join(["python -m datagen", *keep])


def claim_dataset(job: Job, variant: str) -> Claim:
    """Claim the dataset folder for this config (core.outputs, ``DATASET_POLICY``) and write
    its metadata: resume or grow a dataset of this config, refuse one of another (unless
    ``overwrite=true``), wait briefly for and then refuse a run of another config that holds
    it. Alone in the folder, delete the temporary files killed writes left."""
    claim = claim_output(job.out, {"generator": content_config(job.cfg)}, DATASET_POLICY,
                         overwrite=bool(job.cfg.get("overwrite")),
                         write=lambda: write_metadata(job, variant))
    if claim.alone:
        stale = remove_temp_files(job.out)
        if stale:
            log.info("%s: removed %d temporary files of killed writes", job.out, len(stale))
    return claim


def frame_done(d: Path, index: int, depth: bool) -> bool:
    """Whether frame ``index`` is there and sound (each PNG ends with its IEND chunk)."""
    names = ["rgb", "label"] + (["depth"] if depth else [])
    return all(png_complete(d / sub / frame_name(index)) for sub in names)


def write_frame(d: Path, index: int, rgb: np.ndarray, label: np.ndarray,
                depth: np.ndarray | None) -> None:
    """Write one frame; the label goes last, so a frame with a label is complete."""
    if depth is not None:
        write_png(d / "depth" / frame_name(index),
                  np.clip(np.rint(depth * 1000.0), 0, 65535).astype(np.uint16))
    write_png(d / "rgb" / frame_name(index), rgb)
    write_png(d / "label" / frame_name(index), label)


def _slot_meshes(cfg: Mapping, chunk_rng: np.random.Generator, presets: list[Mapping]):
    """Distractor meshes for one scene load: enough slots for the busiest preset used."""
    n_clutter = max(int(p["clutter"]["max"]) for p in presets)
    n_people = max(int(p["people"]["max"]) for p in presets)
    kinds_from = next((p for p in presets if p["clutter"]["max"]), presets[0])
    kinds = distractors.sample_kinds(chunk_rng, n_clutter, kinds_from)
    clutter = [distractors.make_clutter_mesh(k, chunk_rng) for k in kinds]
    people = [distractors.make_person_mesh(chunk_rng) for _ in range(n_people)]
    return clutter, people


def _new_renderer(job: Job, textures, clutter, people):
    from datagen.render import CorridorRenderer

    return CorridorRenderer(job.model, job.camera, textures, clutter, people,
                            max_depth=int(job.cfg["render"]["max_depth"]))


def _dress(job: Job, renderer, rng: np.random.Generator, preset: Mapping,
           body_pose: np.ndarray) -> None:
    """Randomize textures, lights and distractors of one training image."""
    cfg = job.cfg
    renderer.set_textures(appearance.sample_textures(rng, None, cfg["appearance"]))
    renderer.set_lights(appearance.sample_lights(rng, renderer.num_lights, cfg["appearance"])[1])
    n_clutter, n_people = distractors.preset_counts(rng, preset)
    slots = renderer.slots
    clutter_ids = [i for i, (_, c) in enumerate(slots) if c == C.CLUTTER]
    people_ids = [i for i, (_, c) in enumerate(slots) if c == C.PERSON]
    use = (list(rng.permutation(clutter_ids)[:n_clutter])
           + list(rng.permutation(people_ids)[:n_people]))
    poses = np.full((len(slots), 3), np.nan)
    if use:
        radii = np.array([distractors.footprint_radius(slots[i][0]) for i in use])
        cam = (body_pose @ job.camera.body_from_cam)[:3, 3]
        keep = np.array([[cam[0], cam[1], float(preset.get("camera_keepout_m", 0.6))]])
        xy_yaw, _ = distractors.place_objects(
            rng, radii, floor_boxes(job.model, float(preset.get("wall_margin", 0.05))), keep,
            against_walls=float(preset.get("against_walls", 0.0)))
        poses[use] = xy_yaw
    renderer.set_objects(poses, appearance.object_colours(rng, len(slots)))


def _pipelined(cfg: Mapping) -> bool:
    """Whether frames are developed and written on a worker thread (``pipeline``)."""
    return bool(cfg.get("pipeline", True))


def render_split(job: Job, split: str, progress: bool = True) -> int:
    """Render this shard's frames of a split; returns the number of frames rendered."""
    cfg, poses = job.cfg, job.split_poses[split]
    frames = shard_range(len(poses), int(cfg["shard"]), int(cfg["num_shards"]))
    depth = bool(cfg["render"]["depth"])
    d = job.out / split
    todo = [i for i in frames if not frame_done(d, i, depth)]
    if not todo:
        return 0
    names = list(cfg["training"]["distractors"])
    weights = np.array([float(cfg["training"]["distractors"][n]) for n in names])
    presets = [cfg["distractor_presets"][n] for n in names]
    chunk = int(cfg["training"]["chunk"])
    renderer, loaded = None, None
    stream = SPLIT_STREAM[split]
    with Pipeline(enabled=_pipelined(cfg)) as pipe:
        for i in tqdm(todo, desc=f"{split:>5}", unit="img", disable=not progress):
            c = i // chunk
            if loaded != c:
                crng = rng_for(cfg["seed"], stream, c, 1)
                clutter, people = _slot_meshes(cfg, crng, presets)
                tex = appearance.sample_textures(crng, None, cfg["appearance"])
                renderer, loaded = _new_renderer(job, tex, clutter, people), c
            rng = rng_for(cfg["seed"], stream, i, 2)
            preset = presets[rng.choice(len(presets), p=weights / weights.sum())]
            _dress(job, renderer, rng, preset, poses[i])
            _render_frame(job, renderer, d, i, poses[i], int(rng.integers(2**31)), pipe)
    return len(todo)


def _render_frame(job: Job, renderer, d: Path, i: int, body_pose: np.ndarray, seed: int,
                  pipe: Pipeline) -> None:
    """Trace frame i here; develop and write it on the pipeline's worker."""
    r = job.cfg["render"]
    renderer.set_camera(body_pose @ job.camera.body_from_cam)
    sigma = float(r["denoise_sigma_px"])
    traced = renderer.trace(int(r["spp"]), seed, albedo=sigma > 0)
    # The worker gets the renderer's numpy-only developer, never the renderer: the last
    # reference to a Mitsuba scene must not be dropped on the worker (datagen.render.trace).
    pipe.submit(_finish_frame, renderer.developer, traced, d, i, float(r["exposure"]), sigma,
                bool(r["depth"]))


def _finish_frame(developer, traced, d: Path, i: int, exposure: float, sigma: float,
                  depth: bool) -> None:
    rgb, label, z = developer.develop(traced, exposure, sigma)
    write_frame(d, i, rgb, label, z if depth else None)


def render_flight(job: Job, name: str, progress: bool = True) -> int:
    """Render this shard's frames of a flight: one appearance, fixed clutter, walking people."""
    cfg, f = job.cfg, job.flights[name]
    gt, preset = f["groundtruth"], f["preset"]
    frames = shard_range(len(gt), int(cfg["shard"]), int(cfg["num_shards"]))
    depth = bool(cfg["render"]["depth"])
    d = job.out / "flights" / name
    todo = [i for i in frames if not frame_done(d, i, depth)]
    if not todo:
        return 0
    rng = rng_for(cfg["seed"], flight_stream(name), 1)
    dp = cfg["distractor_presets"][preset.get("distractors", "none")]
    n_clutter, n_people = distractors.preset_counts(rng, dp)
    clutter = [distractors.make_clutter_mesh(k, rng)
               for k in distractors.sample_kinds(rng, n_clutter, dp)]
    people = [distractors.make_person_mesh(rng) for _ in range(n_people)]
    textures = appearance.sample_textures(rng, None, cfg["appearance"])
    lights = appearance.sample_lights(rng, len(job.model.lights), cfg["appearance"])[1]
    colours = appearance.object_colours(rng, n_clutter + n_people)
    cam_xy = (gt @ job.camera.body_from_cam)[:, :2, 3]
    path = cam_xy[:: max(1, len(cam_xy) // 60)]
    keep = np.concatenate([path, np.full((len(path), 1),
                                         float(dp.get("camera_keepout_m", 0.6)))], axis=1)
    radii = np.array([distractors.footprint_radius(m) for m in clutter])
    boxes = floor_boxes(job.model, float(dp.get("wall_margin", 0.05)))
    placed = distractors.place_objects(rng, radii, boxes, keep,
                                       against_walls=float(dp.get("against_walls", 0.0)))[0]
    ok = ~np.isnan(placed[:, 0])
    obstacles = np.concatenate([placed[ok, :2], radii[ok, None]], axis=1)
    tracks = distractors.person_tracks(
        rng, n_people, len(gt), float(preset["fps"]), boxes,
        speed=tuple(dp.get("person_speed", (0.6, 1.4))),
        radius=float(dp.get("person_radius", 0.3)), obstacles=obstacles, avoid=cam_xy,
    ) if n_people else np.zeros((0, len(gt), 3))
    renderer = _new_renderer(job, textures, clutter, people)
    renderer.set_lights(lights)
    with Pipeline(enabled=_pipelined(cfg)) as pipe:
        for i in tqdm(todo, desc=f"flight {name}", unit="img", disable=not progress):
            poses = np.concatenate([placed, tracks[:, i]], axis=0)
            renderer.set_objects(poses, colours)
            seed = int(rng_for(cfg["seed"], flight_stream(name), 2, i).integers(2**31))
            _render_frame(job, renderer, d, i, gt[i], seed, pipe)
    return len(todo)


def run(cfg: Mapping, progress: bool = True) -> Path:
    """Render (this shard of) a dataset; returns the dataset directory."""
    from core.variant import choose_variant

    job = prepare(cfg)
    variant = choose_variant(job.cfg["render"]["variant"])
    with claim_dataset(job, variant):
        t0 = time.perf_counter()
        counts = {s: render_split(job, s, progress) for s in SPLITS if len(job.split_poses[s])}
        counts.update({f"flight:{n}": render_flight(job, n, progress) for n in job.flights})
        seconds = time.perf_counter() - t0
        write_stats(job, variant, counts, seconds)
    return job.out


def write_stats(job: Job, variant: str, counts: dict[str, int], seconds: float) -> None:
    """stats/shard-K-of-N.json for this run, and stats.json summing every shard's file."""
    cfg = job.cfg
    rendered = sum(counts.values())
    shard = {"shard": int(cfg["shard"]), "num_shards": int(cfg["num_shards"]),
             "rendered": counts, "seconds": round(seconds, 3),
             "images_per_second": round(rendered / seconds, 3) if rendered else None}
    d = job.out / "stats"
    path = d / f"shard-{cfg['shard']}-of-{cfg['num_shards']}.json"
    if rendered or not path.is_file():  # a resumed run with nothing left keeps the timed one
        atomic_write_json(path, shard)
    runs = [json.loads(p.read_text()) for p in sorted(d.glob("shard-*.json"))]
    timed = [r for r in runs if r["images_per_second"]]
    r = cfg["render"]
    atomic_write_json(job.out / "stats.json", {
        "images_per_second": (round(sum(sum(x["rendered"].values()) for x in timed)
                                    / sum(x["seconds"] for x in timed), 3) if timed else None),
        "images_per_second_note": "labeled RGB+label images per second of one process, "
                                  "summed over the shards' last runs",
        "counts": job.cfg and {s: int(cfg["splits"].get(s, 0)) for s in SPLITS}
        | {f"flight:{n}": len(f["timestamps"]) for n, f in job.flights.items()},
        "render": {"variant": variant, "width": job.camera.width, "height": job.camera.height,
                   "spp": int(r["spp"]), "max_depth": int(r["max_depth"]),
                   "depth": bool(r["depth"])},
        "shards": runs,
    })
