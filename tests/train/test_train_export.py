"""ONNX export: parity with torch through onnxruntime, metadata, dynamic batch, the predictor."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch

from core.classes import as_json
from core.segmenter import OnnxSegmenter, ort_session, read_metadata
from train.deploy.export import (
    ParityError,
    add_label_output,
    check_parity,
    export_checked,
    onnx_metadata,
    to_onnx_proto,
)
from train.deploy.predict import main
from train.net.segnet import SegNet

H, W = 40, 56  # not multiples of the model's 8: the graph pads and crops


@pytest.fixture(scope="module")
def model() -> SegNet:
    m = SegNet(
        8,
        width=0.125,
        stages=3,
        convs_per_stage=[1, 1, 1],
        generator=torch.Generator().manual_seed(0),
    )
    # Non-trivial BatchNorm statistics, as after training.
    g = torch.Generator().manual_seed(1)
    for mod in m.modules():
        if isinstance(mod, torch.nn.BatchNorm2d):
            mod.running_mean.copy_(0.1 * torch.randn(mod.num_features, generator=g))
            mod.running_var.copy_(0.5 + torch.rand(mod.num_features, generator=g))
    return m.eval()


@pytest.fixture(scope="module")
def images() -> torch.Tensor:
    return torch.rand(5, 3, H, W, generator=torch.Generator().manual_seed(2))


@pytest.fixture(scope="module")
def exported(model: SegNet, images: torch.Tensor, tmp_path_factory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("onnx") / "segnet.onnx"
    meta = onnx_metadata(model, as_json(), H, W, "abcd1234")
    report = export_checked(model, path, images, meta, tolerance=1e-4, threads=2, batch_size=2)
    return path, report


class TestExport:
    def test_parity(self, exported) -> None:
        path, report = exported
        assert path.is_file()
        assert report.max_abs_diff <= 1e-4
        assert report.images == 5 and report.label_agreement > 0.999

    def test_graph_interface(self, exported) -> None:
        path, _ = exported
        proto = onnx.load(str(path))
        assert [i.name for i in proto.graph.input] == ["image"]
        assert [o.name for o in proto.graph.output] == ["logits", "labels"]
        assert exported[1].labels_output_mismatch == 0  # labels == argmax(logits), checked
        dims = proto.graph.input[0].type.tensor_type.shape.dim
        assert dims[0].dim_param  # dynamic batch
        assert [d.dim_value for d in dims[1:]] == [3, H, W]
        assert not any(
            t.data_location == onnx.TensorProto.EXTERNAL for t in proto.graph.initializer
        )

    def test_metadata(self, exported, model: SegNet) -> None:
        meta = read_metadata(exported[0])
        assert meta["classes"] == as_json()
        assert (meta["input_height"], meta["input_width"]) == (H, W)
        assert meta["normalization"]["applied_in_graph"] is True
        np.testing.assert_allclose(meta["normalization"]["mean"], model.mean.flatten().tolist())
        assert meta["padding"]["multiple"] == 8
        assert meta["config_hash"] == "abcd1234"

    @pytest.mark.parametrize("batch", [1, 3])
    def test_dynamic_batch(self, exported, model: SegNet, batch: int) -> None:
        x = torch.rand(batch, 3, H, W, generator=torch.Generator().manual_seed(batch))
        out = ort_session(exported[0], threads=1).run(["logits"], {"image": x.numpy()})[0]
        with torch.no_grad():
            ref = model(x).numpy()
        assert out.shape == (batch, 8, H, W)
        np.testing.assert_allclose(out, ref, atol=1e-4, rtol=0)

    def test_window_graph_has_no_scatter(self, exported) -> None:
        ops = {n.op_type for n in onnx.load(str(exported[0])).graph.node}
        assert "MaxPool" in ops and "ScatterND" not in ops and "ScatterElements" not in ops
        assert read_metadata(exported[0])["model"]["pooling"] == "window"

    @pytest.mark.parametrize(("stem", "head"),
                             [("average", "bilinear"), ("unshuffle", "bilinear"),
                              ("unshuffle", "sharpen")])
    def test_downsampled_model_parity(
        self, images: torch.Tensor, tmp_path: Path, stem: str, head: str
    ) -> None:
        m = SegNet(8, width=0.125, stages=2, convs_per_stage=[1, 1], downsample=2, stem=stem,
                   head=head, generator=torch.Generator().manual_seed(3)).eval()
        if m.sharpen_head is not None:  # a head that does something (it starts at zero)
            torch.nn.init.normal_(m.sharpen_head[-1].weight, std=0.1, generator=torch.Generator())
        path = tmp_path / "ds.onnx"
        meta = onnx_metadata(m, as_json(), H, W, "ds")
        report = export_checked(m, path, images, meta, tolerance=1e-4, threads=1, batch_size=5)
        assert report.max_abs_diff <= 1e-4
        assert OnnxSegmenter(path, threads=1).logits(
            (images[:1].permute(0, 2, 3, 1).numpy() * 255).astype(np.uint8)
        ).shape == (1, 8, H, W)

    def test_fails_above_tolerance(
        self, model: SegNet, images: torch.Tensor, tmp_path: Path
    ) -> None:
        path = tmp_path / "strict.onnx"
        meta = onnx_metadata(model, as_json(), H, W, "x")
        with pytest.raises(ParityError, match="does not match torch") as err:
            export_checked(model, path, images[:2], meta, tolerance=0.0)
        assert not path.exists()
        assert err.value.report.max_abs_diff > 0.0

    def test_mismatched_graph_is_caught(self, model: SegNet, images: torch.Tensor) -> None:
        """A graph with other weights must fail even after aligning pooling choices."""
        other = copy.deepcopy(model)
        with torch.no_grad():
            other.classifier.bias.add_(1e-2)
        report = check_parity(model, to_onnx_proto(other, H, W), images[:2], threads=1)
        assert report.raw_max_abs_diff > 1e-3
        assert report.max_abs_diff > 1e-3  # the aligned comparison still sees the change


    def test_wrong_labels_output_is_caught(self, model: SegNet, images: torch.Tensor) -> None:
        proto = add_label_output(to_onnx_proto(model, H, W))
        next(n for n in proto.graph.node if n.op_type == "ArgMax").op_type = "ArgMin"
        report = check_parity(model, proto, images[:2], threads=1)
        assert report.labels_output_mismatch > 0
        assert report.max_abs_diff <= 1e-4  # the logits themselves are right


class TestPredictor:
    def test_predict_matches_torch(self, exported, model: SegNet) -> None:
        seg = OnnxSegmenter(exported[0], threads=1)
        assert seg.num_classes == 8 and seg.input_size == (H, W)
        assert seg.structural_ids.tolist() == [1, 2, 3, 4, 5]
        rng = np.random.default_rng(0)
        rgb = rng.integers(0, 256, (2, H, W, 3), dtype=np.uint8)
        labels, probs = seg.predict(rgb)
        assert labels.shape == (2, H, W) and labels.dtype == np.uint8
        assert probs.shape == (2, 8, H, W) and probs.dtype == np.float32
        np.testing.assert_allclose(probs.sum(1), 1.0, atol=1e-5)
        with torch.no_grad():
            ref = model(torch.from_numpy(rgb).permute(0, 3, 1, 2).float() / 255.0)
        assert (labels == ref.argmax(1).numpy()).mean() > 0.999
        one, one_probs = seg.predict(rgb[0])
        assert one.shape == (H, W) and one_probs.shape == (8, H, W)
        np.testing.assert_array_equal(one, labels[0])
        np.testing.assert_array_equal(seg.labels(rgb), labels)
        np.testing.assert_array_equal(seg.labels(rgb[0]), labels[0])
        z, both = seg.logits_and_labels(rgb)  # one run of the graph
        np.testing.assert_array_equal(z, seg.logits(rgb))
        np.testing.assert_array_equal(both, labels)
        z1, one_both = seg.logits_and_labels(rgb[0])
        assert z1.shape == (8, H, W) and one_both.shape == (H, W)
        np.testing.assert_array_equal(one_both, labels[0])

    def test_graph_without_labels_output(
        self, exported, model: SegNet, tmp_path: Path
    ) -> None:
        """A graph exported before the ``labels`` output still gives labels (numpy argmax)."""
        proto = to_onnx_proto(model, H, W)
        proto.metadata_props.extend(onnx.load(str(exported[0])).metadata_props)
        old = tmp_path / "old.onnx"
        onnx.save(proto, str(old))
        seg_old, seg_new = OnnxSegmenter(old, threads=1), OnnxSegmenter(exported[0], threads=1)
        assert not seg_old.has_labels_output and seg_new.has_labels_output
        rgb = np.random.default_rng(3).integers(0, 256, (3, H, W, 3), dtype=np.uint8)
        np.testing.assert_array_equal(seg_old.labels(rgb), seg_new.labels(rgb))
        np.testing.assert_array_equal(seg_old.labels(rgb), seg_new.logits(rgb).argmax(1))

    def test_bad_input(self, exported) -> None:
        seg = OnnxSegmenter(exported[0], threads=1)
        with pytest.raises(ValueError, match="resize the image"):
            seg.predict(np.zeros((H + 1, W, 3), np.uint8))
        with pytest.raises(ValueError, match="uint8"):
            seg.predict(np.zeros((H, W, 3), np.float32))
        with pytest.raises(ValueError, match="expected an"):
            seg.predict(np.zeros((H, W), np.uint8))
        with pytest.raises(FileNotFoundError, match="python -m train"):
            OnnxSegmenter(exported[0].parent / "missing.onnx")

    def test_cli_writes_overlay(self, exported, tmp_path: Path) -> None:
        from core.atomic import read_png, write_png

        img = tmp_path / "frame.png"
        write_png(img, np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8))
        out = main(
            [
                str(img),
                "--model",
                str(exported[0]),
                "--out",
                str(tmp_path / "o.png"),
                "--labels",
                str(tmp_path / "l.png"),
                "--threads",
                "1",
            ]
        )
        assert read_png(out).shape == (H, W, 3)
        assert read_png(tmp_path / "l.png", rgb=False).max() < 8
