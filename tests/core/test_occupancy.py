"""core.occupancy: free space rasterised from meshes and boxes."""

from __future__ import annotations

import numpy as np
import pytest

from core.occupancy import BLOCKED_RGB, FREE_RGB, MARGIN_RGB, OccupancyMap
from datagen.worlds.corridor import build_world
from tests.buildings import BAND, MARGIN, assemble, occupancy, ring, ring_area, with_ceiling


def _iou(a: OccupancyMap, b: OccupancyMap, step: float) -> float:
    lo = np.minimum(a.extent[:2], b.extent[:2])
    hi = np.maximum(a.extent[2:], b.extent[2:])
    xs, ys = np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step)
    pts = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    ina, inb = a.contains(pts), b.contains(pts)
    return (ina & inb).sum() / (ina | inb).sum()


class TestCorridor:
    def test_mesh_and_boxes_agree(self):
        model = build_world()
        w = model.world
        for cell in (0.05, 0.1):
            mesh = OccupancyMap.from_mesh(w.vertices, w.faces, w.face_class, w.z_range,
                                          MARGIN, cell)
            boxes = OccupancyMap.from_boxes(model.free_boxes, w.z_range, cell, margin=MARGIN)
            assert mesh.area == pytest.approx(boxes.area, rel=0.03)
            assert _iou(mesh, boxes, cell / 3) >= 0.95
            truth = sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in model.free_boxes)
            assert boxes.area == pytest.approx(truth, rel=0.1)  # cells on the box edges
            np.testing.assert_allclose(mesh.distance(np.array([[0.0, 5.0], [0.9, 5.0]])),
                                       [1.0, 0.1], atol=cell / 2)

    def test_boxes_clearance_is_margin_at_the_edge(self):
        occ = OccupancyMap.from_boxes(np.array([[0.0, 0.0, 1.0, 4.0]]), BAND, 0.1,
                                      margin=0.3)
        d = occ.distance(np.array([[0.0, 2.0], [0.5, 2.0], [-0.5, 2.0]]))
        np.testing.assert_allclose(d, [0.3, 0.8, 0.0], atol=1e-6)
        assert occ.area == pytest.approx(11 * 41 * 0.01)  # centres on the edges count


class TestRing:
    def test_area_and_shape(self):
        ring_map = occupancy("ring")
        assert ring_map.area == pytest.approx(ring_area(10, 10, 2, MARGIN), rel=0.05)
        pts = np.array([[1.0, 5.0], [9.0, 5.0], [5.0, 1.0], [5.0, 9.0],  # corridor
                        [5.0, 5.0], [2.1, 5.0],  # inside the solid block, its wall
                        [0.1, 5.0], [-1.0, 5.0], [11.0, 11.0]])  # margin, wall, outside
        np.testing.assert_array_equal(ring_map.contains(pts), [1, 1, 1, 1, 0, 0, 0, 0, 0])
        assert ring_map.distance(pts[:1])[0] == pytest.approx(1.0, abs=0.03)
        assert ring_map.band == BAND and ring_map.margin == MARGIN

    def test_solid_block_is_not_free_unless_asked(self):
        island = OccupancyMap.from_mesh(*ring(), BAND, MARGIN, 0.05, exclude_solids=False)
        assert island.contains(np.array([[5.0, 5.0]]))[0]
        assert island.area == pytest.approx(ring_area(10, 10, 2, MARGIN) + 5.4**2, rel=0.05)

    def test_block_up_to_the_ceiling_is_solid(self):
        ring_map = occupancy("ring")
        occ = OccupancyMap.from_mesh(*with_ceiling(ring(), (-0.2, -0.2), (10.2, 10.2)), BAND,
                                     MARGIN, 0.05)
        np.testing.assert_array_equal(occ.free, ring_map.free)  # top and ceiling touch

    def test_eroded(self):
        ring_map = occupancy("ring")
        more = ring_map.eroded(0.4)
        assert more.margin == pytest.approx(0.7)
        pts = np.array([[1.0, 5.0], [0.5, 5.0]])  # 1.0 and 0.5 m from the wall
        np.testing.assert_array_equal(ring_map.contains(pts), [True, True])
        np.testing.assert_array_equal(more.contains(pts), [True, False])
        assert more.area < ring_map.area
        with pytest.raises(ValueError, match="extra margin"):
            ring_map.eroded(-0.1)
        with pytest.raises(ValueError, match="no free cells to sample"):
            ring_map.eroded(2.0).sample(np.random.default_rng(0), 3)

    def test_grid_is_a_lattice_of_the_cell(self):
        ring_map = occupancy("ring")
        centre = ring_map.centres(np.array([[0], [0]]))[0]
        np.testing.assert_allclose(centre / 0.05, np.round(centre / 0.05), atol=1e-9)

    def test_obstacle_in_the_band_blocks_and_one_below_does_not(self):
        base = [(-0.2, -0.2, 10.2, 10.2)]
        walls = [(-0.2, -0.2, 10.2, 0), (-0.2, 10, 10.2, 10.2), (-0.2, 0, 0, 10),
                 (10, 0, 10.2, 10)]
        v, f, c = assemble(base, walls)
        low = assemble([], [(4, 4, 6, 6)])
        low[0][:, 2] *= 0.4 / 2.8  # a 0.4 m high block: under the band
        high = assemble([], [(4, 4, 6, 6)])  # a 2.8 m one: through it
        for extra, blocked in ((low, False), (high, True)):
            vv = np.concatenate([v, extra[0]])
            ff = np.concatenate([f, extra[1] + len(v)])
            occ = OccupancyMap.from_mesh(vv, ff, np.concatenate([c, extra[2]]), BAND, MARGIN,
                                         0.05)
            assert occ.contains(np.array([[5.0, 5.0]]))[0] != blocked


