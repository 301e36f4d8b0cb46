"""Are the defaults still the best on flights no figure is reported on? Each setting the
corridor's defaults were chosen by, one step below and one above its default, on a dataset's
validation flights (``flight_set=val``: datagen's ``val_flights``, ``<preset>_val``).

Every variant is one ``python -m localize`` report (``<name>_<variant>``, tracking starts, the
seeds given) over the validation flights; the table gives each variant's mean position error
per mode, pooled over the flights and seeds, against the defaults'. A default holds when no
variant beats it by more than the seeds' spread; the test flights are never read.

    python benchmarks/default_check.py                       # the demo's dataset and SegNet
    python benchmarks/default_check.py --dataset outputs/datasets/big onnx_model=...

Resumes: a finished variant's report is read, not run again.
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

from localize.offline.runner import run as localize  # noqa: E402

#: variant -> (the modes it concerns, its overrides). The corridor's defaults chosen on flights:
#: the likelihood's sigma (cnn and oracle: 0.1), the cnn mode's k (40) and the yaw noise of
#: the label modes (0.2 deg a frame).
VARIANTS = {
    "defaults": (("none", "cnn", "oracle"), []),
    "sigma_0.07": (("cnn", "oracle"), ["filter.likelihood.sigma=0.07"]),
    "sigma_0.14": (("cnn", "oracle"), ["filter.likelihood.sigma=0.14"]),
    "cnn_k_30": (("cnn",), ["filter.mode_likelihood.cnn.k=30"]),
    "cnn_k_55": (("cnn",), ["filter.mode_likelihood.cnn.k=55"]),
    "yaw_noise_0.1": (("cnn", "oracle"), ["filter.mode_motion_std.cnn=[0.01,0.005,0.1]",
                                          "filter.mode_motion_std.oracle=[0.01,0.005,0.1]"]),
    "yaw_noise_0.35": (("cnn", "oracle"), ["filter.mode_motion_std.cnn=[0.01,0.005,0.35]",
                                           "filter.mode_motion_std.oracle=[0.01,0.005,0.35]"]),
}


def errors(metrics: dict) -> dict[str, list[float]]:
    """Per mode, the mean position error (m) of each validation flight and seed."""
    out: dict[str, list[float]] = {}
    for flight in metrics["flights"].values():
        for mode, d in flight.items():
            out.setdefault(mode, []).extend(d["per_seed_mean_m"])
    return out


def table(results: dict[str, dict[str, list[float]]]) -> list[str]:
    """Markdown rows: per variant and mode, mean (m) over flights x seeds and the ratio to the
    defaults'; the defaults' row gives the seeds' spread (std of the per-run means)."""
    base = results["defaults"]
    rows = ["| variant | mode | mean error (m) | vs defaults |", "|---|---|---|---|"]
    for name, by_mode in results.items():
        for mode, vals in sorted(by_mode.items()):
            mean = float(np.mean(vals))
            if name == "defaults":
                rows.append(f"| defaults | {mode} | {mean:.4f} (std {np.std(vals):.4f}, "
                            f"{len(vals)} runs) | 1.00 |")
            else:
                rows.append(f"| {name} | {mode} | {mean:.4f} | "
                            f"{mean / float(np.mean(base[mode])):.2f} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", type=Path, default=ROOT / "outputs/datasets/demo")
    ap.add_argument("--name", default="default_check", help="report name prefix")
    ap.add_argument("--seeds", default="[0,1,2]")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("overrides", nargs="*", help="python -m localize overrides for every variant")
    a = ap.parse_args()
    results = {}
    for name in ["defaults", *[v for v in a.variants if v != "defaults"]]:
        modes, extra = VARIANTS[name]
        with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
            cfg = compose(config_name="localize", overrides=[
                f"dataset={a.dataset}", f"name={a.name}_{name}", "flight_set=val",
                "inits=[tracking]", f"seeds={a.seeds}", f"modes=[{','.join(modes)}]",
                *a.overrides, *extra])
        report = localize(cfg)
        results[name] = errors(json.loads((report.parent / "metrics.json").read_text()))
        print(f"{name}: " + ", ".join(f"{m} {np.mean(v):.4f} m"
                                      for m, v in sorted(results[name].items())), flush=True)
    print(f"\nValidation flights of {a.dataset} (tracking starts, seeds {a.seeds}):\n")
    print("\n".join(table(results)))


if __name__ == "__main__":
    main()
