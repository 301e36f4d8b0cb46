"""Where the metres go: per building, the cnn error with one class at a time from the truth.

Usage::

    python benchmarks/class_cost.py                        # every third-party dataset present
    python benchmarks/class_cost.py --buildings hospital bookstore --seeds 0
    python benchmarks/class_cost.py --onnx outputs/models/mine/segnet.onnx --name mine \\
        max_frames=200                                     # + python -m localize overrides

Per building (a dataset ``benchmarks/thirdparty.py`` rendered, ``<root>/datasets/<building>``;
its test flights, from their true starts): the cnn mode with the SegNet (``--onnx``, default the
shipped generalist), the oracle, and for every class K the cnn mode with K taken from the true
labels (``class_swap.swap_labels``: every pixel the truth or the SegNet puts in K gets the
true label, so K's boundaries are where the truth has them and every other one is the
SegNet's), and ``all``, every class from the truth through the cnn path. A class's cost is the
cnn error minus the error with that class true (metres a perfect SegNet on K would save; the
spread of one seed is about 15 %, so costs under that share of the cnn error are noise);
``all``'s error against the oracle's is what the cnn path costs besides segmentation. A
diagnostic: the localizer never reads true labels in cnn mode.

Writes ``<root>/<name>/<building>/<variant>/`` (localize reports; their visibility cache is
the building's third-party report's, ``<root>/reports/<building>/cache``, shared by link),
``<root>/<name>/class_cost.json`` and ``class_cost.md`` (the table). Finished runs are kept,
so a second call only collects and an interrupted one resumes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.class_swap import swapped_source  # noqa: E402
from benchmarks.thirdparty import tracking  # noqa: E402
from core import classes as C  # noqa: E402
from core.atomic import atomic_write_json, atomic_write_text  # noqa: E402
from localize.offline.runner import run as localize  # noqa: E402

GENERALIST = ROOT / "models" / "generalist" / "segnet.onnx"
BUILDINGS = ("hospital", "bookstore", "icl_scan", "floor101", "floor102", "floor103")
#: the classes a SegNet labels (void is the sky-less outside: never in an indoor view)
CLASSES = tuple(n for n in C.NAMES if n != "void")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], epilog="key=value "
                                 "arguments, anywhere, are python -m localize overrides")
    ap.add_argument("--buildings", nargs="+", default=list(BUILDINGS), choices=BUILDINGS)
    ap.add_argument("--classes", nargs="+", default=list(CLASSES), choices=CLASSES)
    ap.add_argument("--onnx", type=Path, default=GENERALIST, help="the SegNet of cnn mode")
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--root", type=Path, default=ROOT / "outputs" / "benchmarks" / "thirdparty",
                    help="benchmarks/thirdparty.py's output folder (its datasets and reports)")
    ap.add_argument("--name", default="class_cost")
    argv = sys.argv[1:] if argv is None else argv
    overrides = [a for a in argv if "=" in a and not a.startswith("-")]
    args = ap.parse_args([a for a in argv if a not in overrides])
    args.overrides = overrides  # python -m localize overrides (key=value), anywhere
    return args


def mean_errors(metrics: dict) -> dict[str, float]:
    """Per mode, the mean position error (m) over a report's flights (``metrics.json``;
    ``thirdparty.tracking``'s means)."""
    return {m: t["mean_m"] for m, t in tracking(metrics).items()}


def costs(errors: dict[str, float]) -> dict[str, float]:
    """Per swapped variant (a class name or ``all``), the metres its truth saves: the cnn
    error minus the variant's (``errors``: variant -> m, with ``cnn``)."""
    return {v: errors["cnn"] - e for v, e in errors.items() if v not in ("cnn", "oracle")}


def table(results: dict[str, dict[str, float]], classes: list[str]) -> str:
    """The markdown table: per building the oracle and cnn errors, cnn with every class true,
    and per class the metres its truth saves."""
    head = ["building", "oracle m", "cnn m", "all true m", *(f"{k} saves m" for k in classes)]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for b, e in results.items():
        saved = costs(e)
        cells = [b, *(f"{e[v]:.3f}" if v in e else "-" for v in ("oracle", "cnn", "all")),
                 *(f"{saved[k]:+.3f}" if k in saved else "-" for k in classes)]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def run_variant(ds: Path, report: Path, cache: Path, args: argparse.Namespace,
                modes: list[str], swap: list[int] | None) -> dict[str, float]:
    """One localize report on ``ds``'s test flights in ``report``: ``modes``, the cnn mode's
    labels with the classes ``swap`` from the truth (None: the SegNet's own); its mean errors
    per mode."""
    lst = lambda xs: "[" + ",".join(str(x) for x in xs) + "]"  # noqa: E731
    report.mkdir(parents=True, exist_ok=True)
    cache.mkdir(parents=True, exist_ok=True)
    link = report / "cache"
    if not link.exists():
        link.symlink_to(cache.resolve(), target_is_directory=True)
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="localize", overrides=[
            f"dataset={ds}", f"onnx_model={args.onnx}", f"out_root={report.parent}",
            f"name={report.name}", f"modes={lst(modes)}", f"seeds={lst(args.seeds)}",
            "inits=[tracking]", "progress=false", *args.overrides])
    wrappers = None if swap is None else {
        "cnn": lambda own: swapped_source(own, np.array(swap))}
    done = localize(cfg, wrappers)
    return mean_errors(json.loads((done.parent / "metrics.json").read_text()))


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = args.root / args.name
    results: dict[str, dict[str, float]] = {}
    for b in args.buildings:
        ds = args.root / "datasets" / b
        if not (ds / "dataset.json").is_file():
            print(f"{b}: no dataset at {ds} (run benchmarks/thirdparty.py --buildings {b} "
                  "first); skipped", flush=True)
            continue
        cache = args.root / "reports" / b / "cache"
        errors = run_variant(ds, out / b / "plain", cache, args, ["cnn", "oracle"], None)
        variants = {"all": [C.ID[k] for k in CLASSES], **{k: [C.ID[k]] for k in args.classes}}
        for v, ids in variants.items():
            errors[v] = run_variant(ds, out / b / f"swap_{v}", cache, args, ["cnn"], ids)["cnn"]
        results[b] = errors
        print(f"{b}: " + json.dumps({k: round(e, 4) for k, e in errors.items()}), flush=True)
    md = table(results, args.classes)
    atomic_write_json(out / "class_cost.json", {"onnx": str(args.onnx), "seeds": args.seeds,
                                                "overrides": args.overrides,
                                                "errors_m": results})
    atomic_write_text(out / "class_cost.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