class TestEll:
    def test_area_and_shape(self):
        ell_map = occupancy("ell")
        legs = 9.4 * 1.4 + 1.4 * 6.0  # [0.3, 9.7] x [0.3, 1.7] and [0.3, 1.7] x [1.7, 7.7]
        assert ell_map.area == pytest.approx(legs, rel=0.06)
        pts = np.array([[8.0, 1.0], [1.0, 7.0], [1.0, 1.0], [5.0, 5.0], [1.0, 7.9]])
        np.testing.assert_array_equal(ell_map.contains(pts), [1, 1, 1, 0, 0])

    def test_sample_is_inside_and_uniform(self):
        ell_map = occupancy("ell")
        pts = ell_map.sample(np.random.default_rng(0), 20000)
        assert pts.shape == (20000, 2)
        assert ell_map.contains(pts).all()
        assert (ell_map.distance(pts) >= MARGIN - 1e-6).all()
        # the share in the long leg (x > 2) matches its share of the free cells
        xs = ell_map.centres(np.nonzero(ell_map.free))[:, 0]
        assert (pts[:, 0] > 2).mean() == pytest.approx((xs > 2).mean(), abs=0.015)
        # within cells: uniform too (jittered, not the centres)
        frac = (pts - ell_map.origin) / ell_map.cell % 1
        assert np.histogram(frac[:, 0], 4, (0, 1))[0].min() > 0.23 * len(pts)

    def test_sample_is_seeded(self):
        ell_map = occupancy("ell")
        a = ell_map.sample(np.random.default_rng(3), 50)
        np.testing.assert_array_equal(a, ell_map.sample(np.random.default_rng(3), 50))
        assert not np.array_equal(a, ell_map.sample(np.random.default_rng(4), 50))


