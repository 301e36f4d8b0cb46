"""Global localization on whole floors: starts spread over each floor, and the kidnapped robot.

Usage::

    python benchmarks/global_start.py                  # the test floors found (TEST_FLOORS)
    python benchmarks/global_start.py --floors floor101 --starts 3 --frames 60   # smoke
    python benchmarks/global_start.py --modes oracle --kidnaps 0 -- filter.global_frames=60

Per floor (``--floors``: a dataset of ``FLOORS``, or ``name=path`` of any dataset made by
``python -m datagen``) and edge mode (``--modes``; cnn with ``--onnx``, default the shipped
generalist), ``--starts`` global starts (``Localizer.reset`` with the config's ``hint``,
none: the whole free space), each from a frame spread evenly along the floor's test flights
(``core.spliced.flight_segment``: the flights' routes are planned through the free space) for
``--frames`` frames; and ``--kidnaps`` kidnapped-robot runs: tracked from the truth for
``--kidnap-after`` frames, then teleported to another flight's stretch
(``core.spliced.kidnapped``) for ``--kidnap-frames`` frames more.

Figures per floor and mode: the share of starts within 0.3 m (from that frame to the end of
the run) by frame 30 / 100 / 200 (None where the runs are shorter), the median frames and
metres of travel to that, the false-convergence rate (status ``tracking`` while > 1 m off for
> 1 s), the filter's ms per global update (the frames the large set is kept, the first left
out) and the process's peak memory; kidnapped: the share whose loss was declared (at all, and
within 30 frames), and back within 0.3 m within 100 frames of the teleport; and the
reliability of the estimates' calibrated quality (every frame of the floor's runs: per
decile of predicted quality, the share within 0.3 m). Timings are context only: the machine's load
(``os.getloadavg``) is recorded beside them.

Writes ``<out-root>/<name>/``: per floor a localize report folder (``reports/<floor>/``: one
run record per start, mode and seed, ``localize.offline.runner.PassRecord``; a finished run is kept,
so an interrupted call resumes and a second one only collects), ``global_start.json``,
``global_start.md`` and ``global_start.png`` (per floor, the share of starts within 0.3 m by
each frame, and of kidnappings back by each frame after the teleport). A floor whose dataset
is absent is skipped with a message.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hydra import compose, initialize_config_dir  # noqa: E402

from benchmarks.floor_localize import global_update_ms  # noqa: E402
from core.atomic import atomic_write, atomic_write_json, atomic_write_text  # noqa: E402
from core.dataset import Dataset  # noqa: E402
from core.spliced import flight_segment, kidnapped  # noqa: E402
from localize.filter.quality import reliability, worst_gap  # noqa: E402
from localize.offline.metrics import convergence_frame, false_convergence  # noqa: E402
from localize.offline.runner import RunSpec, check_resume, prepare, run_pass  # noqa: E402

OUTPUTS = ROOT / "outputs"
THIRDPARTY = OUTPUTS / "benchmarks" / "thirdparty" / "datasets"
#: floor -> its dataset: the hospital and procedural floors whose seeds no shipped SegNet was
#: trained on (benchmarks/thirdparty.py renders the hospital and floors 101-103; floor104:
#: ``python -m datagen name=floor104 out_dir=outputs/benchmarks/thirdparty/datasets/floor104
#: splits.train=0 splits.val=0 splits.test=0 'val_flights=[]' world=procedural world.seed=104
#: flights=floor``), and the corridor.
FLOORS = {"hospital": THIRDPARTY / "hospital",
          **{f"floor{s}": THIRDPARTY / f"floor{s}" for s in (101, 102, 103, 104)},
          "corridor": OUTPUTS / "datasets" / "demo"}
#: the default floors: floor101 is left out, the global search's settings were chosen on it.
TEST_FLOORS = ["hospital", "floor102", "floor103", "floor104", "corridor"]
GENERALIST = ROOT / "models" / "generalist" / "segnet.onnx"
BY_FRAMES = (30, 100, 200)
WITHIN_M = 0.3
FALSE_M, FALSE_S = 1.0, 1.0
KIDNAP_BACK_FRAMES = 100
#: a kidnapping's loss counts as caught when declared within this many frames of the teleport.
KIDNAP_LOST_FRAMES = 30


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--floors", nargs="+", default=TEST_FLOORS,
                    help="names of FLOORS or name=dataset_path")
    ap.add_argument("--modes", nargs="+", default=["oracle", "cnn"])
    ap.add_argument("--onnx", type=Path, default=GENERALIST, help="the SegNet of cnn mode")
    ap.add_argument("--starts", type=int, default=20, help="global starts per floor")
    ap.add_argument("--frames", type=int, default=200, help="frames per start")
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--kidnaps", type=int, default=10, help="kidnapped-robot runs per floor")
    ap.add_argument("--kidnap-after", type=int, default=30,
                    help="frames tracked before the teleport")
    ap.add_argument("--kidnap-frames", type=int, default=KIDNAP_BACK_FRAMES,
                    help="frames after the teleport")
    ap.add_argument("--out-root", type=Path, default=OUTPUTS / "benchmarks")
    ap.add_argument("--name", default="global_start")
    ap.add_argument("overrides", nargs="*", help="more `python -m localize` overrides")
    return ap.parse_args(argv)


def floor_datasets(names: list[str]) -> dict[str, Path]:
    """floor -> dataset folder, from ``FLOORS`` names or ``name=path``; ValueError naming an
    unknown one."""
    out = {}
    for item in names:
        name, _, path = item.partition("=")
        if path:
            out[name] = Path(path)
        elif name in FLOORS:
            out[name] = FLOORS[name]
        else:
            raise ValueError(f"--floors: unknown floor {name!r}; use {', '.join(FLOORS)} or "
                             "name=path/to/dataset")
    return out


def start_frames(length: int, frames: int, count: int) -> list[int]:
    """``count`` first frames spread evenly over a flight of ``length`` frames, each leaving
    ``frames`` frames (as many as there are, for a shorter flight)."""
    last = max(length - frames, 0)
    return sorted({int(round(v)) for v in np.linspace(0, last, max(count, 1))})[:count]


def starts_of(ds: Dataset, frames: int, count: int) -> list[tuple[str, int]]:
    """``count`` (flight, first frame) global starts spread over the test flights: the
    starts dealt to the flights in turn, each flight's spread evenly along it."""
    names = ds.flight_names("test")
    per = [count // len(names) + (i < count % len(names)) for i in range(len(names))]
    out = []
    for name, n in zip(names, per, strict=True):
        if n:
            out += [(name, s) for s in start_frames(len(ds.flight(name)), frames, n)]
    return out


def kidnaps_of(ds: Dataset, after: int, frames: int, count: int) -> list[tuple]:
    """``count`` kidnappings, each ((flight, first frame) tracked ``after`` frames, (flight,
    first frame) teleported to for ``frames``): of ``2 count`` starts spread over the test
    flights (``starts_of``), each of the first ``count`` joined to the one whose first true
    position lies farthest from where its own stretch ends (the flights of a floor often fly
    one route: a start of the other flight at the same frame would barely move)."""
    starts = starts_of(ds, after + frames, max(2 * count, 2))
    flights = {name: ds.flight(name) for name in {s[0] for s in starts}}

    def xy(name: str, i: int) -> np.ndarray:
        return np.asarray(flights[name].groundtruth[min(i, len(flights[name]) - 1)])[:2, 3]

    out = []
    for a in starts[:count]:
        end = xy(a[0], a[1] + after - 1)
        others = [b for b in starts if b != a]
        if others:
            out.append((a, max(others, key=lambda b: np.linalg.norm(xy(*b) - end))))
    return out


def compose_cfg(ds_path: Path, floor: str, args: argparse.Namespace):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="localize", overrides=[
            f"dataset={ds_path}", f"onnx_model={args.onnx}", "progress=false",
            f"modes=[{','.join(args.modes)}]", "inits=[global,tracking]",
            f"seeds=[{','.join(map(str, args.seeds))}]", f"name={floor}",
            f"out_root={args.out_root / args.name / 'reports'}", *args.overrides])


