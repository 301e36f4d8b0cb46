"""The datagen job: render the training splits and the evaluation flights of one world.

Every frame draws its randomness from its own stream, ``SeedSequence([seed, stream, index])``,
so a frame's bytes do not depend on which shard renders it or on what was rendered before:
a stopped run re-run with the same config skips finished frames and ends byte-identical to an
uninterrupted run (up to rare one-level pixel differences from the LLVM variant's multithreaded
kernels; docs/datagen.md). A flight's keys under its stream: 0 trajectory and odometry,
1 scene, (2, i) frame i's render seed (its sub-frames' seeds in turn, datagen/realism/optics.py),
3 route, 4 AHRS, (5, i) frame i's camera effects, 6 exposure series, 7 dropouts, 8 harder
flight (``realism.flight``), 9 odometry jumps, (10, i) frame i's drop and timestamp jitter
(``realism.timing``) (SeedSequence pads a short key with zeros: (k,) is (k, 0), so no k is used
both alone and with an index). The dataset's map error draws from stream ``MAP_STREAM`` (key 0
the map's edits, 1 the built-in objects' placement), its calibration error from
``CALIBRATION_STREAM``.

Flights: ``render_flights`` are the test flights, ``flights/<name>/``; ``val_flights`` the
validation flights, ``flights/<name>_val/``, the same presets drawn from the stream of the name
``<name>_val`` (another trajectory, scene and planned route). flight.json's ``set`` says which.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import math
import platform
import time
import zlib
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from core import camera_effects
from core import classes as C
from core.atomic import (
    atomic_write_json,
    atomic_write_text,
    png_complete,
    remove_temp_files,
    write_png,
)
from core.camera import intrinsics
from core.config import as_config, typed
from core.dataset import SCHEMA_VERSION, SPLITS, Camera, World, frame_name
from core.outputs import Claim, FolderPolicy, claim_output
from core.poses import pose_from_xyz_rpy, write_tum
from core.realism import MapErrorConfig, realism_label
from datagen import trajectories
from datagen.appearance.lights import sample_lights
from datagen.appearance.materials import object_colours, sample_floor_gloss
from datagen.appearance.textures import sample_textures
from datagen.config import CameraConfig, DatagenConfig, DistractorPreset
from datagen.distractors.crowd import person_tracks
from datagen.distractors.meshes import footprint_radius, make_clutter_mesh, make_person_mesh
from datagen.distractors.placement import place_objects
from datagen.distractors.presets import check_preset, preset_counts, sample_kinds
from datagen.importers.plan import write_plan
from datagen.pipeline import Pipeline
from datagen.realism import ahrs, calibration, map_error, optics, timing
from datagen.scene import Scene
from datagen.site import Site, build_site

log = logging.getLogger(__name__)

SPLIT_STREAM = {"train": 0, "val": 1, "test": 2}
MAP_STREAM = 10  # realism.map: (10, 0) the map's edits, (10, 1) the built-ins' placement
CALIBRATION_STREAM = 11  # realism.calibration
NEAR_LIGHTS_FROM = 16  # lights
# Keys that do not change the dataset's content (left out of the config hash).
NON_CONTENT_KEYS = ("shard", "num_shards", "overwrite", "out_dir", "progress")
#: A dataset folder belongs to its ``generator`` config (core.outputs). Split counts and the
#: rendered flights may grow: a frame depends only on (seed, split, index) and a flight on
#: (seed, name), so the frames there are the ones the larger config renders. A flight's
#: ``num_frames`` may not: its trajectory spans the flight's whole duration. Shards of one
#: config render side by side.
DATASET_POLICY = FolderPolicy(record="dataset.json", section="generator",
                              grow=("splits", "render_flights", "val_flights"),
                              results=("*/rgb", "flights/*/rgb"), concurrent=True)


def rng_for(seed: int, *keys: int) -> np.random.Generator:
    """An independent generator for (seed, keys...)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), *map(int, keys)]))


def flight_stream(name: str) -> int:
    return 1000 + zlib.crc32(name.encode()) % 1_000_000


def content_config(cfg: DatagenConfig) -> dict:
    """The settings that decide the dataset's content (dataset.json's ``generator``): all
    but ``NON_CONTENT_KEYS``, as plain containers."""
    return {k: v for k, v in asdict(cfg).items() if k not in NON_CONTENT_KEYS}


