"""``python -m datagen.worlds --seed N [--size X Y] [--out DIR]``: draw a ``world=procedural``
floor (``datagen.worlds.procedural``) and write its plan, to look at a floor before rendering it."""

from __future__ import annotations

import numpy as np

from core.config import user_errors
from datagen.config import ProceduralWorldConfig
from datagen.worlds.procedural import build_floor


def main(argv: list[str] | None = None) -> int:
    """``python -m datagen.worlds --seed N [--size X Y] [--out DIR]``: draw a floor and
    write ``DIR/procedural_<seed>_plan.png`` (classes, free space, a planned route) and
    ``DIR/procedural_<seed>.json`` (the building's info); prints the plan's figures."""
    import argparse
    import json
    import sys
    from pathlib import Path

    from core.atomic import atomic_write_json
    from datagen.flights.routes import find_turns, plan_route, route_length
    from datagen.mesh.plan import write_plan
    from datagen.worlds.site import camera_free_space

    p = argparse.ArgumentParser(prog="python -m datagen.worlds",
                                description="Draw a world=procedural floor and write its plan.")
    p.add_argument("--seed", type=int, default=0, help="world.seed (default 0)")
    p.add_argument("--size", type=float, nargs=2, default=None, metavar=("X", "Y"),
                   help="world.size in m (default: ProceduralWorldConfig's)")
    p.add_argument("--out", default="outputs/procedural", help="output folder")
    args = p.parse_args(argv)
    spec = ProceduralWorldConfig(seed=args.seed)
    if args.size is not None:
        spec.size = list(args.size)
    try:
        b, _ = build_floor(spec)
        free = camera_free_space(b, spec, f"world=procedural seed {spec.seed}")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    route = plan_route(free, np.random.default_rng(spec.seed), {"min_turns": 1})  # else fitted
    out = Path(args.out)
    stem = f"procedural_{spec.seed}"
    plan = write_plan(b, out / f"{stem}_plan.png", free=free, paths=[route])
    info = {**b.info, "free_area_m2": round(free.area, 1),
            "route_m": round(route_length(route), 1), "route_turns": len(find_turns(route))}
    atomic_write_json(out / f"{stem}.json", info)
    print(json.dumps({k: info[k] for k in ("faces", "faces_per_class", "free_area_m2",
                                           "route_m", "route_turns")}))
    print(json.dumps(info["plan"]))
    print(f"plan: {plan}")
    return 0


if __name__ == "__main__":
    with user_errors():
        raise SystemExit(main())
