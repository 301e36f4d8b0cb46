"""The third-party table: buildings and images nobody on the project made, with the defaults.

Usage::

    python benchmarks/thirdparty.py                                # every building, all modes
    python benchmarks/thirdparty.py --buildings icl_scan floor101 --frames 300 --seeds 0
    python benchmarks/thirdparty.py --onnx outputs/models/mine/segnet.onnx --name mine
    python benchmarks/thirdparty.py --buildings bookstore --finetune 1000  # + the fine-tune

Per building, with no per-building setting: ``python -m datagen`` renders its test flights
(``flights=floor``: two 115 s passes along routes planned through its free space; the scan:
``flights=handheld``, camera 1.0-1.6 m, tilts up to ~8 deg, yaw swings up to ~90 deg/s),
no training images and no validation flights (this table is test data: no setting is chosen
on it); then the SegNet (``--onnx``, default the shipped generalist; its int8 copy where one
lies beside it, as localize runs it: ``segmenter.runtime_model``) is scored on every delivered
flight frame (pixel accuracy, mean IoU, boundary F at 2 px: what the likelihood needs), the
model edges are checked against the model's label maps at the flights' poses
(``datagen.mesh.edge_check``: recall and precision at 2 px, "edges R / P"), and
``python -m localize`` tracks each flight from its true start in the given modes
and seeds. The scan's first test flight is also exported as a folder recording
(``localize.recordings.export``: JPEG frames, odometry) and localized as a user's recording.
With ``--finetune N``, N training and N / 8 validation and test images of the building (a dataset of
their own, ``datasets/<building>_train``, apart from the test flights) fine-tune the SegNet
(``experiment=finetune``: 9 epochs from the generalist; the epochs, not the minutes, bound it,
so a busy machine trains the same network), and cnn runs again with it (``cnn_ft``); where the
fine-tune shows no gain on its own validation renders its folder holds the generalist
(``keep``: docs/recipes.md, "A fine-tune that never hurts"), recorded as ``kept``.

Buildings: the AWS hospital and bookstore (Gazebo worlds) and the ICL office scan from
``../shared/worlds`` (skipped where absent), and three procedural floors whose seeds (101-103)
no shipped SegNet was trained on (the generalist: seeds 0-23).

Writes ``<out-root>/<name>/``: one dataset and one localize report per building
(``datasets/<building>``, ``reports/<building>``), ``thirdparty.json`` and ``thirdparty.md``
(the table); thirdparty.json also records the SegNet's digest (``onnx_sha256``) and the
frames per flight, which ``benchmarks/promote.py`` checks before comparing two tables.
Finished datasets, scores and runs are kept, so a second call only collects and an interrupted
one resumes. Lost: a run whose error stayed above 1 m for more than 1 s.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SHARED = ROOT.parent / "shared" / "worlds"

from core.atomic import atomic_write_json, atomic_write_text, file_sha256  # noqa: E402
from localize.frontend.segmenter import runtime_model  # noqa: E402

#: building -> (the model file under ../shared/worlds or None, datagen overrides)
BUILDINGS: dict[str, tuple[str | None, list[str]]] = {
    "hospital": ("aws_hospital/worlds/hospital.world", ["world=file", "flights=floor"]),
    "bookstore": ("aws_bookstore/worlds/bookstore.world", ["world=file", "flights=floor"]),
    "icl_scan": ("icl_office_scan/of_kt2_planeopt.obj", ["world=file", "flights=handheld"]),
    **{f"floor{s}": (None, ["world=procedural", f"world.seed={s}", "flights=floor"])
       for s in (101, 102, 103)},
}
RECORDING_OF = {"icl_scan"}  # buildings whose first test flight is also run as a recording
GENERALIST = ROOT / "models" / "generalist" / "segnet.onnx"


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--buildings", nargs="+", default=list(BUILDINGS), choices=list(BUILDINGS))
    ap.add_argument("--onnx", type=Path, default=GENERALIST, help="the SegNet of cnn mode")
    ap.add_argument("--modes", nargs="+", default=["none", "cnn", "oracle"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--frames", type=int, default=None,
                    help="frames per flight (default: the flight preset's)")
    ap.add_argument("--finetune", type=int, default=0, metavar="N",
                    help="fine-tune on N training images of each building (0: no fine-tune)")
    ap.add_argument("--out-root", type=Path, default=ROOT / "outputs" / "benchmarks")
    ap.add_argument("--name", default="thirdparty")
    return ap.parse_args()


def onnx_digest(path: Path) -> str:
    """16 hex digits of the file's sha256: the digest localize records (``onnx_sha256``)."""
    return file_sha256(path)[:16]


