"""Labeled 320x240 images per second at the default render quality, llvm and scalar.

Also the process's CPU seconds per image (all its threads): on a shared machine, less moved
by the other jobs than the wall time.

Renders N training images (path-traced RGB + denoiser + label pass + PNG writes, i.e. what
`python -m datagen` does per frame) into a temporary dataset, once per Mitsuba variant, each
in a fresh process (a process can only hold one variant). The first image of each run (scene
load and kernel compilation) is excluded. Config overrides (before the options) render another
config, e.g. a floor of the generalist's:

    .venv/bin/python benchmarks/datagen_throughput.py [overrides ...] [--images 40] \
        [--variants ...]
    .venv/bin/python benchmarks/datagen_throughput.py datagen_experiment=generalist_floors \
        world.seed=0 --variants llvm_ad_rgb
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, time
sys.path.insert(0, {root!r})
from core.config import compose_config
import datagen.dataset_writer as writer
import datagen.job as datagen_job
import datagen.rendering.frame as render_frame
import datagen.rendering.split as render_split
from core.imaging.variant import choose_variant
variant = choose_variant({variant!r})
n = {images}
cfg = compose_config("datagen", ["splits.train=%d" % (n + 1), "splits.val=0", "splits.test=0",
                                 "render_flights=[]", "training.chunk=%d" % (n + 1),
                                 "out_dir={out}", "render.variant=" + {variant!r}] + {overrides!r})
job = datagen_job.prepare(cfg)
writer.write_metadata(job, variant)
times, cpu = [], []
real = render_frame.write_frame
def timed(*a, **k):
    real(*a, **k)
    times.append(time.perf_counter())
    cpu.append(time.process_time())
render_frame.write_frame = timed
render_split.render_split(job, "train", progress=False)
dt = times[-1] - times[0]
print(json.dumps({{"variant": variant, "images": n, "seconds": dt, "images_per_second": n / dt,
                  "cpu_seconds": cpu[-1] - cpu[0]}}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=40)
    ap.add_argument("--variants", nargs="+", default=["llvm_ad_rgb", "scalar_rgb"])
    ap.add_argument("overrides", nargs="*", help="datagen config overrides (before the options)")
    a = ap.parse_args()
    print(f"datagen throughput: 320x240, default render config, {a.images} images per variant"
          + (f", {' '.join(a.overrides)}" if a.overrides else ""))
    for variant in a.variants:
        with tempfile.TemporaryDirectory() as tmp:
            code = CHILD.format(root=str(ROOT), variant=variant, images=a.images, out=tmp,
                                overrides=a.overrides)
            t = time.perf_counter()
            res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
            if res.returncode != 0:
                print(f"{variant:>12}: failed\n{res.stderr[-2000:]}")
                continue
            r = json.loads(res.stdout.strip().splitlines()[-1])
            print(f"{r['variant']:>12}: {r['images_per_second']:.2f} labeled images/s "
                  f"({r['seconds'] / r['images'] * 1000:.0f} ms/image, "
                  f"{r['cpu_seconds'] / r['images'] * 1000:.0f} CPU ms/image; "
                  f"process {time.perf_counter() - t:.0f} s incl. start-up)")


if __name__ == "__main__":
    main()
