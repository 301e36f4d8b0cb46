"""What the flights' optics (realism.lens, .motion_blur, .rolling_shutter;
datagen/realism/optics.py) cost in render time, and what they look like.

Usage::

    python benchmarks/flight_optics.py                       # 320x240, a 20-frame paper flight
    python benchmarks/flight_optics.py --frames 40 --image docs/img/flight_optics.png

Renders the same short flight (no training images) once per setting: ideal, the lens alone,
motion blur alone, the rolling shutter alone, blur and rolling shutter, and all three (the
realism=real values), each into its own dataset under ``--out``, and prints seconds per frame
(datagen's stats.json: tracing, developing and writing) with the mean number of sub-frames
per frame. With ``--image``, writes a side-by-side PNG of one frame: the pinhole render and
the same frame through all three.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

LENS = ["realism.lens.k1=-0.28340811", "realism.lens.k2=0.07395907",
        "realism.lens.p1=0.00019359", "realism.lens.p2=0.0000176187114"]
BLUR = ["realism.motion_blur.exposure_s=0.01"]
ROLLING = ["realism.rolling_shutter.readout_s=0.02"]
SETTINGS = {"ideal": [], "lens": LENS, "blur": BLUR, "rolling": ROLLING,
            "blur+rolling": BLUR + ROLLING, "all": LENS + BLUR + ROLLING}


def main(argv: list[str] | None = None) -> dict[str, float]:
    import datagen  # noqa: F401  (registers the config schema)
    from core.config import compose_config
    from datagen import generate as gen
    from datagen.job import prepare
    from datagen.realism import optics

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=20)
    p.add_argument("--width", type=int, default=320)
    p.add_argument("--height", type=int, default=240)
    p.add_argument("--flight", default="paper")
    p.add_argument("--out", type=Path, default=None, help="datasets here (default: a temp dir)")
    p.add_argument("--image", type=Path, default=None, help="before/after PNG of one frame")
    a = p.parse_args(argv)
    out = a.out or Path(tempfile.mkdtemp(prefix="flight_optics_"))
    base = [f"camera.width={a.width}", f"camera.height={a.height}", "splits.train=0",
            "splits.val=0", "splits.test=0", f"render_flights=[{a.flight}]",
            f"flights.{a.flight}.num_frames={a.frames}", "overwrite=true"]
    per_frame = {}
    for name, extra in SETTINGS.items():
        cfg = compose_config("datagen", [*base, *extra, f"out_dir={out / name}"])
        gen.run(cfg, progress=False)
        stats = json.loads((out / name / "stats.json").read_text())
        per_frame[name] = 1.0 / stats["images_per_second"]
        job = prepare(cfg)
        subs, size = 1.0, (job.camera.width, job.camera.height)
        if optics.is_active(job.cfg.realism):
            fo = optics.FlightOptics.build(job.cfg.realism, job.camera,
                                           job.flights[a.flight]["groundtruth"],
                                           job.cfg.flights[a.flight].fps)
            subs = float(np.mean([len(fo.subframes(i)[0].times) for i in range(a.frames)]))
            size = (fo.render_camera.width, fo.render_camera.height)
        print(f"{name:>13}: {per_frame[name]:.3f} s/frame "
              f"({per_frame[name] / per_frame['ideal']:.1f}x ideal), {subs:.1f} sub-frames of "
              f"{size[0]}x{size[1]} per frame", flush=True)
    if a.image:
        import cv2

        from core.atomic import read_png

        i = a.frames // 2
        frame = f"flights/{a.flight}/rgb/{i:06d}.png"
        pair = np.hstack([read_png(out / "ideal" / frame), np.full((a.height, 4, 3), 255,
                                                                     np.uint8),
                          read_png(out / "all" / frame)])
        a.image.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(a.image), pair[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
        print(f"wrote {a.image}")
    if a.out is None:
        shutil.rmtree(out)
    return per_frame


if __name__ == "__main__":
    main()