class TestFilesAndImages:
    def test_save_load_round_trip(self, tmp_path):
        ell_map = occupancy("ell")
        path = tmp_path / "maps" / "occupancy.npz"
        ell_map.save(path)
        back = OccupancyMap.load(path)
        np.testing.assert_array_equal(back.free, ell_map.free)
        np.testing.assert_array_equal(back.clearance, ell_map.clearance)
        np.testing.assert_array_equal(back.origin, ell_map.origin)
        assert (back.cell, back.band, back.margin) == (ell_map.cell, ell_map.band,
                                                       ell_map.margin)
        assert [p.name for p in path.parent.iterdir()] == ["occupancy.npz"]

    def test_load_rejects_other_files(self, tmp_path):
        np.savez(tmp_path / "other.npz", free=np.zeros((2, 2), bool))
        with pytest.raises(ValueError, match=r"other.npz: not an occupancy map.*clearance"):
            OccupancyMap.load(tmp_path / "other.npz")
        with pytest.raises(FileNotFoundError, match="missing.npz"):
            OccupancyMap.load(tmp_path / "missing.npz")

    def test_plot(self):
        ell_map = occupancy("ell")
        img = ell_map.plot()
        assert img.shape == (*ell_map.shape, 3) and img.dtype == np.uint8
        colours = {tuple(c) for c in img.reshape(-1, 3)}
        assert colours == {FREE_RGB, MARGIN_RGB, BLOCKED_RGB}
        # +Y up: the top-left pixel near (0, 8) m is the L's upper end, bottom-right (10, 0)
        u, v = np.round(ell_map.to_pixels(np.array([[1.0, 7.5], [9.5, 1.0]]))).astype(int).T
        assert tuple(img[v[0], u[0]]) == FREE_RGB and tuple(img[v[1], u[1]]) == FREE_RGB
        big = ell_map.plot([np.array([[1.0, 7.0], [1.0, 1.0], [9.0, 1.0]])], scale=3)
        assert big.shape == (3 * ell_map.shape[0], 3 * ell_map.shape[1], 3)
        assert len({tuple(c) for c in big.reshape(-1, 3)}) > 3  # the path


class TestBadInput:
    def test_no_floor(self):
        v, f, c = ring()
        with pytest.raises(ValueError, match="no floor below the band"):
            OccupancyMap.from_mesh(v, f, np.full_like(c, 2), BAND, MARGIN, 0.1)

    def test_margin_too_large(self):
        with pytest.raises(ValueError, match="no free space left.*lower the margin"):
            OccupancyMap.from_mesh(*ring(), BAND, 1.5, 0.1)

    def test_band_and_shapes(self):
        v, f, c = ring()
        with pytest.raises(ValueError, match="band must be"):
            OccupancyMap.from_mesh(v, f, c, (2.0, 1.0), MARGIN, 0.1)
        with pytest.raises(ValueError, match="face_class has"):
            OccupancyMap.from_mesh(v, f, c[:-1], BAND, MARGIN, 0.1)
        with pytest.raises(ValueError, match="faces index vertices"):
            OccupancyMap.from_mesh(v[:5], f, c, BAND, MARGIN, 0.1)
        with pytest.raises(ValueError, match="free_boxes must be"):
            OccupancyMap.from_boxes(np.array([[1.0, 0.0, 0.0, 1.0]]), BAND, 0.1)

    def test_nan_vertices(self):
        v, f, c = ring()
        v = v.copy()
        v[[0, 3]] = np.nan
        with pytest.raises(ValueError, match=rf"vertices: 2 of {len(v)} are not finite"):
            OccupancyMap.from_mesh(v, f, c, BAND, MARGIN, 0.1)


class TestGridSize:
    """A grid of more than MAX_CELLS cells is refused before anything is built."""

    def test_a_model_in_millimetres(self):
        """The ring (10.4 m across with its walls) drawn in mm, read as metres: 1e10 cells of
        0.1 m; refused at once (not built into tens of GB)."""
        v, f, c = ring()
        with pytest.raises(ValueError, match=r"the grid over 10400\.0 x 10400\.0 m at 0\.1 m "
                                             r"cells would have 10,816,624,009 cells, more than "
                                             r"50,000,000 .*is the model in metres"):
            OccupancyMap.from_mesh(v * 1000.0, f, c, BAND, MARGIN, 0.1)
        with pytest.raises(ValueError, match="cells would have 10,0"):
            OccupancyMap.from_boxes(np.array([[0.0, 0.0, 1e4, 1e4]]), BAND, 0.1)

    def test_the_bound(self, monkeypatch: pytest.MonkeyPatch):
        """A grid of exactly MAX_CELLS cells is built, one of a cell more is refused."""
        import core.occupancy as occupancy

        v, f, c = ring()
        cells = int(np.prod(OccupancyMap.from_mesh(v, f, c, BAND, MARGIN, 0.1).shape))
        monkeypatch.setattr(occupancy, "MAX_CELLS", cells)
        assert OccupancyMap.from_mesh(v, f, c, BAND, MARGIN, 0.1).free.size == cells
        monkeypatch.setattr(occupancy, "MAX_CELLS", cells - 1)
        with pytest.raises(ValueError, match=f"would have {cells:,} cells, more than "
                                             f"{cells - 1:,} "):
            OccupancyMap.from_mesh(v, f, c, BAND, MARGIN, 0.1)