def run(cmd: list[str]) -> None:
    print("+ " + " ".join(str(c) for c in cmd[1:]), flush=True)
    subprocess.run([str(c) for c in cmd], check=True, cwd=ROOT)


def datagen(building: str, out: Path, frames: int | None) -> Path | None:
    """The building's test flights (rendered once); None where its model is absent."""
    model, overrides = BUILDINGS[building]
    if model is not None and not (SHARED / model).is_file():
        print(f"{building}: skipped, {SHARED / model} not found", flush=True)
        return None
    ds = out / "datasets" / building
    cmd = [sys.executable, "-m", "datagen", f"name={building}", f"out_dir={ds}",
           "splits.train=0", "splits.val=0", "splits.test=0", "val_flights=[]", *overrides]
    if model is not None:
        cmd.append(f"world.path={SHARED / model}")
    if frames:
        cmd += [f"flights.{p}.num_frames={frames}" for p in ("paper", "cluttered")]
    run(cmd)  # a finished dataset is resumed: nothing rendered again
    return ds


def finetune(building: str, out: Path, images: int) -> Path:
    """The SegNet fine-tuned on ``images`` training renders of the building (rendered and
    trained once); its ONNX file."""
    model, overrides = BUILDINGS[building]
    train_ds = out / "datasets" / f"{building}_train"
    cmd = [sys.executable, "-m", "datagen", f"name={building}_train", f"out_dir={train_ds}",
           f"splits.train={images}", f"splits.val={max(images // 8, 1)}",
           f"splits.test={max(images // 8, 1)}",
           "render_flights=[]", "val_flights=[]", *overrides]
    if model is not None:
        cmd.append(f"world.path={SHARED / model}")
    run(cmd)
    onnx = out / "models" / building / "segnet.onnx"
    if not onnx.is_file():
        run([sys.executable, "-m", "train", "experiment=finetune", f"name={building}",
             f"dataset={train_ds}", f"out_root={onnx.parent.parent}", "max_minutes=null",
             "progress=false"])
    return onnx


def segnet_scores(ds: Path, onnx: Path, cache: Path) -> dict:
    """Pixel accuracy, mean IoU, per-class IoU and boundary F of ``onnx`` on every delivered
    test-flight frame of ``ds`` (kept in ``cache``)."""
    key = f"{onnx.resolve()}"
    done = json.loads(cache.read_text()) if cache.is_file() else {}
    if key in done:
        return done[key]
    import torch

    from benchmarks.segnet_flights import labelled_batches
    from core.dataset import Dataset
    from localize.frontend.segmenter import load_segmenter
    from train.metrics import boundary_counts, boundary_f, confusion_matrix, metrics_json

    dataset = Dataset(ds)
    seg = load_segmenter(onnx, dataset.classes)
    cm = torch.zeros(seg.num_classes, seg.num_classes, dtype=torch.int64)
    bc = np.zeros(4, np.int64)
    for pred, truth in labelled_batches(seg, dataset, "test", progress=False):
        cm += confusion_matrix(torch.from_numpy(pred.astype(np.int64)),
                               torch.from_numpy(truth.astype(np.int64)), seg.num_classes)
        bc += sum(boundary_counts(p, t) for p, t in zip(pred, truth, strict=True))
    m = metrics_json(cm, [c["name"] for c in dataset.classes])
    res = {k: m[k] for k in ("pixel_accuracy", "mean_iou", "per_class_iou")} | boundary_f(bc)
    atomic_write_json(cache, {**done, key: res})
    return res


