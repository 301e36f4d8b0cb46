"""The paper's likelihood against the vectorized one: accuracy and filter time per frame.

Usage::

    python benchmarks/paper_faithful.py                     # demo dataset, flight paper, oracle
    python benchmarks/paper_faithful.py --mode cnn --frames 30 --particles 100 --seeds 0 1
    python benchmarks/paper_faithful.py -- filter.likelihood.sigma=0.3   # localize overrides

Tracks the first ``--frames`` frames of ``--flight`` (tracking start, ``--particles``
particles, one run per seed) twice through the runner's pass (``localize.offline.runner.run_pass``):
with the vectorized edge likelihood and with the paper-faithful one
(``localize.paper.faithful``: a Mitsuba render, its contours and Hough lines per particle, a
Python loop over particles) as the likelihood override. Both share the frames, the edge images,
the particles' start and the filter's settings (conf/localize.yaml with the given overrides).
Prints each one's mean position error and filter ms per frame and the speed-up of the
vectorized likelihood; writes the figures to ``<out-root>/<name>/paper_faithful.json`` (the
runs beside it, under ``runs/``; a finished run is kept). Exits 0 with a message when the
dataset is absent.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.atomic import atomic_write_json  # noqa: E402
from core.outputs import releases_claims  # noqa: E402
from localize.config import HoughConfig  # noqa: E402
from localize.offline.metrics import error_stats, timing_stats  # noqa: E402
from localize.offline.runner import RunSpec, check_resume, load_runs, prepare, run_pass  # noqa: E402
from localize.paper.faithful import PaperFaithfulConfig, PaperFaithfulLikelihood  # noqa: E402
from localize.paper.render import centred  # noqa: E402

DATASET = ROOT / "outputs" / "datasets" / "demo"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", type=Path, default=DATASET)
    ap.add_argument("--onnx-model", default="auto", help="localize's onnx_model (mode cnn)")
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "benchmarks")
    ap.add_argument("--name", default="paper_faithful")
    ap.add_argument("--flight", default="paper")
    ap.add_argument("--mode", default="oracle", choices=["none", "cnn", "oracle"],
                    help="edge mode of both likelihoods")
    ap.add_argument("--frames", type=int, default=30, help="the first N frames")
    ap.add_argument("--particles", type=int, default=100, help="both likelihoods")
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--hough", nargs=3, type=int, default=None,
                    metavar=("THRESHOLD", "MIN_LENGTH", "MAX_GAP"),
                    help="Hough segments of the rendered contours (votes, pixels, pixels; "
                    "default: PaperFaithfulConfig')")
    ap.add_argument("overrides", nargs="*", help="more `python -m localize` overrides")
    return ap.parse_args(argv)


def comparison_config(args: argparse.Namespace) -> DictConfig:
    """conf/localize.yaml composed for the comparison's runs (``args`` from ``parse_args``)."""
    lst = "[" + ",".join(str(s) for s in args.seeds) + "]"
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="localize", overrides=[
            f"dataset={args.dataset}", f"onnx_model={args.onnx_model}",
            f"out_root={args.out_root}", f"name={args.name}", f"modes=[{args.mode}]",
            "inits=[tracking]", f"seeds={lst}", f"flight_names=[{args.flight}]",
            f"max_frames={args.frames}", "progress=false", *args.overrides])


def likelihood_settings(args: argparse.Namespace) -> PaperFaithfulConfig:
    """How the paper-faithful likelihood renders and searches: its defaults, with ``--hough``
    where given."""
    pf = PaperFaithfulConfig()
    return pf if args.hough is None else replace(pf, hough=HoughConfig(*args.hough))


def run_specs(flight: str, mode: str, seeds: list[int], n: int) -> dict[str, list[RunSpec]]:
    """The runs of each likelihood (``vectorized_n<n>``, ``paper_faithful_n<n>``): one per
    seed, tracking start."""
    return {kind: [RunSpec(flight, mode, "tracking", int(s), f"{kind}_n{n}") for s in seeds]
            for kind in ("vectorized", "paper_faithful")}


