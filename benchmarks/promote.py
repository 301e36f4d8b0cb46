"""Promote a candidate generalist SegNet into models/generalist/ only where it is better.

Usage::

    python benchmarks/thirdparty.py --onnx outputs/models/generalist/segnet.onnx --name gen_new
    python -m localize name=corridor_gen_new dataset=outputs/datasets/demo modes=[cnn] \\
        seeds=[0,1,2] onnx_model=outputs/models/generalist/segnet.onnx
    python benchmarks/promote.py --candidate outputs/models/generalist \\
        --candidate-table outputs/benchmarks/gen_new/thirdparty.json \\
        --candidate-corridor outputs/reports/corridor_gen_new \\
        --shipped-corridor outputs/reports/corridor_shipped

The shipped model's figures are made the same way: ``python benchmarks/thirdparty.py`` (its
default ``--onnx`` is models/generalist/segnet.onnx; ``--shipped-table`` defaults to its
thirdparty.json) and ``python -m localize name=corridor_shipped dataset=outputs/datasets/demo
modes=[cnn] seeds=[0,1,2] onnx_model=models/generalist/segnet.onnx``.

The candidate replaces the shipped model when

- on every building of the shipped model's third-party table its cnn mean error (m, over the
  flights and seeds) is lower, with no more lost runs. Lower, without a margin: noise there
  can only block a candidate, never promote one, and a margin on each of six buildings run
  with one or two seeds would block nearly every candidate;
- in the corridor (the demo's flights) its cnn mean error is not worse: at most the shipped
  model's plus the larger of 10 % of it (two trainings of one recipe track about 8 % apart,
  docs/train.md: a difference that size tells the recipes nothing) and 2 standard errors of
  the difference from the per-seed errors (3 seeds: the seed spread), with no more lost runs.

Both tables must come from the same seeds and frames, each from the model it is compared as
(its ``onnx_sha256``: the file localize runs, the folder's int8 copy where it holds a valid one,
``segmenter.runtime_model``), and both corridor reports from the same dataset, flights and seeds,
each from its model. Otherwise the script says which figure to make again. Promoted, the
candidate's files (``FILES``) are copied into ``--shipped`` (default models/generalist/), the
folder replaced as a whole (a copy beside it, then two renames); its README.md stays and its
figures are to be updated by hand. Exit status: 0 promoted (or would be, ``--dry-run``), 1
blocked, 2 an input missing or not comparable.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.thirdparty import onnx_digest  # noqa: E402
from localize.frontend.segmenter import runtime_model  # noqa: E402

#: The model folder's files a promotion copies (those marked True must be there).
FILES = {"segnet.onnx": True, "checkpoint_best.pt": True, "metrics.json": True,
         "config.json": True, "localize.yaml": False, "train_log.csv": False,
         "confusion.png": False, "segnet_int8.onnx": False, "quantize.json": False}
#: The corridor's "not worse": the relative tolerance and the standard errors allowed.
CORRIDOR_REL = 0.10
CORRIDOR_SIGMAS = 2.0


class NotComparable(ValueError):
    """The inputs do not measure what the comparison needs (the message says what to run)."""


@dataclass(frozen=True)
class Row:
    """One line of the side-by-side table.

    Attributes:
        place: a building, or ``corridor``.
        shipped, candidate: cnn mean error (m) and lost runs / runs, or None where not run.
        passes: whether the candidate passes there.
        why: what blocks it ("" where it passes).
    """

    place: str
    shipped: tuple[float, int, int] | None
    candidate: tuple[float, int, int] | None
    passes: bool
    why: str = ""


def read_json(path: Path, what: str, fix: str) -> dict:
    if not path.is_file():
        raise NotComparable(f"{what}: {path} not found; {fix}")
    return json.loads(path.read_text())


def cnn_figures(result: dict) -> tuple[float, int, int] | None:
    """A third-party building's cnn (mean m, lost, runs), or None where cnn was not run."""
    cnn = (result.get("tracking") or {}).get("cnn")
    return None if cnn is None else (float(cnn["mean_m"]), int(cnn["lost"]), int(cnn["runs"]))


def compare_buildings(shipped: dict, candidate: dict) -> list[Row]:
    """One row per building of either table: the candidate passes where its cnn mean error is
    lower than the shipped model's with no more lost runs.

    Args:
        shipped, candidate: the two thirdparty.json contents (``results`` by building).
    """
    rows = []
    a, b = shipped["results"], candidate["results"]
    for place in list(a) + [p for p in b if p not in a]:
        s = cnn_figures(a[place]) if place in a else None
        c = cnn_figures(b[place]) if place in b else None
        if s is None or c is None:
            why = ("not in the candidate's table" if c is None else
                   "no shipped figure: run benchmarks/thirdparty.py for the shipped model there")
            rows.append(Row(place, s, c, False, why))
            continue
        why = []
        if not c[0] < s[0]:
            why.append(f"cnn {c[0]:.3f} m, not below {s[0]:.3f} m")
        if c[1] > s[1]:
            why.append(f"{c[1]} lost runs against {s[1]}")
        rows.append(Row(place, s, c, not why, "; ".join(why)))
    return rows