def edge_scores(ds: Path, cache: Path, step: int = 20) -> dict:
    """Rendered-edge recall and precision (``datagen.mesh.edge_check``) of the dataset's model
    edges at every ``step``-th ground-truth pose of its test flights (kept in ``cache`` under
    the digest of the edges, their classes and normals)."""
    from core.dataset import Dataset
    from datagen.mesh.edge_check import EdgeChecker, agreement

    dataset = Dataset(ds)
    w, cam = dataset.world(), dataset.camera
    h = hashlib.sha256()
    for a in (w.segments, w.segment_classes, w.normals):
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    key = h.hexdigest()[:16]
    done = json.loads(cache.read_text()) if cache.is_file() else {}
    if key in done:
        return done[key]
    checker = EdgeChecker(w.vertices, w.faces, w.face_class, w.segments, w.segment_classes,
                          cam.K, cam.width, cam.height, w.normals)
    poses = np.concatenate([dataset.flight(n).groundtruth[::step] @ cam.body_from_cam
                            for n in dataset.flight_names("test")])
    res = agreement(checker, poses).as_dict()
    cache.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(cache, {**done, key: res})
    return res


def localize(ds: Path, report: Path, args: argparse.Namespace, rec: Path | None = None,
             onnx: Path | None = None, modes: list[str] | None = None) -> dict:
    """``python -m localize`` on the test flights, or on the recording ``rec``, with the SegNet
    ``onnx`` (None: ``--onnx``) in ``modes`` (None: ``--modes``); its metrics."""
    lst = lambda xs: "[" + ",".join(str(x) for x in xs) + "]"  # noqa: E731
    run([sys.executable, "-m", "localize", f"dataset={ds}", f"onnx_model={onnx or args.onnx}",
         f"out_root={report.parent}", f"name={report.name}",
         f"modes={lst(modes or args.modes)}",
         f"seeds={lst(args.seeds)}", "inits=[tracking]", "progress=false",
         *([f"recording={rec}"] if rec else [])])
    folder = report / "recordings" / rec.name if rec else report
    return json.loads((folder / "metrics.json").read_text())


def recording(ds: Path, out: Path) -> Path:
    """The dataset's first test flight exported as a folder recording (once)."""
    from core.dataset import Dataset

    name = Dataset(ds).flight_names("test")[0]
    rec = out / "recordings" / ds.name
    if not (rec / "images.txt").is_file():
        run([sys.executable, "-m", "localize.recordings.export", ds, name, rec])
    return rec


def tracking(metrics: dict) -> dict:
    """Per mode: mean error over the flights (m), lost runs, frame ms."""
    out = {}
    for per_mode in metrics["flights"].values():
        for mode, e in per_mode.items():
            if "mean_position_error_m" not in e:
                continue
            o = out.setdefault(mode, {"errors": [], "lost": 0, "runs": 0})
            runs = len(e["per_seed_mean_m"])
            o["errors"].append(e["mean_position_error_m"])
            o["runs"] += runs
            o["lost"] += int(round(e["lost_rate"] * runs))
    timing = metrics.get("timing_ms_by_mode", {})
    for mode, o in out.items():
        o["mean_m"] = float(np.mean(o.pop("errors")))
        o["frame_ms"] = timing.get(mode, {}).get("total", {}).get("avg")
    return out