def run_floor(floor: str, ds_path: Path, args: argparse.Namespace) -> list[dict]:
    """Every start and kidnapping of one floor, each mode and seed (finished ones kept);
    their summaries (``run_summary``)."""
    cfg = compose_cfg(ds_path, floor, args)
    ctx = prepare(cfg)
    check_resume(ctx.out_dir, cfg)
    ds = ctx.dataset
    rows = []
    for mode in args.modes:
        for name, s in starts_of(ds, args.frames, args.starts):
            source = flight_segment(ds.flight(name), s, min(args.frames, len(ds.flight(name))
                                                            - s))
            runs = [RunSpec(source.name, mode, "global", k) for k in args.seeds]
            run_pass(ctx, source, mode, [r for r in runs if not r.done(ctx.out_dir)])
            rows += [run_summary(ctx.out_dir, r, "global") for r in runs]
        for (fa, sa), (fb, sb) in kidnaps_of(ds, args.kidnap_after, args.kidnap_frames,
                                             args.kidnaps):
            a, b = ds.flight(fa), ds.flight(fb)
            source = kidnapped(flight_segment(a, sa, min(args.kidnap_after, len(a) - sa)),
                               flight_segment(b, sb, min(args.kidnap_frames, len(b) - sb)),
                               name=f"{fa}@{sa}+{fb}@{sb}")
            runs = [RunSpec(source.name, mode, "tracking", k) for k in args.seeds]
            run_pass(ctx, source, mode, [r for r in runs if not r.done(ctx.out_dir)])
            at = len(flight_segment(a, sa, min(args.kidnap_after, len(a) - sa)))
            rows += [run_summary(ctx.out_dir, r, "kidnapped", at) for r in runs]
    for r in rows:
        r["floor"] = floor
    return rows