@releases_claims
def run_comparison(cfg: DictConfig, n: int, pf_settings: PaperFaithfulConfig) -> Path:
    """Both likelihoods' runs of ``cfg``'s flight and mode with ``n`` particles (finished
    runs are kept unless ``overwrite``).

    Returns:
        The output folder (its ``runs/`` hold the run records).

    Raises:
        ValueError: the camera's principal point is off its image's centre (the renderer
            needs a centred K).
    """
    ctx = prepare(cfg)
    if not centred(ctx.camera):
        raise ValueError(f"{cfg.dataset}: the camera's principal point is off its image's "
                         "centre (a calibrated K); the paper-faithful renderer needs a centred "
                         "one: run the comparison on a rendered dataset")
    check_resume(ctx.out_dir, cfg)
    (mode,) = cfg.modes
    flight = ctx.dataset.flight(str(cfg.flight_names[0]))
    specs = run_specs(flight.name, mode, list(cfg.seeds), n)
    todo = {k: [r for r in v if cfg.overwrite or not r.done(ctx.out_dir)]
            for k, v in specs.items()}
    run_pass(ctx, flight, mode, todo["vectorized"], num_particles=n)
    if todo["paper_faithful"]:
        pfl = PaperFaithfulLikelihood(ctx.world, ctx.camera, ctx.settings.likelihood,
                                      pf_settings)

        def paper_faithful(edge, tilt):
            return lambda states: pfl.log_likelihood(states, edge, tilt)

        run_pass(ctx, flight, mode, todo["paper_faithful"], likelihood_override=paper_faithful,
                 num_particles=n)
    return ctx.out_dir


def comparison_summary(records: list[dict]) -> dict:
    """Accuracy and filter time of each likelihood's runs, and the speed ratio.

    Args:
        records: run records (``localize.offline.runner.load_runs``); those of the comparison have
            ``likelihood`` ``vectorized_n<n>`` or ``paper_faithful_n<n>``.

    Returns:
        ``{"vectorized": {...}, "paper_faithful": {...}, "speed_ratio": paper-faithful /
        vectorized filter ms}`` (each: flight, mode, particles, frames, ``error_stats`` and
        ``filter_ms``; ``speed_ratio`` where both ran).
    """
    rows = {}
    for r in records:
        lik = r["likelihood"]
        if lik == "vectorized":
            continue
        kind = "paper_faithful" if lik.startswith("paper_faithful") else "vectorized"
        d = rows.setdefault(kind, {"errors": [], "filter_ms": [], "flight": r["flight"],
                                   "mode": r["mode"], "num_particles": r["filter_particles"],
                                   "num_frames": r["num_frames"]})
        d["errors"].append(np.array(r["position_error_m"]))
        d["filter_ms"].append(np.array(r["timing_ms"]["filter"]))
    out = {}
    for kind, d in rows.items():
        out[kind] = {
            "flight": d["flight"], "mode": d["mode"], "num_particles": d["num_particles"],
            "num_frames": d["num_frames"],
            **error_stats(np.concatenate(d["errors"])),
            "filter_ms": timing_stats(np.concatenate(d["filter_ms"])),
        }
    if "paper_faithful" in out and "vectorized" in out:
        out["speed_ratio"] = (out["paper_faithful"]["filter_ms"]["avg"]
                              / max(out["vectorized"]["filter_ms"]["avg"], 1e-9))
    return out


def print_summary(s: dict) -> None:
    """The comparison's table (``comparison_summary``)."""
    v = s["vectorized"]
    print(f"paper-faithful vs vectorized likelihood: flight {v['flight']}, mode {v['mode']}, "
          f"first {v['num_frames']} frames, {v['num_particles']} particles, tracking start")
    print(f"  {'likelihood':<16}{'mean error m':>13}{'filter ms/frame':>17}")
    for kind in ("vectorized", "paper_faithful"):
        k = s[kind]
        print(f"  {kind:<16}{k['mean_position_error_m']:>13.3f}{k['filter_ms']['avg']:>17.1f}")
    print(f"  speed-up of the vectorized likelihood: {s['speed_ratio']:.0f}x")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if not (args.dataset / "dataset.json").is_file():
        print(f"{args.dataset} not found: make it first (python -m datagen)")
        return 0
    out = run_comparison(comparison_config(args), args.particles, likelihood_settings(args))
    summary = comparison_summary(load_runs(out))
    atomic_write_json(out / "paper_faithful.json", summary)
    print_summary(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