def config_hash(cfg: DatagenConfig) -> str:
    return hashlib.sha256(json.dumps(content_config(cfg), sort_keys=True).encode()).hexdigest()[:16]


def make_camera(cam_cfg: CameraConfig | Mapping) -> Camera:
    """Camera from config (``CameraConfig``, or a mapping of the keys that differ from its
    defaults): K and body_from_cam for a forward camera (OpenCV axes)."""
    cam_cfg = as_config(CameraConfig, cam_cfg, "camera")
    W, H = cam_cfg.width, cam_cfg.height
    K = intrinsics(W, H, cam_cfg.hfov_deg)
    # Columns: the camera's x (right), y (down), z (forward) axes in the body frame (FLU).
    base = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    pitch = math.radians(cam_cfg.mount.pitch_deg)
    tilt = pose_from_xyz_rpy(np.zeros(3), np.array([0.0, pitch, 0.0]))[0, :3, :3]
    xyz = np.asarray(cam_cfg.mount.xyz, dtype=np.float64)
    if np.linalg.norm(xyz) > 0.5:
        raise ValueError(f"camera.mount.xyz {xyz.tolist()} puts the camera more than 0.5 m from "
                         "the body centre; give it in metres in the body frame")
    body_from_cam = np.eye(4)
    body_from_cam[:3, :3] = tilt @ base
    body_from_cam[:3, 3] = xyz
    return Camera(K, W, H, body_from_cam)


@dataclass
class Job:
    """Everything a shard needs, resolved and checked before any rendering."""

    cfg: DatagenConfig
    out: Path
    site: Site
    camera: Camera
    split_poses: dict[str, np.ndarray]  # split -> (N, 4, 4) world_from_body
    flights: dict[str, dict[str, Any]]  # name -> preset (FlightConfig), preset_name, set
    # (test | val), groundtruth ((N, 4, 4) at the capture times), timestamps ((N,) s, the
    # capture times i / fps), odometry ((M, 4, 4)) at odometry_times ((M,) s), delivered
    # ((N,) bool) and stamps ((N,) s, the images' timestamps) and jumps (realism.timing),
    # exposure_ev ((N,) EV stops) and dropout (camera_effects.Dropout list): the image
    # effects of realism
    told_camera: Camera | None = None  # the camera the localizer is told (realism.calibration;
    # None: the rendering's, ``camera``)
    calibration_error: dict | None = None  # the drawn error (calibration.told_camera)
    map_world: World | None = None  # the map the localizer reads (realism.map; None: the
    # truth, ``site.world``)
    map_error: dict | None = None  # the map's edits (map_error.make_map) and built-ins
    builtins: list[map_error.Builtin] = field(default_factory=list)  # unmodelled objects in
    # the flights' renders (realism.map.builtins)

    @property
    def flight_render_scene(self) -> Scene:
        """What the flights' renders draw: the site's scene and the built-in objects."""
        scene = self.site.scene
        if not self.builtins:
            return scene
        return Scene(scene.surfaces + map_error.builtin_surfaces(self.builtins), scene.lights,
                     scene.images)


def val_flights(cfg: DatagenConfig) -> list[str]:
    """The presets rendered as validation flights (``val_flights``; None: ``render_flights``)."""
    return list(cfg.render_flights if cfg.val_flights is None else cfg.val_flights)


def _check_counts(cfg: DatagenConfig) -> None:
    """Seed, counts, sizes and shards: positive where they must be."""
    if cfg.seed < 0:
        raise ValueError(f"seed = {cfg.seed} must be >= 0 (numpy's SeedSequence takes "
                         "non-negative integers); pass seed=0 or another non-negative one")
    for split in SPLITS:
        n = getattr(cfg.splits, split)
        if n < 0:
            raise ValueError(f"splits.{split} = {n} must be >= 0")
    for key in ("width", "height"):
        if getattr(cfg.camera, key) <= 0:
            raise ValueError(f"camera.{key} = {getattr(cfg.camera, key)} must be positive")
    if cfg.render.spp <= 0 or cfg.render.max_depth <= 0:
        raise ValueError("render.spp and render.max_depth must be positive")
    if not 0 <= cfg.shard < cfg.num_shards:
        raise ValueError(f"shard={cfg.shard} must be in [0, num_shards={cfg.num_shards})")
    if cfg.training.chunk <= 0:
        raise ValueError("training.chunk must be positive")
    if cfg.training.min_view_m < 0:
        raise ValueError(f"training.min_view_m={cfg.training.min_view_m} must be >= 0 m")
    if not 0.0 <= cfg.training.flight_views <= 1.0:
        raise ValueError(f"training.flight_views={cfg.training.flight_views} must be a share "
                         "in [0, 1]")


