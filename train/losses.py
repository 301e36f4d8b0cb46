"""Class-balanced cross-entropy (median frequency balancing, as in SegNet), with optional
extra weight on the pixels next to a class change."""

from __future__ import annotations

import torch
import torch.nn.functional as F

IGNORE = 255
#: Label images counted at once (bounds the int64 temporaries: ~0.2 GB at 320 x 240).
COUNT_CHUNK = 256


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
    parts = []
    for s in range(0, n, COUNT_CHUNK):  # int64 copies of a chunk, not of the whole split
        k = min(COUNT_CHUNK, n - s)
        flat = labels[s:s + k].reshape(k, -1).long()
        # Ignore pixels go to an extra bin C, dropped afterwards.
        flat = torch.where(flat == IGNORE, num_classes, flat).clamp_(max=num_classes)
        offset = torch.arange(k).unsqueeze(1) * (num_classes + 1)
        parts.append(torch.bincount((flat + offset).reshape(-1),
                                    minlength=k * (num_classes + 1)).view(k, num_classes + 1))
    per_image = torch.cat(parts)[:, :num_classes]
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
) -> torch.Tensor:
    """Weighted per-pixel cross-entropy ignoring 255.

    Args:
        logits: (B, C, H, W) float.
        target: (B, H, W) int64 class ids, 255 = ignore.
        weight: (C,) class weights or None.
        boundary_weight: extra factor on the pixels next to a class change
            (``boundary_mask``); 1 = plain cross-entropy.

    Returns:
        Scalar loss (weighted mean over valid pixels).
    """
    if boundary_weight == 1.0:
        return F.cross_entropy(logits, target, weight=weight, ignore_index=IGNORE)
    ce = F.cross_entropy(logits, target, ignore_index=IGNORE, reduction="none")
    w_pix = pixel_loss_weights(target, weight, boundary_weight)
    return (ce * w_pix).sum() / w_pix.sum().clamp(min=1e-12)


def pixel_loss_weights(target: torch.Tensor, weight: torch.Tensor | None = None,
                       boundary_weight: float = 1.0) -> torch.Tensor:
    """(B, H, W) float32 weight of each pixel in ``segmentation_loss``: its class weight times
    the boundary factor, 0 where ignored (255).

    Args:
        target, weight, boundary_weight: as for ``segmentation_loss``.
    """
    valid = target != IGNORE
    w_pix = (torch.ones(target.shape, device=target.device) if weight is None
             else weight[target.clamp(max=len(weight) - 1)]) * valid
    if boundary_weight != 1.0:
        w_pix = torch.where(boundary_mask(target), float(boundary_weight), 1.0) * w_pix
    return w_pix


def boundary_mask(target: torch.Tensor) -> torch.Tensor:
    """(B, H, W) bool: pixels whose 3x3 neighbourhood holds another class (ignored pixels
    count as a class)."""
    t = target.unsqueeze(1).float()
    hi = F.max_pool2d(t, 3, 1, 1)
    lo = -F.max_pool2d(-t, 3, 1, 1)
    return (hi != lo).squeeze(1)
