"""The robustness table: each imperfection of ``realism=real`` alone, and all together.

Usage::

    python benchmarks/robustness.py                                  # strength 1, 3 seeds
    python benchmarks/robustness.py --strengths 0.5 1 2 --factors ahrs lens
    python benchmarks/robustness.py --onnx outputs/models/demo/segnet.onnx --modes cnn oracle

For each factor (a sub-config of conf/realism/real.yaml: ``ahrs``, ``noise``, ``exposure``,
``jpeg``, ``dropout``, ``lens``, ``motion_blur``, ``rolling_shutter``, ``timing``, ``flight``,
...) and strength s, renders the test flights of ``realism=ideal`` with that factor set to the
real preset's values, its magnitudes scaled by s (``STRENGTH``; ``all``: every factor,
``ideal``: none), with ``python -m datagen`` into ``outputs/datasets/rob_<factor>_s<s>``, then
runs ``python -m localize`` on them (tracking start, the given modes and seeds) and writes
``<out-root>/robustness/``: metrics.json (``"robustness": {factor: {mode:
{mean_position_error_m, p95_m, lost_rate}}}`` at strength 1, ``"by_strength"``, ``"realism"``),
report.md (the table) and robustness.png (error against each factor's strength). Finished
datasets and runs are kept, so a second call only collects; the rows of factors and strengths
an earlier call measured stay in metrics.json, the table and the plot. The errors pool every
frame of every flight and seed; lost: a run whose error stayed above 1 m for more than 1 s.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.atomic import atomic_write_json, atomic_write_text  # noqa: E402
from core.imaging.realism import load_realism  # noqa: E402
from localize.offline.metrics import error_stats, lost_track  # noqa: E402

#: Per factor, how a strength s scales the real preset's magnitudes: "mul" x s, "inv" / s
#: (a sensor's full well: less is noisier), "quality" 100 - (100 - q) x s.
STRENGTH = {
    "ahrs": {"bias_deg": "mul", "noise_deg": "mul", "drift_deg": "mul"},
    "noise": {"full_well_e": "inv", "read_noise_e": "mul"},
    "exposure": {"drift_ev": "mul", "steps_per_min": "mul", "step_ev": "mul"},
    "jpeg": {"quality": "quality"},
    "dropout": {"per_min": "mul"},
    "lens": {"k1": "mul", "k2": "mul", "p1": "mul", "p2": "mul", "k3": "mul"},
    "motion_blur": {"exposure_s": "mul"},
    "rolling_shutter": {"readout_s": "mul"},
    "timing": {"drop_rate": "mul", "jitter_ms": "mul", "jump_per_min": "mul"},
    "flight": {"speed": "mul", "yaw_rate_deg_s": "mul"},
}
SUMMARY_KEYS = ("mean_position_error_m", "p95_m", "lost_rate")


def real_preset() -> dict:
    """conf/realism/real.yaml over ``RealismConfig``'s defaults, as a plain dict."""
    return asdict(load_realism("real"))


def factors(real: dict) -> list[str]:
    """The imperfections of the real preset: its sub-configs but ``subframes`` (a render
    setting)."""
    return [k for k, v in real.items() if isinstance(v, dict) and k != "subframes"]


def scaled(value, how: str, s: float):
    """A magnitude (or a list of them) at strength s."""
    if isinstance(value, list):
        return [scaled(v, how, s) for v in value]
    if value is None:
        return None
    if how == "mul":
        return value * s
    if how == "inv":
        return value / s if s > 0 else 0.0
    if how == "quality":
        return int(round(100 - (100 - value) * s))
    raise ValueError(f"unknown strength rule {how!r}")


def _value(v) -> str:
    if isinstance(v, list):
        return "[" + ",".join(_value(x) for x in v) + "]"
    if v is None:
        return "null"
    return str(v).lower() if isinstance(v, bool) else repr(v) if isinstance(v, str) else f"{v:g}"


def factor_overrides(factor: str, s: float, real: dict) -> list[str]:
    """``python -m datagen`` overrides of one factor (or ``all`` / ``ideal``) at strength s."""
    if factor == "ideal":
        return ["realism=ideal"]
    names = factors(real) if factor == "all" else [factor]
    out = ["realism=ideal", f"realism.name={'real' if factor == 'all' else 'only_' + factor}"]
    for name in names:
        rules = STRENGTH.get(name, {})
        for key, value in real[name].items():
            v = scaled(value, rules[key], s) if key in rules else value
            out.append(f"realism.{name}.{key}={_value(v)}")
    return out