def _check_presets(cfg: DatagenConfig) -> None:
    """The presets a run uses exist and are sound."""
    presets = cfg.distractor_presets
    for name, preset in presets.items():
        check_preset(preset, f"distractor_presets.{name}")
    for name in cfg.training.distractors:
        if name not in presets:
            raise ValueError(f"training.distractors: unknown preset {name!r}; "
                             f"known: {sorted(presets)}")
    for name, flight in cfg.flights.items():  # every preset: flight_views samples them all
        if flight.num_frames <= 0 or flight.fps <= 0:
            raise ValueError(f"flights.{name}: num_frames ({flight.num_frames}) and fps "
                             f"({flight.fps}) must be positive")
    for key in ("render_flights", "val_flights"):
        for name in getattr(cfg, key) or []:
            if name not in cfg.flights:
                raise ValueError(f"{key}: unknown flight preset {name!r}; "
                                 f"known: {sorted(cfg.flights)}")
    clash = sorted(set(cfg.render_flights) & {f"{n}_val" for n in val_flights(cfg)})
    if clash:
        raise ValueError(f"render_flights {clash} has the name of a validation flight "
                         "(<name>_val of val_flights); rename the preset")
    for name in {*cfg.render_flights, *val_flights(cfg)}:
        dp = cfg.flights[name].distractors
        if dp not in presets:
            raise ValueError(f"flights.{name}.distractors: unknown preset {dp!r}; "
                             f"known: {sorted(presets)}")


def _check_inside(site: Site, camera: Camera, poses: np.ndarray, where: str) -> None:
    """Every camera centre must lie within the camera margin of the free space (its cells and
    its band of heights): nearer to no surface than the margin allows."""
    free = site.world.free
    centres = (poses @ camera.body_from_cam)[:, :3, 3]
    off = np.maximum(free.outside_distance(centres[:, :2]),
                     np.maximum(free.band[0] - centres[:, 2], centres[:, 2] - free.band[1]))
    bad = np.flatnonzero(off >= free.margin)
    if len(bad):
        i = int(bad[0])
        raise ValueError(f"{where}: camera {i} at {np.round(centres[i], 3).tolist()} is "
                         f"{off[i]:.2f} m outside the free space (more than its margin "
                         f"{free.margin} m); check world.camera_margin, world.z_range, "
                         "camera.mount and the flight preset's trajectory")


def poses_of_split(cfg: DatagenConfig, site: Site, split: str) -> np.ndarray:
    """(N, 4, 4) body poses of a split's frames; frame i's depends only on (seed, split, i).

    A share ``training.flight_views`` of them (decided per frame by its own generator) are
    posed as the flights fly (``trajectories.sample_flight_views``, along each preset's route,
    resolved once per split), the rest spread over the free space
    (``trajectories.sample_training_poses``).
    """
    tr, seed, free = cfg.training, cfg.seed, site.world.free
    z_range = np.asarray(free.band)
    stream = SPLIT_STREAM[split]
    poses = np.zeros((getattr(cfg.splits, split), 4, 4))
    views = {i for i in range(len(poses)) if tr.flight_views > 0
             and rng_for(seed, stream, i, 3).random() < tr.flight_views}
    if views:
        presets = list(cfg.flights.values())
        routes = [trajectories.flight_route(p, free, site.route,
                                            rng_for(seed, 100 + stream, k), f"flights.{name}")
                  for k, (name, p) in enumerate(cfg.flights.items())]
    for i in range(len(poses)):
        if i in views:
            poses[i] = trajectories.sample_flight_views(
                rng_for(seed, stream, i, 4), 1, free, z_range, presets, routes)[0]
        else:
            poses[i] = trajectories.sample_training_poses(
                rng_for(seed, stream, i, 0), 1, free, z_range,
                tr.max_roll_pitch_deg, tr.yaw_along_corridor, tr.yaw_spread_deg,
                tr.min_view_m)[0]
    return poses


