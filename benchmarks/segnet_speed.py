"""Segmentation network inference speed: onnxruntime vs torch, ms per frame at the localizer's
input size, for one network or several side by side (SegNet, LR-ASPP).

Usage::

    python benchmarks/segnet_speed.py                      # outputs/models/demo if trained
    python benchmarks/segnet_speed.py --model segnet_small --height 240 --width 320
    python benchmarks/segnet_speed.py --model segnet_small lraspp segnet_wide   # side by side
    python benchmarks/segnet_speed.py --model-dir outputs/models/demo --runs 50 --threads 2
    python benchmarks/segnet_speed.py --model-dir outputs/models/a outputs/models/b
    python benchmarks/segnet_speed.py --model-dir none model.downsample=2 model.stem=unshuffle \
        model.head=sharpen      # the best3_highres recipe's network, random weights

Each trained model folder given (checkpoint_best.pt + segnet.onnx) is timed with its weights,
each ``--model`` preset (conf/model/) as a randomly initialised network exported to a temporary
file (speed does not depend on the weights); without either, conf/model/segnet_small.yaml.
Prints the median and 90th percentile wall time per frame over ``--runs`` runs after warm-up,
and the process CPU time per frame, which is less sensitive to other jobs on a shared machine.
Timings are for batch 1 unless --batch is given. ``onnxruntime_int8`` is the int8 copy
(``train.deploy.quantize``): the model folder's ``segnet_int8.onnx`` if there is one, else the
timed graph quantized here with random calibration frames (speed does not depend on the
ranges).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import onnx
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from core.classes import as_json
from core.segmenter import OnnxSegmenter
from train.deploy.export import graph_module, onnx_metadata, to_onnx_proto
from train.deploy.quantize import INT8_NAME, quantize_segnet
from train.loop.checkpoint import load_checkpoint
from train.net.build import build_model
from train.net.segnet import count_parameters

CONF_DIR = Path(__file__).resolve().parents[1] / "conf"


def timed(fn, runs: int, warmup: int = 3) -> dict:
    """Median / p90 wall ms and median CPU ms of ``fn()`` over ``runs`` calls."""
    for _ in range(warmup):
        fn()
    wall, cpu = [], []
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    wall_ms, cpu_ms = 1e3 * np.array(wall), 1e3 * np.array(cpu)
    return {
        "median_ms": float(np.median(wall_ms)),
        "p90_ms": float(np.percentile(wall_ms, 90)),
        "min_ms": float(wall_ms.min()),
        "cpu_ms": float(np.median(cpu_ms)),
    }


def trained_model(mdir: Path) -> tuple[torch.nn.Module, Path, str] | None:
    """A trained model folder's network and segnet.onnx, or None where it has neither."""
    if (mdir / "checkpoint_best.pt").is_file() and (mdir / "segnet.onnx").is_file():
        return load_checkpoint(mdir / "checkpoint_best.pt"), mdir / "segnet.onnx", str(mdir)
    return None


