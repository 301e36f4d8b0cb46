"""Segment an image with an exported segnet.onnx (``core.segmenter.OnnxSegmenter``) and
write a coloured label overlay::

    python -m train.deploy.predict image.png [--model outputs/models/demo/segnet.onnx] [--out x.png]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from core.atomic import read_png, write_png
from core.config import user_errors
from core.model_folder import MODELS_ROOT
from core.segmenter import OnnxSegmenter

DEFAULT_MODEL = MODELS_ROOT / "demo" / "segnet.onnx"


def main(argv: list[str] | None = None) -> Path:
    """``python -m train.deploy.predict image.png``: write a coloured label overlay next to it."""
    ap = argparse.ArgumentParser(prog="python -m train.deploy.predict",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("image", type=Path, help="RGB image (PNG/JPEG) of the model's input size")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL, help="segnet.onnx")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="overlay PNG (default: outputs/predict/<image stem>_overlay.png)",
    )
    ap.add_argument("--labels", type=Path, default=None, help="also write the label map here")
    ap.add_argument("--alpha", type=float, default=0.5, help="overlay opacity of the colours")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    seg = OnnxSegmenter(args.model, threads=args.threads)
    rgb = read_png(args.image)
    labels, probs = seg.predict(rgb)
    out = args.out or Path("outputs/predict") / f"{args.image.stem}_overlay.png"
    write_png(out, seg.overlay(rgb, labels, args.alpha))
    if args.labels is not None:
        write_png(args.labels, labels)
    counts = np.bincount(labels.ravel(), minlength=seg.num_classes) / labels.size
    shares = {c["name"]: round(float(counts[c["id"]]), 3) for c in seg.classes}
    print(f"overlay: {out}")
    print(f"class shares: {json.dumps(shares)}")
    return out


if __name__ == "__main__":
    with user_errors():
        main()
