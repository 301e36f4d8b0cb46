"""Median-frequency class balancing and the weighted loss."""

from __future__ import annotations

import pytest
import torch

import train.losses as losses
from train.losses import (
    boundary_mask,
    class_pixel_counts,
    median_frequency_weights,
    segmentation_loss,
)


def test_pixel_counts_hand_made() -> None:
    labels = torch.tensor([[[0, 0], [1, 255]], [[1, 1], [1, 2]]], dtype=torch.uint8)
    counts, image_pixels = class_pixel_counts(labels, 4)
    assert counts.tolist() == [2, 4, 1, 0]
    # class 0 only in image 0 (3 valid px), class 1 in both (3 + 4), class 2 in image 1 (4)
    assert image_pixels.tolist() == [3, 7, 4, 0]


def test_pixel_counts_a_chunk_at_a_time(monkeypatch) -> None:
    """Counted a chunk of images at a time (the generalist's split does not fit in int64):
    the same counts."""
    labels = torch.tensor([[[0, 0], [1, 255]], [[1, 1], [1, 2]], [[2, 2], [255, 0]]],
                          dtype=torch.uint8)
    whole = class_pixel_counts(labels, 4)
    monkeypatch.setattr(losses, "COUNT_CHUNK", 2)
    chunked = class_pixel_counts(labels, 4)
    assert [t.tolist() for t in chunked] == [t.tolist() for t in whole]
    assert whole[0].tolist() == [3, 4, 3, 0] and whole[1].tolist() == [6, 7, 7, 0]


def test_median_frequency_hand_made() -> None:
    labels = torch.tensor([[[0, 0], [1, 255]], [[1, 1], [1, 2]]], dtype=torch.uint8)
    w = median_frequency_weights(labels, 4)
    freq = torch.tensor([2 / 3, 4 / 7, 1 / 4])
    median = 4 / 7
    torch.testing.assert_close(w[:3], median / freq)
    assert w[3] == 0.0  # absent class
    clipped = median_frequency_weights(labels, 4, max_weight=2.0)
    assert float(clipped.max()) == pytest.approx(2.0)


def test_all_ignore_raises() -> None:
    with pytest.raises(ValueError, match="ignore"):
        median_frequency_weights(torch.full((1, 2, 2), 255, dtype=torch.uint8), 3)


def test_loss_ignores_255() -> None:
    logits = torch.randn(1, 3, 2, 2, generator=torch.Generator().manual_seed(0))
    target = torch.tensor([[[0, 1], [2, 255]]])
    full = segmentation_loss(logits, target)
    manual = -torch.log_softmax(logits, 1)[0, [0, 1, 2], [0, 0, 1], [0, 1, 0]].mean()
    torch.testing.assert_close(full, manual)
    w = torch.tensor([1.0, 2.0, 0.0])
    weighted = segmentation_loss(logits, target, w)
    terms = -torch.log_softmax(logits, 1)[0, [0, 1], [0, 0], [0, 1]]
    torch.testing.assert_close(weighted, (terms * torch.tensor([1.0, 2.0])).sum() / 3.0)


def test_median_frequency_power_softens():
    labels = torch.tensor([[[0, 0, 0, 1]]]).expand(2, 4, 4).clone()
    full = median_frequency_weights(labels, 2)
    soft = median_frequency_weights(labels, 2, power=0.5)
    torch.testing.assert_close(soft, full.sqrt())


def test_boundary_mask() -> None:
    """Pixels with another class in their 3x3 neighbourhood: the two columns at a change."""
    t = torch.zeros(1, 4, 6, dtype=torch.long)
    t[..., 3:] = 2
    m = boundary_mask(t)
    assert m[0, :, 2:4].all() and not m[0, :, :2].any() and not m[0, :, 4:].any()


def test_boundary_weighted_loss() -> None:
    """boundary_weight 1 is the plain loss; above 1, errors at a class change weigh more, and
    a weighted mean of equal per-pixel losses stays that loss."""
    t = torch.zeros(1, 4, 6, dtype=torch.long)
    t[..., 3:] = 1
    t[0, 0, 0] = 255
    w = torch.tensor([0.5, 2.0])
    logits = torch.where(t.unsqueeze(1) == torch.arange(2).view(1, 2, 1, 1), 4.0, 0.0)
    wrong = logits.clone()
    wrong[..., 2:4] = wrong[..., 2:4].flip(1)  # wrong only at the boundary columns
    plain = segmentation_loss(wrong, t, w)
    torch.testing.assert_close(segmentation_loss(wrong, t, w, 1.0), plain)
    assert segmentation_loss(wrong, t, w, 4.0) > plain
    flat = torch.zeros(1, 2, 4, 6)  # every pixel costs log 2, whatever its weight
    torch.testing.assert_close(segmentation_loss(flat, t, w, 4.0), torch.tensor(0.6931472))