def run_summary(out_dir: Path, run: RunSpec, kind: str, kidnapped_at: int | None = None
                ) -> dict:
    """One run's figures from its record: frames and metres to convergence (within
    ``WITHIN_M`` from there to the end), false convergence, global update ms; kidnapped: the
    frame its loss was declared and the frames back after the teleport."""
    rec = json.loads(run.paths(out_dir)[1].read_text())
    err = np.asarray(rec["position_error_m"])
    truth = np.asarray(rec["truth"])
    travel = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1))]
    out = {"run": run.stem, "source": run.flight, "mode": run.mode, "seed": run.seed,
           "kind": kind, "frames": len(err),
           "false_convergence": false_convergence(err, rec["timestamps"], rec["status"],
                                                  FALSE_M, FALSE_S),
           "global_update_ms": global_update_ms(rec),
           "peak_particles": int(max(rec["num_particles"])),
           "final_error_m": float(err[-1]),
           "quality": [round(float(v), 4) for v in rec.get("quality", [np.nan] * len(err))],
           "within": (err < WITHIN_M).astype(int).tolist()}
    if kind == "global":
        c = convergence_frame(err, WITHIN_M)
        out.update(converged_frame=c, converged_m=None if c is None else float(travel[c]))
    else:
        after = err[kidnapped_at:]
        c = convergence_frame(after, WITHIN_M)
        status = rec["status"][kidnapped_at:]
        out.update(kidnapped_at=kidnapped_at,
                   teleport_m=float(np.linalg.norm(truth[kidnapped_at, :2]
                                                   - truth[kidnapped_at - 1, :2])),
                   lost_declared=("lost" in status),
                   lost_after_frames=status.index("lost") if "lost" in status else None,
                   back_frames=c)
    return out


def _share(flags: list[bool]) -> float | None:
    return float(np.mean(flags)) if flags else None


def _runs(rows: list[dict], floor: str, mode: str, kind: str) -> list[dict]:
    return [r for r in rows if (r["floor"], r["mode"], r["kind"]) == (floor, mode, kind)]