def corridor_errors(metrics: dict) -> tuple[float, float, int, int]:
    """A corridor report's cnn figures: mean error over its flights (m), the standard error of
    that mean from the per-seed errors, lost runs, runs.

    Args:
        metrics: a localize report's metrics.json.
    """
    means, variances, lost, runs = [], [], 0, 0
    for name, per_mode in metrics["flights"].items():
        e = per_mode.get("cnn")
        if not e or "mean_position_error_m" not in e:
            raise NotComparable(f"the corridor report has no cnn run of flight {name}: run "
                                "localize with modes=[cnn]")
        seeds = np.asarray(e["per_seed_mean_m"], dtype=np.float64)
        means.append(float(e["mean_position_error_m"]))
        variances.append(float(np.var(seeds, ddof=1)) / len(seeds) if len(seeds) > 1 else 0.0)
        lost += int(round(e["lost_rate"] * len(seeds)))
        runs += len(seeds)
    n = len(means)
    return float(np.mean(means)), math.sqrt(sum(variances)) / n, lost, runs


def compare_corridor(shipped: dict, candidate: dict) -> Row:
    """The corridor's row: the candidate passes where its cnn mean error is at most the shipped
    model's plus the larger of ``CORRIDOR_REL`` of it and ``CORRIDOR_SIGMAS`` standard errors
    of the difference, with no more lost runs.

    Args:
        shipped, candidate: the two corridor reports' metrics.json contents.
    """
    ms, ses, ls, rs = corridor_errors(shipped)
    mc, sec, lc, rc = corridor_errors(candidate)
    tolerance = max(CORRIDOR_REL * ms, CORRIDOR_SIGMAS * math.hypot(ses, sec))
    why = []
    if mc > ms + tolerance:
        why.append(f"cnn {mc:.3f} m, above {ms:.3f} m + {tolerance:.3f}")
    if lc > ls:
        why.append(f"{lc} lost runs against {ls}")
    return Row("corridor", (ms, ls, rs), (mc, lc, rc), not why, "; ".join(why))


def check_tables(shipped: dict, candidate: dict, shipped_onnx: Path, candidate_onnx: Path
                 ) -> None:
    """Raise NotComparable unless the tables ran the same seeds and frames, each on its model."""
    for what, table, onnx, flag in (("the shipped table", shipped, shipped_onnx, "--shipped-table"),
                                    ("the candidate's table", candidate, candidate_onnx,
                                     "--candidate-table")):
        if "onnx_sha256" not in table:
            raise NotComparable(f"{what} ({flag}) does not record its SegNet's digest: run "
                                "benchmarks/thirdparty.py again with the same options (it "
                                "collects what it has) to record it")
        if table["onnx_sha256"] != onnx_digest(onnx):
            raise NotComparable(f"{what} ({flag}) was made with another SegNet than {onnx} "
                                f"({table['onnx_sha256']} against {onnx_digest(onnx)}): run "
                                f"benchmarks/thirdparty.py --onnx {onnx} again")
        if "cnn" not in table["modes"]:
            raise NotComparable(f"{what} ({flag}) has no cnn runs: run it with cnn in --modes")
    for key in ("seeds", "frames"):
        if shipped.get(key) != candidate.get(key):
            raise NotComparable(f"the tables ran other {key}: {shipped.get(key)} (shipped) and "
                                f"{candidate.get(key)} (candidate); run both with the same "
                                f"--{key}")


def check_corridors(shipped: dict, candidate: dict, shipped_onnx: Path, candidate_onnx: Path
                    ) -> None:
    """Raise NotComparable unless both reports ran one dataset, its flights and seeds, each
    with its model."""
    for what, m, onnx in (("--shipped-corridor", shipped, shipped_onnx),
                          ("--candidate-corridor", candidate, candidate_onnx)):
        got = (m.get("model") or {}).get("onnx_sha256")
        if got != onnx_digest(onnx):
            raise NotComparable(f"{what}: the report's cnn runs used another SegNet ({got}) "
                                f"than {onnx} ({onnx_digest(onnx)}): run localize with "
                                f"onnx_model={onnx}")
    if Path(str(shipped.get("dataset"))).resolve() != Path(str(candidate.get("dataset"))).resolve():
        raise NotComparable(f"the corridor reports ran other datasets: {shipped.get('dataset')}"
                            f" and {candidate.get('dataset')}")
    for key in ("flights", "seeds"):
        a, b = _runs(shipped, key), _runs(candidate, key)
        if a != b:
            raise NotComparable(f"the corridor reports ran other {key}: {a} and {b}")


def _runs(metrics: dict, key: str) -> list:
    if key == "flights":
        return sorted(metrics["flights"])
    return sorted({s for per_mode in metrics["flights"].values()
                   for s in (per_mode.get("cnn") or {}).get("seeds", [])})


