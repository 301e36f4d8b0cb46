"""The front end: edge sources, frames, and score maps made once per map settings."""

from __future__ import annotations

import numpy as np
import pytest

from core import classes as C
from localize.config import CnnConfig
from localize.filter.likelihood import EdgeLikelihood, LikelihoodConfig
from localize.filter.projection import sample_segments
from localize.frontend.front_end import FrontEnd
from localize.frontend.sources import (
    CannyEdges,
    EdgeSource,
    LabelFunction,
    SegmenterLabels,
    TrueLabels,
    edge_source,
)
from tests.localize.test_localize_edges import EDGES_CFG, two_walls

PLAIN = CnnConfig(prior_correction=0.0)  # the stub has no class weights to take out


class Labeller:
    """A segmenter stub: the same labels for every frame."""

    def labels(self, rgb: np.ndarray) -> np.ndarray:
        return two_walls()


class TestEdgeSource:
    def test_names_callables_and_sources(self):
        assert isinstance(edge_source("none"), CannyEdges)
        assert isinstance(edge_source("oracle"), TrueLabels)
        assert isinstance(edge_source("cnn", Labeller(), PLAIN), SegmenterLabels)
        fn = edge_source(lambda rgb: two_walls())
        assert isinstance(fn, LabelFunction) and fn.mode == "cnn" and not fn.needs_truth
        own = TrueLabels()
        assert edge_source(own) is own
        for source in (CannyEdges(), TrueLabels(), SegmenterLabels(Labeller(), PLAIN), fn):
            assert isinstance(source, EdgeSource)

    def test_bad_sources(self):
        with pytest.raises(ValueError, match="unknown edge source 'sobel'"):
            edge_source("sobel")
        with pytest.raises(ValueError, match=r"needs a segmenter.*SegmenterLabels"):
            edge_source("cnn")
        with pytest.raises(ValueError, match="use 'cnn' or 'oracle'"):
            LabelFunction(lambda rgb: rgb, mode="none")


class TestFrame:
    def test_each_mode(self):
        rgb = C.colorize(two_walls())
        canny = FrontEnd("none", EDGES_CFG).frame(rgb)
        assert canny.labels is None and canny.edge.known.all() and canny.edge.edges.any()
        oracle = FrontEnd("oracle", EDGES_CFG).frame(None, two_walls())
        np.testing.assert_array_equal(oracle.labels, two_walls())
        assert not oracle.edge.known.all()  # the person is unknown
        cnn = FrontEnd(SegmenterLabels(Labeller(), PLAIN), EDGES_CFG).frame(rgb)
        np.testing.assert_array_equal(cnn.labels, two_walls())
        assert set(cnn.timing_ms) == {"segmentation", "edges"}

    def test_bad_input(self):
        front = FrontEnd("oracle", EDGES_CFG)
        with pytest.raises(ValueError, match=r"labels must be \(H, W\).*got \(20, 30, 3\)"):
            front.frame(None, np.zeros((20, 30, 3), np.uint8))
        with pytest.raises(ValueError, match=r"image \(20, 30\), got \(10, 30\)"):
            front.frame(np.zeros((20, 30, 3), np.uint8), two_walls()[:10])
        with pytest.raises(ValueError, match="needs the image"):
            FrontEnd("none", EDGES_CFG).frame(None)

    def test_score_maps_made_once_per_settings(self, small_world, camera):
        samples = sample_segments(small_world.segments, 0.2)
        lik = [EdgeLikelihood(samples, camera, LikelihoodConfig(sigma=s)) for s in (0.1, 0.1,
                                                                                      0.3)]
        labels = np.full((camera.height, camera.width), C.WALL, np.uint8)
        labels[:, 80:] = C.DOOR
        frame = FrontEnd("oracle", EDGES_CFG).frame(None, labels)
        a, ms = frame.observation(lik[0])
        b, ms_b = frame.observation(lik[1])  # same map settings: the same maps
        c, _ = frame.observation(lik[2])
        assert a is b and ms == ms_b and c is not a
        assert len(frame._maps) == 2
        assert not np.array_equal(a.g, c.g)
