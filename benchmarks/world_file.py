"""One command from a building file reproduces the dataset path: ``world=FILE`` against
``dataset=``.

Usage::

    python benchmarks/world_file.py                                   # the ring, rendered here
    python benchmarks/world_file.py --dataset outputs/benchmarks/thirdparty/datasets/bookstore
    python benchmarks/world_file.py --dataset DS --flight cluttered --frames 400 --modes none cnn

A building rendered by ``python -m datagen world=file`` (``--dataset``: one made already, e.g.
by benchmarks/thirdparty.py; default: a 10 m ring corridor written as a glTF and rendered
here, one 320 x 240 flight of ``--frames`` frames), then:

1. the map of ``world=FILE``: ``localize.world_file.file_map`` of the dataset's building file
   with its ``world.*`` keys (those that differ from the defaults), into a fresh cache; its
   model, edges and free space compared with the dataset's ``world/`` (equal arrays, or the
   largest difference);
2. the flight exported as a folder recording (``localize.recordings.export``: JPEG frames,
   camera.yaml with the mount, odometry, ground truth);
3. ``python -m localize recording=REC dataset=DS`` and ``python -m localize recording=REC
   world=FILE``, the defaults (the shipped SegNet), modes ``--modes``, seed 0, tracking from
   the first true pose; then a second ``world=FILE`` run in a fresh report folder: the cache
   reused (no import) and its time.

Prints, per mode, the mean / p95 position error of both paths and their largest
per-frame difference; writes ``<out>/world_file.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.atomic import atomic_write_json  # noqa: E402
from core.dataset import Dataset, load_world  # noqa: E402
from core.poses import read_tum  # noqa: E402


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", type=Path, default=None,
                    help="a world=file dataset (default: render the ring corridor)")
    ap.add_argument("--flight", default="paper")
    ap.add_argument("--frames", type=int, default=120, help="frames run (and rendered)")
    ap.add_argument("--modes", nargs="+", default=["none", "cnn"])
    ap.add_argument("--out", type=Path, default=ROOT / "outputs" / "benchmarks" / "world_file")
    return ap.parse_args()


def run(cmd: list[str]) -> float:
    """Run a command from the repository's root; its wall time (s)."""
    print("+ " + " ".join(str(c) for c in cmd[1:]), flush=True)
    t0 = time.perf_counter()
    subprocess.run([str(c) for c in cmd], check=True, cwd=ROOT)
    return time.perf_counter() - t0


def ring_dataset(out: Path, frames: int) -> Path:
    """A 10 m square ring corridor 2 m wide (walls 2.8 m, 0.2 m thick, on one slab; the
    tests' ``tests.buildings.ring``) as a glTF, rendered by datagen: one flight."""
    import trimesh

    glb = out / "ring.glb"
    if not glb.is_file():
        boxes = [(-0.2, -0.2, 10.2, 10.2, -0.2, 0.0), (-0.2, -0.2, 10.2, 0, 0, 2.8),
                 (-0.2, 10, 10.2, 10.2, 0, 2.8), (-0.2, 0, 0, 10, 0, 2.8),
                 (10, 0, 10.2, 10, 0, 2.8), (2, 2, 8, 8, 0, 2.8)]
        mesh = trimesh.util.concatenate([trimesh.creation.box(
            extents=(x1 - x0, y1 - y0, z1 - z0),
            transform=trimesh.transformations.translation_matrix(
                ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2)))
            for x0, y0, x1, y1, z0, z1 in boxes])
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
        glb.parent.mkdir(parents=True, exist_ok=True)
        mesh.export(glb)
    ds = out / "datasets" / "ring"
    run([sys.executable, "-m", "datagen", "name=ring", f"out_dir={ds}", "world=file",
         f"world.path={glb}", "splits.train=0", "splits.val=0", "splits.test=0",
         "val_flights=[]", "render_flights=[paper]", f"flights.paper.num_frames={frames}",
         "progress=false"])
    return ds


def world_overrides(ds: Dataset) -> tuple[str, dict]:
    """The dataset's building file and its ``world.*`` import keys that differ from the
    defaults (``WorldFileConfig``'s keys only)."""
    from dataclasses import asdict, fields

    from datagen.config import FileWorldConfig
    from localize.config import WorldFileConfig

    given = ds.meta["generator"]["world"]
    if given.get("kind") != "file":
        raise SystemExit(f"{ds.root}: not a world=file dataset (world.kind {given.get('kind')})")
    base = asdict(FileWorldConfig(path=given["path"]))
    keys = {f.name for f in fields(WorldFileConfig)} - {"path", "cache"}
    return given["path"], {k: given[k] for k in sorted(keys) if given.get(k) != base.get(k)}