def summarize(rows: list[dict]) -> dict:
    """Per floor and mode: the global starts' and the kidnappings' figures."""
    table: dict = {}
    for floor, mode in sorted({(r["floor"], r["mode"]) for r in rows}):
        g, k = _runs(rows, floor, mode, "global"), _runs(rows, floor, mode, "kidnapped")
        entry = {"starts": len(g)}
        for f in BY_FRAMES:  # within its first f frames; None where the runs are shorter
            ok = [r["converged_frame"] is not None and r["converged_frame"] < f for r in g
                  if r["frames"] >= f]
            entry[f"within_{WITHIN_M}m_by_{f}"] = _share(ok)
        conv = [r for r in g if r["converged_frame"] is not None]
        entry["median_frames_to_converge"] = (float(np.median([r["converged_frame"]
                                                               for r in conv]))
                                              if conv else None)
        entry["median_m_to_converge"] = (float(np.median([r["converged_m"] for r in conv]))
                                         if conv else None)
        entry["false_convergence_rate"] = _share([r["false_convergence"] for r in g])
        ms = [v for r in g for v in r["global_update_ms"]]
        entry["global_update_ms"] = ({"median": float(np.median(ms)), "max": float(max(ms))}
                                     if ms else None)
        entry["peak_particles"] = max((r["peak_particles"] for r in g), default=None)
        if k:
            entry["kidnaps"] = len(k)
            entry["kidnap_lost_declared"] = _share([r["lost_declared"] for r in k])
            entry[f"kidnap_lost_by_{KIDNAP_LOST_FRAMES}"] = _share([
                r["lost_after_frames"] is not None
                and r["lost_after_frames"] <= KIDNAP_LOST_FRAMES for r in k])
            entry[f"kidnap_back_by_{KIDNAP_BACK_FRAMES}"] = _share([
                r["back_frames"] is not None and r["back_frames"] <= KIDNAP_BACK_FRAMES
                for r in k])
            entry["kidnap_false_convergence_rate"] = _share([r["false_convergence"] for r in k])
        runs = g + k
        entry["quality_reliability"] = reliability(
            np.concatenate([r["quality"] for r in runs]) if runs else [],
            np.concatenate([r["within"] for r in runs]) if runs else [])
        table.setdefault(floor, {})[mode] = entry
    return table


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.0f}%"


def _num(v, fmt="{:.0f}") -> str:
    return "-" if v is None else fmt.format(v)


