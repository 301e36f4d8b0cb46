"""The guided refinement of class probabilities: settings, behaviour, and the predictor's use."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from core.classes import as_json
from train.export import export_checked, onnx_metadata
from train.predict import OnnxSegmenter
from train.refine import GuidedRefine, refine_logits, refine_logits_np
from train.segnet import SegNet


def step_scene(h: int = 32, w: int = 48, edge: int = 24, boundary: float = 20.5,
               ramp: float = 3.0) -> tuple[torch.Tensor, torch.Tensor]:
    """An image with a vertical edge at column ``edge`` and two-class logits whose soft
    boundary sits at ``boundary`` instead (as a low-resolution network's would)."""
    img = torch.full((1, 3, h, w), 0.2)
    img[..., edge:] = 0.8
    x = torch.arange(w, dtype=torch.float32)
    z = ((x - boundary) / ramp).expand(h, w)
    return img, torch.stack([-z, z])[None]


def boundary_column(logits: torch.Tensor) -> float:
    """Mean first column of class 1 over the rows."""
    lab = logits.argmax(1)[0]
    return lab.float().argmax(1).float().mean().item()


class TestSettings:
    def test_from_cfg(self) -> None:
        assert GuidedRefine.from_cfg(None) is None
        assert GuidedRefine.from_cfg({"enabled": False, "kernel_size": 9}) is None
        r = GuidedRefine.from_cfg({"enabled": True, "kernel_size": 9, "eps": "1e-3"})
        assert r == GuidedRefine(kernel_size=9, eps=1e-3, subsample=4)
        assert GuidedRefine(**r.as_dict()) == r

    @pytest.mark.parametrize("bad, match", [
        ({"kernel": 9}, r"unknown eval.refine keys \['kernel'\]"),
        ({"kernel_size": 8}, "positive odd"),
        ({"eps": 0}, "eps must be > 0"),
        ({"subsample": 0}, "subsample must be >= 1"),
    ])
    def test_bad_settings(self, bad: dict, match: str) -> None:
        with pytest.raises(ValueError, match=match):
            GuidedRefine.from_cfg(bad)


class TestRefine:
    @pytest.mark.parametrize("subsample, tol", [(1, 0.5), (4, 1.0)])
    def test_boundary_moves_to_the_image_edge(self, subsample: int, tol: float) -> None:
        """3 px off before; on the edge after (within a pixel when subsampled: the fast
        filter's coefficients are interpolated)."""
        img, logits = step_scene()
        assert boundary_column(logits) == pytest.approx(21.0)
        out = refine_logits(img, logits, GuidedRefine(kernel_size=15, eps=1e-4,
                                                      subsample=subsample))
        assert out.shape == logits.shape and torch.isfinite(out).all()
        assert boundary_column(out) == pytest.approx(24.0, abs=tol)

    def test_flat_image_keeps_the_boundary(self) -> None:
        """Without an edge in the guide there is nothing to snap to: a symmetric soft
        boundary stays where it was."""
        img, logits = step_scene()
        img[:] = 0.5
        out = refine_logits(img, logits, GuidedRefine(kernel_size=9, eps=1e-4, subsample=1))
        assert boundary_column(out) == pytest.approx(boundary_column(logits), abs=1.0)

    def test_numpy_wrapper(self) -> None:
        img, logits = step_scene()
        rgb = (img.permute(0, 2, 3, 1).numpy() * 255).round().astype(np.uint8)
        s = GuidedRefine(kernel_size=15, eps=1e-4, subsample=1)
        got = refine_logits_np(rgb, logits.numpy(), s)
        ref = refine_logits(torch.from_numpy(rgb).permute(0, 3, 1, 2).float() / 255, logits, s)
        np.testing.assert_allclose(got, ref.numpy(), atol=1e-5)


def test_predictor_applies_the_models_refinement(tmp_path: Path) -> None:
    """segnet.onnx records its refinement; OnnxSegmenter applies it unless refine=False."""
    h, w = 40, 56
    m = SegNet(8, width=0.125, stages=3, convs_per_stage=[1, 1, 1],
               generator=torch.Generator().manual_seed(0)).eval()
    images = torch.rand(2, 3, h, w, generator=torch.Generator().manual_seed(2))
    settings = GuidedRefine(kernel_size=9, eps=1e-3, subsample=2)
    meta = onnx_metadata(m, as_json(), h, w, "r", extra={"refine": settings.as_dict()})
    path = tmp_path / "r.onnx"
    export_checked(m, path, images, meta, tolerance=1e-4, threads=1)
    rgb = (images.permute(0, 2, 3, 1).numpy() * 255).round().astype(np.uint8)
    plain = OnnxSegmenter(path, threads=1, refine=False)
    refined = OnnxSegmenter(path, threads=1)
    assert plain.refine is None and refined.refine == settings
    raw = plain.logits(rgb)
    np.testing.assert_allclose(refined.logits(rgb), refine_logits_np(rgb, raw, settings),
                               atol=1e-5)
    labels, probs = refined.predict(rgb[0])
    assert labels.shape == (h, w) and np.isfinite(probs).all()
