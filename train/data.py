"""Dataset splits in memory and joint image/label augmentation on batches.

A split is read once through ``core.dataset.Dataset`` into uint8 tensors (the demo dataset
is a few hundred MB, the generalist's 48 floors about 4 GB; the work on a whole split holds
at most one more copy of it), so an epoch is pure tensor work. Augmentation runs on a whole
batch at once with kornia functions and draws every random number from an explicit
``torch.Generator``, so a resumed run sees the same batches as an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from kornia.enhance import adjust_brightness, adjust_contrast, adjust_hue, adjust_saturation
from kornia.filters import gaussian_blur2d
from kornia.geometry.transform import crop_and_resize
from tqdm import tqdm

from core.atomic import read_png
from core.dataset import Dataset
from core.imaging.camera_effects import apply_effects
from core.imaging.realism import RealismConfig
from train.config import AugmentConfig

IGNORE = 255
#: Images per step of the work on a whole split (bounds its float temporaries).
CHUNK = 256


@dataclass(frozen=True)
class SplitData:
    """One split held in memory.

    Attributes:
        images: (N, 3, H, W) uint8 RGB.
        labels: (N, H, W) uint8 class ids, 255 = ignore.
        paths: the N rgb image paths, in order.
    """

    images: torch.Tensor
    labels: torch.Tensor
    paths: list[Path]

    def __len__(self) -> int:
        return int(self.images.shape[0])


def check_classes(classes: Sequence[dict], num_classes: int | None, source: str) -> int:
    """Number of classes of a dataset, checked against a configured count.

    Args:
        classes: the ``classes`` list of dataset.json (dicts with id, name, color, structural).
        num_classes: ``model.num_classes`` from the config, or None to take the dataset's.
        source: the dataset.json path, for error messages.

    Returns:
        The number of classes C; ids must be exactly 0..C-1.
    """
    ids = [int(c["id"]) for c in classes]
    if ids != list(range(len(ids))):
        raise ValueError(f"{source}: class ids must be 0..{len(ids) - 1} in order, got {ids}")
    if num_classes is not None and int(num_classes) != len(ids):
        raise ValueError(
            f"class-count mismatch: model.num_classes={num_classes} but {source} lists "
            f"{len(ids)} classes ({[c['name'] for c in classes]}). Set model.num_classes=null to "
            f"take the dataset's classes, or train on a dataset with {num_classes} classes."
        )
    return len(ids)


def check_same_kind(datasets: Sequence[Dataset]) -> None:
    """Raise unless the datasets trained on together share their classes and image size.

    Args:
        datasets: the datasets of ``dataset`` (a folder or a glob pattern).
    """
    first = datasets[0]
    want = (first.classes, first.camera.width, first.camera.height)
    for d in datasets[1:]:
        if (d.classes, d.camera.width, d.camera.height) != want:
            raise ValueError(
                f"{d.root / 'dataset.json'}: its classes or image size "
                f"({d.camera.width}x{d.camera.height}) differ from those of "
                f"{first.root / 'dataset.json'} ({want[1]}x{want[2]}); train on datasets "
                "made with one class list and one camera.width/height."
            )


def load_splits(datasets: Sequence[Dataset], split: str, num_classes: int,
                limit: int | None = None, progress: bool = False) -> SplitData:
    """``load_split`` of each dataset, concatenated in order (``limit`` applies to each),
    read into one array (no second copy of the whole split)."""
    lists = [_split_paths(d, split, limit) for d in datasets]
    n = sum(len(rgb) for rgb, _ in lists)
    cam = datasets[0].camera
    images = np.empty((n, 3, cam.height, cam.width), dtype=np.uint8)
    labels = np.empty((n, cam.height, cam.width), dtype=np.uint8)
    at = 0
    for d, (rgb, lab) in zip(datasets, lists, strict=True):
        _read_into(d, rgb, lab, images[at:at + len(rgb)], labels[at:at + len(rgb)],
                   num_classes, split, progress)
        at += len(rgb)
    return SplitData(
        images=torch.from_numpy(images),
        labels=torch.from_numpy(labels),
        paths=[path for rgb, _ in lists for path in rgb],
    )


def load_split(
    dataset: Dataset,
    split: str,
    num_classes: int,
    limit: int | None = None,
    progress: bool = False,
) -> SplitData:
    """Read a split's rgb and label PNGs into memory, checking sizes and label ids.

    Args:
        dataset: the dataset to read.
        split: "train", "val" or "test".
        num_classes: C; every label value must be < C or 255.
        limit: read only the first ``limit`` frames (None = all).
        progress: show a progress bar.

    Returns:
        The split as uint8 tensors. Raises FileNotFoundError if the split is empty and
        ValueError naming the file if an image has the wrong size or a label an unknown id.
    """
    return load_splits([dataset], split, num_classes, limit, progress)


def _split_paths(dataset: Dataset, split: str, limit: int | None) -> tuple[list, list]:
    """(rgb paths, label paths) of a split, the first ``limit``; FileNotFoundError when
    empty."""
    rgb_paths, label_paths = dataset.split(split)
    if limit is not None:
        rgb_paths, label_paths = rgb_paths[:limit], label_paths[:limit]
    if not rgb_paths:
        raise FileNotFoundError(
            f"split {split!r} of dataset {dataset.root} has no images in "
            f"{dataset.root / split / 'rgb'}; finish the dataset with `python -m datagen`."
        )
    return list(rgb_paths), list(label_paths)


def _read_into(dataset: Dataset, rgb_paths: list, label_paths: list, images: np.ndarray,
               labels: np.ndarray, num_classes: int, split: str, progress: bool) -> None:
    """Read the PNGs into ``images`` (n, 3, H, W) and ``labels`` (n, H, W), checking each
    against the dataset's camera and the class ids."""
    cam = dataset.camera
    n = len(rgb_paths)
    pairs = zip(rgb_paths, label_paths, strict=True)
    for i, (rp, lp) in enumerate(tqdm(pairs, total=n, desc=f"load {split}", disable=not progress)):
        rgb = read_png(rp)
        lab = read_png(lp, rgb=False)
        for path, arr, want in ((rp, rgb, 3), (lp, lab, 2)):
            if arr.ndim != want or arr.shape[:2] != (cam.height, cam.width):
                raise ValueError(
                    f"{path}: image shape {arr.shape} does not match the dataset camera "
                    f"{cam.height}x{cam.width} in {dataset.root / 'dataset.json'} "
                    f"({'RGB' if want == 3 else 'single-channel label'} expected); "
                    f"regenerate the dataset or fix camera.width/height."
                )
        images[i] = rgb.transpose(2, 0, 1)
        labels[i] = lab
    bad = np.unique(labels[(labels >= num_classes) & (labels != IGNORE)])
    if bad.size:
        frames = np.flatnonzero(((labels >= num_classes) & (labels != IGNORE)).any(axis=(1, 2)))
        raise ValueError(
            f"{label_paths[frames[0]]}: label ids {bad.tolist()} are not among the "
            f"{num_classes} classes of {dataset.root / 'dataset.json'} (255 = ignore); the "
            f"labels and the class list disagree, regenerate the dataset."
        )


