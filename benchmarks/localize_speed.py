"""Localizer speed per frame: filter update, whole frame, vectorized vs paper-faithful likelihood.

Usage::

    python -m datagen && python -m train          # a dataset and outputs/models/demo/segnet.onnx
    python benchmarks/localize_speed.py            # conf/localize.yaml defaults
    python benchmarks/localize_speed.py filter.num_particles=1000 --frames 100

Runs one tracking ``Localizer`` over the first ``--frames`` frames of a flight (default: paper) and
times each stage on its own, as the paper's Table 1 does:

- segmentation: ``segnet.onnx`` through onnxruntime (uint8 frame in, labels out);
- preprocessing: edge map (label boundaries or Canny + Hough) and the score maps;
- filter: motion + likelihood + resampling with ``filter.num_particles`` particles;
- frame: segmentation + preprocessing + filter (the cnn mode's whole frame, disk read excluded).

Then the paper-faithful likelihood (a Mitsuba render, contours and Hough lines per particle)
and the vectorized one score the same ``--pf-particles`` particles on ``--pf-frames`` frames,
and the ratio of their times is printed. Targets (issue "localize"): filter update with 500
particles <= 20 ms, whole frame <= 50 ms on a 2-core CPU (the paper: 177 ms with a GPU).

Side by side with another commit's code (issue 82: against 331b21c)::

    python benchmarks/localize_speed.py dataset=$PWD/outputs/datasets/demo --baseline 331b21c

``--baseline COMMIT`` checks the commit out in a temporary ``git worktree`` and runs this
benchmark and that commit's own ``benchmarks/localize_speed.py`` (same arguments and
overrides; give ``dataset=`` as an absolute path) alternately, ``--rounds`` times each, each in
a fresh process, so both meet the same machine load; it prints each stage's median over the
rounds' medians and the ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.poses import xyzyaw_from_pose  # noqa: E402
from localize.filter.projection import tilt_from_pose  # noqa: E402
from localize.frontend.segmenter import model_path  # noqa: E402
from localize.localizer import Localizer  # noqa: E402
from localize.offline.runner import prepare  # noqa: E402

TARGET_FILTER_MS = 20.0
TARGET_FRAME_MS = 50.0


def stats(ms: list[float]) -> dict:
    a = np.asarray(ms, dtype=np.float64)
    return {"median": float(np.median(a)), "mean": float(a.mean()), "p90": float(
        np.percentile(a, 90)), "max": float(a.max())}


def time_frames(loc: Localizer, flight, T: int) -> tuple[dict[str, list[float]], list]:
    """Step ``loc`` over the first T frames (read beforehand), the first one a warm-up.

    Returns:
        ms per frame of each stage (``segmentation``, ``preprocessing``, ``filter`` from the
        estimates; ``frame``: the whole step, front end included), the particles after each
        step (``particles``) and, per frame, its edge image, its tracking observation and tilt
        (for ``compare_likelihoods``).
    """
    steps = list(flight.steps(T, labels=True))  # read beforehand: decoding is not timed
    times = {k: [] for k in ("segmentation", "preprocessing", "filter", "frame", "particles")}
    seen = []
    for t, step in enumerate(steps):
        a = time.perf_counter()
        frame = loc.front_end.frame(step.image, step.labels)
        est = loc.step(frame, step.odometry_increment, step.attitude, step.timestamp)
        d = time.perf_counter()
        seen.append((frame.edge, frame.observation(loc.likelihood)[0],
                     tilt_from_pose(step.attitude)))
        if t == 0:
            continue  # warm-up (onnxruntime and numpy first calls)
        for k, v in est.timing_ms.items():
            times[k].append(v)
        times["frame"].append((d - a) * 1e3)
        times["particles"].append(est.num_particles)
    return times, seen


def compare_likelihoods(ctx, loc: Localizer, seen: list, truth: np.ndarray, n: int,
                        frames: int) -> tuple[list[float], list[float]]:
    """ms of the vectorized and the paper-faithful likelihood of the same ``n`` particles
    around the truth, on the first ``frames`` frames of ``seen`` (``time_frames``)."""
    from localize.paper.faithful import PaperFaithfulConfig, PaperFaithfulLikelihood

    pfl = PaperFaithfulLikelihood(ctx.world, ctx.camera, ctx.settings.likelihood,
                                  PaperFaithfulConfig())
    rng = np.random.default_rng(1)
    t_vec, t_pf = [], []
    for t in range(min(frames, len(seen))):
        edge, obs, tilt = seen[t]
        states = truth[t] + rng.normal(0, 1, (n, 4)) * [0.1, 0.1, 0.05, 0.05]
        pfl.log_likelihood(states[:2], edge, tilt)  # warm-up (kernel compilation)
        a = time.perf_counter()
        with threadpool_limits(limits=1, user_api="blas"):
            loc.likelihood.log_likelihood(states, obs, tilt)
        b = time.perf_counter()
        pfl.log_likelihood(states, edge, tilt)
        c = time.perf_counter()
        t_vec.append((b - a) * 1e3)
        t_pf.append((c - b) * 1e3)
    return t_vec, t_pf


def report(res: dict) -> None:
    """Print the table of ``main``'s results."""
    load0, load1 = res["load"]
    print(f"localize speed: flight {res['flight']}, mode {res['mode']}, {res['frames']} frames, "
          f"{res['particles']} particles (mean {res['mean_particles']:.0f}), SegNet "
          f"{res['segnet']}; load average {load0:.2f} -> {load1:.2f}")
    print(f"  {'stage':<16}{'median ms':>10}{'mean ms':>9}{'p90 ms':>9}{'max ms':>9}  target")
    for key, target in (("segmentation_ms", ""), ("preprocessing_ms", ""),
                        ("filter_ms", f"<= {TARGET_FILTER_MS:.0f}"),
                        ("frame_ms", f"<= {TARGET_FRAME_MS:.0f}")):
        s = res[key]
        ok = "" if not target else (" PASS" if s["mean"] <= float(target[3:]) else " MISS")
        print(f"  {key[:-3]:<16}{s['median']:>10.1f}{s['mean']:>9.1f}{s['p90']:>9.1f}"
              f"{s['max']:>9.1f}  {target}{ok}")
    lk = res["likelihood_ms"]
    print(f"  likelihood of {lk['particles']} particles: vectorized "
          f"{lk['vectorized']['median']:.2f} ms, paper-faithful "
          f"{lk['paper_faithful']['median']:.0f} ms -> {lk['speedup']:.0f}x faster")
    print(json.dumps(res))


