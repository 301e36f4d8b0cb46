"""Writing a dataset: dataset.json and its claim on the folder, a frame's files, a flight's
image list, stats.json (the format ``core.dataset`` reads)."""

from __future__ import annotations

import json
import logging
import math
import platform
from dataclasses import asdict
from pathlib import Path

import numpy as np

from core import classes as C
from core.atomic import (
    atomic_write_json,
    atomic_write_text,
    png_complete,
    remove_temp_files,
    write_png,
)
from core.dataset import SCHEMA_VERSION, SPLITS, frame_name
from core.outputs import Claim, claim_output
from core.poses import write_tum
from datagen.config import DatagenConfig
from datagen.job import (
    DATASET_POLICY,
    NON_CONTENT_KEYS,
    Job,
    config_hash,
    content_config,
    flight_stream,
)
from datagen.mesh.plan import write_plan
from datagen.realism import builtin_objects, calibration, optics, timing

log = logging.getLogger(__name__)


def software_versions(variant: str) -> dict[str, str]:
    import drjit
    import mitsuba
    import trimesh

    return {"python": platform.python_version(), "numpy": np.__version__,
            "mitsuba": mitsuba.__version__, "drjit": drjit.__version__,
            "trimesh": trimesh.__version__, "mitsuba_variant": variant}


def write_metadata(job: Job, variant: str) -> None:
    """dataset.json, world/ and the pose files (identical bytes from every shard)."""
    from datagen.worlds.save import save_world

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
        save_world(out / "world_truth", builtin_objects.with_builtins(
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
            "realism": asdict(cfg.realism), "seed_stream": flight_stream(name, preset.seed),
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
