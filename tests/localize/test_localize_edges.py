"""Edge images, the three modes' edge maps (extractor), the segmenter's class check."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from core import classes as C
from core.atomic import file_sha256
from core.classes import pair_classes, pair_code, pair_name
from localize.config import HoughConfig
from localize.frontend.boundaries import label_edges
from localize.frontend.canny import canny_edges
from localize.frontend.edge_image import EdgeImage
from localize.frontend.extractor import EdgeExtractor, edge_settings
from localize.frontend.segmenter import (
    check_classes,
    class_log_prior,
    int8_copy,
    load_segmenter,
    runtime_model,
    structural_prior_labels,
)
from localize.frontend.sources import SegmenterLabels, edge_source
from tests.localize.conftest import palette_segnet

# the cnn mode as the plain class boundaries of the predicted labels (no prior correction, no
# snap, no image edges added); tests that exercise one of those turn it on with cnn(...)
PLAIN_CNN = {"prior_correction": 0.0, "snap_px": 0, "refine": "none"}
EDGES_CFG = {"canny": {"low": 50.0, "high": 150.0, "blur": 3},
             "hough": {"threshold": 10, "min_length": 8, "max_gap": 2},
             "labels": {"dilate_px": 1, "median": 0},
             "cnn": PLAIN_CNN}


def cnn(**settings) -> dict:
    """EDGES_CFG with these ``edges.cnn`` settings on top of the plain ones."""
    return {**EDGES_CFG, "cnn": {**PLAIN_CNN, **settings}}


def segment(segmenter, edges: dict, rgb: np.ndarray) -> np.ndarray:
    """The cnn mode's labels of a frame with these ``edges`` settings."""
    return SegmenterLabels(segmenter, edge_settings(edges).cnn).labels(rgb, None)


def two_walls() -> np.ndarray:
    """(20, 30) labels: ceiling above row 5, wall left of column 15, door right of it, a person
    blob, floor below row 15."""
    lab = np.full((20, 30), C.WALL, dtype=np.uint8)
    lab[:5] = C.CEILING
    lab[5:15, 15:] = C.DOOR
    lab[15:] = C.FLOOR
    lab[8:12, 22:26] = C.PERSON
    return lab


class TestLabelEdges:
    def test_boundaries_between_structural_classes(self):
        e = label_edges(two_walls(), dilate_px=0)
        assert e.edges[4, 3] and e.edges[5, 3]  # ceiling | wall, both sides marked
        assert e.edges[8, 14] and e.edges[8, 15]  # wall | door
        assert not e.edges[10, 5]  # inside the wall
        assert not e.known[9, 23] and e.known[9, 20]  # the person is unknown
        assert not e.edges[7, 23]  # door | person is not a model edge

    def test_class_pair_of_each_edge_pixel(self):
        lab = two_walls()
        lab[0, :3] = 255  # ignore pixels, as true label images have
        e = label_edges(lab, dilate_px=0)
        assert e.pairs[4, 3] == e.pairs[5, 3] == pair_code(C.CEILING, C.WALL)
        assert e.pairs[8, 14] == e.pairs[8, 15] == pair_code(C.DOOR, C.WALL)
        assert e.pairs[14, 3] == pair_code(C.WALL, C.FLOOR)
        assert (e.pairs[~e.edges] == 0).all() and (e.pairs[e.edges] > 0).all()
        assert pair_code(C.WALL, C.DOOR) == pair_code(C.DOOR, C.WALL) != pair_code(C.WALL,
                                                                                  C.WINDOW)
        with pytest.raises(ValueError, match="below 16"):
            pair_code(3, 16)
        assert pair_classes(int(pair_code(C.DOOR, C.WALL))) == (C.WALL, C.DOOR)
        assert pair_name(pair_code(C.DOOR, C.WALL), {C.WALL: "wall"}) == f"wall | {C.DOOR}"

    def test_dilation_grows_unknown(self):
        a = label_edges(two_walls(), dilate_px=0)
        b = label_edges(two_walls(), dilate_px=2)
        assert (~b.known).sum() > (~a.known).sum()
        assert not (b.edges & ~b.known).any()

    def test_all_clutter(self):
        e = label_edges(np.full((10, 10), C.CLUTTER, np.uint8))
        assert not e.edges.any() and not e.known.any()

    def test_bad_shape(self):
        with pytest.raises(ValueError, match=r"\(H, W\)"):
            label_edges(np.zeros((4, 4, 3), np.uint8))