def run(cmd: list[str]) -> bool:
    """Run a stage; False when it refused (a setting out of range: a lens scaled until it
    folds the image), with its message printed."""
    print("+", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if done.returncode:
        msg = [ln for ln in done.stderr.splitlines() if "Error" in ln][-1:]
        print(f"refused: {msg[0] if msg else done.stderr[-500:]}", flush=True)
    return done.returncode == 0


def pooled(report: Path, threshold_m: float = 1.0, lost_s: float = 1.0) -> dict:
    """Per mode: mean and p95 error over every frame of every tracking run, and the share of
    runs that lost track."""
    runs = [json.loads(p.read_text()) for p in sorted((report / "runs").glob("*/*.json"))]
    out = {}
    for mode in sorted({r["mode"] for r in runs}):
        rs = [r for r in runs if r["mode"] == mode and r["init"] == "tracking"
              and r["likelihood"] == "vectorized"]
        e = error_stats(np.concatenate([r["position_error_m"] for r in rs]))
        out[mode] = {"mean_position_error_m": e["mean_position_error_m"], "p95_m": e["p95_m"],
                     "lost_rate": float(np.mean([lost_track(r["position_error_m"],
                                                            r["timestamps"], threshold_m,
                                                            lost_s) for r in rs])),
                     "runs": len(rs)}
    return out


def table(robust: dict) -> list[str]:
    seen = {m for f in robust.values() for m in f}
    modes = [m for m in ("none", "cnn", "oracle") if m in seen] + sorted(
        seen - {"none", "cnn", "oracle"})
    lines = ["| factor | " + " | ".join(f"{m} mean / p95 (m), lost" for m in modes) + " |",
             "|---|" + "---|" * len(modes)]
    for factor, by_mode in robust.items():
        cells = [f"{by_mode[m]['mean_position_error_m']:.3f} / {by_mode[m]['p95_m']:.3f}, "
                 f"{100 * by_mode[m]['lost_rate']:.0f}%" if m in by_mode else "-" for m in modes]
        lines.append(f"| {factor} | " + " | ".join(cells) + " |")
    return lines


def plot(by_strength: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    factors = [f for f in by_strength if f != "ideal"]
    modes = sorted({m for f in by_strength.values() for r in f.values() for m in r})
    cols = min(4, max(1, len(factors)))
    rows = -(-len(factors) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for ax, factor in zip(axes.ravel(), factors, strict=False):
        pts = sorted((float(s), r) for s, r in by_strength[factor].items())
        if "ideal" in by_strength:  # strength 0: no flaw
            pts = [(0.0, by_strength["ideal"]["1"]), *pts]
        for mode in modes:
            xs = [s for s, r in pts if mode in r]
            ys = [r[mode]["mean_position_error_m"] for s, r in pts if mode in r]
            ax.plot(xs, ys, "o-", label=mode)
        ax.set_title(factor, fontsize=9)
        ax.set_xlabel("strength (x realism=real)", fontsize=8)
        ax.set_ylabel("mean error (m)", fontsize=8)
        ax.set_yscale("log")
    for ax in axes.ravel()[len(factors):]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=7)
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=90)
    plt.close(fig)
    tmp.replace(path)


def main() -> None:
    real = real_preset()
    known = factors(real)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--factors", nargs="+", default=["ideal", *known, "all"],
                    help=f"of {['ideal', *known, 'all']}")
    ap.add_argument("--strengths", nargs="+", type=float, default=[1.0])
    ap.add_argument("--modes", nargs="+", default=["none", "cnn", "oracle"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--onnx", default="outputs/models/demo/segnet.onnx")
    ap.add_argument("--datasets", type=Path, default=ROOT / "outputs" / "datasets")
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "benchmarks")
    ap.add_argument("--datagen", nargs="*", default=[], help="more datagen overrides")
    ap.add_argument("--localize", nargs="*", default=[], help="more localize overrides")
    args = ap.parse_args()
    bad = [f for f in args.factors if f not in ("ideal", "all", *known)]
    if bad:
        sys.exit(f"--factors: unknown {bad}; use {['ideal', *known, 'all']}")
    if "cnn" in args.modes and not (ROOT / args.onnx).is_file() and not Path(args.onnx).is_file():
        sys.exit(f"--onnx {args.onnx} not found: train one (make demo) or leave cnn out of "
                 "--modes")
    lst = lambda xs: "[" + ",".join(str(x) for x in xs) + "]"  # noqa: E731
    out = args.out_root / "robustness"
    earlier = out / "metrics.json"  # rows of earlier calls are kept, this call's replaced
    by_strength: dict = (json.loads(earlier.read_text())["by_strength"] if earlier.is_file()
                         else {})
    for factor in args.factors:
        for s in ([1.0] if factor == "ideal" else args.strengths):
            tag = f"rob_{factor}_s{s:g}"
            ds = args.datasets / tag
            if not run([sys.executable, "-m", "datagen", f"name={tag}", f"out_dir={ds}",
                        "splits.train=0", "splits.val=0", "splits.test=0", "val_flights=[]",
                        "progress=false", *factor_overrides(factor, s, real), *args.datagen]):
                continue
            if not run([sys.executable, "-m", "localize", f"name={tag}", f"dataset={ds}",
                        f"out_root={args.out_root / 'robustness' / 'runs'}",
                        f"modes={lst(args.modes)}", "inits=[tracking]",
                        f"seeds={lst(args.seeds)}", f"onnx_model={args.onnx}",
                        "progress=false", *args.localize]):
                sys.exit(f"localize failed on {ds}")
            by_strength.setdefault(factor, {})[f"{s:g}"] = pooled(
                args.out_root / "robustness" / "runs" / tag)
    robust = {f: {m: {k: r[m][k] for k in SUMMARY_KEYS} for m in r}
              for f, by_s in by_strength.items() if (r := by_s.get("1"))}
    atomic_write_json(out / "metrics.json", {
        "realism": "per factor: realism=ideal with one factor of realism=real (all: every one)",
        "robustness": robust, "by_strength": by_strength,
        "modes": args.modes, "seeds": args.seeds, "onnx_model": str(args.onnx)})
    lines = ["# Robustness: each imperfection alone, and all together", "",
             "Test flights of `realism=ideal` with one factor of `realism=real` (`all`: every "
             "one); tracking start; every frame of every flight and seed pooled. Lost: a run "
             "whose error stayed above 1 m for more than 1 s.", "", *table(robust), ""]
    if any(len(v) > 1 for v in by_strength.values()):
        plot(by_strength, out / "robustness.png")
        lines += ["![mean error against each factor's strength](robustness.png)", ""]
    atomic_write_text(out / "report.md", "\n".join(lines))
    print("\n".join(table(robust)))
    print(f"written: {out / 'report.md'}")


if __name__ == "__main__":
    main()
