"""The estimate's quality: fit its calibration on validation floors, check it on test floors.

Usage::

    python benchmarks/quality.py --val outputs/bench/val_*/reports/* --write
    python benchmarks/quality.py --val outputs/bench/val_*/reports/* \\
        --test outputs/bench/test_*/reports/*

The run records are those of ``benchmarks/global_start.py`` (global starts and kidnapped
runs; any report folder of ``python -m localize`` serves): per frame the quality's inputs
(``quality_inputs``, ``localize.filter.quality.INPUTS``) and the position error. Per edge
mode: the calibration is fitted on every ``--val`` report folder's frames
(``quality.fit``: each run weighs alike in the logistic fit), and checked

- on the validation floors themselves by leaving one floor out at a time (the fit on the
  others predicts it): the figure the settings are chosen by, with the status gate's
  ``filter.tracking_quality`` table (frames the filter calls ``tracking`` that keep the
  status at each threshold, their share within 0.3 m, and the runs that would declare a
  false convergence: ``tracking`` while > 1 m off for > 1 s);
- on the ``--test`` report folders (never used for a choice): the reliability table, per
  decile of predicted quality the frames, their mean quality and the share within 0.3 m,
  pooled and per floor. Where a record carries the quality the Localizer computed
  (``quality``), it is checked to equal the calibration's of its inputs.

``--write`` stores the calibration in ``localize/filter/quality.json`` (the shipped one;
``--out`` another file). Prints the tables and writes them to ``<out-root>/quality.md`` and
``quality.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.atomic import atomic_write_json, atomic_write_text  # noqa: E402
from localize.filter import quality as Q  # noqa: E402
from localize.offline.metrics import false_convergence  # noqa: E402

WITHIN_M = 0.3
FALSE_M, FALSE_S = 1.0, 1.0
THRESHOLDS = (0.0, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
#: A decile's gap counts against the target only with this many frames (fewer: noise).
MIN_FRAMES = 30


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--val", nargs="+", type=Path, required=True,
                    help="validation report folders (their runs/ fit the calibration)")
    ap.add_argument("--test", nargs="*", type=Path, default=[], help="test report folders")
    ap.add_argument("--modes", nargs="+", default=["oracle", "cnn"])
    ap.add_argument("--write", action="store_true", help="store the calibration (--out)")
    ap.add_argument("--out", type=Path, default=Q.SHIPPED)
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "benchmarks" / "quality")
    return ap.parse_args(argv)


def frames_of(folders: list[Path], mode: str) -> dict:
    """The frames of every run record of ``mode`` under the report folders: ``x`` (N, F)
    inputs, ``err`` (N,) m, ``run`` (N,) run ids, ``floor`` (N,) the report folder's name,
    ``quality`` (N,) recorded (NaN: none), ``runs`` [(floor, record)]."""
    xs, errs, runs, floors, recorded, records = [], [], [], [], [], []
    for folder in folders:
        for path in sorted((folder / "runs").glob("*/*.json")):
            r = json.loads(path.read_text())
            if r.get("mode") != mode or "position_error_m" not in r:
                continue
            x = np.asarray(r.get("quality_inputs", []), dtype=np.float64)
            if x.ndim != 2 or x.shape != (len(r["position_error_m"]), len(Q.INPUTS)):
                print(f"{path}: no quality inputs of this code, skipped", flush=True)
                continue
            xs.append(x)
            errs.append(np.asarray(r["position_error_m"]))
            runs += [len(records)] * len(x)
            floors += [folder.name] * len(x)
            recorded.append(np.asarray(r.get("quality", [np.nan] * len(x)), dtype=np.float64))
            records.append((folder.name, r))
    if not xs:
        return {}
    return {"x": np.concatenate(xs), "err": np.concatenate(errs), "run": np.array(runs),
            "floor": np.array(floors), "quality": np.concatenate(recorded), "runs": records}


#: The fits compared by leaving one validation floor out: (map, ridge penalty).
CHOICES = [(m, l2) for m in Q.MAPS for l2 in (1.0, 10.0, 30.0)]


def cross_validated(d: dict, method: str, l2: float) -> np.ndarray:
    """(N,) each frame's quality by the calibration fitted on the other floors."""
    q = np.full(len(d["err"]), np.nan)
    for floor in np.unique(d["floor"]):
        out = d["floor"] == floor
        if out.all():
            continue
        model = Q.fit(d["x"][~out], d["err"][~out] < WITHIN_M, d["run"][~out], l2=l2,
                      method=method)
        q[out] = model(d["x"][out])
    return q


