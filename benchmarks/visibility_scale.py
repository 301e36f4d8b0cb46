"""Localization at floor scale: visibility lists and filter updates on the AWS hospital floor.

Usage::

    python benchmarks/visibility_scale.py                  # ../shared/worlds/aws_hospital
    python benchmarks/visibility_scale.py --max-range 15 --cell-xy 0.3 --global-particles 0

Imports the hospital (``datagen.importers.load_building``), extracts its edges
(``datagen.mesh.edges.extract_edges``) and free space (``OccupancyMap.from_mesh``, the corridor
world's flyable band above the floor), samples the structural edges and builds their
visibility lists (``EdgeModel.build``, cached under ``--cache``). Then:

- tracking: a ``Localizer`` (mode ``none``: every structural edge is scored) with
  ``--particles`` particles started at the truth follows ``--frames`` poses along a planned
  route; each frame's edge image is the model itself seen from the truth (the structural
  edges resampled every 1 cm, ray-cast, projected);
- global: ``--global-particles`` particles spread over the whole floor, ms per update.

Prints the segments and samples kept, the visibility memory and build time, the ms of each
and a JSON line. Targets (issue 55): filter update <= 20 ms with 500 particles, visibility
<= 2 GB. Exits 0 with a message when the world is absent.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.dataset import Camera, World  # noqa: E402
from core.imaging.rays import RayCaster  # noqa: E402
from core.occupancy import OccupancyMap  # noqa: E402
from core.poses import odometry_increment, pose_from_xyzyaw  # noqa: E402
from localize.config import LocalizerConfig  # noqa: E402
from localize.edge_model import EdgeModel, scored_segments  # noqa: E402
from localize.filter.projection import (  # noqa: E402
    cam_from_world,
    camera_centres,
    pixel_index,
    projection_matrices,
    sample_segments,
)
from localize.frontend.edge_image import EdgeImage  # noqa: E402
from localize.frontend.front_end import EdgeFrame  # noqa: E402
from localize.localizer import Localizer  # noqa: E402

HOSPITAL = ROOT.parent / "shared" / "worlds" / "aws_hospital" / "worlds" / "hospital.world"
TARGET_FILTER_MS, TARGET_GB = 20.0, 2.0


def hospital_world(path: Path) -> tuple[World, OccupancyMap]:
    """The hospital as ``python -m datagen world=file`` builds it (``datagen.worlds.site``): its
    ``World`` and free space (0.1 m cells, 0.3 m margin, 0.5-2.2 m above the floor)."""
    from datagen.worlds.site import build_site

    world = build_site({"kind": "file", "path": str(path)}).world
    return world, world.free


def camera() -> Camera:
    """The datagen default camera (320 x 240, 70 deg, forward)."""
    from datagen.config import CameraConfig
    from datagen.job import make_camera

    return make_camera(CameraConfig())


def truth_states(occ: OccupancyMap, frames: int, step: float, z: float) -> np.ndarray:
    """(frames, 4) poses ``step`` m apart along a planned route, from its first third."""
    from datagen.flights.routes import plan_route, route_at, route_length

    route = plan_route(occ, np.random.default_rng(0))
    s = route_length(route) / 3 + step * np.arange(frames)
    xy, t = route_at(route, s)
    return np.c_[xy, np.full(frames, z), np.arctan2(t[:, 1], t[:, 0])]


def model_frame(state: np.ndarray, cam: Camera, fine: np.ndarray, caster: RayCaster,
                max_range: float) -> EdgeFrame:
    """The edge image of the model itself at ``state``: the points ``fine`` (P, 3) that a ray
    from the camera reaches, projected to pixels."""
    c = camera_centres(state[None], cam.body_from_cam)[0]
    near = fine[np.linalg.norm(fine - c, axis=1) <= max_range]
    seen = near[~caster.hidden(np.broadcast_to(c, near.shape).copy(), near, 0.02)]
    P = projection_matrices(cam_from_world(state[None], cam.body_from_cam), cam.K)
    ph = np.r_[seen.T, np.ones((1, len(seen)))].astype(np.float32)
    idx, valid, _ = pixel_index(P, ph, cam.width, cam.height)
    edges = np.zeros(cam.height * cam.width, bool)
    edges[idx[0][valid[0]]] = True
    edges = edges.reshape(cam.height, cam.width)
    return EdgeFrame(EdgeImage(edges, np.ones_like(edges)), None, {"segmentation": 0.0,
                                                               "edges": 0.0})


def time_tracking(loc: Localizer, truth: np.ndarray, frames: list[EdgeFrame]) -> tuple[list, list]:
    """Filter ms per frame (the first, a warm-up, left out) and position errors (m)."""
    poses = pose_from_xyzyaw(truth)
    loc.reset(truth[0])
    ms, err = [], []
    for t, frame in enumerate(frames):
        delta = odometry_increment(poses[t - 1], poses[t]) if t else None
        est = loc.step(frame, delta, None, 0.1 * t)
        err.append(float(np.linalg.norm(est.state[:2] - truth[t, :2])))
        if t:
            ms.append(est.timing_ms["filter"])
    return ms, err


def time_global(loc: Localizer, truth: np.ndarray, frames: list[EdgeFrame], n: int) -> list:
    """Filter ms of the first ``n`` updates of a global start."""
    poses = pose_from_xyzyaw(truth)
    loc.reset(None)
    ms = []
    for t, frame in enumerate(frames[:n]):
        delta = odometry_increment(poses[t - 1], poses[t]) if t else None
        ms.append(loc.step(frame, delta, None, 0.1 * t).timing_ms["filter"])
    return ms


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--world", type=Path, default=HOSPITAL)
    ap.add_argument("--cache", type=Path, default=ROOT / "outputs" / "benchmarks" / "visibility")
    ap.add_argument("--cell-xy", type=float, default=0.4)
    ap.add_argument("--cell-z", type=float, default=0.5)
    ap.add_argument("--max-range", type=float, default=10.0)
    ap.add_argument("--min-length", type=float, default=0.05)
    ap.add_argument("--particles", type=int, default=500)
    ap.add_argument("--frames", type=int, default=21)
    ap.add_argument("--global-particles", type=int, default=40000, help="0: skip the global "
                    "phase")
    ap.add_argument("--global-frames", type=int, default=3)
    return ap.parse_args()


def main() -> int:
    args = parse_args()
    if not args.world.is_file():
        print(f"skipped: {args.world} not found (the shared worlds are not here)")
        return 0
    t0 = time.perf_counter()
    world, occ = hospital_world(args.world)
    import_s = time.perf_counter() - t0
    base = LocalizerConfig()
    settings = replace(base, model_edges=replace(base.model_edges, min_length=args.min_length),
                       visibility=replace(base.visibility, cell_xy=args.cell_xy,
                                          cell_z=args.cell_z, max_range=args.max_range))
    settings = settings.with_particles(args.particles)
    keep = scored_segments(world, args.min_length)
    t0 = time.perf_counter()
    model = EdgeModel.build(world, settings, args.cache, free=occ)
    build_s = time.perf_counter() - t0
    vis = model.visibility
    counts = vis.counts()
    res = {"import_s": round(import_s, 1), "segments": len(world.segments),
           "segments_all_samples": int(len(sample_segments(world.segments, 0.1))),
           "segments_scored": int(keep.sum()), "samples": len(model.samples),
           "cells": len(counts), "visible_per_cell_mean": float(counts.mean()),
           "visible_per_cell_max": int(counts.max()), "visibility_gb": vis.nbytes / 1e9,
           "build_or_load_s": round(build_s, 1),
           "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}
    print(json.dumps(res))
    cam = camera()
    z = float(np.mean(world.z_range))
    truth = truth_states(occ, args.frames, 0.1, z)
    fine, _ = sample_segments(world.segments, 0.01).select(keep)
    caster = RayCaster(world.vertices, world.faces)
    frames = [model_frame(s, cam, fine.points.astype(np.float64), caster, args.max_range)
              for s in truth]
    loc = Localizer(world, cam, "none", settings, np.random.default_rng(0), model=model)
    ms, err = time_tracking(loc, truth, frames)
    res.update(filter_ms_median=float(np.median(ms)), filter_ms_mean=float(np.mean(ms)),
               final_error_m=err[-1], edge_pixels=int(frames[0].edge.edges.sum()))
    if args.global_particles > 0:
        gs = replace(settings, filter=replace(settings.filter,
                                              global_particles=args.global_particles))
        gloc = Localizer(world, cam, "none", gs, np.random.default_rng(0), model=model)
        res["global_ms"] = time_global(gloc, truth, frames, args.global_frames)
        res["global_particles"] = args.global_particles
    res["peak_rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(f"hospital: {res['segments']} segments -> {res['segments_scored']} scored, "
          f"{res['samples']} samples; visibility {res['cells']} cells, "
          f"{res['visibility_gb']:.2f} GB (<= {TARGET_GB}), {res['build_or_load_s']} s; "
          f"filter {res['filter_ms_median']:.1f} ms median with {args.particles} particles "
          f"(<= {TARGET_FILTER_MS:.0f}), final error {res['final_error_m']:.2f} m"
          + (f"; global {args.global_particles}: {res['global_ms']} ms" if "global_ms" in res
             else ""))
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
