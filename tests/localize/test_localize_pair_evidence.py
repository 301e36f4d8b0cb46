"""benchmarks/pair_evidence.py: per class pair, do the edges prefer the truth to an estimate?"""

from __future__ import annotations

import numpy as np

from benchmarks.pair_evidence import evidence, pair_likelihoods
from core.classes import pair_code
from localize.config import VisibilityConfig
from localize.filter.likelihood import LikelihoodConfig
from localize.filter.projection import cam_from_world, sample_segments
from localize.filter.visibility import build_visibility
from localize.frontend.boundaries import label_edges
from localize.frontend.front_end import EdgeFrame

TRUE = np.array([0.2, 0.8, 1.2, np.deg2rad(80.0)])


def test_pairs_prefer_the_truth(small_world, camera, renderer):
    s = sample_segments(small_world.segments, 0.05)
    sc = small_world.segment_classes
    s, _ = s.select(sc[:, 0] != sc[:, 1])
    vis = build_visibility(small_world, s.points,
                           settings=VisibilityConfig(cell_xy=0.2, cell_z=0.3))
    pairs = pair_code(sc[s.segment, 0], sc[s.segment, 1])
    liks = pair_likelihoods(s, vis, pairs, camera, LikelihoodConfig(k=20.0, sigma=0.1))
    assert set(liks) == {"all", *(str(int(c)) for c in np.unique(pairs))}
    for key, lik in liks.items():  # each pair's likelihood holds that pair's samples only
        if key != "all":
            np.testing.assert_array_equal(pairs[np.isin(s.segment, lik.samples.segment)],
                                          int(key))
    labels, _ = renderer.render(np.linalg.inv(cam_from_world(TRUE[None],
                                                             camera.body_from_cam)[0]))
    frame = EdgeFrame(label_edges(labels, dilate_px=0), labels, {})
    same = evidence(liks, frame, TRUE, TRUE, None)
    assert all(v == 0.0 for v in same.values())
    off = evidence(liks, frame, TRUE + [0.0, 0.05, 0.0, 0.0], TRUE, None)
    assert off["all"] < -1.0  # 5 cm off: true edges pull back, strongly at k = 20
    assert sum(v < 0 for k, v in off.items() if k != "all") >= 2
