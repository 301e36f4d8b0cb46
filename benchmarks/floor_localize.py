"""Localization on a whole floor: `python -m localize` on a dataset, then its figures.

Usage::

    python benchmarks/floor_localize.py                       # hospital_eval, oracle, global
    python benchmarks/floor_localize.py --inits tracking --modes oracle none --seeds 0 1 2
    python benchmarks/floor_localize.py --max-frames 100 -- filter.global_max_particles=100000

Runs ``python -m localize`` (``--dataset``, default ``outputs/datasets/hospital_eval``: the AWS
hospital's two evaluation flights, ``python -m datagen world=file flights=floor``) into
``--out-root/--name`` with the given modes, inits, seeds and frames (a finished run is kept, so
a second call only prints), then prints per flight and mode: tracking mean / median / p95 error
and failure rate; global start: the frame each seed converged (error below 0.3 m from there
on) and the share converged within ``--within`` frames (target: >= 80 % within 60 frames);
timing: the filter's ms per frame while tracking, the global phase's ms per update and the
whole frame's ms, with the machine's load (``os.getloadavg``) as the timing's context.
Exits 0 with a message when the dataset is absent.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATASET = ROOT / "outputs" / "datasets" / "hospital_eval"
TARGET_WITHIN, TARGET_RATE = 60, 0.8


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", type=Path, default=DATASET)
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "benchmarks")
    ap.add_argument("--name", default="floor_localize")
    ap.add_argument("--flights", nargs="*", default=None, help="default: all")
    ap.add_argument("--modes", nargs="+", default=["oracle"])
    ap.add_argument("--inits", nargs="+", default=["global"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    ap.add_argument("--max-frames", type=int, default=100)
    ap.add_argument("--within", type=int, default=TARGET_WITHIN,
                    help="convergence target, frames")
    ap.add_argument("overrides", nargs="*", help="more `python -m localize` overrides")
    return ap.parse_args()


def localize_command(args: argparse.Namespace) -> list[str]:
    """The ``python -m localize`` command line of these arguments."""
    lst = lambda xs: "[" + ",".join(str(x) for x in xs) + "]"  # noqa: E731
    cmd = [sys.executable, "-m", "localize", f"dataset={args.dataset}",
           f"out_root={args.out_root}", f"name={args.name}", f"modes={lst(args.modes)}",
           f"inits={lst(args.inits)}", f"seeds={lst(args.seeds)}",
           f"max_frames={args.max_frames}", "progress=false",
           f"metrics.converge_within_frames={args.within}"]
    if args.flights:
        cmd.append(f"flight_names={lst(args.flights)}")
    return cmd + list(args.overrides)


def global_update_ms(run: dict) -> list[float]:
    """Filter ms of a global run's frames while the large set is kept (more particles than
    after thinning), the first frame left out (warm-up)."""
    ms, n = np.array(run["timing_ms"]["filter"]), np.array(run["num_particles"])
    big = np.flatnonzero(n > n[-1])
    return ms[big[1:]].tolist() if len(big) > 1 else []


def summary(out: Path) -> dict:
    """Per flight and mode: tracking and global figures and timings from ``out``'s metrics.json
    and run records."""
    m = json.loads((out / "metrics.json").read_text())
    runs = [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*/*.json"))]
    res = {}
    for flight, modes in m["flights"].items():
        for mode, e in modes.items():
            r = {}
            if "mean_position_error_m" in e:
                r["tracking"] = {k: e[k] for k in ("mean_position_error_m", "median_m", "p95_m",
                                                   "failure_rate", "per_seed_mean_m")}
            if "global" in e:
                g = e["global"]
                mine = [x for x in runs if (x["flight"], x["mode"], x["init"]) ==
                        (flight, mode, "global")]
                ms = np.concatenate([global_update_ms(x) for x in mine] or [[]])
                r["global"] = {**{k: g[k] for k in ("seeds", "convergence_frames",
                                                    "converged_within_rate",
                                                    "mean_error_after_convergence_m")},
                               "particles": int(max(max(x["num_particles"]) for x in mine)),
                               "update_ms_median": float(np.median(ms)) if len(ms) else None}
            res[f"{flight}/{mode}"] = r
    res["timing_ms_by_mode"] = {mode: {s: round(t["avg"], 1) for s, t in st.items()}
                                for mode, st in m.get("timing_ms_by_mode", {}).items()}
    return res


def main() -> int:
    args = parse_args()
    if not (args.dataset / "dataset.json").is_file():
        print(f"skipped: dataset {args.dataset} not found (render it with `python -m datagen "
              "world=file world.path=.../hospital.world flights=floor`)")
        return 0
    cmd = localize_command(args)
    print(" ".join(cmd[1:]), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)
    res = summary(args.out_root / args.name)
    res["load_avg"] = [round(v, 2) for v in os.getloadavg()]
    for key, r in res.items():
        if "global" in r:
            g = r["global"]
            ok = g["converged_within_rate"] >= TARGET_RATE
            print(f"{key}: global {g['particles']} particles, converged at frames "
                  f"{g['convergence_frames']}: {100 * g['converged_within_rate']:.0f}% within "
                  f"{args.within} (target >= {100 * TARGET_RATE:.0f}%: "
                  f"{'met' if ok else 'not met'}), {g['update_ms_median']} ms per update")
        if "tracking" in r:
            t = r["tracking"]
            print(f"{key}: tracking mean {t['mean_position_error_m']:.3f} m, p95 "
                  f"{t['p95_m']:.3f} m, failures {100 * t['failure_rate']:.1f}%")
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
