"""Model edges of an imported building: class pairs, time, what the localizer scores.

Usage::

    python benchmarks/edges_scale.py                  # ../shared/worlds/aws_hospital
    python benchmarks/edges_scale.py --path some.world --step 0.5

Imports the building (``datagen.importers.load_building``, the ``world=file`` defaults),
times ``datagen.mesh.edges.extract_edges`` (best of ``--repeat``; the covered-face and boundary
probes included, the Mitsuba variant chosen beforehand as a datagen run does) and prints:
segments and metres per class pair (largest first), the segments the localizer scores
(``localize.localizer.scored_segments``, ``--min-length`` m) and their samples every
``--spacing`` m, and of those the ones between two different structural classes (the
boundaries the label modes see: floor|wall, wall|ceiling, wall|door, ...) and the ones with
void on one side; then a JSON line. Exits 0 with a message when the building is absent.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import classes as C  # noqa: E402
from datagen.mesh.edges import BoundaryProbe, extract_edges  # noqa: E402

HOSPITAL = ROOT.parent / "shared" / "worlds" / "aws_hospital" / "worlds" / "hospital.world"


def pair_table(seg: np.ndarray, cls: np.ndarray) -> list[tuple[str, int, float]]:
    """(name, segments, metres) per class pair, most metres first."""
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    keys, inv = np.unique(cls, axis=0, return_inverse=True)
    inv = inv.ravel()
    rows = [(f"{C.NAMES[a]}|{C.NAMES[b]}", int((inv == k).sum()),
             float(length[inv == k].sum())) for k, (a, b) in enumerate(keys)]
    return sorted(rows, key=lambda r: -r[2])


def scored(seg: np.ndarray, cls: np.ndarray, min_length: float, spacing: float) -> dict:
    """Segments and samples the localizer scores: all, those between two different
    structural classes, those with void on one side."""
    from localize.edge_model import scored_segments
    from localize.filter.projection import sample_segments

    world = SimpleNamespace(segments=seg, segment_classes=cls)
    keep = scored_segments(world, min_length)
    change = keep & np.isin(cls, C.STRUCTURAL).all(axis=1) & (cls[:, 0] != cls[:, 1])
    void = keep & (cls == C.VOID).any(axis=1)
    out = {}
    for name, m in (("scored", keep), ("class_change", change), ("void", void)):
        out[f"{name}_segments"] = int(m.sum())
        out[f"{name}_samples"] = len(sample_segments(seg[m], spacing).points) if m.any() else 0
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--path", type=Path, default=HOSPITAL)
    ap.add_argument("--step", type=float, default=BoundaryProbe.step)
    ap.add_argument("--min-length", type=float, default=0.05)
    ap.add_argument("--spacing", type=float, default=0.1)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    if not args.path.exists():
        print(f"{args.path} not found: nothing to measure (needs ../shared/worlds)")
        return 0
    from core.imaging.variant import choose_variant
    from datagen.importers import load_building
    from datagen.worlds.site import world_config

    spec = world_config({"kind": "file", "path": str(args.path)})
    b = load_building(settings=spec)
    choose_variant("auto")
    best = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        seg, cls, crease, _ = extract_edges(b.vertices, b.faces, b.face_class, spec.crease_deg,
                                         BoundaryProbe(step=args.step))
        best = min(best, time.perf_counter() - t0)
    print(f"{args.path.name}: {len(b.faces)} faces -> {len(seg)} segments, "
          f"{np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum():.0f} m, "
          f"extract_edges {best:.2f} s")
    table = pair_table(seg, cls)
    for name, n, metres in table[:16]:
        print(f"  {name:18s} {n:7d} {metres:8.0f} m")
    res = {"faces": len(b.faces), "segments": len(seg), "extract_s": round(best, 2),
           **scored(seg, cls, args.min_length, args.spacing),
           "pairs_m": {name: round(m, 1) for name, _, m in table}}
    print(f"scored (>= {args.min_length} m): {res['scored_segments']} segments, "
          f"{res['scored_samples']} samples; between two structural classes: "
          f"{res['class_change_segments']} segments, {res['class_change_samples']} samples; "
          f"void on one side: {res['void_segments']} segments, {res['void_samples']} samples")
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