def prepare(cfg: DatagenConfig | Mapping) -> Job:
    """Resolve and validate a datagen config (``DatagenConfig``, or a mapping such as the
    composed conf/datagen.yaml, merged onto the defaults); build the world and every pose.
    No rendering."""
    cfg = typed(DatagenConfig, cfg, "datagen")
    cfg.realism.name = realism_label(cfg.realism)
    _check_counts(cfg)
    _check_presets(cfg)
    ahrs.check_settings(cfg.realism.ahrs, "realism.ahrs")
    camera_effects.check_settings(cfg.realism, "realism")
    map_cfg = map_error.check_settings(cfg.realism.map, "realism.map")
    cal_cfg = calibration.check_settings(cfg.realism.calibration, "realism.calibration")
    camera = make_camera(cfg.camera)
    timing.check_settings(cfg.realism.timing, "realism.timing")
    trajectories.check_harder(cfg.realism.flight, "realism.flight")
    for name in {*cfg.render_flights, *val_flights(cfg)}:
        try:
            timing.check_flight(cfg.realism.timing, cfg.flights[name].fps, "realism.timing")
        except ValueError as e:
            raise ValueError(f"flights.{name}: {e}") from None
    optics.check_settings(cfg.realism, camera, {n: cfg.flights[n].fps for n in
                                                {*cfg.render_flights, *val_flights(cfg)}},
                          "realism")
    site = build_site(cfg.world)
    split_poses = {}
    for split in SPLITS:
        poses = poses_of_split(cfg, site, split)
        _check_inside(site, camera, poses, f"splits.{split}")
        split_poses[split] = poses
    flights = {}
    sets = [(n, n, "test") for n in cfg.render_flights] + [
        (f"{n}_val", n, "val") for n in val_flights(cfg)]
    for name, preset_name, flight_set in sets:
        flights[name] = prepare_flight(cfg, site, camera, name, preset_name)
        flights[name]["set"] = flight_set
    job = Job(cfg, Path(cfg.out_dir), site, camera, split_poses, flights)
    if calibration.is_active(cal_cfg):
        job.told_camera, job.calibration_error = calibration.told_camera(
            camera, cal_cfg, rng_for(cfg.seed, CALIBRATION_STREAM))
    if map_error.is_active(map_cfg):
        _make_map(job, map_cfg)
    return job


def _make_map(job: Job, c: MapErrorConfig) -> None:
    """The map the localizer reads and the built-in objects the flights show
    (``realism.map``, datagen/realism/map_error.py), onto ``job``."""
    t0 = time.perf_counter()
    site, cfg = job.site, job.cfg
    paths = [(f["groundtruth"] @ job.camera.body_from_cam)[:, :2, 3]
             for f in job.flights.values()]
    floor_z = float(site.building.info.get("floor_z", 0.0))
    w = site.world
    job.builtins = map_error.place_builtins(c, site.floor, paths, w.vertices, w.faces,
                                            w.face_class, floor_z,
                                            rng_for(cfg.seed, MAP_STREAM, 1))
    if len(job.builtins) < c.builtins:
        log.warning("realism.map.builtins: %d of %d built-in objects fit against a wall off "
                    "the flights' paths", len(job.builtins), c.builtins)
    job.map_world, record = map_error.make_map(site.world, c, float(cfg.world.crease_deg),
                                               rng_for(cfg.seed, MAP_STREAM, 0))
    for key, asked in (("missing_openings", c.missing_openings),
                       ("extra_openings", c.extra_openings)):
        if len(record[key]) < asked:
            log.warning("realism.map.%s: %d of %d made (no more %s)", key, len(record[key]),
                        asked, "doors or windows in the world" if key[0] == "m"
                        else "room on plain walls")
    record["builtins"] = [b.as_json() for b in job.builtins]
    job.map_error = record
    log.info("realism.map: the map made in %.2f s (%d walls, %d missing and %d extra "
             "openings, %d built-ins)", time.perf_counter() - t0, len(record["walls"]),
             len(record["missing_openings"]), len(record["extra_openings"]),
             len(job.builtins))


