"""Check a building import: ``python -m datagen.importers FILE [--out DIR]``.

Prints the counts, class area shares, missing models and the time, and writes
``DIR/<name>_plan.png`` (top-down plan of the classes) and ``DIR/<name>_import.json`` (info).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from datagen.importers.load import EXTENSIONS, load_building
from datagen.importers.plan import write_plan
from datagen.importers.settings import ImportSettings


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m datagen.importers",
                                description="Import a building model and report what came in "
                                            f"({', '.join(EXTENSIONS)}).")
    p.add_argument("file", help="the building model file")
    p.add_argument("--out", default="outputs/imports", help="folder for the plan image and "
                   "info (default: outputs/imports)")
    p.add_argument("--model-path", action="append", default=[], help="a Gazebo model folder "
                   "(repeatable)")
    p.add_argument("--units", type=float, default=1.0, help="metres per file unit (OBJ/PLY/STL)")
    p.add_argument("--up-axis", choices=("z", "y"), default="z")
    p.add_argument("--storey", default=None, help="IFC storey name (default: the ground storey)")
    p.add_argument("--doors", choices=("open", "closed"), default="open")
    p.add_argument("--ceiling", choices=("auto", "none"), default="auto")
    p.add_argument("--px", type=float, default=None, help="plan image metres per pixel")
    p.add_argument("--cut", type=float, default=None, help="plan cut height in metres "
                   "(default: 1.5 m above the floor)")
    return p.parse_args(argv)


def summary(info: dict) -> str:
    """The lines printed for an import."""
    lines = [f"{info['source']}: {info['format']}, {info['faces']} faces, {info['vertices']} "
             f"vertices, {info['seconds']:.1f} s",
             "bounds (m): " + " .. ".join(str([round(v, 2) for v in b]) for b in info["bounds"]),
             f"floor z {info['floor_z']:.2f} m, wall tops {info['wall_top_z']:.2f} m"
             + (f", ceiling added ({info['ceiling_added']} faces)" if info["ceiling_added"]
                else ""),
             "class     faces   area share"]
    for name, share in info["class_shares"].items():
        lines.append(f"{name:8s} {info['faces_per_class'].get(name, 0):7d}   {100 * share:5.1f} %")
    missing = info.get("missing_models", {})
    if missing:
        lines.append(f"missing models ({len(missing)}, {sum(missing.values())} includes): "
                     + ", ".join(f"{n} x{c}" for n, c in missing.items()))
    if info.get("missing_meshes"):
        lines.append(f"missing meshes: {', '.join(info['missing_meshes'])}")
    if info.get("format") == "ifc":
        lines.append(f"storey {info['storey']!r} at {info['elevation']:.2f} m "
                     f"(storeys: {info['storeys']})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    args = parse_args(argv)
    settings = ImportSettings(path=args.file, model_path=args.model_path, units=args.units,
                              up_axis=args.up_axis, storey=args.storey, doors=args.doors,
                              ceiling=args.ceiling)
    try:
        b = load_building(settings=settings)
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out = Path(args.out)
    stem = Path(args.file).stem
    plan = write_plan(b, out / f"{stem}_plan.png", args.px, args.cut)
    (out / f"{stem}_import.json").write_text(json.dumps(b.info, indent=1))
    print(summary(b.info))
    print(f"plan: {plan}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
