"""How far the cnn mode's class boundaries lie from the true ones, class pair by class pair.

Usage::

    python benchmarks/boundary_distance.py                    # the demo's dataset and SegNet
    python benchmarks/boundary_distance.py --dataset outputs/datasets/big \
        --model outputs/models/big/segnet.onnx --step 4 edges.cnn.snap_nearest=true

For every flight, every ``--step``-th frame: the localizer's cnn edges (a ``FrontEnd`` of the
SegNet, with the ``conf/localize.yaml`` edge settings and any overrides given) and the true
label boundaries (the oracle's). For each true boundary pixel on a known pixel, the distance
in pixels to the nearest cnn boundary pixel *of the same class pair* (capped at ``--cap``).
Prints per flight and class pair the count of true boundary pixels, the mean distance, and the
shares within 1 px and beyond 3 px. With the 1-pixel tolerance of the likelihood, what lies
beyond ~3 px is a boundary the cnn mode misses or puts elsewhere (docs/localize.md, "part 6":
door jambs).

Then the other way round, which side the cnn boundaries err to: for each cnn boundary pixel,
its distance to the nearest true boundary pixel of the same pair, signed by the true class
under it: + when it lies inside the pair's higher-id class (that class comes out too small, the
boundary moved into it), - inside the lower-id one. Prints the mean signed offset and the
shares at least 1.5 px off to each side: a bias a fixed correction could take out shows as a
mean of one sign on every flight.

Then, pooled over the flights, per class pair: the cnn boundary pixels by their distance to the
true boundary of their pair, in bands (on it, 1 px, 2 px, 2.5-5, 5-10, 10 px or more;
``distance_bands``), and the share of true boundary pixels with a cnn one within 1 px. A
boundary 2.5 px or more off is on another image edge (the top of a skirting board, a poster's
outline; docs/localize.md, "image edges inside one class"), which the snap cannot reach.

Last, before any snap or median, where the network's own decision crosses: for each pair of
4-neighbour pixels the true labels give two structural classes a | b, whether the decision
between a and b (the logits with the cnn mode's prior correction; ``logit_crossings``) changes
sign between the two pixels (the boundary within half a pixel of the true one) or lies beyond
one of them. Prints per pair the share between the two pixels and the shares beyond into a and
into b: how often the network places a boundary to the pixel, which the distances above, in
whole pixels of the snapped edges, cannot tell.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from core.atomic import read_png  # noqa: E402
from core.classes import (  # noqa: E402  # noqa: E402
    STRUCTURAL,  # noqa: E402
    class_changes,
    pair_classes,
    pair_code,
    pair_name,
    structural_mask,
)
from core.dataset import Dataset  # noqa: E402
from localize.filter.likelihood import distance_to  # noqa: E402
from localize.frontend.edge_image import EdgeImage  # noqa: E402
from localize.frontend.front_end import FrontEnd  # noqa: E402
from localize.frontend.segmenter import LabelPredictor, load_segmenter  # noqa: E402
from localize.frontend.sources import SegmenterLabels  # noqa: E402

CONF_DIR = Path(__file__).resolve().parents[1] / "conf"


def frame_edges(cnn: FrontEnd, oracle: FrontEnd, rgb: np.ndarray,
                labels: np.ndarray) -> tuple[EdgeImage, EdgeImage]:
    """The cnn mode's and the true (oracle) edge images of a frame (rgb (H, W, 3) uint8,
    labels (H, W) uint8 true class ids), from the two modes' front ends."""
    return cnn.frame(rgb).edge, oracle.frame(rgb, labels).edge


def pair_distances(cnn: FrontEnd, oracle: FrontEnd, rgb: np.ndarray, labels: np.ndarray,
                   cap: float) -> dict[int, np.ndarray]:
    """Per class-pair code, the distances (n,) float32, px, from the frame's true boundary
    pixels to the nearest cnn boundary pixel of the same pair, capped at ``cap``."""
    return true_to_cnn(*frame_edges(cnn, oracle, rgb, labels), cap)


def true_to_cnn(ec: EdgeImage, eo: EdgeImage, cap: float) -> dict[int, np.ndarray]:
    """``pair_distances`` of given cnn (``ec``) and true (``eo``) edge images."""
    out = {}
    for code in np.unique(eo.pairs[eo.edges]):
        true = eo.edges & (eo.pairs == code) & ec.known
        if true.any():
            out[int(code)] = np.minimum(distance_to(ec.edges & (ec.pairs == code))[true], cap)
    return out


