"""Class-balanced cross-entropy (median frequency balancing, as in SegNet), with optional
extra weight on the pixels next to a class change and on image edges inside one class."""

from __future__ import annotations

import kornia
import torch
import torch.nn.functional as F

IGNORE = 255


def class_pixel_counts(labels: torch.Tensor, num_classes: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixels of each class, and valid pixels of the images each class appears in.

    Args:
        labels: (N, H, W) integer class ids, 255 = ignore.
        num_classes: C.

    Returns:
        counts (C,) int64: pixels of class c over all images;
        image_pixels (C,) int64: valid (non-ignore) pixels summed over the images that contain
        class c.
    """
    if labels.ndim != 3:
        raise ValueError(f"labels must be (N, H, W), got {tuple(labels.shape)}")
    n = labels.shape[0]
    flat = labels.reshape(n, -1).long()
    # Ignore pixels go to an extra bin C, dropped afterwards.
    flat = torch.where(flat == IGNORE, num_classes, flat).clamp_(max=num_classes)
    offset = torch.arange(n).unsqueeze(1) * (num_classes + 1)
    per_image = torch.bincount((flat + offset).reshape(-1), minlength=n * (num_classes + 1))
    per_image = per_image.view(n, num_classes + 1)[:, :num_classes]
    valid = per_image.sum(1, keepdim=True)
    counts = per_image.sum(0)
    image_pixels = (valid * (per_image > 0)).sum(0)
    return counts, image_pixels


def median_frequency_weights(
    labels: torch.Tensor,
    num_classes: int,
    max_weight: float | None = None,
    power: float = 1.0,
) -> torch.Tensor:
    """SegNet's class weights: w_c = median_freq / freq_c.

    freq_c is the pixel count of class c divided by the (valid) pixel count of the images
    where c is present; the median is taken over the classes present. Classes absent from
    the labels get weight 0 (they cannot be learned and never appear as targets).

    Args:
        labels: (N, H, W) integer class ids, 255 = ignore.
        num_classes: C.
        max_weight: clip weights to at most this value (None = no clipping).
        power: weights are ``(median_freq / freq_c) ** power``; 1.0 is SegNet's balancing,
            0.5 a softer one that costs less global accuracy.

    Returns:
        (C,) float32 weights.
    """
    counts, image_pixels = class_pixel_counts(labels, num_classes)
    present = counts > 0
    if not present.any():
        raise ValueError("no labelled pixels: every label is 255 (ignore)")
    freq = torch.zeros(num_classes, dtype=torch.float64)
    freq[present] = counts[present].double() / image_pixels[present].double()
    # torch.median returns the lower middle value for even counts; use the mean of the two.
    sorted_freq = freq[present].sort().values
    m = sorted_freq.numel()
    median = 0.5 * (sorted_freq[(m - 1) // 2] + sorted_freq[m // 2])
    weights = torch.zeros(num_classes, dtype=torch.float64)
    weights[present] = (median / freq[present]) ** float(power)
    if max_weight is not None:
        weights = weights.clamp(max=max_weight)
    return weights.float()


def segmentation_loss(
    logits: torch.Tensor,
    target: torch.Tensor,
    weight: torch.Tensor | None = None,
    boundary_weight: float = 1.0,
    edge_weight: float = 1.0,
    image_edges: torch.Tensor | None = None,
) -> torch.Tensor:
    """Weighted per-pixel cross-entropy ignoring 255.

    Args:
        logits: (B, C, H, W) float.
        target: (B, H, W) int64 class ids, 255 = ignore.
        weight: (C,) class weights or None.
        boundary_weight: extra factor on the pixels next to a class change
            (``boundary_mask``); 1 = plain cross-entropy.
        edge_weight: extra factor on the pixels of ``image_edges`` that are not next to a class
            change: image edges inside one class (the top of a skirting board, a poster's or a
            door panel's outline), where a network is tempted to put a class boundary.
        image_edges: (B, H, W) bool (``image_edge_mask``), needed when ``edge_weight`` != 1.

    Returns:
        Scalar loss (weighted mean over valid pixels).
    """
    if boundary_weight == 1.0 and edge_weight == 1.0:
        return F.cross_entropy(logits, target, weight=weight, ignore_index=IGNORE)
    ce = F.cross_entropy(logits, target, weight=weight, ignore_index=IGNORE, reduction="none")
    valid = target != IGNORE
    w_pix = torch.ones_like(ce) if weight is None else weight[target.clamp(max=len(weight) - 1)]
    near = boundary_mask(target)
    pw = torch.where(near, float(boundary_weight), 1.0)
    if edge_weight != 1.0:
        if image_edges is None or image_edges.shape != target.shape:
            raise ValueError(f"edge_weight {edge_weight} needs image_edges of the target's shape "
                             f"{tuple(target.shape)}, got "
                             f"{None if image_edges is None else tuple(image_edges.shape)}")
        pw = torch.where(image_edges & ~near, float(edge_weight), pw)
    pw = pw * valid
    return (ce * pw).sum() / (w_pix * pw).sum().clamp(min=1e-12)


def image_edge_mask(images: torch.Tensor, threshold: float, size: tuple[int, int] | None = None
                    ) -> torch.Tensor:
    """Where an image has an edge: the gradient magnitude of its grey version, 3x3-Gaussian
    smoothed, at least ``threshold``.

    Args:
        images: (B, 3, H, W) float RGB in [0, 1].
        threshold: on kornia's normalized Sobel magnitude of the smoothed grey image, in [0, 1]
            intensity per pixel: a sharp step of height h peaks at 0.36 h (0.03: a step of ~21
            grey levels of 255).
        size: (h, w) of the mask when the labels have another resolution (a coarser mask keeps
            a pixel when any image pixel it covers is an edge; a finer one repeats them).

    Returns:
        (B, h, w) bool.
    """
    grey = kornia.color.rgb_to_grayscale(images)
    grey = kornia.filters.gaussian_blur2d(grey, (3, 3), (1.0, 1.0))
    mag = kornia.filters.sobel(grey, normalized=True)  # (B, 1, H, W)
    m = (mag >= threshold).float()
    if size is not None and tuple(size) != tuple(m.shape[-2:]):
        m = (F.adaptive_max_pool2d(m, size) if size[0] < m.shape[-2]
             else F.interpolate(m, size=size, mode="nearest"))
    return m.squeeze(1) > 0


def boundary_mask(target: torch.Tensor) -> torch.Tensor:
    """(B, H, W) bool: pixels whose 3x3 neighbourhood holds another class (ignored pixels
    count as a class)."""
    t = target.unsqueeze(1).float()
    hi = F.max_pool2d(t, 3, 1, 1)
    lo = -F.max_pool2d(-t, 3, 1, 1)
    return (hi != lo).squeeze(1)
