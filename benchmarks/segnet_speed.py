"""SegNet inference speed: onnxruntime vs torch, ms per frame at the localizer's input size.

Usage::

    python benchmarks/segnet_speed.py                      # outputs/models/demo if trained
    python benchmarks/segnet_speed.py --model segnet_small --height 240 --width 320
    python benchmarks/segnet_speed.py --model-dir outputs/models/demo --runs 50 --threads 2
    python benchmarks/segnet_speed.py --model-dir none model.downsample=2 model.stem=unshuffle \
        model.head=sharpen      # the best3_highres recipe's network, random weights

With a trained model folder (checkpoint_best.pt + segnet.onnx) both runtimes use its weights;
otherwise a randomly initialised model of the given config is exported to a temporary file
(speed does not depend on the weights). Prints the median and 90th percentile wall time per
frame over ``--runs`` runs after warm-up, and the process CPU time per frame, which is less
sensitive to other jobs on a shared machine. Timings are for batch 1 unless --batch is given.
``onnxruntime_int8`` is the int8 copy
(``train.deploy.quantize``): the model folder's ``segnet_int8.onnx`` if there is one, else the timed
graph quantized here with random calibration frames (speed does not depend on the ranges).
"""

from __future__ import annotations

import argparse
import copy
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
from train.deploy.export import GRAPH_POOLING, onnx_metadata, to_onnx_proto
from train.deploy.quantize import INT8_NAME, quantize_segnet
from train.loop.checkpoint import load_checkpoint
from train.net.segnet import SegNet, build_segnet, count_parameters

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


def build_model(args: argparse.Namespace, tmp: Path) -> tuple[SegNet, Path, str]:
    """The model to time and its ONNX file: a trained model folder or a fresh export."""
    mdir = Path(args.model_dir) if args.model_dir else None
    if mdir and (mdir / "checkpoint_best.pt").is_file() and (mdir / "segnet.onnx").is_file():
        path = mdir / "segnet.onnx"
        return load_checkpoint(mdir / "checkpoint_best.pt"), path, str(mdir)
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("train", overrides=[f"model={args.model}", *args.overrides])
    model = build_segnet(OmegaConf.to_object(cfg.model), len(as_json()),
                         torch.Generator().manual_seed(0)).eval()
    exported = copy.deepcopy(model).set_pooling(GRAPH_POOLING)
    proto = to_onnx_proto(exported, args.height, args.width)
    onnx.helper.set_model_props(
        proto, onnx_metadata(model, as_json(), args.height, args.width, "benchmark"))
    path = tmp / "segnet.onnx"
    onnx.save_model(proto, str(path))
    extra = f" {' '.join(args.overrides)}" if args.overrides else ""
    return model, path, f"conf/model/{args.model}.yaml{extra} (random weights)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--model-dir",
        default="outputs/models/demo",
        help="trained model folder; ignored if it has no checkpoint/onnx",
    )
    ap.add_argument("--model", default="segnet_small", help="conf/model/<name>.yaml fallback")
    ap.add_argument("overrides", nargs="*", help="conf/train.yaml overrides of the fallback "
                    "model, e.g. model.downsample=2 model.stem=unshuffle model.head=sharpen")
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--batch", type=int, default=1)
    args = ap.parse_args()
    if args.runs < 20:
        ap.error("--runs must be >= 20")

    with tempfile.TemporaryDirectory() as tmp:
        model, onnx_path, source = build_model(args, Path(tmp))
        seg = OnnxSegmenter(onnx_path, threads=args.threads)  # the network
        h, w = seg.input_size
        rng = np.random.default_rng(0)
        rgb = rng.integers(0, 256, (args.batch, h, w, 3), dtype=np.uint8)
        x = torch.from_numpy(rgb).permute(0, 3, 1, 2).contiguous().float() / 255.0
        load0 = os.getloadavg()[0]
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
            int8_path = Path(tmp) / INT8_NAME
            quantize_segnet(onnx_path, int8_path, rng.integers(0, 256, (8, h, w, 3), np.uint8))
        seg8 = OnnxSegmenter(int8_path, threads=args.threads)
        results["onnxruntime_int8"] = timed(lambda: seg8.logits(rgb), args.runs)
        load1 = os.getloadavg()[0]

    per_frame = {k: {m: v / args.batch for m, v in r.items()} for k, r in results.items()}
    print(
        f"SegNet inference, {w}x{h}, batch {args.batch}, {args.threads} threads, "
        f"{args.runs} runs; model: {source}"
    )
    print(
        f"  parameters {count_parameters(model)}, channels {model.channels}, "
        f"convs/stage {model.convs_per_stage}"
    )
    print(
        f"  machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"load average {load0:.2f} -> {load1:.2f} (other jobs inflate wall times)"
    )
    print(f"  {'runtime':<22}{'median ms':>10}{'p90 ms':>9}{'min ms':>9}{'cpu ms':>9}")
    for k, r in per_frame.items():
        print(
            f"  {k:<22}{r['median_ms']:>10.1f}{r['p90_ms']:>9.1f}{r['min_ms']:>9.1f}"
            f"{r['cpu_ms']:>9.1f}"
        )
    print(
        json.dumps(
            {
                "size": [h, w],
                "batch": args.batch,
                "threads": args.threads,
                "load": [load0, load1],
                "ms_per_frame": per_frame,
            }
        )
    )


if __name__ == "__main__":
    main()