def signed_offsets(ec: EdgeImage, eo: EdgeImage, labels: np.ndarray,
                   cap: float) -> dict[int, np.ndarray]:
    """Per class-pair code, the signed offsets (n,) float32, px, of the cnn boundary pixels
    from the nearest true boundary pixel of the same pair, capped at ``cap``: + where the true
    class under the pixel is the pair's higher-id class, - the lower-id one, 0 on a true
    boundary pixel; pixels over a third class are left out.

    Args:
        ec, eo: the cnn and the true edge images of a frame (``frame_edges``), (H, W).
        labels: (H, W) uint8 true class ids.
    """
    out = {}
    for code in np.unique(ec.pairs[ec.edges & ec.known]):
        ys, xs = np.nonzero(ec.edges & ec.known & (ec.pairs == code))
        d = np.minimum(distance_to(eo.edges & (eo.pairs == code))[ys, xs], cap)
        lower, higher = pair_classes(int(code))
        under = labels[ys, xs]
        sign = np.where(under == higher, 1.0, np.where(under == lower, -1.0, np.nan))
        s = np.where(d == 0, 0.0, sign * d)
        out[int(code)] = s[~np.isnan(s)].astype(np.float32)
    return out


def logit_crossings(z: np.ndarray, labels: np.ndarray,
                    structural: tuple[int, ...]) -> dict[int, np.ndarray]:
    """Where the network's decision crosses at the true class changes, per class-pair code.

    Args:
        z: (C, H, W) float class scores as the cnn mode decides by them (logits minus the
            prior correction).
        labels: (H, W) uint8 true class ids.
        structural: the class ids of the model.

    Returns:
        Per pair code, (n,) int8 over the n pairs of 4-neighbour pixels p, q whose true
        classes are two structural classes: 0 where z_b - z_a changes sign from p (class a)
        to q (class b), the boundary within half a pixel of the true one; +1 where it lies
        beyond, inside the pair's higher-id class (which comes out too small); -1 inside the
        lower-id one. Signs as ``signed_offsets``.
    """
    labels = np.ascontiguousarray(labels, dtype=np.uint8)
    out: dict[int, list[np.ndarray]] = {}
    changes = class_changes(labels, structural_mask(labels, structural))
    for (dy, dx), (diff, a, b) in zip(((1, 0), (0, 1)), changes, strict=True):
        ys, xs = np.nonzero(diff)
        ca, cb = a[ys, xs].astype(np.intp), b[ys, xs].astype(np.intp)
        f_p = z[cb, ys, xs] - z[ca, ys, xs]  # at p (true class a): should be < 0
        f_q = z[cb, ys + dy, xs + dx] - z[ca, ys + dy, xs + dx]  # at q (class b): > 0
        # beyond p: b reaches into a; beyond q: a reaches into b
        side = np.where(f_p >= 0, -1, np.where(f_q <= 0, 1, 0))
        side = np.where(cb > ca, side, -side).astype(np.int8)  # + into the higher id
        code = pair_code(ca, cb)
        for c in np.unique(code):
            out.setdefault(int(c), []).append(side[code == c])
    return {c: np.concatenate(v) for c, v in out.items()}


#: Upper edges (px, exclusive) of ``distance_bands``' bands; the last band is open.
BANDS = (0.5, 1.5, 2.5, 5.0, 9.99)
BAND_NAMES = ("0 px", "1 px", "2 px", "2.5-5", "5-10", ">= 10")


def distance_bands(offsets: np.ndarray) -> np.ndarray:
    """Shares (6,) of boundary pixels per band of |offset| (``BAND_NAMES``; offsets capped at
    10 px fall in the last band), from (n,) signed or unsigned offsets in px; zeros if n = 0."""
    a = np.abs(np.asarray(offsets, dtype=np.float64))
    if not len(a):
        return np.zeros(len(BANDS) + 1)
    return np.bincount(np.searchsorted(BANDS, a, side="right"), minlength=len(BANDS) + 1) / len(a)