def prepare_flight(cfg: DatagenConfig, site: Site, camera: Camera, name: str,
                   preset_name: str) -> dict[str, Any]:
    """One flight's poses, odometry, clocks and image-effect series (``Job.flights``), drawn
    from the flight's own stream (``flight_stream(name)``)."""
    preset = cfg.flights[preset_name]
    stream, z_range = flight_stream(name), site.world.z_range
    r = rng_for(cfg.seed, stream, 0)
    n, fps = preset.num_frames, preset.fps
    route = trajectories.flight_route(preset, site.world.free, site.route,
                                      rng_for(cfg.seed, stream, 3), f"flights.{preset_name}")
    gt = trajectories.flight_trajectory(r, n, fps, route, site.world.free, z_range,
                                        preset.trajectory, cfg.realism.flight,
                                        rng_for(cfg.seed, stream, 8))
    tc = cfg.realism.timing
    capture = trajectories.timestamps(n, fps)
    odo_times, odo_truth, odo_fps, odo_cfg = capture, gt, fps, preset.odometry
    if tc.odometry_hz is not None and n > 1:
        odo_times = timing.odometry_times(n, fps, tc)
        odo_truth = timing.resample_poses(gt, fps, odo_times)
        odo_fps = float(tc.odometry_hz)
        odo_cfg = timing.odometry_at_rate(preset.odometry, fps, odo_fps)
    odo = trajectories.noisy_odometry(r, odo_truth, odo_fps, odo_cfg)
    odo = ahrs.ahrs_odometry(rng_for(cfg.seed, stream, 4), odo, odo_truth, odo_fps,
                             cfg.realism.ahrs, "realism.ahrs")
    odo, jumps = timing.odometry_jumps(rng_for(cfg.seed, stream, 9), odo_times, odo, tc)
    delivered, stamps = timing.frame_delivery(lambda i: rng_for(cfg.seed, stream, 10, i), n,
                                              fps, tc)
    _check_inside(site, camera, gt, f"flights.{name}")
    ev = camera_effects.exposure_ev(rng_for(cfg.seed, stream, 6), n, fps,
                                    cfg.realism.exposure, "realism.exposure")
    try:
        dropout = camera_effects.dropout_stretches(rng_for(cfg.seed, stream, 7), n, fps,
                                                   cfg.realism.dropout, "realism.dropout")
    except ValueError as e:
        raise ValueError(f"flights.{name}: {e}") from None
    return {"preset": preset, "preset_name": preset_name, "groundtruth": gt,
            "odometry": odo, "odometry_times": odo_times, "timestamps": capture,
            "delivered": delivered, "stamps": stamps, "jumps": jumps, "exposure_ev": ev,
            "dropout": dropout}


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
        "name": cfg.name,
        "classes": C.as_json(),
        "structural_classes": list(C.STRUCTURAL),
        "ignore_index": C.IGNORE,
        "camera": calibration.camera_json(cam, float(cfg.camera.hfov_deg)),
        "seed": cfg.seed,
        "config_hash": config_hash(cfg),
        "counts": {**split_counts(cfg),
                   "flights": {k: int(v["groundtruth"].shape[0]) for k, v in job.flights.items()}},
        "generator": content_config(cfg),
        "command": datagen_command(),
        "software": software_versions(variant),
    }
    if job.told_camera is not None:  # the localizer reads "camera"; the truth kept beside it
        told = job.told_camera
        meta["camera"] = calibration.camera_json(
            told, 2.0 * math.degrees(math.atan(told.width / (2.0 * told.K[0, 0]))))
        meta["camera_truth"] = calibration.camera_json(cam, float(cfg.camera.hfov_deg))
        meta["calibration_error"] = job.calibration_error
    save_world(out / "world", job.site.world if job.map_world is None else job.map_world)
    if job.map_world is not None:  # world/ is the map; the truth, with its built-ins, beside
        save_world(out / "world_truth", map_error.with_builtins(
            job.site.world, job.builtins, float(cfg.world.crease_deg)))
        meta["map_error"] = job.map_error
    write_plan(job.site.building, out / "world" / "plan.png", free=job.site.world.free,
               paths=[(f["groundtruth"] @ cam.body_from_cam)[:, :2, 3]
                      for f in job.flights.values()])
    for split, poses in job.split_poses.items():
        if len(poses):
            write_tum(out / split / "poses.txt", np.arange(len(poses), dtype=float), poses)
    for name, f in job.flights.items():
        d = out / "flights" / name
        write_tum(d / "groundtruth.txt", f["timestamps"], f["groundtruth"])
        write_tum(d / "odometry.txt", f["odometry_times"], f["odometry"])
        preset = f["preset"]
        info = {
            "name": name, "fps": float(preset.fps), "num_frames": int(len(f["timestamps"])),
            "distractors": preset.distractors, "preset": asdict(preset),
            "realism": asdict(cfg.realism), "seed_stream": flight_stream(name),
            "dropout": [d.as_json() for d in f["dropout"]],
            "set": f["set"], "preset_name": f["preset_name"], **flight_camera(job)}
        if timing.is_active(cfg.realism.timing):
            write_images_list(d / "images.txt", f["stamps"], f["delivered"])
            info["timing"] = {
                "images": "images.txt",
                "dropped": np.flatnonzero(~f["delivered"]).tolist(),
                "odometry_hz": cfg.realism.timing.odometry_hz,
                "odometry_samples": int(len(f["odometry_times"])),
                "jumps": f["jumps"]}
        atomic_write_json(d / "flight.json", info)
    atomic_write_json(out / "dataset.json", meta)


