"""benchmarks/edges_scale.py: the class pair table and the scored counts of a small room."""

from __future__ import annotations

from benchmarks.edges_scale import pair_table, scored
from datagen.mesh.edges import extract_edges
from tests.buildings import assemble


def test_pair_table_and_scored_counts_of_walls_on_a_slab():
    t = 0.2
    walls = [(-t, -t, 4 + t, 0), (-t, 4, 4 + t, 4 + t), (-t, 0, 0, 4), (4, 0, 4 + t, 4)]
    seg, cls, _, _ = extract_edges(*assemble([(-1, -1, 5, 5)], walls))
    table = {name: (n, m) for name, n, m in pair_table(seg, cls)}
    assert table["floor|wall"][1] > 33
    res = scored(seg, cls, 0.05, 0.1)
    assert res["scored_segments"] == len(seg)
    assert 0 < res["class_change_segments"] < res["scored_segments"]
    assert res["class_change_samples"] >= 10 * 33
