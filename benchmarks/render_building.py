"""Rendering an imported building: scene build and load times, light count, images per second.

Renders N views of the AWS hospital (``../shared/worlds``; skipped where absent) from random
poses in its free space at the dataset's default camera and render settings (320x240, spp 1,
max_depth 3, denoiser on), redrawing the textures and lights before each view as the training
split does, and the default corridor the same way for comparison. The first view (kernel
compilation) is excluded. ``noise``: the mean absolute difference of two traces of one view
with different seeds over the mean radiance (path-tracer noise before the denoiser; more
lights a view cannot see make it larger, as Mitsuba picks an emitter uniformly; ``+near``:
the hospital again with ``Renderer(near_lights=True)``).

    .venv/bin/python benchmarks/render_building.py [--images 20] [--variant llvm_ad_rgb]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
HOSPITAL = ROOT.parent / "shared" / "worlds" / "aws_hospital" / "worlds" / "hospital.world"


def views(free, n: int, seed: int, height: float) -> list[np.ndarray]:
    """(4, 4) body poses at ``height`` m over random free cells, random yaw."""
    from core.poses import pose_from_xyz_rpy

    rng = np.random.default_rng(seed)
    xy = free.sample(rng, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    return [pose_from_xyz_rpy([x, y, height], [0.0, 0.0, a])[0]
            for (x, y), a in zip(xy, yaw, strict=True)]


def run(name: str, scene, poses: list[np.ndarray], cfg: dict, near_lights: bool = False
        ) -> None:
    """Load the scene, render the views; print the figures."""
    from datagen.appearance.lights import sample_lights
    from datagen.appearance.textures import sample_textures
    from datagen.job import make_camera
    from datagen.rendering.render import Renderer

    camera = make_camera(cfg["camera"])
    look, r = cfg["appearance"], cfg["render"]
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    renderer = Renderer(scene, camera, sample_textures(rng, None, look),
                        max_depth=r["max_depth"], near_lights=near_lights)
    load = time.perf_counter() - t
    stamps, means, noise = [], [], []
    for i, body in enumerate(poses):
        renderer.set_textures(sample_textures(rng, None, look))
        renderer.set_lights(sample_lights(rng, renderer.num_lights, look)[1])
        renderer.set_camera(body @ camera.body_from_cam)
        rgb, _, _ = renderer.render(r["spp"], i, r["exposure"], r["denoise_sigma_px"])
        stamps.append(time.perf_counter())
        means.append(rgb.mean())
    for body in poses[:4]:  # after the timing
        renderer.set_camera(body @ camera.body_from_cam)
        a, b = (renderer.trace(r["spp"], s, albedo=False).rgb for s in (1000, 1001))
        noise.append(np.abs(a - b).mean() / max((a + b).mean() / 2, 1e-9))
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    tris = sum(len(s.vertices) // 3 for s in scene.surfaces)
    print(f"{name:>9}: {renderer.num_lights:4d} lights, {tris:7d} triangles, Mitsuba scene "
          f"load {load:5.2f} s, {rate:5.2f} images/s, mean sRGB {np.mean(means):5.1f}, "
          f"noise {np.mean(noise):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=20)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--spacing", type=float, default=3.0, help="lattice light spacing, m")
    a = ap.parse_args()
    from core.config import compose_config
    from core.imaging.variant import choose_variant
    from core.occupancy import OccupancyMap
    from datagen.importers import load_building
    from datagen.worlds.corridor import build_world
    from datagen.worlds.scene import building_scene, corridor_scene

    variant = choose_variant(a.variant)
    cfg = compose_config("datagen")
    print(f"render throughput: {variant}, {cfg['camera']['width']}x{cfg['camera']['height']}, "
          f"spp {cfg['render']['spp']}, max_depth {cfg['render']['max_depth']}, "
          f"{a.images} views")
    model = build_world(cfg["world"])
    run("corridor", corridor_scene(model),
        views(model.world.free,
              a.images, 0, 1.3), cfg)
    if not HOSPITAL.is_file():
        print(f"{HOSPITAL} absent: hospital skipped")
        return
    t0 = time.perf_counter()
    b = load_building(HOSPITAL)
    t1 = time.perf_counter()
    free = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class, band=(0.5, 2.2),
                                  margin=0.3, cell=0.1)
    t2 = time.perf_counter()
    scene = building_scene(b, free, light_spacing=a.spacing)
    t3 = time.perf_counter()
    print(f"hospital: import {t1 - t0:.1f} s, free space {t2 - t1:.1f} s, building_scene "
          f"{t3 - t2:.1f} s")
    poses = views(free, a.images, 0, b.info["floor_z"] + 1.3)
    run("hospital", scene, poses, cfg)
    run("+near", scene, poses, cfg, near_lights=True)


if __name__ == "__main__":
    main()
