"""Accuracy over more flights: the localizer on N new flights of each of a dataset's presets.

A dataset holds one flight per preset (`paper`, `cluttered`), and the filter's error on a
flight is mostly the flight's own (the seeds agree to a few mm), so one flight is one sample.
This renders ``--flights`` more flights of every preset the dataset rendered, with the
dataset's own generator config (same world, camera, appearance and distractor presets; each
new flight ``<preset>_<k>`` draws its own trajectory, textures, clutter and people), into a
flights-only dataset beside it, runs ``python -m localize`` on them and on the dataset's own
flights (``--no-own``: the new ones only), and prints, per flight and pooled per preset, the
mean position error of each mode and the targets' ratios.

    python benchmarks/flight_spread.py                                  # the demo's outputs
    python benchmarks/flight_spread.py --dataset outputs/datasets/big --flights 5 \\
        onnx_model=outputs/models/big/segnet.onnx edges.cnn.snap_px=1   # localize overrides

Both stages resume: re-running skips rendered frames and finished runs.
"""

from __future__ import annotations

import argparse
import copy
import json
import re
import sys
from pathlib import Path

from hydra import compose, initialize_config_dir

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.dataset import SPLITS  # noqa: E402
from datagen.generate import run as render  # noqa: E402
from localize.offline.runner import run as localize  # noqa: E402


def flights_config(dataset: Path, n: int, out: Path) -> dict:
    """The dataset's generator config made into one that renders only ``n`` new flights of each
    of its rendered presets (``<preset>_1`` .. ``<preset>_n``) into ``out``."""
    meta = dataset / "dataset.json"
    if not meta.is_file():
        raise FileNotFoundError(f"{meta} not found: give --dataset a folder made by "
                                "`python -m datagen`")
    gen = copy.deepcopy(json.loads(meta.read_text())["generator"])
    presets = list(gen["render_flights"])
    if not presets:
        raise ValueError(f"{meta}: the dataset rendered no flights (render_flights is empty)")
    gen["splits"] = {s: 0 for s in SPLITS}
    gen["flights"].update({f"{p}_{k}": copy.deepcopy(gen["flights"][p])
                           for p in presets for k in range(1, n + 1)})
    gen["render_flights"] = [f"{p}_{k}" for p in presets for k in range(1, n + 1)]
    gen["val_flights"] = []  # the new flights are test flights of their own
    gen.update(name=out.name, out_dir=str(out), shard=0, num_shards=1, overwrite=False)
    return gen


def merge_flights(*metrics: dict) -> dict:
    """One ``{"flights": ...}`` of several reports' ``metrics.json`` (flight names must differ)."""
    flights: dict = {}
    for m in metrics:
        twice = flights.keys() & m["flights"].keys()
        if twice:
            raise ValueError(f"flights {sorted(twice)} are in two reports")
        flights.update(m["flights"])
    return {"flights": flights}


def summarize(metrics: dict) -> list[str]:
    """Table rows: per flight and pooled per preset, mean position error (m) per mode and the
    targets' ratios (none / cnn >= 2, cnn / oracle <= 1.25). A flight's preset is its name
    without a ``_<k>`` suffix (``flights_config``'s new flights), or the name itself (the
    dataset's own flights, one per preset)."""
    flights = metrics["flights"]
    modes = [m for m in ("cnn", "oracle", "none") if any(m in d for d in flights.values())]
    rows = ["| flight | " + " | ".join(f"{m} (m)" for m in modes)
            + " | cnn / oracle | none / cnn | cnn global start |",
            "|---|" + "---|" * (len(modes) + 3)]

    def row(name: str, err: dict, conv: str) -> str:
        cells = [f"{err[m]:.4f}" if m in err else "-" for m in modes]
        ratio = (f"{err['cnn'] / err['oracle']:.2f}" if {"cnn", "oracle"} <= err.keys()
                 else "-")
        gain = f"{err['none'] / err['cnn']:.2f}" if {"cnn", "none"} <= err.keys() else "-"
        return f"| {name} | " + " | ".join(cells) + f" | {ratio} | {gain} | {conv} |"

    pooled: dict[str, dict[str, list[float]]] = {}
    for name in sorted(flights):
        d = flights[name]
        err = {m: d[m]["mean_position_error_m"] for m in modes if m in d}
        g = d.get("cnn", {}).get("global")
        conv = f"{g['converged_within_rate']:.0%}" if g else "-"
        rows.append(row(name, err, conv))
        preset = re.sub(r"_\d+$", "", name)
        for m, e in err.items():
            pooled.setdefault(preset, {}).setdefault(m, []).append(e)
    for preset, errs in sorted(pooled.items()):
        n = len(next(iter(errs.values())))
        rows.append(row(f"**{preset}, {n} flights pooled**",
                        {m: sum(v) / len(v) for m, v in errs.items()}, ""))
    return rows


def main(source_wrappers=None) -> None:
    """The command line; ``source_wrappers``: ``localize.offline.runner.run``'s, per edge mode a
    function of the mode's own edge source giving the one to use (benchmarks/class_swap.py)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", type=Path, default=ROOT / "outputs/datasets/demo")
    ap.add_argument("--flights", type=int, default=3, help="new flights per preset")
    ap.add_argument("--out", type=Path, default=None,
                    help="flights-only dataset (default: <dataset>_flights beside it)")
    ap.add_argument("--own", action=argparse.BooleanOptionalAction, default=True,
                    help="also localize the dataset's own flights and pool them with the new")
    ap.add_argument("overrides", nargs="*", help="python -m localize overrides (key=value)")
    a = ap.parse_args()
    if a.flights < 1:
        ap.error("--flights must be >= 1")
    out = a.out or a.dataset.with_name(a.dataset.name + "_flights")
    render(flights_config(a.dataset, a.flights, out))
    runs = [(out, None)] + ([(a.dataset, "_own")] if a.own else [])
    reports = []
    for dataset, suffix in runs:
        with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
            cfg = compose(config_name="localize", overrides=[
                f"dataset={dataset}", f"name={out.name}", "inits=[tracking]", *a.overrides])
        if suffix:  # the own flights' report beside the new ones' (a `name=` override too)
            cfg.name = f"{cfg.name}{suffix}"
        reports.append(localize(cfg, source_wrappers))
    metrics = merge_flights(*(json.loads((r.parent / "metrics.json").read_text())
                              for r in reports))
    own = " and its own" if a.own else ""
    print(f"\n{a.flights} new flights per preset of {a.dataset}{own} (reports: "
          f"{', '.join(str(r) for r in reports)})\n")
    print("\n".join(summarize(metrics)))


if __name__ == "__main__":
    main()