def preset_model(preset: str, overrides: list[str], height: int, width: int, tmp: Path
                 ) -> tuple[torch.nn.Module, Path, str]:
    """A conf/model preset with random weights, exported to ``tmp``."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("train", overrides=[f"model={preset}", *overrides])
    model = build_model(OmegaConf.to_object(cfg.model), len(as_json()),
                        torch.Generator().manual_seed(0)).eval()
    proto = to_onnx_proto(graph_module(model), height, width)
    onnx.helper.set_model_props(
        proto, onnx_metadata(model, as_json(), height, width, "benchmark"))
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "segnet.onnx"
    onnx.save_model(proto, str(path))
    extra = f" {' '.join(overrides)}" if overrides else ""
    return model, path, f"conf/model/{preset}.yaml{extra} (random weights)"


def time_model(model: torch.nn.Module, onnx_path: Path, args: argparse.Namespace,
               tmp: Path) -> tuple[dict, tuple[int, int]]:
    """ms per frame of each runtime (``timed``) and the graph's input size (H, W)."""
    seg = OnnxSegmenter(onnx_path, threads=args.threads)  # the network
    h, w = seg.input_size
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (args.batch, h, w, 3), dtype=np.uint8)
    x = torch.from_numpy(rgb).permute(0, 3, 1, 2).contiguous().float() / 255.0
    results = {}
    torch.set_num_threads(args.threads)
    with torch.inference_mode():
        results["torch"] = timed(lambda: model(x), args.runs)
    results["onnxruntime"] = timed(lambda: seg.logits(rgb), args.runs)
    results["onnxruntime_predict"] = timed(lambda: seg.predict(rgb), args.runs)
    seg1 = OnnxSegmenter(onnx_path, threads=1)
    results["onnxruntime_1thread"] = timed(lambda: seg1.logits(rgb), args.runs)
    int8_path = onnx_path.parent / INT8_NAME
    if not int8_path.is_file():
        tmp.mkdir(parents=True, exist_ok=True)
        int8_path = tmp / INT8_NAME
        quantize_segnet(onnx_path, int8_path, rng.integers(0, 256, (8, h, w, 3), np.uint8))
    seg8 = OnnxSegmenter(int8_path, threads=args.threads)
    results["onnxruntime_int8"] = timed(lambda: seg8.logits(rgb), args.runs)
    return {k: {m: v / args.batch for m, v in r.items()} for k, r in results.items()}, (h, w)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--model-dir", nargs="*", default=["outputs/models/demo"],
        help="trained model folders; one without checkpoint/onnx is skipped",
    )
    ap.add_argument("--model", nargs="*", default=None,
                    help="conf/model/<name>.yaml presets to time with random weights "
                    "(default: segnet_small where no model folder is trained)")
    ap.add_argument("overrides", nargs="*", help="conf/train.yaml overrides of the presets, "
                    "e.g. model.downsample=2 model.stem=unshuffle model.head=sharpen")
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--batch", type=int, default=1)
    args = ap.parse_args()
    if args.runs < 20:
        ap.error("--runs must be >= 20")

    rows = []
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        found = [t for d in args.model_dir if (t := trained_model(Path(d))) is not None]
        presets = args.model if args.model is not None else ([] if found else ["segnet_small"])
        for i, preset in enumerate(presets):
            found.append(preset_model(preset, args.overrides, args.height, args.width,
                                      Path(tmp) / str(i)))
        for i, (model, onnx_path, source) in enumerate(found):
            per_frame, (h, w) = time_model(model, onnx_path, args, Path(tmp) / f"t{i}")
            rows.append((source, model, per_frame, (h, w)))
    load1 = os.getloadavg()[0]

    print(f"inference, batch {args.batch}, {args.threads} threads, {args.runs} runs")
    print(f"  machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {load0:.2f} -> {load1:.2f} (other jobs inflate wall times; cpu ms "
          "less so)")
    for source, model, per_frame, (h, w) in rows:
        print(f"model: {source}, {w}x{h}")
        print(f"  parameters {count_parameters(model)}, channels {model.channels}"
              + ("" if model.convs_per_stage is None
                 else f", convs/stage {model.convs_per_stage}"))
        print(f"  {'runtime':<22}{'median ms':>10}{'p90 ms':>9}{'min ms':>9}{'cpu ms':>9}")
        for k, r in per_frame.items():
            print(f"  {k:<22}{r['median_ms']:>10.1f}{r['p90_ms']:>9.1f}{r['min_ms']:>9.1f}"
                  f"{r['cpu_ms']:>9.1f}")
    print(json.dumps({
        "batch": args.batch, "threads": args.threads, "load": [load0, load1],
        "models": [{"model": source, "size": [h, w], "parameters": count_parameters(model),
                    "ms_per_frame": per_frame} for source, model, per_frame, (h, w) in rows],
    }))


if __name__ == "__main__":
    main()