def through_camera(data: SplitData, settings: RealismConfig, seed: int, stream: int) -> SplitData:
    """Each image once through a drone camera (``data.realism``): an exposure offset, sensor
    noise and JPEG as ``core.imaging.camera_effects.apply_effects`` gives a flight's frames.

    A training image is a still, not a flight, so its exposure offset is drawn on its own:
    uniform in +/-``exposure.step_ev`` (a light switched on or off, before auto exposure
    settles) plus Normal(0, ``exposure.drift_ev``), clipped to +/-``exposure.max_ev``. Lens
    distortion, motion blur and rolling shutter are left out: the localizer undistorts its
    frames, and the Gaussian blur of ``data.augment`` covers the softness of both.

    Args:
        data: the split, (N, 3, H, W) uint8 images at the dataset's resolution.
        settings: the camera's realism preset (``core.imaging.realism.load_realism``).
        seed: the training's seed; image i draws from SeedSequence([seed, stream, i]).
        stream: the split's stream (one per split, so train and val draw apart).

    Returns:
        the split with new images (labels and paths shared).
    """
    c = settings.exposure
    out = torch.empty_like(data.images)
    for i in range(len(data)):
        rng = np.random.default_rng([seed, stream, i])
        ev = rng.uniform(-c.step_ev, c.step_ev) + c.drift_ev * rng.standard_normal()
        rgb = data.images[i].permute(1, 2, 0).numpy()
        out[i] = torch.from_numpy(apply_effects(
            rgb, rng, settings, float(np.clip(ev, -c.max_ev, c.max_ev)))).permute(2, 0, 1)
    return SplitData(images=out, labels=data.labels, paths=data.paths)