def render(rows: list[Row]) -> str:
    """The side-by-side markdown table."""
    def cell(f: tuple[float, int, int] | None) -> str:
        return "-" if f is None else f"{f[0]:.3f} ({f[1]}/{f[2]})"

    def verdict(r: Row) -> str:
        if not r.passes:
            return f"blocks: {r.why}"
        return "not worse" if r.place == "corridor" else "better"

    out = ["| place | shipped cnn m (lost) | candidate cnn m (lost) | candidate |",
           "|---|---|---|---|"]
    out += [f"| {r.place} | {cell(r.shipped)} | {cell(r.candidate)} | {verdict(r)} |"
            for r in rows]
    return "\n".join(out) + "\n"


def aside(dest: Path) -> Path:
    """Where ``copy_model`` moves the shipped folder before renaming the new one into place."""
    return dest.parent / f".{dest.name}.old"


def restore_stopped(dest: Path) -> bool:
    """Put the shipped folder back where a promotion stopped between its two renames (the old
    folder aside, no new one in place); whether it did."""
    if dest.exists() or not aside(dest).is_dir():
        return False
    aside(dest).rename(dest)
    return True


def copy_model(candidate: Path, dest: Path) -> list[str]:
    """Replace ``dest`` by a copy of itself with the candidate's ``FILES`` over it (its other
    files, the README, stay): the new folder is made beside it, then renamed into place.

    Returns:
        The files copied.
    """
    missing = [f for f, needed in FILES.items() if needed and not (candidate / f).is_file()]
    if missing:
        raise NotComparable(f"{candidate} lacks {', '.join(missing)}: is it a model folder of "
                            "python -m train?")
    if candidate.resolve() == dest.resolve():
        raise NotComparable(f"the candidate {candidate} is the shipped folder itself")
    old = aside(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{dest.name}.promote.", dir=dest.parent))
    try:
        if dest.is_dir():
            shutil.copytree(dest, staged, dirs_exist_ok=True)
        copied = [f for f in FILES if (candidate / f).is_file()]
        for f in copied:
            shutil.copy2(candidate / f, staged / f)
        for f in set(FILES) - set(copied):  # none of the shipped model's left beside it
            (staged / f).unlink(missing_ok=True)
        shutil.rmtree(old, ignore_errors=True)
        if dest.exists():
            dest.rename(old)
        staged.rename(dest)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
    return copied


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--candidate", type=Path, required=True, help="the candidate model folder")
    ap.add_argument("--candidate-table", type=Path, required=True,
                    help="its thirdparty.json (benchmarks/thirdparty.py --onnx ... --name ...)")
    ap.add_argument("--candidate-corridor", type=Path, required=True,
                    help="its corridor report folder (python -m localize ... modes=[cnn])")
    ap.add_argument("--shipped", type=Path, default=ROOT / "models" / "generalist")
    ap.add_argument("--shipped-table", type=Path,
                    default=ROOT / "outputs" / "benchmarks" / "thirdparty" / "thirdparty.json")
    ap.add_argument("--shipped-corridor", type=Path, required=True,
                    help="the shipped model's corridor report folder")
    ap.add_argument("--dry-run", action="store_true", help="compare, copy nothing")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    cand_onnx, ship_onnx = (runtime_model(str(args.candidate / "segnet.onnx"), ""),
                            runtime_model(str(args.shipped / "segnet.onnx"), ""))
    if restore_stopped(args.shipped):
        print(f"{args.shipped}: put back from {aside(args.shipped)} (a promotion stopped "
              "before its end)")
    try:
        for onnx, flag in ((cand_onnx, "--candidate"), (ship_onnx, "--shipped")):
            if not onnx.is_file():
                raise NotComparable(f"{flag}: {onnx} not found")
        fix = "make it with benchmarks/thirdparty.py (this script's docstring)"
        shipped_t = read_json(args.shipped_table, "--shipped-table", fix)
        cand_t = read_json(args.candidate_table, "--candidate-table", fix)
        check_tables(shipped_t, cand_t, ship_onnx, cand_onnx)
        fix = "make it with python -m localize (this script's docstring)"
        shipped_c = read_json(args.shipped_corridor / "metrics.json", "--shipped-corridor", fix)
        cand_c = read_json(args.candidate_corridor / "metrics.json", "--candidate-corridor", fix)
        check_corridors(shipped_c, cand_c, ship_onnx, cand_onnx)
        rows = [*compare_buildings(shipped_t, cand_t), compare_corridor(shipped_c, cand_c)]
    except NotComparable as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"candidate {args.candidate} against the shipped {args.shipped}:\n")
    print(render(rows))
    blocking = [r for r in rows if not r.passes]
    if blocking:
        print("not promoted; blocked by " + ", ".join(f"{r.place} ({r.why})" for r in blocking))
        return 1
    if args.dry_run:
        print(f"better everywhere: it would be promoted into {args.shipped} (--dry-run)")
        return 0
    try:
        copied = copy_model(args.candidate, args.shipped)
    except NotComparable as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"promoted: {', '.join(copied)} copied into {args.shipped}; update the figures of "
          f"{args.shipped / 'README.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