def flight_camera(job: Job) -> dict:
    """flight.json's ``camera`` when the flights' lens distorts: the calibration of the
    frames (K, size, plumb_bob coefficients; read by ``core.dataset.Flight.undistorter``);
    else {}."""
    d = optics.lens_coefficients(job.cfg.realism)
    if not np.any(d):
        return {}
    cam = job.camera
    return {"camera": {"K": cam.K.tolist(), "width": cam.width, "height": cam.height,
                       "distortion_model": "plumb_bob", "distortion": d.tolist()}}


def write_images_list(path: Path, stamps: np.ndarray, delivered: np.ndarray) -> None:
    """A flight's images.txt: one ``timestamp rgb/NNNNNN.png`` line per delivered frame (the
    layout of a folder recording's images.txt, docs/recording.md), timestamps in seconds."""
    lines = ["# timestamp (s) image: the frames delivered (realism.timing)"]
    lines += [f"{stamps[i]:.9f} rgb/{frame_name(int(i))}" for i in np.flatnonzero(delivered)]
    atomic_write_text(path, "\n".join(lines) + "\n")


def split_counts(cfg: DatagenConfig) -> dict[str, int]:
    """Images per split: ``splits``."""
    return {s: getattr(cfg.splits, s) for s in SPLITS}


def datagen_command() -> str | None:
    """``python -m datagen <overrides>`` of this Hydra run without the per-run keys (shard,
    num_shards, overwrite, progress); None outside Hydra."""
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
                         overwrite=job.cfg.overwrite,
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


def _slot_meshes(chunk_rng: np.random.Generator, presets: list[DistractorPreset]):
    """Distractor meshes for one scene load: enough slots for the busiest preset used."""
    n_clutter = max(p.clutter.max for p in presets)
    n_people = max(p.people.max for p in presets)
    kinds_from = next((p for p in presets if p.clutter.max), presets[0])
    kinds = sample_kinds(chunk_rng, n_clutter, kinds_from)
    clutter = [make_clutter_mesh(k, chunk_rng) for k in kinds]
    people = [make_person_mesh(chunk_rng) for _ in range(n_people)]
    return clutter, people