def choose(d: dict) -> tuple[list[dict], tuple[str, float], np.ndarray]:
    """Each of ``CHOICES`` left one floor out at a time: (rows of method, l2, worst decile
    gap (deciles of >= ``MIN_FRAMES`` frames), Brier score; the choice with the smallest
    worst gap, then Brier; its cross-validated qualities)."""
    within = d["err"] < WITHIN_M
    rows, best = [], None
    for method, l2 in CHOICES:
        q = cross_validated(d, method, l2)
        gap = Q.worst_gap(Q.reliability(q, within), MIN_FRAMES)
        brier = float(np.nanmean((q - within) ** 2))
        rows.append({"method": method, "l2": l2, "worst_gap": gap, "brier": brier})
        key = (np.inf if gap is None else gap, brier)
        if best is None or key < best[0]:
            best = (key, (method, l2), q)
    return rows, best[1], best[2]


def gate_table(d: dict, q: np.ndarray) -> list[dict]:
    """Per ``filter.tracking_quality`` threshold: the frames the filter calls ``tracking``
    that keep the status, their share within ``WITHIN_M``, and the runs with a false
    convergence."""
    dom = Q.INPUTS.index("dominated")
    coast = Q.INPUTS.index("coasting")
    lost = Q.INPUTS.index("lost")
    x, err = d["x"], d["err"]
    filter_tracking = (x[:, dom] > 0) & (x[:, coast] == 0) & (x[:, lost] == 0)
    rows = []
    for t in THRESHOLDS:
        keep = filter_tracking & (q >= t)
        false = 0
        for i, (_, r) in enumerate(d["runs"]):
            sel = d["run"] == i
            status = np.where(keep[sel], "tracking", "ambiguous")
            false += int(false_convergence(err[sel], r["timestamps"], status.tolist(),
                                           FALSE_M, FALSE_S))
        rows.append({"threshold": t, "tracking_frames": int(keep.sum()),
                     "within_share": float(np.mean(err[keep] < WITHIN_M)) if keep.any() else None,
                     "false_convergences": false, "runs": len(d["runs"])})
    return rows


