"""Test-split accuracy of a trained model against the targets (reads metrics.json).

Usage::

    python -m train                                  # writes outputs/models/demo/metrics.json
    python benchmarks/train_accuracy.py [outputs/models/demo]

Targets (issue "train"): pixel accuracy >= 0.95 and mean IoU >= 0.85 over the classes present
on the synthetic test split, training within 20 minutes on 2 CPU cores, ONNX parity <= 1e-4.
The SegNet paper reports 82-85 % pixel accuracy on its data (a different, real dataset).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

TARGETS = {"pixel_accuracy": 0.95, "mean_iou": 0.85}
MAX_TRAIN_MINUTES = 20.0
MAX_ONNX_DIFF = 1e-4


def main() -> int:
    model_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "outputs/models/demo")
    path = model_dir / "metrics.json"
    if not path.is_file():
        print(f"{path} not found; train first with `python -m train`", file=sys.stderr)
        return 2
    m = json.loads(path.read_text())
    test = m["test"]
    rows = [
        ("pixel accuracy", test["pixel_accuracy"], f">= {TARGETS['pixel_accuracy']}",
         test["pixel_accuracy"] >= TARGETS["pixel_accuracy"]),
        ("class accuracy", test["class_accuracy"], "", None),
        ("mean IoU (present classes)", test["mean_iou"], f">= {TARGETS['mean_iou']}",
         test["mean_iou"] >= TARGETS["mean_iou"]),
        ("train minutes", m["train_seconds"] / 60.0, f"<= {MAX_TRAIN_MINUTES}",
         m["train_seconds"] / 60.0 <= MAX_TRAIN_MINUTES),
        ("whole run minutes", m.get("run_seconds", float("nan")) / 60.0, "", None),
        ("onnx max |diff|", m["onnx_max_abs_diff"], f"<= {MAX_ONNX_DIFF}",
         m["onnx_max_abs_diff"] is not None and m["onnx_max_abs_diff"] <= MAX_ONNX_DIFF),
    ]
    print(f"{model_dir}: {m.get('epochs_done')} / {m.get('epochs')} epochs, best epoch "
          f"{m.get('best_epoch')}, model {m.get('model', {}).get('name')}, "
          f"{m.get('images', {}).get('test')} test images")
    for name, value, target, ok in rows:
        flag = "" if ok is None else ("PASS" if ok else "MISS")
        print(f"  {name:<28}{value:>10.4g}  {target:<10}{flag}")
    print("  per-class IoU: " + ", ".join(
        f"{k} {v:.3f}" for k, v in test["per_class_iou"].items() if v is not None))
    return 0 if all(ok for *_, ok in rows if ok is not None) else 1


if __name__ == "__main__":
    sys.exit(main())