def downsample_split(data: SplitData, factor: int, keep_labels: bool = False) -> SplitData:
    """The split at 1/factor resolution, as a SegNet with ``downsample=factor`` sees it.

    Images are averaged over factor x factor blocks (what ``SegNet.preprocess`` does) and
    rounded back to uint8; labels take each block's majority class (``block_majority``), so a
    low-resolution label describes the same block, centred at the same point, as its pixel.
    H and W must be multiples of ``factor``.

    Args:
        keep_labels: keep the full-resolution labels (for a loss on upsampled logits).

    Returns:
        images (N, 3, H / factor, W / factor) uint8 and labels (N, H / factor, W / factor),
        or (N, H, W) with ``keep_labels``.
    """
    if factor == 1:
        return data
    h, w = data.images.shape[-2:]
    if h % factor or w % factor:
        raise ValueError(f"image size {h}x{w} is not a multiple of model.downsample={factor}")
    n, c = data.images.shape[:2]
    images = torch.empty((n, c, h // factor, w // factor), dtype=torch.uint8)
    for s in range(0, n, CHUNK):  # a float copy of a chunk, not of the split
        images[s:s + CHUNK] = F.avg_pool2d(data.images[s:s + CHUNK].float(),
                                           factor).round_().to(torch.uint8)
    labels = data.labels if keep_labels else block_majority(data.labels, factor)
    return SplitData(images=images, labels=labels, paths=data.paths)


def block_majority(labels: torch.Tensor, factor: int, chunk: int = CHUNK) -> torch.Tensor:
    """The most frequent class of each factor x factor block of a label batch.

    Ignored pixels (255) do not vote; a block with no other pixel stays 255; ties go to the
    lower class id. (Keeping one pixel per block instead, e.g. the top-left, would move every
    boundary by (factor - 1) / 2 input pixels relative to the box-averaged image.)

    Args:
        labels: (N, H, W) uint8 class ids, H and W multiples of ``factor``.
        factor: block size.
        chunk: images per step (bounds the memory of the per-class counts).

    Returns:
        (N, H / factor, W / factor) uint8.
    """
    n, h, w = labels.shape
    present = set()  # the classes present, a chunk at a time (unique sorts a copy)
    for s in range(0, n, chunk):
        present.update(int(c) for c in torch.unique(labels[s:s + chunk]))
    ids = sorted(present - {IGNORE})
    out = torch.full((n, h // factor, w // factor), IGNORE, dtype=torch.uint8)
    if not ids:
        return out
    table = torch.tensor(ids, dtype=torch.uint8)
    for s in range(0, n, chunk):
        lab = labels[s : s + chunk, None]
        counts = torch.cat([F.avg_pool2d((lab == c).float(), factor) for c in ids], dim=1)
        best, arg = counts.max(dim=1)
        out[s : s + chunk] = torch.where(best > 0, table[arg], IGNORE)
    return out


def to_float(images: torch.Tensor) -> torch.Tensor:
    """(B, 3, H, W) uint8 -> float32 in [0, 1]."""
    return images.float().div_(255.0)


def batches(
    n: int, batch_size: int, generator: torch.Generator | None = None, drop_last: bool = False
) -> Iterator[torch.Tensor]:
    """Index batches over n items, shuffled if a generator is given.

    Args:
        n: number of items.
        batch_size: items per batch.
        generator: draws the permutation; None keeps the order.
        drop_last: skip a final batch smaller than ``batch_size`` (unless it is the only one).

    Yields:
        (b,) int64 index tensors.
    """
    order = torch.randperm(n, generator=generator) if generator is not None else torch.arange(n)
    stop = n - n % batch_size if drop_last and n >= batch_size else n
    for i in range(0, stop, batch_size):
        yield order[i : i + batch_size]


def num_batches(n: int, batch_size: int, drop_last: bool = False) -> int:
    if drop_last and n >= batch_size:
        return n // batch_size
    return -(-n // batch_size)


def _uniform(gen: torch.Generator, n: int, lo: float, hi: float) -> torch.Tensor:
    return lo + (hi - lo) * torch.rand(n, generator=gen)


def _crop_labels_finer(
    y: torch.Tensor, boxes: torch.Tensor, size: tuple[int, int], f: int
) -> torch.Tensor:
    """Labels (B, 1, f H, f W) float cropped (nearest) from the image boxes (B, 4, 2) that
    ``crop_and_resize`` maps to an output of ``size`` (h, w) with ``align_corners=True``;
    returns (B, 1, f h, f w), 255 outside the labels.

    Output label pixel p sits at output image coordinate u = (p + 0.5) / f - 0.5, which the box
    maps to image coordinate X, i.e. label coordinate f (X + 0.5) - 0.5: so the label box's
    corners are those of the pixels p = 0 and f w - 1 (and likewise in y).
    """
    (oh, ow), lo, hi = size, 0.5 / f - 0.5, -0.5 / f - 0.5
    p0, p1 = boxes[:, 0], boxes[:, 2]  # (B, 2) top-left, bottom-right (x, y)
    extent = torch.tensor([ow, oh], dtype=boxes.dtype)
    step = (p1 - p0) / (extent - 1).clamp(min=1)
    q0 = f * (p0 + lo * step + 0.5) - 0.5
    q1 = f * (p0 + (extent + hi) * step + 0.5) - 0.5
    lboxes = torch.stack(
        [q0, torch.stack([q1[:, 0], q0[:, 1]], -1), q1, torch.stack([q0[:, 0], q1[:, 1]], -1)],
        dim=1,
    )
    # shifted by one so that the zero padding outside the labels comes out as -1 -> 255
    out = crop_and_resize(y + 1, lboxes, (f * oh, f * ow), mode="nearest", align_corners=True)
    return torch.where(out < 0.5, float(IGNORE), out - 1)


def augment_batch(
    images: torch.Tensor, labels: torch.Tensor, cfg: AugmentConfig, gen: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """Random scale/crop, flip, colour jitter, blur and noise on a batch, labels kept aligned.

    Geometric changes are applied to images (bilinear) and labels (nearest) with the same
    parameters; photometric ones to images only. The labels may have f times the images'
    resolution (pixel i of the image covering label pixels f i .. f i + f - 1, as
    ``downsample_split`` makes them); they are then cropped from the same box at their own
    resolution, and label pixels that fall outside the image are 255 (ignore).

    Args:
        images: (B, 3, H, W) uint8 RGB.
        labels: (B, f H, f W) uint8 class ids, f a positive integer.
        cfg: augmentation parameters.
        gen: source of all random numbers.

    Returns:
        images (B, 3, h, w) float32 in [0, 1] and labels (B, f h, f w) int64, where (h, w) is
        ``cfg.crop`` or (H, W).
    """
    f = labels.shape[-1] // images.shape[-1] if images.ndim == 4 and images.shape[-1] else 0
    if (
        images.ndim != 4
        or images.shape[1] != 3
        or f < 1
        or labels.shape != (images.shape[0], f * images.shape[2], f * images.shape[3])
    ):
        raise ValueError(
            f"expected images (B, 3, H, W) and labels (B, f H, f W) for an integer f, got "
            f"{tuple(images.shape)} and {tuple(labels.shape)}"
        )
    b, _, h, w = images.shape
    oh, ow = cfg.crop if cfg.crop is not None else (h, w)
    x = to_float(images)
    y = labels.float().unsqueeze(1)

    # Scale / crop: a box of size output / zoom, kept inside the image.
    zoom = _uniform(gen, b, *cfg.scale).clamp(min=max(oh / h, ow / w))
    bw, bh = ow / zoom, oh / zoom
    x0 = torch.rand(b, generator=gen) * (w - bw)
    y0 = torch.rand(b, generator=gen) * (h - bh)
    x1, y1 = x0 + bw - 1.0, y0 + bh - 1.0
    boxes = torch.stack(
        [
            torch.stack([x0, y0], -1),
            torch.stack([x1, y0], -1),
            torch.stack([x1, y1], -1),
            torch.stack([x0, y1], -1),
        ],
        dim=1,
    )
    x = crop_and_resize(x, boxes, (oh, ow), mode="bilinear", align_corners=True)
    if f == 1:
        y = crop_and_resize(y, boxes, (oh, ow), mode="nearest", align_corners=True)
    else:
        y = _crop_labels_finer(y, boxes, (oh, ow), f)

    flip = (torch.rand(b, generator=gen) < cfg.hflip).view(b, 1, 1, 1)
    x = torch.where(flip, x.flip(-1), x)
    y = torch.where(flip, y.flip(-1), y)

    if cfg.brightness > 0:
        x = adjust_brightness(x, _uniform(gen, b, -cfg.brightness, cfg.brightness))
    if cfg.contrast > 0:
        x = adjust_contrast(x, _uniform(gen, b, 1 - cfg.contrast, 1 + cfg.contrast))
    if cfg.saturation > 0:
        x = adjust_saturation(x, _uniform(gen, b, 1 - cfg.saturation, 1 + cfg.saturation))
    if cfg.hue > 0:
        x = adjust_hue(x, _uniform(gen, b, -cfg.hue, cfg.hue) * 2 * torch.pi)
    if cfg.blur_prob > 0:
        sigma = _uniform(gen, b, *cfg.blur_sigma)
        blur = (torch.rand(b, generator=gen) < cfg.blur_prob).view(b, 1, 1, 1)
        ksize = 2 * int(np.ceil(3 * cfg.blur_sigma[1])) + 1
        blurred = gaussian_blur2d(x, ksize, torch.stack([sigma, sigma], -1))
        x = torch.where(blur, blurred, x)
    if cfg.noise_std > 0:
        std = _uniform(gen, b, 0.0, cfg.noise_std).view(b, 1, 1, 1)
        x = x + std * torch.randn(x.shape, generator=gen)
    return x.clamp_(0.0, 1.0), y.squeeze(1).round().long()
