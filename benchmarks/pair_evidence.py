"""Which class pairs' edges hold a report's estimate to the truth, and which let it drift.

Usage::

    python benchmarks/pair_evidence.py outputs/reports/demo --flight cluttered --frames 71 91
    python benchmarks/pair_evidence.py outputs/reports/demo --flight paper --every 4 --per-frame

For every frame of the range, the estimate of the report's ``--run-mode`` runs (tracking init,
mean over their seeds) and the true pose. With each ``--edges`` mode's image edges (``cnn``: the
report's SegNet; ``oracle``: the true labels), and that mode's own likelihood settings, the
log-likelihood difference ``k * (score(estimate) - score(truth))``:

- of all the model lines the mode matches (``all``), and
- of each class pair's lines alone (floor | wall, wall | door, ...), scored as if they were the
  whole model; so the pairs' figures do not add up to ``all``.

Negative: these edges prefer the truth, they pull the estimate back. Near 0: they cannot tell
the two poses apart (weak evidence). Positive: they prefer where the estimate is (a bias).
Summed over the frames. Comparing the ``cnn`` and ``oracle`` columns on a stretch where the
cnn estimate drifts shows which boundaries the SegNet gets wrong there (docs/localize.md, "part
8"). The report's settings are read from its ``config.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.atomic import read_png  # noqa: E402
from core.classes import pair_name  # noqa: E402
from localize.context import Context  # noqa: E402
from localize.filter.likelihood import EdgeLikelihood  # noqa: E402
from localize.filter.pose_stats import estimate as estimate_pose  # noqa: E402
from localize.filter.projection import ModelSamples, tilt_from_pose  # noqa: E402
from localize.filter.visibility import SparseVisibility  # noqa: E402
from localize.frontend.front_end import EdgeFrame  # noqa: E402
from localize.offline.runner import load_runs, prepare  # noqa: E402


def pair_likelihoods(samples: ModelSamples, vis: SparseVisibility, sample_pairs: np.ndarray,
                     camera, params) -> dict[str, EdgeLikelihood]:
    """``{"all": ..., <pair code>: ...}``: the likelihood of all samples and of each class
    pair's samples alone (pair codes as strings), with the same settings."""
    out = {"all": EdgeLikelihood(samples, camera, params, vis, sample_pairs)}
    for code in np.unique(sample_pairs):
        keep = np.zeros(int(samples.segment.max()) + 1, dtype=bool)
        keep[samples.segment[sample_pairs == code]] = True
        sub, cols = samples.select(keep)
        out[str(int(code))] = EdgeLikelihood(sub, camera, params, vis.select(cols),
                                             sample_pairs[cols])
    return out


def evidence(liks: dict[str, EdgeLikelihood], frame: EdgeFrame, estimate: np.ndarray,
             truth: np.ndarray, tilt: np.ndarray | None) -> dict[str, float]:
    """``k * (score(estimate) - score(truth))`` per entry of ``liks`` for one frame.

    Args:
        liks: from ``pair_likelihoods``.
        frame: the frame through its mode's front end (``FrontEnd.frame``); its score maps
            are made once per map settings and class pairs (without ``class_pairs`` one set
            serves every entry).
        estimate, truth: (4,) x, y, z (m), yaw (rad).
        tilt: (3, 3) roll/pitch of the frame (None: level).
    """
    states = np.stack([truth, estimate]).astype(np.float64)
    out = {}
    for key, lik in liks.items():
        score, _ = lik.scores(states, frame.observation(lik)[0], tilt)
        out[key] = float(lik.params.k * (score[1] - score[0]))
    return out