def _new_renderer(job: Job, textures, clutter, people, camera: Camera | None = None,
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
                renderer, loaded = _new_renderer(job, tex, clutter, people), c
            rng = rng_for(cfg.seed, stream, i, 2)
            preset = presets[rng.choice(len(presets), p=weights / weights.sum())]
            _dress(job, renderer, rng, preset, poses[i])
            _render_frame(job, renderer, d, i, poses[i], int(rng.integers(2**31)), pipe)
    return len(todo)


def _render_frame(job: Job, renderer, d: Path, i: int, body_pose: np.ndarray, seed: int,
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


def _render_optics_frame(job: Job, renderer, d: Path, i: int, fo: optics.FlightOptics,
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


def flight_effect(job: Job, name: str, i: int) -> Callable[[np.ndarray], np.ndarray] | None:
    """What the drone's camera does to frame i of a flight (``camera_effects.apply_effects``
    with the frame's own generator, ``rng_for(seed, flight stream, 5, i)``, its exposure
    offset and dropout kind); None when realism has no image effect."""
    cfg, f = job.cfg, job.flights[name]
    if not camera_effects.is_active(cfg.realism):
        return None
    return functools.partial(camera_effects.apply_effects,
                             rng=rng_for(cfg.seed, flight_stream(name), 5, i),
                             settings=cfg.realism, ev=float(f["exposure_ev"][i]),
                             dropout=camera_effects.dropout_kind(f["dropout"], i),
                             where="realism")


@dataclass
class FlightScene:
    """A flight's fixed dressing: drawn once, in this order, from the flight's generator.

    placed: (C, 3) clutter x, y, yaw (NaN: not placed); tracks: (P, N, 3) people x, y, yaw
    per frame; colours: (C + P, 3) linear RGB of the distractors.
    """

    clutter: list
    people: list
    textures: dict[str, np.ndarray]
    lights: np.ndarray
    colours: np.ndarray
    placed: np.ndarray
    tracks: np.ndarray
    gloss: tuple[float, float] | None = None  # the floor's (weight, alpha), drawn last


def flight_scene(job: Job, name: str) -> FlightScene:
    """One appearance, fixed clutter placed off the flight path, and people walking."""
    cfg, f = job.cfg, job.flights[name]
    gt, preset = f["groundtruth"], f["preset"]
    rng = rng_for(cfg.seed, flight_stream(name), 1)
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
    radii = np.array([footprint_radius(m) for m in clutter])
    floor = job.site.floor
    placed = place_objects(rng, radii, floor, keep, against_walls=dp.against_walls,
                                       wall_margin=dp.wall_margin)[0]
    ok = ~np.isnan(placed[:, 0])
    obstacles = np.concatenate([placed[ok, :2], radii[ok, None]], axis=1)
    if len(builtins):
        obstacles = np.concatenate([obstacles, builtins])
    tracks = person_tracks(
        rng, n_people, len(gt), preset.fps, floor, speed=tuple(dp.person_speed),
        radius=dp.person_radius, obstacles=obstacles, avoid=cam_xy,
        avoid_radius=dp.person_camera_keepout, max_turn_deg_s=dp.person_max_turn_deg_s,
        patience_s=dp.person_patience_s,
    ) if n_people else np.zeros((0, len(gt), 3))
    gloss = sample_floor_gloss(rng, cfg.appearance)
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
    renderer = _new_renderer(job, scene.textures, scene.clutter, scene.people,
                             None if fo is None else fo.render_camera, job.flight_render_scene)
    renderer.set_lights(scene.lights)
    if scene.gloss is not None:
        renderer.set_floor_gloss(*scene.gloss)
    with Pipeline() as pipe:
        for i in tqdm(todo, desc=f"flight {name}", unit="img", disable=not progress):
            renderer.set_objects(np.concatenate([scene.placed, scene.tracks[:, i]], axis=0),
                                 scene.colours)
            seeds = rng_for(cfg.seed, flight_stream(name), 2, i)
            if fo is None:
                _render_frame(job, renderer, d, i, gt[i], int(seeds.integers(2**31)), pipe,
                              flight_effect(job, name, i))
            else:
                _render_optics_frame(job, renderer, d, i, fo, seeds, pipe,
                                     flight_effect(job, name, i))
    return len(todo)


def run(cfg: DatagenConfig | Mapping, progress: bool | None = None) -> Path:
    """Render (this shard of) a dataset; returns the dataset directory.

    Args:
        cfg: the settings (``prepare``).
        progress: tqdm progress bars; None: the config's ``progress``.
    """
    from core.variant import choose_variant

    job = prepare(cfg)
    progress = job.cfg.progress if progress is None else progress
    variant = choose_variant(job.cfg.render.variant)
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
    shard = {"shard": cfg.shard, "num_shards": cfg.num_shards,
             "rendered": counts, "seconds": round(seconds, 3),
             "images_per_second": round(rendered / seconds, 3) if rendered else None}
    d = job.out / "stats"
    path = d / f"shard-{cfg.shard}-of-{cfg.num_shards}.json"
    if rendered or not path.is_file():  # a resumed run with nothing left keeps the timed one
        atomic_write_json(path, shard)
    runs = [json.loads(p.read_text()) for p in sorted(d.glob("shard-*.json"))]
    timed = [r for r in runs if r["images_per_second"]]
    r = cfg.render
    atomic_write_json(job.out / "stats.json", {
        "images_per_second": (round(sum(sum(x["rendered"].values()) for x in timed)
                                    / sum(x["seconds"] for x in timed), 3) if timed else None),
        "images_per_second_note": "labeled RGB+label images per second of one process, "
                                  "summed over the shards' last runs",
        "counts": split_counts(cfg)
        | {f"flight:{n}": len(f["timestamps"]) for n, f in job.flights.items()},
        "render": {"variant": variant, "width": job.camera.width, "height": job.camera.height,
                   "spp": r.spp, "max_depth": r.max_depth, "depth": r.depth},
        "shards": runs,
    })
