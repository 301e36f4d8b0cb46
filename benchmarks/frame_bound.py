"""A bounded frame: the mean and the worst frame of each edge mode per building, and the error.

Usage::

    python benchmarks/frame_bound.py --datasets outputs/datasets/demo --flight-set val
    python benchmarks/frame_bound.py --datasets outputs/bench/datasets/hospital \\
        --onnx models/generalist/segnet.onnx --frames 120 --baseline 331b21c
    python benchmarks/frame_bound.py --datasets D filter.likelihood.max_samples=0  # no budget

Per dataset, ``python -m localize`` tracks each flight of ``--flight-set`` (``test``: figures;
``val``: where settings are chosen) from its true start in ``--modes`` with ``--seeds``, over
the first ``--frames`` frames, and its metrics.json gives per mode the filter's and the whole
frame's mean and worst time (``timing_ms_by_mode``: the filter is motion, likelihood and
resampling; the frame adds the edges, the score maps and, in mode cnn, the SegNet) and the mean
position error over the flights. Target (issue 82): no frame over ``TARGET_MS`` with 500
particles on 2 cores, on every third-party building and the procedural floors.

With ``--baseline COMMIT`` the same runs are made with that commit's code (a ``git worktree``
in a temporary folder, its own conf/) right after this code's, on the same machine, and both
rows are printed; the key=value overrides go to this code only (``--baseline-overrides``:
the baseline's). The visibility lists are cached per dataset and code under
``<out-root>/cache``, so a second call casts no rays. Writes ``<out-root>/<name>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.thirdparty import tracking  # noqa: E402
from core.atomic import atomic_write_json  # noqa: E402

#: ms: no frame of any mode above it (issue 82, 2 cores, 500 particles).
TARGET_MS = 100.0


def localize(code: Path, dataset: Path, report: Path, cache: Path, args: argparse.Namespace,
             overrides: list[str]) -> dict:
    """``python -m localize`` of the code at ``code`` on ``dataset`` into ``report`` (its
    cache a link to ``cache``); the metrics.json."""
    lst = lambda xs: "[" + ",".join(str(x) for x in xs) + "]"  # noqa: E731
    report.mkdir(parents=True, exist_ok=True)
    cache.mkdir(parents=True, exist_ok=True)
    if not (report / "cache").exists():
        (report / "cache").symlink_to(cache.resolve(), target_is_directory=True)
    cmd = [sys.executable, "-m", "localize", f"dataset={dataset.resolve()}",
           f"out_root={report.parent.resolve()}", f"name={report.name}",
           f"modes={lst(args.modes)}", f"seeds={lst(args.seeds)}", "inits=[tracking]",
           f"flight_set={args.flight_set}", "progress=false", "overwrite=true",
           *([f"flight_names={lst(args.flights)}"] if args.flights else []),
           f"onnx_model={args.onnx}", *([f"max_frames={args.frames}"] if args.frames else []),
           *overrides]
    print(f"+ [{code.name}] " + " ".join(cmd[3:]), flush=True)
    env = {**os.environ, "PYTHONPATH": str(code)}
    subprocess.run(cmd, check=True, cwd=code, env=env)
    return json.loads((report / "metrics.json").read_text())


def per_mode(metrics: dict) -> dict:
    """Per mode: mean error over the flights (m), lost runs (``thirdparty.tracking``), filter
    and frame ms (mean, worst)."""
    out = tracking(metrics)
    for mode, o in out.items():
        o.pop("frame_ms")
        t = metrics.get("timing_ms_by_mode", {}).get(mode, {})
        for stage in ("filter", "total"):
            s = t.get(stage, {})
            o[f"{stage}_ms"] = {"mean": s.get("avg"), "max": s.get("max")}
    return out


def baseline_tree(commit: str, into: Path) -> Path:
    """A detached worktree of ``commit`` under ``into``."""
    path = into / f"baseline_{commit[:12]}"
    subprocess.run(["git", "worktree", "add", "--detach", str(path), commit], check=True,
                   cwd=ROOT, stdout=subprocess.DEVNULL)
    return path


def table(results: dict, modes: list[str]) -> str:
    """Markdown rows: dataset, code, mode, error, lost, filter and frame mean / worst ms."""
    rows = ["| dataset | code | mode | error m (lost) | filter ms mean / worst | "
            "frame ms mean / worst | worst <= 100 ms |", "|---|---|---|---|---|---|---|"]
    for ds, by_code in results.items():
        for code, modes_res in by_code.items():
            for m in modes:
                r = modes_res.get(m)
                if r is None:
                    continue
                f, t = r["filter_ms"], r["total_ms"]
                ok = "yes" if (t["max"] or 0) <= TARGET_MS else "NO"
                rows.append(f"| {ds} | {code} | {m} | {r['mean_m']:.3f} ({r['lost']}/"
                            f"{r['runs']}) | {f['mean']:.1f} / {f['max']:.1f} | "
                            f"{t['mean']:.1f} / {t['max']:.1f} | {ok} |")
    return "\n".join(rows) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("overrides", nargs="*", help="conf/localize.yaml overrides of this code")
    ap.add_argument("--datasets", nargs="+", type=Path, required=True)
    ap.add_argument("--modes", nargs="+", default=["none", "cnn", "oracle"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--frames", type=int, default=None, help="frames per flight (all: none)")
    ap.add_argument("--flight-set", default="test", choices=["test", "val"])
    ap.add_argument("--flights", nargs="+", default=None, help="flights of the set (all: none)")
    ap.add_argument("--onnx", default="auto", help="the SegNet of mode cnn (onnx_model)")
    ap.add_argument("--baseline", default=None, metavar="COMMIT",
                    help="also run this commit's code, side by side")
    ap.add_argument("--baseline-overrides", nargs="*", default=[])
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "frame_bound")
    ap.add_argument("--name", default="frame_bound")
    args = ap.parse_args()

    results: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        codes = {"this": (ROOT, args.overrides)}
        if args.baseline:
            codes[args.baseline] = (baseline_tree(args.baseline, Path(tmp)),
                                    args.baseline_overrides)
        try:
            for ds in args.datasets:
                for label, (code, over) in codes.items():
                    key = f"{args.name}_{ds.name}_{label}"
                    m = localize(code, ds, args.out_root / "reports" / key,
                                 args.out_root / "cache" / f"{ds.name}_{label}", args, over)
                    results.setdefault(ds.name, {})[label] = per_mode(m)
                    print(f"{ds.name} [{label}]: {json.dumps(results[ds.name][label])}",
                          flush=True)
        finally:
            for code, _ in codes.values():
                if code != ROOT:
                    subprocess.run(["git", "worktree", "remove", "--force", str(code)],
                                   cwd=ROOT, check=False)
    md = table(results, args.modes)
    atomic_write_json(args.out_root / f"{args.name}.json", {
        "modes": args.modes, "seeds": args.seeds, "frames": args.frames,
        "flight_set": args.flight_set, "flights": args.flights, "onnx": args.onnx,
        "overrides": args.overrides,
        "baseline": args.baseline, "load": os.getloadavg()[0], "results": results})
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