def mean_estimate(report: Path, flight: str, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """(T, 4) mean estimate over the tracking seeds of ``mode`` and the (T, 4) truth."""
    runs = [r for r in load_runs(report)
            if r["flight"] == flight and r["mode"] == mode and r["init"] == "tracking"
            and r["likelihood"] == "vectorized"]
    if not runs:
        raise SystemExit(f"{report}/runs/{flight}/ has no tracking runs of mode {mode!r}; run "
                         f"`python -m localize name={report.name} modes=[{mode}] "
                         f"inits=[tracking]` first")
    est = np.asarray([r["estimate"] for r in runs])  # (seeds, T, 4)
    equal = np.zeros(len(runs))  # log-weights: every seed counts the same
    mean = np.stack([estimate_pose(est[:, t], equal) for t in range(est.shape[1])])
    return mean, np.asarray(runs[0]["truth"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("report", type=Path, help="a report folder of `python -m localize`")
    ap.add_argument("--flight", default="cluttered")
    ap.add_argument("--frames", type=int, nargs=2, default=None, metavar=("FIRST", "END"),
                    help="frame range [FIRST, END); default: the whole flight")
    ap.add_argument("--every", type=int, default=1, help="every n-th frame of the range")
    ap.add_argument("--run-mode", default="cnn", help="whose estimate to test")
    ap.add_argument("--edges", nargs="+", default=["cnn", "oracle"], choices=["cnn", "oracle"])
    ap.add_argument("--per-frame", action="store_true", help="print each frame's `all` too")
    args = ap.parse_args(argv)
    path = args.report / "config.json"
    if not path.is_file():
        raise SystemExit(f"{path} not found: pass a report folder of `python -m localize`")
    conf = json.loads(path.read_text())
    conf.pop("onnx_sha256", None)  # the report's record of its SegNet, not a setting
    cfg = OmegaConf.create(conf)
    cfg.modes = list(args.edges)
    cfg.out_root, cfg.name = str(args.report.parent), args.report.name  # its visibility cache
    ctx: Context = prepare(cfg)
    estimate, truth = mean_estimate(args.report, args.flight, args.run_mode)
    flight = ctx.dataset.flight(args.flight)
    first, end = args.frames or (0, len(truth))
    frames = range(max(first, 0), min(end, len(truth)), max(args.every, 1))
    if not frames:
        raise SystemExit(f"--frames {first} {end}: no frame of the flight's {len(truth)} in range")
    names = {int(c["id"]): c["name"] for c in ctx.dataset.classes}
    liks, fronts = {}, {}
    for mode in args.edges:
        model = ctx.model_for(mode)
        params = ctx.settings.filter.likelihood_for(mode)
        liks[mode] = pair_likelihoods(model.samples, model.visibility, model.pairs, ctx.camera,
                                      params)
        fronts[mode] = ctx.front_end(mode)
    total = {m: {} for m in args.edges}
    for t in frames:
        rgb = read_png(flight.rgb[t])
        true_labels = read_png(flight.label[t], rgb=False)
        tilt = tilt_from_pose(flight.odometry[t])
        row = []
        for mode, front in fronts.items():
            ev = evidence(liks[mode], front.frame(rgb, true_labels), estimate[t], truth[t], tilt)
            for key, v in ev.items():
                total[mode][key] = total[mode].get(key, 0.0) + v
            row.append(f"{mode} {ev['all']:+7.2f}")
        if args.per_frame:
            off = estimate[t] - truth[t]
            print(f"frame {t:4d}: estimate off by {100 * np.linalg.norm(off[:3]):5.1f} cm, "
                  f"{np.rad2deg((off[3] + np.pi) % (2 * np.pi) - np.pi):+5.2f} deg; all: "
                  + ", ".join(row))
    print(f"{args.report}, flight {args.flight}, frames {frames.start}-{frames.stop - 1} every "
          f"{frames.step}, estimate of {args.run_mode}: k * (score(estimate) - score(truth)) "
          "summed (negative: the edges pull back to the truth)")
    print(f"  {'model lines':18s}" + "".join(f" {m + ' edges':>13s}" for m in args.edges))
    for key in total[args.edges[0]]:
        label = key if key == "all" else pair_name(int(key), names)
        print(f"  {label:18s}" + "".join(f" {total[m].get(key, 0.0):+13.2f}"
                                         for m in args.edges))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