class TestCanny:
    def test_finds_the_step(self):
        img = np.zeros((40, 40, 3), np.uint8)
        img[:, 20:] = 200
        e = canny_edges(img, blur=0)
        assert e.edges[:, 19:21].any(axis=1).mean() > 0.9
        assert not e.edges[:, :15].any() and e.known.all()

    def test_colour_finds_a_step_of_equal_brightness(self):
        """Red | green of the same grey level: no grey edge, a colour one."""
        img = np.zeros((40, 40, 3), np.uint8)
        img[:, :20] = (150, 0, 0)
        img[:, 20:] = (0, 76, 0)   # 0.299 * 150 = 44.9, 0.587 * 76 = 44.6: the same grey
        assert not canny_edges(img, blur=0).edges.any()
        e = canny_edges(img, blur=0, colour=True)
        assert e.edges[:, 19:21].any(axis=1).mean() > 0.9 and not e.edges[:, :15].any()

    def test_hough_keeps_lines(self):
        img = np.zeros((40, 40, 3), np.uint8)
        img[:, 20:] = 200
        e = canny_edges(img, blur=0, hough={"threshold": 10, "min_length": 10, "max_gap": 2})
        assert e.edges[:, 18:22].sum() >= 30

    def test_black_image_has_no_edges(self):
        e = canny_edges(np.zeros((24, 32, 3), np.uint8))
        assert not e.edges.any()

    def test_bad_input(self):
        with pytest.raises(ValueError, match="uint8"):
            canny_edges(np.zeros((8, 8, 3), np.float32))

    def test_edge_image_shape_check(self):
        with pytest.raises(ValueError, match="same"):
            EdgeImage(np.zeros((4, 4), bool), np.zeros((4, 5), bool))


class TestPriorCorrection:
    def test_takes_the_class_weights_out_of_structural_choices(self):
        z = np.zeros((C.NUM_CLASSES, 1, 3), np.float32)
        z[C.DOOR, 0, 0], z[C.WALL, 0, 0] = 1.0, 0.5      # door wins only by its weight
        z[C.DOOR, 0, 1], z[C.WALL, 0, 1] = 3.0, 0.5      # door wins clearly
        z[C.PERSON, 0, 2], z[C.WALL, 0, 2] = 1.0, 0.9    # a person stays a person
        log_w = np.zeros(C.NUM_CLASSES)
        log_w[C.WALL], log_w[C.DOOR] = np.log(0.36), np.log(1.0)
        out = structural_prior_labels(z, np.array(C.STRUCTURAL), log_w)
        assert out.tolist() == [[C.WALL, C.DOOR, C.PERSON]] and out.dtype == np.uint8
        given = structural_prior_labels(z, np.array(C.STRUCTURAL), log_w,
                                        z.argmax(0).astype(np.uint8))  # the graph's argmax
        np.testing.assert_array_equal(given, out)
        same = structural_prior_labels(z, np.array(C.STRUCTURAL), np.zeros(C.NUM_CLASSES))
        np.testing.assert_array_equal(same, z.argmax(0))

    def test_extractor_reads_the_weights_from_the_model(self, tmp_path):
        lab = two_walls()
        cfg = cnn(prior_correction=1.0)
        weights = {c["name"]: 1.0 for c in C.as_json()}
        seg = load_segmenter(palette_segnet(tmp_path / "a.onnx", 20, 30,
                                            extra_metadata={"class_weights": weights}),
                             C.as_json(), 1)
        labels = segment(seg, cfg, C.colorize(lab))
        np.testing.assert_array_equal(labels, lab)  # equal weights: nothing to correct
        weights["door"] = 1e-9  # the network "learned" door with a tiny weight: favour it
        seg = load_segmenter(palette_segnet(tmp_path / "b.onnx", 20, 30,
                                            extra_metadata={"class_weights": weights}),
                             C.as_json(), 1)
        labels = segment(seg, cfg, C.colorize(lab))
        structural = np.isin(lab, C.STRUCTURAL)
        assert (labels[structural] == C.DOOR).all()
        np.testing.assert_array_equal(labels[~structural], lab[~structural])  # masks unchanged
        assert SegmenterLabels(seg, edge_settings(cnn(prior_correction=0.0)).cnn
                               ).predictor.log_prior is None  # strength 0: off
        np.testing.assert_array_equal(segment(seg, cnn(prior_correction=0.0), C.colorize(lab)),
                                      lab)

    def test_model_without_weights_warns_and_skips(self, tmp_path, caplog):
        seg = load_segmenter(palette_segnet(tmp_path / "s.onnx", 20, 30), C.as_json(), 1)
        with caplog.at_level("WARNING"):
            assert class_log_prior(seg) is None
        assert "class_weights" in caplog.text
        lab = two_walls()
        np.testing.assert_array_equal(segment(seg, cnn(prior_correction=1.0), C.colorize(lab)),
                                      lab)

    def test_model_trained_without_weighting_needs_no_correction(self, tmp_path, caplog):
        path = palette_segnet(tmp_path / "s.onnx", 20, 30, extra_metadata={"class_weights": None})
        with caplog.at_level("WARNING"):
            assert class_log_prior(load_segmenter(path, C.as_json(), 1)) is None
        assert "class_weights" not in caplog.text

    def test_weights_missing_a_class(self, tmp_path):
        path = palette_segnet(tmp_path / "s.onnx", 20, 30,
                              extra_metadata={"class_weights": {"wall": 0.4}})
        with pytest.raises(ValueError, match="class_weights lacks"):
            class_log_prior(load_segmenter(path, C.as_json(), 1))


