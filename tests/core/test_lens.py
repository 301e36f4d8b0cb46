"""core/imaging/lens.py: the plumb_bob fold check, the maps that render through a lens and undo it,
and the round trip on a rendered flight (datagen's realism.lens, read back by
core.dataset.Flight)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from core import classes as C
from core.atomic import read_png
from core.config import compose_config
from core.dataset import Camera, Dataset
from core.imaging import lens
from core.imaging.camera import intrinsics
from datagen import generate as gen

#: EuRoC MAV cam0's plumb_bob coefficients (the realism=real lens).
EUROC = [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0]
LENS = [f"realism.lens.{k}={v}" for k, v in zip(lens.PLUMB_BOB, EUROC, strict=True)]
SMALL = ["camera.width=128", "camera.height=96", "splits.train=0", "splits.val=0",
         "splits.test=0", "render.spp=1", "render_flights=[paper]", "flights.paper.num_frames=3"]


def camera(width: int = 128, height: int = 96) -> Camera:
    return Camera(intrinsics(width, height, 70.0), width, height, np.eye(4))


def boundaries(label: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose right or lower neighbour has another class (both known)."""
    b = np.zeros(label.shape, bool)
    known = label != C.IGNORE
    dx = (label[:, 1:] != label[:, :-1]) & known[:, 1:] & known[:, :-1]
    dy = (label[1:] != label[:-1]) & known[1:] & known[:-1]
    b[:, :-1] |= dx
    b[:-1] |= dy
    return b


class TestLens:
    def test_fold_check(self):
        K = camera().K
        np.testing.assert_array_equal(lens.check_plumb_bob(EUROC, K, 128, 96, "realism.lens"),
                                      EUROC)
        for bad in ([-0.5, 0, 0, 0, 0], [-0.35, 0.05, 0, 0, 0], [0, 0, 0, 0, -0.6]):
            with pytest.raises(ValueError, match=r"realism.lens: .* fold the image"):
                lens.check_plumb_bob(bad, K, 128, 96, "realism.lens")
        with pytest.raises(ValueError, match="realism.lens: .* must be finite"):
            lens.check_plumb_bob([float("nan"), 0, 0, 0, 0], K, 128, 96, "realism.lens")
        # The same k1 folds a wider image only: the check follows the image's corner radius.
        lens.check_plumb_bob([-0.5, 0, 0, 0, 0], intrinsics(128, 96, 40.0), 128, 96, "x")

    def test_maps_invert_each_other(self):
        """A pixel of the distorted image, through distort_maps into the covering pinhole and
        back through the localizer's undistortion maps, lands where it started."""
        cam = camera(320, 240)
        Kc, wc, hc = lens.cover_camera(cam.K, EUROC, 320, 240)
        assert wc > 320 and hc > 240 and Kc[0, 0] == pytest.approx(cam.K[0, 0])
        mx, my = lens.distort_maps(cam.K, EUROC, 320, 240, Kc)
        assert 0 <= mx.min() and mx.max() <= wc - 1 and 0 <= my.min() and my.max() <= hc - 1
        xy = np.stack([(mx.ravel() - Kc[0, 2]) / Kc[0, 0], (my.ravel() - Kc[1, 2]) / Kc[1, 1]], 1)
        uv = lens.distort_points(xy, cam.K, np.array(EUROC))
        u, v = np.meshgrid(np.arange(320), np.arange(240))
        assert np.abs(uv - np.stack([u.ravel(), v.ravel()], 1)).max() < 1e-3
        # Barrel: the pinhole K's image lies inside the distorted one, all of it seen.
        und = lens.Undistorter(cam.K, np.array(EUROC), 320, 240)
        labels = und.labels(np.full((240, 320), 3, np.uint8))
        assert (labels == 3).all()

    def test_round_trip_on_a_rendered_flight(self, tmp_path):
        """Rendered through the lens and undistorted by the reader (Flight.labels/image), a
        frame's class boundaries lie within ~1 px of the pinhole render's (border excluded),
        its image matches the pinhole's, and flight.json holds the calibration."""
        ideal, bent = tmp_path / "ideal", tmp_path / "lens"
        gen.run(compose_config("datagen", [*SMALL, f"out_dir={ideal}"]), progress=False)
        gen.run(compose_config("datagen", [*SMALL, *LENS, f"out_dir={bent}"]), progress=False)
        a, b = Dataset(ideal).flight("paper"), Dataset(bent).flight("paper")
        assert "camera" not in a.info and not np.any(a.distortion)
        np.testing.assert_allclose(b.distortion, EUROC)
        assert b.info["camera"]["distortion_model"] == "plumb_bob"
        np.testing.assert_allclose(b.info["camera"]["K"], Dataset(bent).camera.K)
        m = 6  # px of border left out
        for t in range(3):
            raw = read_png(b.label[t], rgb=False)
            assert raw.shape == (96, 128)
            truth, back = a.labels(t), b.labels(t)
            assert (raw != truth).mean() > 0.05  # the lens moved the image
            bt, bb = boundaries(truth), boundaries(back)
            dist = cv2.distanceTransform((~bt).astype(np.uint8), cv2.DIST_L2, 5)
            inner = np.zeros_like(bb)
            inner[m:-m, m:-m] = True
            d = dist[bb & inner]
            assert np.median(d) <= 1.0 and np.mean(d <= 1.5) > 0.9, (t, np.median(d))
            assert (back[inner] == truth[inner]).mean() > 0.97
            # The image's edges (Canny; the shading's path-tracing noise differs between the
            # two renders): >= 85 % within 1.5 px of the pinhole's (a 3 px shift: ~67 %).
            ea, eb = (cv2.Canny(cv2.cvtColor(f.image(t), cv2.COLOR_RGB2GRAY), 80, 160) > 0
                      for f in (a, b))
            dist = cv2.distanceTransform((~ea).astype(np.uint8), cv2.DIST_L2, 5)
            assert np.mean(dist[eb & inner] <= 1.5) > 0.85