def decision_scores(predictor: LabelPredictor, rgb: np.ndarray) -> np.ndarray:
    """(C, H, W) the scores the cnn mode's structural decision takes the argmax of: the
    logits, minus its prior correction when it has one."""
    z = np.asarray(predictor.segmenter.logits(rgb), dtype=np.float32)
    return z if predictor.log_prior is None else z - np.asarray(predictor.log_prior,
                                                                np.float32)[:, None, None]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", default="outputs/datasets/demo")
    ap.add_argument("--model", default="outputs/models/demo/segnet.onnx")
    ap.add_argument("--step", type=int, default=2, help="every n-th frame of each flight")
    ap.add_argument("--cap", type=float, default=10.0, help="distances capped here, px")
    ap.add_argument("overrides", nargs="*", help="localize config overrides, e.g. "
                    "edges.cnn.snap_px=3")
    args = ap.parse_args(argv)
    if args.step < 1:
        ap.error("--step must be at least 1")
    dataset = Dataset(args.dataset)
    with initialize_config_dir(str(CONF_DIR), version_base=None):
        cfg = compose("localize", overrides=list(args.overrides))
    edges = OmegaConf.to_object(cfg.edges)  # localize.config.EdgesConfig
    source = SegmenterLabels(load_segmenter(args.model, dataset.classes), edges.cnn)
    cnn, oracle = FrontEnd(source, edges), FrontEnd("oracle", edges)
    names = {int(c["id"]): c["name"] for c in dataset.classes}
    print(f"dataset {args.dataset}, model {args.model}, every {args.step} frames")
    pooled_side: dict[int, list[np.ndarray]] = {}
    pooled_found: dict[int, list[np.ndarray]] = {}
    for name in dataset.flight_names():
        flight = dataset.flight(name)
        found: dict[int, list[np.ndarray]] = {}
        side: dict[int, list[np.ndarray]] = {}
        cross: dict[int, list[np.ndarray]] = {}
        for t in range(0, len(flight.rgb), args.step):
            labels = read_png(flight.label[t], rgb=False)
            rgb = read_png(flight.rgb[t])
            ec, eo = frame_edges(cnn, oracle, rgb, labels)
            z = decision_scores(source.predictor, rgb)
            for code, c in logit_crossings(z, labels, STRUCTURAL).items():
                cross.setdefault(code, []).append(c)
            for code, d in true_to_cnn(ec, eo, args.cap).items():
                found.setdefault(code, []).append(d)
                pooled_found.setdefault(code, []).append(d)
            for code, s in signed_offsets(ec, eo, labels, args.cap).items():
                side.setdefault(code, []).append(s)
                pooled_side.setdefault(code, []).append(s)
        print(f"flight {name}: class pair, true boundary px, mean px, within 1 px, beyond 3 px")
        for code, parts in sorted(found.items()):
            d = np.concatenate(parts)
            pair = pair_name(code, names)
            print(f"  {pair:18s} {len(d):8d} {d.mean():6.2f} {np.mean(d <= 1):6.0%} "
                  f"{np.mean(d > 3):6.0%}")
        print(f"flight {name}: class pair a | b, cnn boundary px, mean signed px (+: into b), "
              "at least 1.5 px into a, into b")
        for code, parts in sorted(side.items()):
            s = np.concatenate(parts)
            if not len(s):
                continue
            pair = pair_name(code, names)
            print(f"  {pair:18s} {len(s):8d} {s.mean():+6.2f} {np.mean(s <= -1.5):6.0%} "
                  f"{np.mean(s >= 1.5):6.0%}")
        print(f"flight {name}: class pair a | b, true class changes, the network's decision "
              "crossing between the two pixels, beyond them into a, into b")
        for code, parts in sorted(cross.items()):
            c = np.concatenate(parts)
            pair = pair_name(code, names)
            print(f"  {pair:18s} {len(c):8d} {np.mean(c == 0):6.0%} {np.mean(c < 0):6.0%} "
                  f"{np.mean(c > 0):6.0%}")
    print("all flights: class pair, cnn boundary px, shares by distance to the true boundary ("
          + ", ".join(BAND_NAMES) + "), true boundary px with a cnn one within 1 px")
    for code, parts in sorted(pooled_side.items()):
        s = np.concatenate(parts)
        if not len(s):
            continue
        d = np.concatenate(pooled_found.get(code, [np.zeros(0)]))
        within = f"{np.mean(d <= 1):6.0%}" if len(d) else "     -"
        print(f"  {pair_name(code, names):18s} {len(s):8d} "
              + " ".join(f"{v:6.0%}" for v in distance_bands(s)) + f" {within}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
