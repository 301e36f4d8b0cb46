"""The shape of the flights: statistics of many flights of each preset, without rendering.

For the corridor (the composed datagen config's world and flight presets, along its own
route), or for an imported building (``--world FILE``: its free space as
``python -m datagen.importers`` computes it, and a route planned per flight as
``flights.<name>.route: auto`` does), prints per preset the mean and 5-95 % range over
``--flights`` flights of: the distance flown along the route, the mean speed, the start
offset, the sway across the route, the height, the yaw about the direction of travel, the
tilt, and (``--world``) the turns of >= 60 deg flown.

    python benchmarks/flight_shape.py                                   # the corridor
    python benchmarks/flight_shape.py --world ../shared/worlds/aws_hospital/worlds/hospital.world \\
        --frames 1150 --speed 0.35 0.45 --flights 20
"""

from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.config import typed  # noqa: E402
from core.occupancy import OccupancyMap  # noqa: E402
from core.poses import xyzyaw_from_pose  # noqa: E402
from datagen.config import DatagenConfig, FlightConfig  # noqa: E402
from datagen.flights import trajectories as TR  # noqa: E402
from datagen.flights.routes import find_turns, route_at, route_length  # noqa: E402

NAMES = ("flown m", "mean speed m/s", "start m", "mean |across| m", "across std m",
         "height m", "height ptp m", "yaw dev max deg", "yaw dev rms deg", "tilt max deg",
         "turns >= 60 deg")


def flight_figures(route: np.ndarray, poses: np.ndarray, fps: float) -> list[float]:
    """The figures of ``NAMES`` of one flight (N, 4, 4) along its route (K, 2)."""
    state = xyzyaw_from_pose(poses)
    grid = np.arange(0.0, route_length(route), 0.02)
    dense = route_at(route, grid)[0]
    s = grid[np.argmin(np.linalg.norm(state[:, None, :2] - dense[None], axis=-1), axis=1)]
    centre, tangent = route_at(route, s)
    across = np.einsum("nc,nc->n", state[:, :2] - centre,
                       np.stack([tangent[:, 1], -tangent[:, 0]], 1))
    travel = np.arctan2(tangent[:, 1], tangent[:, 0]) + (np.pi if s[-1] < s[0] else 0.0)
    dev = np.rad2deg(np.abs(np.angle(np.exp(1j * (state[:, 3] - travel)))))
    rpy = np.rad2deg(np.abs(np.stack([np.arctan2(poses[:, 2, 1], poses[:, 2, 2]),
                                      -np.arcsin(np.clip(poses[:, 2, 0], -1, 1))], 1)))
    turns = find_turns(route)
    flown = ((turns[:, 0] > s.min()) & (turns[:, 0] < s.max())).sum()
    step = np.linalg.norm(np.diff(state[:, :2], axis=0), axis=1)
    start = min(s[0], route_length(route) - s[0])
    return [s.max() - s.min(), step.mean() * fps, start, np.abs(across).mean(), across.std(),
            state[:, 2].mean(), np.ptp(state[:, 2]), dev.max(), np.sqrt((dev**2).mean()),
            rpy.max(), flown]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=300, help="flights per preset")
    ap.add_argument("--world", type=Path, default=None, help="an imported building file")
    ap.add_argument("--frames", type=int, default=None, help="num_frames of every preset")
    ap.add_argument("--speed", type=float, nargs=2, default=None, help="speed [min, max]")
    a = ap.parse_args()
    from core.config import compose_config

    cfg = typed(DatagenConfig, compose_config("datagen"), "datagen")
    from datagen.worlds.site import build_site

    if a.world is not None:
        logging.disable(logging.WARNING)
    site = build_site(cfg.world if a.world is None else {"kind": "file", "path": str(a.world)})
    free, own = site.world.free, site.route
    for name, preset in cfg.flights.items():
        preset = tune(preset, a.frames, a.speed)
        rows = []
        for seed in range(a.flights):
            route = TR.flight_route(preset, free, own, np.random.default_rng([seed, 1]),
                                    f"flights.{name}")
            poses = TR.flight_trajectory(np.random.default_rng(seed), preset.num_frames,
                                         preset.fps, route, free, np.array(free.band),
                                         preset.trajectory)
            rows.append(flight_figures(route, poses, preset.fps))
        report(name, np.array(rows), free)


def tune(preset: FlightConfig, frames: int | None, speed: list[float] | None) -> FlightConfig:
    """The preset with ``--frames`` / ``--speed`` where given."""
    if frames is not None:
        preset = replace(preset, num_frames=frames)
    if speed is not None:
        preset = replace(preset, trajectory=replace(preset.trajectory, speed=list(speed)))
    return preset


def report(name: str, rows: np.ndarray, free: OccupancyMap) -> None:
    print(f"{name}: {len(rows)} flights, mean [5 %, 95 %] (map {free.shape}, cell "
          f"{free.cell} m)")
    for i, key in enumerate(NAMES):
        v = rows[:, i]
        print(f"  {key:18s} {v.mean():8.3f} [{np.percentile(v, 5):8.3f}, "
              f"{np.percentile(v, 95):8.3f}]")


if __name__ == "__main__":
    main()