def _num(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def table_md(title: str, table: list[dict]) -> list[str]:
    gap = Q.worst_gap(table, MIN_FRAMES)
    lines = [f"**{title}** (worst |observed - predicted| over deciles with >= {MIN_FRAMES} "
             f"frames: {'-' if gap is None else f'{gap:.3f}'})", "",
             "| predicted | frames | mean predicted | observed within 0.3 m | gap |",
             "|---|---|---|---|---|"]
    for b in table:
        if b["frames"]:
            lines.append(f"| [{b['lo']:.1f}, {b['hi']:.1f}) | {b['frames']} | "
                         f"{b['predicted']:.3f} | {b['observed']:.3f} | "
                         f"{abs(b['observed'] - b['predicted']):.3f} |")
        else:
            lines.append(f"| [{b['lo']:.1f}, {b['hi']:.1f}) | 0 | - | - | - |")
    return [*lines, ""]


def gate_md(rows: list[dict]) -> list[str]:
    lines = ["| tracking_quality | frames kept `tracking` | within 0.3 m | runs with false "
             "convergence |", "|---|---|---|---|"]
    for r in rows:
        w = "-" if r["within_share"] is None else f"{100 * r['within_share']:.1f}%"
        lines.append(f"| {r['threshold']:.1f} | {r['tracking_frames']} | {w} | "
                     f"{r['false_convergences']} of {r['runs']} |")
    return [*lines, ""]


def main(argv=None) -> int:
    args = parse_args(argv)
    md = ["# Quality calibration", "",
          f"Validation: {', '.join(str(p) for p in args.val)}.",
          f"Test: {', '.join(str(p) for p in args.test) or 'none'}.", ""]
    result: dict = {"val": [str(p) for p in args.val], "test": [str(p) for p in args.test],
                    "modes": {}}
    models = {}
    for mode in args.modes:
        val = frames_of(args.val, mode)
        if not val:
            print(f"{mode}: no validation records, no calibration", flush=True)
            continue
        within = val["err"] < WITHIN_M
        floors = sorted(set(val["floor"].tolist()))
        entry: dict = {"val_frames": int(len(within)), "val_runs": len(val["runs"])}
        md += [f"## {mode}", "", f"Validation: {len(val['runs'])} runs, {len(within)} frames "
               f"({100 * within.mean():.1f}% within {WITHIN_M} m), floors {', '.join(floors)}.",
               ""]
        method, l2 = "logistic", 10.0
        if len(floors) > 1:
            rows, (method, l2), cv = choose(val)
            entry["choices"] = rows
            md += ["Fits compared, each validation floor predicted by the others:", "",
                   "| map | ridge | worst decile gap | Brier |", "|---|---|---|---|",
                   *[f"| {r['method']} | {r['l2']:g} | {_num(r['worst_gap'])} | "
                     f"{r['brier']:.4f} |" for r in rows], "",
                   f"Chosen: {method}, ridge {l2:g}.", ""]
            entry["val_cross_validated"] = Q.reliability(cv, within)
            entry["gate_cross_validated"] = gate_table(val, cv)
            md += table_md("validation, each floor predicted by the others",
                           entry["val_cross_validated"])
            md += ["Status gate (validation, cross-validated):", "",
                   *gate_md(entry["gate_cross_validated"])]
        model = Q.fit(val["x"], within, val["run"], l2=l2, method=method,
                      fitted_on={"floors": floors, "frames": int(len(within)),
                                 "runs": len(val["runs"]), "within_m": WITHIN_M,
                                 "method": method, "l2": l2})
        models[mode] = model
        entry["chosen"] = {"method": method, "l2": l2}
        test = frames_of(args.test, mode) if args.test else {}
        if test:
            q = model(test["x"])
            rec = test["quality"]
            same = np.isfinite(rec)
            if same.any() and args.write is False:
                entry["recorded_matches"] = bool(np.allclose(rec[same], q[same], atol=1e-6))
            tw = test["err"] < WITHIN_M
            entry["test"] = Q.reliability(q, tw)
            entry["test_gate"] = gate_table(test, q)
            entry["test_by_floor"] = {f: Q.reliability(q[test["floor"] == f],
                                                       tw[test["floor"] == f])
                                      for f in sorted(set(test["floor"].tolist()))}
            md += [f"Test: {len(test['runs'])} runs, {len(tw)} frames ({100 * tw.mean():.1f}% "
                   f"within {WITHIN_M} m).", ""]
            if "recorded_matches" in entry:
                md += [f"The Localizer's recorded quality equals this calibration's: "
                       f"{entry['recorded_matches']}.", ""]
            md += table_md("test, pooled", entry["test"])
            for f, t in entry["test_by_floor"].items():
                md += table_md(f"test, {f}", t)
            md += ["Status gate (test):", "", *gate_md(entry["test_gate"])]
        result["modes"][mode] = entry
    if args.write and models:
        Q.save(models, args.out, WITHIN_M,
               note="benchmarks/quality.py --val " + " ".join(str(p) for p in args.val))
        print(f"calibration written to {args.out}", flush=True)
    args.out_root.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out_root / "quality.json", result)
    atomic_write_text(args.out_root / "quality.md", "\n".join(md))
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    sys.exit(main())