def table(results: dict, modes: list[str]) -> str:
    """The markdown table of ``results`` (one row per building)."""
    head = ["building", "floor / free m²", "flags", "edges R / P", "SegNet acc / mIoU / bF"]
    head += [f"{m} m (lost)" for m in modes]
    if any("finetuned" in r for r in results.values()):
        head += ["fine-tuned mIoU / bF", "cnn fine-tuned m (lost)"]
    head += ["cnn frame ms", "recording cnn / none m"]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for b, r in results.items():
        s = r.get("import") or {}
        seg = r.get("segnet") or {}
        tr = r.get("tracking") or {}
        rec = r.get("recording") or {}
        ed = r.get("edges") or {}
        cells = [b, f"{s.get('floor_footprint_m2', '-')} / {s.get('free_area_m2', '-')}",
                 str(len(s.get("flags", []))) if s else "-",
                 f"{ed['recall']:.3f} / {ed['precision']:.3f}" if ed else "-",
                 (f"{seg['pixel_accuracy']:.3f} / {seg['mean_iou']:.3f} / "
                  f"{seg['boundary_f']:.3f}") if seg else "-"]
        cells += [f"{tr[m]['mean_m']:.3f} ({tr[m]['lost']}/{tr[m]['runs']})" if m in tr else "-"
                  for m in modes]
        if "fine-tuned mIoU / bF" in head:
            ft = r.get("finetuned") or {}
            fs, fc = ft.get("segnet"), ft.get("tracking", {}).get("cnn")
            cells.append((f"{fs['mean_iou']:.3f} / {fs['boundary_f']:.3f}" if fs else "-")
                         + (" (start kept)" if ft.get("kept") == "init" else ""))
            cells.append(f"{fc['mean_m']:.3f} ({fc['lost']}/{fc['runs']})" if fc else "-")
        ms = tr.get("cnn", {}).get("frame_ms")
        cells.append(f"{ms:.0f}" if ms else "-")
        cells.append(" / ".join(f"{rec[m]['mean_m']:.3f}" if m in rec else "-"
                                for m in ("cnn", "none")) if rec else "-")
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def main() -> int:
    args = parse_args()
    args.onnx = runtime_model(str(args.onnx), "")  # scored, run, recorded: what localize runs
    out = args.out_root / args.name
    results: dict = {}
    for b in args.buildings:
        ds = datagen(b, out, args.frames)
        if ds is None:
            continue
        summary = ds / "world" / "import_summary.json"
        r = {"import": json.loads(summary.read_text()) if summary.is_file() else None,
             "edges": edge_scores(ds, out / "edges" / f"{b}.json")}
        if "cnn" in args.modes:
            r["segnet"] = segnet_scores(ds, args.onnx, out / "segnet" / f"{b}.json")
        r["tracking"] = tracking(localize(ds, out / "reports" / b, args))
        if args.finetune:
            onnx = runtime_model(str(finetune(b, out, args.finetune)), "")
            keep = json.loads((onnx.parent / "metrics.json").read_text()).get("keep")
            r["finetuned"] = {
                "onnx": str(onnx), "images": args.finetune,
                "kept": keep["kept"] if keep else "finetuned",
                "segnet": segnet_scores(ds, onnx, out / "segnet" / f"{b}.json"),
                "tracking": tracking(localize(ds, out / "reports" / f"{b}_ft", args,
                                              onnx=onnx, modes=["cnn"]))}
        if b in RECORDING_OF:
            rec = recording(ds, out)
            r["recording"] = tracking(localize(ds, out / "reports" / b, args, rec))
        results[b] = r
        print(f"{b}: " + json.dumps({k: v for k, v in r.items() if k != "import"}), flush=True)
        for f in (r["import"] or {}).get("flags", []):
            print(f"  import flag: {f['what']} (key: {f['key']})")
    md = table(results, args.modes)
    atomic_write_json(out / "thirdparty.json", {
        "onnx": str(args.onnx), "onnx_sha256": onnx_digest(args.onnx), "modes": args.modes,
        "seeds": args.seeds, "frames": args.frames, "finetune": args.finetune,
        "results": results})
    atomic_write_text(out / "thirdparty.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