class TestSegmenter:
    def test_palette_segnet_is_exact(self, tmp_path):
        lab = two_walls()
        seg = load_segmenter(palette_segnet(tmp_path / "s.onnx", 20, 30), C.as_json(), 1)
        ex = EdgeExtractor("cnn", EDGES_CFG)
        labels = segment(seg, EDGES_CFG, C.colorize(lab))
        np.testing.assert_array_equal(labels, lab)
        e = ex.edges(C.colorize(lab), labels)
        ref = label_edges(lab, dilate_px=1)
        np.testing.assert_array_equal(e.edges, ref.edges)

    def test_union_adds_image_edges_beside_boundaries(self):
        """refine union: every predicted boundary stays (with its class pair); Canny edges
        within refine_px of one join it, without a pair; those farther away do not."""
        lab = two_walls()
        rgb = C.colorize(lab)
        rgb[9:11, 2:8] = 255   # a stripe inside the wall, far from every boundary
        rgb[6:9, 12] = 255     # a short mark 2 px left of the wall | door boundary
        plain = EdgeExtractor("cnn", cnn(refine="none")).edges(rgb, lab)
        both = EdgeExtractor("cnn", cnn(refine="union", refine_px=2)).edges(rgb, lab)
        canny = canny_edges(rgb, **{k: EDGES_CFG["canny"][k] for k in ("low", "high", "blur")})
        assert canny.edges[8:12, 2:8].any() and canny.edges[6:9, 11:14].any()
        assert (both.edges >= plain.edges).all()
        np.testing.assert_array_equal(both.pairs, plain.pairs)
        np.testing.assert_array_equal(both.known, plain.known)
        assert not both.edges[8:12, 2:8].any()           # the far stripe stays out
        added = both.edges & ~plain.edges
        assert added[6:9, 11:14].any()                   # the mark beside the boundary joins
        dist = cv2.distanceTransform((~plain.edges).astype(np.uint8), cv2.DIST_L2, 3)
        assert dist[added].max() <= 2.0 + 1e-6
        assert not (added & ~both.known).any()

    def test_int8_copy_made_of_the_model(self, tmp_path):
        """segnet_int8: the int8 copy beside segnet.onnx is run where quantize.json says it
        was made of that file's bytes (its SHA-256); a stale, foreign or undated one is not."""
        model = tmp_path / "segnet.onnx"
        palette_segnet(model, 20, 30)
        assert runtime_model(str(model), "unused") == model  # no copy
        copy = tmp_path / "segnet_int8.onnx"
        copy.write_bytes(model.read_bytes())
        assert int8_copy(model) is None  # no quantize.json: unknown origin
        made_of = {"model": "elsewhere/segnet.onnx", "model_sha256": file_sha256(model)}
        (tmp_path / "quantize.json").write_text(json.dumps(made_of))
        assert runtime_model(str(model), "unused") == copy
        assert runtime_model(str(model), "unused", int8=False) == model
        assert int8_copy(copy) is None  # the copy has no copy
        (tmp_path / "quantize.json").write_text(json.dumps({**made_of, "model": "other.onnx"}))
        assert int8_copy(model) is None  # made of another file
        (tmp_path / "quantize.json").write_text(json.dumps({"model": "segnet.onnx"}))
        assert int8_copy(model) is None  # no digest: quantize again
        (tmp_path / "quantize.json").write_text(json.dumps(made_of))
        model.write_bytes(model.read_bytes() + b"\0")  # retrained: other bytes
        assert int8_copy(model) is None

    def test_image_cues_made_apart_give_the_same_edges(self):
        """The colour image's cues made beforehand (as FrontEnd.frame does, on a second
        thread) give the edges made in one go."""
        lab = two_walls()
        rgb = C.colorize(lab)
        rgb[6:9, 12] = 255
        ex = EdgeExtractor("cnn", cnn(refine="union", refine_px=2))
        assert ex.reads_image and not EdgeExtractor("oracle", EDGES_CFG).reads_image
        whole, apart = ex.edges(rgb, lab), ex.edges(rgb, lab, ex.image_cues(rgb))
        np.testing.assert_array_equal(whole.edges, apart.edges)
        np.testing.assert_array_equal(whole.pairs, apart.pairs)

    def test_missing_model(self, tmp_path):
        with pytest.raises(FileNotFoundError, match="python -m train"):
            load_segmenter(tmp_path / "nope.onnx", C.as_json())

    def test_classes_must_match(self, tmp_path):
        other = C.as_json()
        other[6]["name"] = "furniture"
        path = palette_segnet(tmp_path / "s.onnx", 20, 30, classes=other)
        with pytest.raises(ValueError, match="do not match"):
            load_segmenter(path, C.as_json())
        with pytest.raises(ValueError, match="do not match"):
            check_classes(C.as_json()[:5], C.as_json(), "x.onnx")
        assert json.loads(json.dumps(C.as_json())) == C.as_json()

    def test_modes(self):
        with pytest.raises(ValueError, match="unknown edge mode"):
            EdgeExtractor("sobel", EDGES_CFG)
        with pytest.raises(ValueError, match="needs a segmenter"):
            edge_source("cnn")
        # a partial edges config takes the defaults for the rest
        assert EdgeExtractor("none", {"canny": EDGES_CFG["canny"]}).settings.hough == \
            HoughConfig()
        with pytest.raises(ValueError, match="needs a label map"):
            EdgeExtractor("oracle", EDGES_CFG).edges(np.zeros((20, 30, 3), np.uint8))
        e = EdgeExtractor("oracle", EDGES_CFG).edges(None, two_walls())
        assert e.edges.any()


class TestCnnSettings:
    def test_unknown_cnn_key_raises(self):
        with pytest.raises(ValueError, match=r"edges.cnn.snap_pixels: Key 'snap_pixels' not in"):
            EdgeExtractor("cnn", cnn(snap_pixels=3))

    def test_cnn_setting_of_the_wrong_type_raises(self):
        for key, value in (("snap_nearest", "maybe"), ("snap_px", 1.5),
                           ("snap_min_gradient", "steep")):
            with pytest.raises(ValueError, match=f"edges.cnn.{key}: "):
                edge_settings({"cnn": {key: value}})
        assert edge_settings({"cnn": {"snap_px": 3, "snap_min_gradient": 5}}).cnn.snap_px == 3

    @pytest.mark.parametrize("refine", ["sobel", "canny", "mask"])
    def test_unknown_refine_raises(self, refine):
        with pytest.raises(ValueError, match="edges.cnn.refine"):
            EdgeExtractor("cnn", cnn(refine=refine))