def compare_maps(a: Path, b: Path) -> dict:
    """Per array of model.npz, edges.npz and free.npz: equal, or the largest difference."""
    out = {}
    for name in ("model.npz", "edges.npz", "free.npz"):
        x, y = np.load(a / name), np.load(b / name)
        for k in sorted(set(x.files) | set(y.files)):
            if k not in x.files or k not in y.files:
                out[f"{name}:{k}"] = "missing on one side"
            elif x[k].shape != y[k].shape:
                out[f"{name}:{k}"] = f"shape {x[k].shape} vs {y[k].shape}"
            elif x[k].dtype.kind in "fc":
                d = float(np.nanmax(np.abs(x[k] - y[k]))) if x[k].size else 0.0
                same = np.array_equal(x[k], y[k], equal_nan=True)
                out[f"{name}:{k}"] = "equal" if same else f"max diff {d:.3g}"
            else:
                out[f"{name}:{k}"] = "equal" if np.array_equal(x[k], y[k]) else "differ"
    return out


def errors(report: Path, mode: str) -> tuple[dict, np.ndarray, np.ndarray]:
    """A recording report's metrics of ``mode`` and its trajectory (timestamps, xyz)."""
    m = json.loads((report / "metrics.json").read_text())
    entry = next(iter(m["flights"].values()))[mode]
    t, poses = read_tum(report / "trajectories" / f"{mode}.txt")
    return entry, t, poses[:, :3, 3]


def main() -> None:
    args = parse_args()
    out = args.out.resolve()
    ds_path = (args.dataset.resolve() if args.dataset else ring_dataset(out, args.frames))
    ds = Dataset(ds_path)
    path, keys = world_overrides(ds)
    name = ds_path.name
    cache = out / "cache" / name
    from localize.world_file import file_map

    t0 = time.perf_counter()
    found = file_map(path, keys, str(cache))
    import_s = time.perf_counter() - t0
    maps = compare_maps(ds_path / "world", found.folder)
    w = load_world(found.folder)
    print(f"map of {path}: {found.folder} ({'reused' if found.reused else 'imported'} in "
          f"{import_s:.1f} s): {len(w.segments)} edges, {w.free.area:.1f} m2 free")
    for k, v in maps.items():
        print(f"  {k}: {v}")
    rec = out / "recordings" / f"{name}_{args.flight}"
    if not rec.exists():
        run([sys.executable, "-m", "localize.recordings.export", ds_path, args.flight, rec])
    common = [f"recording={rec}", f"out_root={out / 'reports'}",
              f"modes=[{','.join(args.modes)}]", "seeds=[0]", f"max_frames={args.frames}",
              "progress=false", f"world.cache={cache}"]
    world_keys = [f"world.{k}={json.dumps(v)}" for k, v in keys.items()]
    seconds = {
        "dataset": run([sys.executable, "-m", "localize", f"name={name}_dataset",
                        f"dataset={ds_path}", *common]),
        "world": run([sys.executable, "-m", "localize", f"name={name}_world", f"world={path}",
                      *world_keys, *common]),
        "world_again": run([sys.executable, "-m", "localize", f"name={name}_world_again",
                            "overwrite=true", f"world={path}", *world_keys, *common]),
    }
    result = {"dataset": str(ds_path), "world": path, "world_keys": keys, "flight": args.flight,
              "frames": args.frames, "map": maps, "import_s": round(import_s, 1),
              "seconds": {k: round(v, 1) for k, v in seconds.items()}, "modes": {}}
    print(f"\n{name}, flight {args.flight}, {args.frames} frames; import {import_s:.1f} s; "
          f"runs: dataset {seconds['dataset']:.1f} s, world=FILE {seconds['world']:.1f} s, "
          f"again (cache reused) {seconds['world_again']:.1f} s")
    print("| mode | dataset= mean / p95 (m) | world=FILE mean / p95 (m) | largest difference (m) |")
    print("|---|---|---|---|")
    for mode in args.modes:
        a, ta, xa = errors(out / "reports" / f"{name}_dataset" / "recordings" / rec.name, mode)
        b, tb, xb = errors(out / "reports" / f"{name}_world" / "recordings" / rec.name, mode)
        same_t = len(ta) == len(tb) and np.allclose(ta, tb)
        diff = float(np.abs(xa - xb).max()) if same_t else float("nan")
        result["modes"][mode] = {
            "dataset": {"mean_m": a["mean_position_error_m"], "p95_m": a["p95_m"]},
            "world": {"mean_m": b["mean_position_error_m"], "p95_m": b["p95_m"]},
            "max_trajectory_difference_m": diff}
        print(f"| {mode} | {a['mean_position_error_m']:.4f} / {a['p95_m']:.4f} | "
              f"{b['mean_position_error_m']:.4f} / {b['p95_m']:.4f} | {diff:.2e} |")
    atomic_write_json(out / f"world_file_{name}.json", result)


if __name__ == "__main__":
    main()