STAGES = ("segmentation_ms", "preprocessing_ms", "filter_ms", "frame_ms")


def side_by_side(args: argparse.Namespace, argv: list[str]) -> int:
    """This code and ``args.baseline``'s, alternately (module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "baseline"
        subprocess.run(["git", "worktree", "add", "--detach", str(base), args.baseline],
                       check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        runs: dict[str, list[dict]] = {"this": [], args.baseline: []}
        try:
            for r in range(args.rounds):
                for label, code in (("this", ROOT), (args.baseline, base)):
                    out = subprocess.run(
                        [sys.executable, str(code / "benchmarks" / "localize_speed.py"), *argv],
                        check=True, cwd=code, capture_output=True, text=True,
                        env={**os.environ, "PYTHONPATH": str(code)}).stdout
                    runs[label].append(json.loads(out.strip().splitlines()[-1]))
                    print(f"round {r + 1} [{label}]: frame median "
                          f"{runs[label][-1]['frame_ms']['median']:.1f} ms", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=ROOT,
                           check=False)
    this, other = runs["this"], runs[args.baseline]
    print(f"localize speed, this code vs {args.baseline}: median of {args.rounds} rounds' "
          "medians, ms (this, baseline)")
    res = {}
    for k in STAGES:
        a = [float(np.median([x[k]["median"] for x in v])) for v in (this, other)]
        worst = [max(x[k]["max"] for x in v) for v in (this, other)]
        res[k] = {"this": a[0], "baseline": a[1], "ratio": a[1] / a[0] if a[0] else None,
                  "this_max": worst[0], "baseline_max": worst[1]}
        print(f"  {k[:-3]:<16}{a[0]:>8.1f}{a[1]:>8.1f}  baseline / this "
              f"x{res[k]['ratio'] or 0:.2f}; worst {worst[0]:.1f} / {worst[1]:.1f}")
    print(json.dumps({"baseline": args.baseline, "rounds": args.rounds, "stages": res}))
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("overrides", nargs="*", help="conf/localize.yaml overrides (key=value)")
    ap.add_argument("--flight", default="paper")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--mode", default="cnn", choices=["none", "cnn", "oracle"],
                    help="edge mode of the whole-frame timing (cnn includes the SegNet)")
    ap.add_argument("--pf-particles", type=int, default=100)
    ap.add_argument("--pf-frames", type=int, default=3)
    ap.add_argument("--baseline", default=None, metavar="COMMIT",
                    help="time this commit's code side by side (module docstring)")
    ap.add_argument("--rounds", type=int, default=3, help="alternate runs of each code")
    args = ap.parse_args()
    if args.baseline:
        argv, skip = [], False
        for a in sys.argv[1:]:  # the same arguments, without --baseline / --rounds
            if skip:
                skip = False
            elif a in ("--baseline", "--rounds"):
                skip = True
            elif not a.startswith(("--baseline=", "--rounds=")):
                argv.append(a)
        return side_by_side(args, argv)

    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose("localize", overrides=["progress=false", "name=speed",
                                             "out_root=outputs/benchmarks",
                                             f"modes=[{args.mode}]", *args.overrides])
    onnx_path = model_path(cfg.onnx_model, cfg.dataset)
    if args.mode == "cnn" and not onnx_path.is_file():
        print(f"{onnx_path} not found: train first (python -m train) or pass --mode oracle",
              file=sys.stderr)
        return 2
    ctx = prepare(cfg)
    flight = ctx.dataset.flight(args.flight)
    T = min(args.frames, len(flight.timestamps))
    loc = Localizer(ctx.world, ctx.camera, ctx.front_end(args.mode), ctx.settings,
                    np.random.default_rng(0), model=ctx.model_for(args.mode))
    loc.reset(flight.groundtruth[0])
    load0 = os.getloadavg()[0]
    times, seen = time_frames(loc, flight, T)
    truth = xyzyaw_from_pose(flight.groundtruth[:T])
    t_vec, t_pf = compare_likelihoods(ctx, loc, seen, truth, args.pf_particles, args.pf_frames)
    counts = times.pop("particles")
    res = {
        "flight": args.flight, "mode": args.mode, "frames": T - 1,
        "particles": ctx.settings.filter.num_particles,
        "mean_particles": float(np.mean(counts)),
        "segnet": None if ctx.segmenter is None else str(ctx.segmenter.path),
        **{f"{k}_ms": stats(v) for k, v in times.items()},
        "likelihood_ms": {"particles": args.pf_particles, "vectorized": stats(t_vec),
                          "paper_faithful": stats(t_pf),
                          "speedup": float(np.median(t_pf) / np.median(t_vec))},
        "load": [load0, os.getloadavg()[0]],
    }
    report(res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
