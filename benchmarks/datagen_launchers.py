"""Wall time of a small dataset: one process vs 2 shards through Hydra's launchers.

Runs `python -m datagen` of the tests' tiny dataset (core/config.py TINY_DATAGEN: 128x96,
20 images and three 30-frame flights) as a user does, from the repository's root, once as one
process and once per launcher as `-m shard=0,1 num_shards=2 hydra/launcher=<launcher>`, each
into a new folder, and prints the wall time of each command (start-up, Ray's cluster start
and stop, the shards' scene set-up and rendering) and the load average before it.

    .venv/bin/python benchmarks/datagen_launchers.py [--repeat 2] [--launchers joblib ray ...]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.config import TINY_DATAGEN  # noqa: E402


def run(args: list[str], out: Path) -> float:
    """Seconds of wall time of ``python -m datagen <args>`` writing to ``out``."""
    cmd = [sys.executable, "-m", "datagen", *args, *TINY_DATAGEN, f"out_dir={out}",
           "progress=false", f"hydra.run.dir={out}-hydra", f"hydra.sweep.dir={out}-hydra"]
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    t = time.perf_counter()
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{res.stderr[-3000:]}")
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--launchers", nargs="+", default=["joblib", "ray", "submitit_local"])
    a = ap.parse_args()
    runs = {"one process": []} | {f"2 shards, {k}": ["-m", "shard=0,1", "num_shards=2",
                                                      f"hydra/launcher={k}"]
                                  for k in a.launchers}
    print(f"tiny dataset (110 frames at 128x96), {os.cpu_count()} CPUs, wall seconds")
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.repeat):
            for i, (name, args) in enumerate(runs.items()):
                load = os.getloadavg()[0]
                dt = run(args, Path(tmp) / f"r{r}-{i}")
                print(f"  {name:<26} {dt:6.1f} s   (load before: {load:.1f})", flush=True)


if __name__ == "__main__":
    main()
