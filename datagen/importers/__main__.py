"""Check a building import: ``python -m datagen.importers FILE [--out DIR]``.

Prints the counts, class area shares, missing models and the time, the import summary (its
figures and what looks wrong, each with the key to set: datagen/importers/summary.py), the
free space and a planned route, and writes ``DIR/<name>_plan.png`` (top-down plan of the
classes), ``DIR/<name>_free.png`` (the free space of the flyable heights, with the route),
``DIR/<name>_import.json`` (info) and ``DIR/<name>_summary.json`` (the summary).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import numpy as np

from core.atomic import atomic_write_json, write_png
from core.config import user_errors
from core.occupancy import OccupancyMap
from datagen.config import FileWorldConfig, RouteConfig
from datagen.flights.routes import find_turns, plan_route, route_length
from datagen.importers.config import ImportConfig
from datagen.importers.load import EXTENSIONS, load_building
from datagen.importers.orient import AXES
from datagen.importers.summary import (
    edge_figures,
    import_summary,
    summary_lines,
    vertical_edges,
)
from datagen.mesh.building import Building
from datagen.mesh.plan import write_plan
from datagen.worlds.site import camera_free_space


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
    p.add_argument("--up-axis", choices=("auto", *AXES, "x", "y", "z"), default="auto",
                   help="the file's up axis (OBJ/PLY/STL/DAE; default auto: found from the mesh); "
                   "a minus sign needs '=': --up-axis=-y")
    p.add_argument("--storey", default=None, help="IFC storey name (default: the ground storey)")
    p.add_argument("--doors", choices=("open", "closed"), default="open")
    p.add_argument("--ceiling", choices=("auto", "none"), default="auto")
    p.add_argument("--px", type=float, default=None, help="plan image metres per pixel")
    p.add_argument("--cut", type=float, default=None, help="plan cut height in metres "
                   "(default: 1.5 m above the floor)")
    p.add_argument("--route-length", type=float, default=40.0, help="metres the planned route "
                   "should reach (drawn again up to 8 times, else laps of a loop around the "
                   "free space; default 40)")
    p.add_argument("--seed", type=int, default=0, help="seed of the route's ends")
    return p.parse_args(argv)


def free_space_and_route(b: Building, min_length: float, seed: int
                         ) -> tuple[OccupancyMap, np.ndarray | None, dict]:
    """The free space above the building's floor as ``world=file`` builds it
    (``FileWorldConfig``: ``z_range``, ``camera_margin``, ``free_cell``), and a route through
    it with at least two turns of 60 deg and ``min_length`` metres, else one fitted to the free
    space (``plan_route``: fewer turns, or laps of a loop; a warning).

    Returns:
        the map, the route ((K, 2) m, or None where the free space is too small for any) and
        the figures printed and stored in info.
    """
    occ = camera_free_space(b, FileWorldConfig(path=b.info["source"]))
    figures = {"free_area_m2": round(occ.area, 1)}
    try:
        route = plan_route(occ, np.random.default_rng(seed),
                           RouteConfig(min_length=min_length, min_turns=2))
    except ValueError as err:
        figures["route_error"] = str(err)
        return occ, None, figures
    figures.update(route_m=round(route_length(route), 1),
                   route_turns_deg=[round(float(a)) for _, a in find_turns(route)])
    return occ, route, figures


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
    settings = ImportConfig(path=args.file, model_path=args.model_path, units=args.units,
                              up_axis=args.up_axis, storey=args.storey, doors=args.doors,
                              ceiling=args.ceiling)
    try:
        b = load_building(settings=settings)
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out = Path(args.out)
    stem = Path(args.file).stem
    occ, route, figures = free_space_and_route(b, args.route_length, args.seed)
    plan = write_plan(b, out / f"{stem}_plan.png", args.px, args.cut, occ,
                      [] if route is None else [route])
    write_png(out / f"{stem}_free.png", occ.plot([] if route is None else [route], scale=2))
    from datagen.mesh.edges import extract_edges

    edges = extract_edges(b.vertices, b.faces, b.face_class, FileWorldConfig.crease_deg)
    report = import_summary(b, occ.area, vertical_edges(edges.segments),
                            edge_figures(b, edges, occ))
    atomic_write_json(out / f"{stem}_import.json", {**b.info, **figures})
    atomic_write_json(out / f"{stem}_summary.json", report)
    print(summary(b.info))
    print("\n".join(summary_lines(report)))
    print(f"free space {figures['free_area_m2']} m2; " + (
        f"route {figures['route_m']} m, turns {figures['route_turns_deg']} deg" if route is not None
        else f"no route: {figures['route_error']}"))
    print(f"plan: {plan}\nfree space: {out / f'{stem}_free.png'}")
    return 0


if __name__ == "__main__":
    with user_errors():
        sys.exit(main())
