"""A datagen job: its settings checked, its random streams, poses and flights prepared
(``prepare``); rendering it is ``datagen.generate.run``.

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

import hashlib
import json
import logging
import time
import zlib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from core.config import as_config, typed
from core.dataset import SPLITS, Camera, World
from core.imaging import camera_effects
from core.imaging.camera import forward_mount, intrinsics
from core.imaging.realism import MapErrorConfig, realism_label
from core.outputs import FolderPolicy
from datagen.config import CameraConfig, DatagenConfig
from datagen.distractors.presets import check_preset
from datagen.flights import training_views, trajectories
from datagen.realism import ahrs, builtin_objects, calibration, map_error, optics, timing
from datagen.worlds.scene import Scene
from datagen.worlds.site import Site, build_site

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


def flight_stream(name: str, seed: int = 0) -> int:
    """The random stream of flight ``name`` drawn with its preset's ``seed`` (0: the name's own
    stream; s: that of ``<name>/seed<s>``, another flight of the same preset)."""
    key = name if seed == 0 else f"{name}/seed{seed}"
    return 1000 + zlib.crc32(key.encode()) % 1_000_000


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
    xyz = np.asarray(cam_cfg.mount.xyz, dtype=np.float64)
    if np.linalg.norm(xyz) > 0.5:
        raise ValueError(f"camera.mount.xyz {xyz.tolist()} puts the camera more than 0.5 m from "
                         "the body centre; give it in metres in the body frame")
    body_from_cam = forward_mount(xyz, cam_cfg.mount.pitch_deg)
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
    builtins: list[builtin_objects.Builtin] = field(default_factory=list)  # unmodelled
    # objects in the flights' renders (realism.map.builtins)

    @property
    def flight_render_scene(self) -> Scene:
        """What the flights' renders draw: the site's scene and the built-in objects."""
        scene = self.site.scene
        if not self.builtins:
            return scene
        return Scene(scene.surfaces + builtin_objects.builtin_surfaces(self.builtins),
                     scene.lights, scene.images)


def val_flights(cfg: DatagenConfig) -> list[str]:
    """The presets rendered as validation flights (``val_flights``; None: ``render_flights``)."""
    return list(cfg.render_flights if cfg.val_flights is None else cfg.val_flights)


def needs_edges(cfg: DatagenConfig, map_active: bool) -> bool:
    """Whether the dataset's world needs its model edges: it has flights (test or
    validation; the localizer reads world/edges.npz) or a map error (``realism.map`` edits
    them). A training-only dataset (the generalist's floors) skips them: the SegNet trains
    on images and labels, and a procedural floor's edges are most of its build
    (``datagen.worlds.site.build_site``)."""
    return bool(cfg.render_flights or val_flights(cfg) or map_active)


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
    if not 0.0 <= cfg.training.handheld <= 1.0:
        raise ValueError(f"training.handheld={cfg.training.handheld} must be a share in [0, 1]")
    z = cfg.training.z_range
    if z is not None and (len(z) != 2 or not z[0] < z[1]):
        raise ValueError(f"training.z_range={list(z)} must be [min, max] m above the floor "
                         "with min < max (null: world.z_range)")


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


#: draws of a training pose whose camera would leave the free space (the body under a high
#: ceiling, the camera a few centimetres ahead under a door's head) before the last is kept
REDRAWS = 10


def outside_by(site: Site, camera: Camera, poses: np.ndarray) -> np.ndarray:
    """(N,) m by which each camera centre of ``poses`` (N, 4, 4) lies outside the free space:
    its cells and its band of heights, or up to ``site.camera_top`` above the band (0 inside)."""
    free = site.world.free
    centres = (poses @ camera.body_from_cam)[:, :3, 3]
    top = np.full(len(centres), free.band[1])
    high = centres[:, 2] > free.band[1]
    if high.any():
        top[high] = site.camera_top(centres[high, :2])
    return np.maximum(free.outside_distance(centres[:, :2]),
                      np.maximum(free.band[0] - centres[:, 2], centres[:, 2] - top))


def check_inside(site: Site, camera: Camera, poses: np.ndarray, where: str) -> None:
    """Every camera centre must lie within the camera margin of the free space
    (``outside_by``): nearer to no surface than the margin allows."""
    free = site.world.free
    off = outside_by(site, camera, poses)
    bad = np.flatnonzero(off >= free.margin)
    if len(bad):
        i = int(bad[0])
        centre = (poses[i] @ camera.body_from_cam)[:3, 3]
        raise ValueError(f"{where}: camera {i} at {np.round(centre, 3).tolist()} is "
                         f"{off[i]:.2f} m outside the free space (more than its margin "
                         f"{free.margin} m); check world.camera_margin, world.z_range, "
                         "camera.mount and the flight preset's trajectory")


def poses_of_split(cfg: DatagenConfig, site: Site, camera: Camera, split: str) -> np.ndarray:
    """(N, 4, 4) body poses of a split's frames; frame i's depends only on (seed, split, i).

    A share ``training.flight_views`` of them (decided per frame by its own generator) are
    posed as the flights fly (``trajectories.sample_flight_views``, along each preset's route,
    resolved once per split), the rest spread over the free space
    (``training_views.sample_training_poses``; heights ``training.z_range`` where the ceiling
    leaves room, ``Site.camera_top``; a pose whose camera would leave the free space is drawn
    again, from its frame's next generator, up to ``REDRAWS`` times).
    """
    tr, seed, free = cfg.training, cfg.seed, site.world.free
    z_range = np.asarray(free.band)
    spread, top = z_range, None
    if tr.z_range is not None:
        spread = float(site.building.info.get("floor_z", 0.0)) + np.asarray(tr.z_range, float)
        if spread[0] < z_range[0] - 1e-9:
            raise ValueError(f"training.z_range {list(tr.z_range)} starts below world.z_range "
                             f"(the free space is known from {z_range[0]:.2f} m up); raise its "
                             "min")
        reach = float(np.linalg.norm(cfg.camera.mount.xyz))  # the camera, off the body

        def top(xy: np.ndarray) -> np.ndarray:
            return site.camera_top(xy) - reach
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
            continue
        for k in range(REDRAWS):  # a draw whose camera leaves the free space: the next
            poses[i] = training_views.sample_training_poses(
                rng_for(seed, stream, i, 0, *([k] if k else [])), 1, free, spread,
                tr.max_roll_pitch_deg, tr.yaw_along_corridor, tr.yaw_spread_deg,
                tr.min_view_m, handheld=tr.handheld,
                handheld_deg=(tr.handheld_pitch_deg, tr.handheld_roll_deg), top=top)[0]
            if outside_by(site, camera, poses[i][None])[0] < free.margin:
                break
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
    # model edges only where a flight is localized against them (training-only: none)
    site = build_site(cfg.world, edges=needs_edges(cfg, map_error.is_active(map_cfg)))
    split_poses = {}
    for split in SPLITS:
        poses = poses_of_split(cfg, site, camera, split)
        check_inside(site, camera, poses, f"splits.{split}")
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
    job.builtins = builtin_objects.place_builtins(c, site.floor, paths, w.vertices, w.faces,
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
    from the flight's own stream (``flight_stream(name, preset.seed)``)."""
    preset = cfg.flights[preset_name]
    stream, z_range = flight_stream(name, preset.seed), site.world.z_range
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
    check_inside(site, camera, gt, f"flights.{name}")
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
