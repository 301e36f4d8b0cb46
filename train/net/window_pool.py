"""2x2 max pooling that remembers where each maximum was, as a window-local code, and its
inverse: SegNet's pooling indices in a form that exports to a fast ONNX graph (a plain
MaxPool, Mul and DepthToSpace: docs/train.md, "the pooling graph without Where").

``code_to_plane_index`` / ``plane_index_to_code`` convert to and from the plane indices of
``nn.MaxPool2d(2, 2, return_indices=True)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn


def window_element(x: torch.Tensor, dy: int, dx: int) -> torch.Tensor:
    """``x[..., dy::2, dx::2]``, computed as a depthwise 2x2 / stride-2 convolution whose kernel
    is 1 at (dy, dx) and 0 elsewhere: exact for finite x (one product by 1, three by 0), and in
    onnxruntime a fast NCHWc convolution where a strided Slice is not.

    Shapes: (B, C, H, W) with even H, W -> (B, C, H/2, W/2).
    """
    c = x.shape[1]
    kernel = torch.zeros(c, 1, 2, 2, dtype=x.dtype, device=x.device)
    kernel[:, 0, dy, dx] = 1.0
    return F.conv2d(x, kernel, stride=2, groups=c)


class WindowMaxPool(nn.Module):
    """2x2 / stride-2 max pooling that returns, per window, where the maximum was.

    Same values and the same choice as ``nn.MaxPool2d(2, 2, return_indices=True)`` (the first
    maximum in row-major order wins a tie), but the position is a window-local code
    0..3 = 2 * dy + dx instead of an index into the H*W plane. Exported to ONNX this is a
    plain MaxPool (fast NCHWc kernel in onnxruntime) and a few cheap ops, about twice as fast
    as MaxPool-with-indices + ScatterND. The code is arithmetic on the "not the maximum" flags
    of the first three positions, code = na * (1 + nb * (1 + nc)), not nested ``where``
    (onnxruntime's Where is several times slower than Mul on uint8), and the positions are
    read by ``window_element``, not strided slices (docs/train.md, "the pooling graph
    without Where").

    Shapes: (B, C, H, W) with even H, W -> values (B, C, H/2, W/2), codes (B, C, H/2, W/2) uint8.
    """

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        y = F.max_pool2d(x, 2, 2)
        na, nb, nc = (
            (window_element(x, dy, dx) != y).to(torch.uint8)
            for dy, dx in ((0, 0), (0, 1), (1, 0))
        )
        return y, na * (1 + nb * (1 + nc))


class WindowMaxUnpool(nn.Module):
    """Inverse of ``WindowMaxPool``: each value goes to its window's code position, zeros
    elsewhere; equals ``nn.MaxUnpool2d(2, 2)`` with the corresponding plane indices.

    The four positions are the values times a 0/1 mask (Mul, not Where: see
    ``WindowMaxPool``), interleaved by ``pixel_shuffle`` (DepthToSpace).

    Shapes: values (B, C, h, w), codes (B, C, h, w) -> (B, C, 2h, 2w).
    """

    def forward(
        self, y: torch.Tensor, code: torch.Tensor, output_size: Sequence[int] | None = None
    ) -> torch.Tensor:
        parts = torch.stack([y * (code == k).to(y.dtype) for k in range(4)], dim=2)
        b, c, h, w = y.shape
        return F.pixel_shuffle(parts.reshape(b, c * 4, h, w), 2)


def code_to_plane_index(code: torch.Tensor) -> torch.Tensor:
    """Window codes (B, C, h, w) -> ``nn.MaxPool2d`` indices into the (2h, 2w) plane, int64."""
    h, w = code.shape[-2:]
    rows = torch.arange(h, device=code.device).view(h, 1) * 2
    cols = torch.arange(w, device=code.device).view(1, w) * 2
    c = code.long()
    return (rows + c // 2) * (2 * w) + cols + c % 2


def plane_index_to_code(index: torch.Tensor) -> torch.Tensor:
    """``nn.MaxPool2d`` indices (B, C, h, w) into the (2h, 2w) plane -> window codes, uint8."""
    w2 = 2 * index.shape[-1]
    return ((index // w2) % 2 * 2 + index % w2 % 2).to(torch.uint8)