def markdown(result: dict) -> str:
    """The table of ``global_start.json``."""
    lines = ["# Global start", "",
             f"Converged: within {WITHIN_M} m from that frame to the end of the run. False "
             f"convergence: status `tracking` while > {FALSE_M} m off for > {FALSE_S} s. "
             f"Kidnapped: the loss declared (at all / within {KIDNAP_LOST_FRAMES} frames of the "
             f"teleport) and back within {WITHIN_M} m within {KIDNAP_BACK_FRAMES} frames of it. "
             "Timings with the load average "
             f"{', '.join(f'{v:.1f}' for v in result['load'])}; peak memory "
             f"{result['peak_rss_gb']:.2f} GB (the process).", "",
             "| floor | mode | starts | by 30 | by 100 | by 200 | median frames / m to "
             "converge | false conv. | global update ms (median / max) | particles | "
             "kidnaps: lost declared / by 30 / back | kidnaps false conv. |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for floor, modes in result["table"].items():
        for mode, e in modes.items():
            ms = e["global_update_ms"]
            lines.append(
                f"| {floor} | {mode} | {e['starts']} | "
                + " | ".join(_pct(e[f"within_{WITHIN_M}m_by_{f}"]) for f in BY_FRAMES)
                + f" | {_num(e['median_frames_to_converge'])} / "
                f"{_num(e['median_m_to_converge'], '{:.1f}')} | "
                f"{_pct(e['false_convergence_rate'])} | "
                f"{'-' if ms is None else '{:.0f} / {:.0f}'.format(ms['median'], ms['max'])} | "
                f"{_num(e['peak_particles'])} | "
                + (f"{_pct(e.get('kidnap_lost_declared'))} / "
                   f"{_pct(e.get(f'kidnap_lost_by_{KIDNAP_LOST_FRAMES}'))} / "
                   f"{_pct(e.get(f'kidnap_back_by_{KIDNAP_BACK_FRAMES}'))} | "
                   f"{_pct(e.get('kidnap_false_convergence_rate'))} |"
                   if "kidnaps" in e else "- | - |"))
    lines += ["", "Quality reliability (every frame of the starts and the kidnappings): per "
              "decile of the estimates' quality, the share of its frames within "
              f"{WITHIN_M} m / the decile's mean quality (frames).", "",
              "| floor | mode | worst gap | " + " | ".join(f"[{b / 10:.1f}, {(b + 1) / 10:.1f})"
                                                      for b in range(10)) + " |",
              "|---|---|---|" + "---|" * 10]
    for floor, modes in result["table"].items():
        for mode, e in modes.items():
            t = e.get("quality_reliability", [])
            if not any(b["frames"] for b in t):
                continue
            gap = worst_gap(t)
            lines.append(f"| {floor} | {mode} | {gap:.2f} | " + " | ".join(
                "-" if not b["frames"] else
                f"{b['observed']:.2f} / {b['predicted']:.2f} ({b['frames']})" for b in t) + " |")
    return "\n".join([*lines, ""])


def plot(rows: list[dict], path: Path) -> None:
    """Per floor, the share of global starts within ``WITHIN_M`` (from that frame to the end)
    by each frame, one line per mode, and of kidnappings back by each frame after the
    teleport (dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floors = sorted({r["floor"] for r in rows})
    fig, axes = plt.subplots(1, len(floors), figsize=(4 * len(floors), 3.2), squeeze=False,
                             sharey=True)
    for ax, floor in zip(axes[0], floors, strict=True):
        for i, mode in enumerate(sorted({r["mode"] for r in rows if r["floor"] == floor})):
            for kind, key, style in (("global", "converged_frame", "-"),
                                     ("kidnapped", "back_frames", "--")):
                runs = _runs(rows, floor, mode, kind)
                if not runs:
                    continue
                n = max(r["frames"] - r.get("kidnapped_at", 0) for r in runs)
                done = np.array([n if r[key] is None else r[key] for r in runs])
                share = (done[None, :] <= np.arange(n)[:, None]).mean(axis=1)
                ax.plot(np.arange(n), 100 * share, style, color=f"C{i}",
                        label=f"{mode}, {'start' if kind == 'global' else 'kidnapped'} "
                              f"({len(runs)})")
        ax.axhline(90, color="0.6", lw=0.8)
        ax.set(title=floor, xlabel="frame (after the teleport: dashed)", ylim=(0, 102))
        ax.legend(fontsize=7, loc="upper left")
    axes[0][0].set_ylabel(f"% within {WITHIN_M} m to the end")
    atomic_write(path, lambda p: fig.savefig(p, dpi=110, bbox_inches="tight"))
    plt.close(fig)


def main(argv=None) -> int:
    args = parse_args(argv)
    out = args.out_root / args.name
    rows = []
    for floor, path in floor_datasets(args.floors).items():
        if not (path / "dataset.json").is_file():
            print(f"{floor}: skipped, no dataset at {path} (render it with "
                  "benchmarks/thirdparty.py, or give --floors name=path)", flush=True)
            continue
        print(f"{floor}: {path}", flush=True)
        rows += run_floor(floor, path, args)
    peak_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2
    result = {"args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
              "load": list(os.getloadavg()), "peak_rss_gb": peak_gb,
              "table": summarize(rows), "runs": rows}
    atomic_write_json(out / "global_start.json", result)
    atomic_write_text(out / "global_start.md", markdown(result))
    if rows:
        plot(rows, out / "global_start.png")
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
