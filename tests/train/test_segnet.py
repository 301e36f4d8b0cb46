"""SegNet model: topology, shapes, padding, unpooling, bad input."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from train.net.segnet import (
    STEM_CONV_KEY,
    SegNet,
    build_segnet,
    finer_unshuffle_stem,
    pad_to_multiple,
    vgg_stages,
)
from train.net.window_pool import (
    WindowMaxPool,
    WindowMaxUnpool,
    code_to_plane_index,
    plane_index_to_code,
    window_element,
)


def _tiny(**kw) -> SegNet:
    args = dict(
        num_classes=5,
        width=0.125,
        stages=3,
        convs_per_stage=[1, 1, 2],
        generator=torch.Generator().manual_seed(0),
    )
    args.update(kw)
    return SegNet(**args).eval()


class TestTopology:
    def test_full_model_is_vgg16_bn(self) -> None:
        m = SegNet(num_classes=8)
        convs = [x for x in m.encoder.modules() if isinstance(x, nn.Conv2d)]
        bns = [x for x in m.encoder.modules() if isinstance(x, nn.BatchNorm2d)]
        assert len(convs) == 13 and len(bns) == 13
        assert [c.out_channels for c in convs] == [
            v for v in (64, 64, 128, 128, 256, 256, 256, 512, 512, 512, 512, 512, 512)
        ]
        assert m.multiple == 32
        # Decoder mirrors the encoder: 13 - 1 convs (the last becomes the classifier).
        dec = [x for x in m.decoder.modules() if isinstance(x, nn.Conv2d)]
        assert len(dec) == 12
        assert m.classifier.out_channels == 8

    def test_vgg_stages(self) -> None:
        assert vgg_stages("D") == [[64, 64], [128, 128], [256] * 3, [512] * 3, [512] * 3]
        with pytest.raises(ValueError, match="VGG config"):
            vgg_stages("Z")

    def test_compact_config(self) -> None:
        m = build_segnet({"width": 0.125, "stages": 5, "convs_per_stage": [1, 1, 2, 2, 2]}, 8)
        assert m.channels == [8, 16, 32, 64, 64]
        assert m.convs_per_stage == [1, 1, 2, 2, 2]

    @pytest.mark.parametrize(
        "bad",
        [
            dict(stages=6),
            dict(stages=0),
            dict(width=0.0),
            dict(convs_per_stage=[1, 1]),
            dict(num_classes=1),
        ],
    )
    def test_bad_config(self, bad: dict) -> None:
        with pytest.raises(ValueError):
            _tiny(**bad)


class TestForward:
    @pytest.mark.parametrize("size", [(32, 48), (48, 64), (30, 50), (17, 9)])
    def test_output_shape(self, size: tuple[int, int]) -> None:
        m = _tiny()
        x = torch.rand(2, 3, *size)
        with torch.no_grad():
            y = m(x)
        assert y.shape == (2, 5, *size)
        assert y.dtype == torch.float32

    def test_padding_matches_explicit_pad(self) -> None:
        m = _tiny()
        x = torch.rand(1, 3, 30, 50)
        xp, (h, w) = pad_to_multiple(x, m.multiple)
        assert xp.shape[-2:] == (32, 56) and (h, w) == (30, 50)
        with torch.no_grad():
            torch.testing.assert_close(m(x), m(xp)[..., :30, :50])

    def test_no_auto_pad_raises_with_advice(self) -> None:
        m = _tiny(auto_pad=False)
        with pytest.raises(ValueError, match="divisible by 8.*pad_to_multiple"):
            m(torch.rand(1, 3, 30, 48))
        assert m(torch.rand(1, 3, 32, 48)).shape == (1, 5, 32, 48)

    @pytest.mark.parametrize(
        "x",
        [
            torch.rand(3, 32, 32),
            torch.rand(1, 1, 32, 32),
            torch.zeros(1, 3, 32, 32, dtype=torch.uint8),
        ],
    )
    def test_bad_input(self, x: torch.Tensor) -> None:
        with pytest.raises(ValueError, match="SegNet expects"):
            _tiny()(x)

    @pytest.mark.parametrize("size", [(32, 48), (30, 50)])
    def test_downsample_output_shape(self, size: tuple[int, int]) -> None:
        m = _tiny(downsample=2)
        assert m.multiple == 16
        with torch.no_grad():
            assert m(torch.rand(2, 3, *size)).shape == (2, 5, *size)

    def test_downsample_is_box_average_then_bilinear(self) -> None:
        """downsample=2 equals the same weights at 1 on a 2x2-averaged image, upsampled."""
        full = _tiny(downsample=2).eval()
        half = _tiny().eval()
        half.load_state_dict(full.state_dict())
        x = torch.rand(1, 3, 32, 48)
        with torch.no_grad():
            ref = torch.nn.functional.interpolate(
                half(torch.nn.functional.avg_pool2d(x, 2)), scale_factor=2, mode="bilinear"
            )
            torch.testing.assert_close(full(x), ref)

    def test_network_resolution_matches_forward_before_upsampling(self) -> None:
        """Training's low-resolution path gives forward's logits before the upsampling."""
        m = _tiny(downsample=2, skip="add").eval()
        x = torch.rand(2, 3, 32, 48)
        with torch.no_grad():
            low = m.forward_network_resolution(torch.nn.functional.avg_pool2d(x, 2))
            up = torch.nn.functional.interpolate(low, scale_factor=2, mode="bilinear")
            assert low.shape == (2, 5, 16, 24)
            torch.testing.assert_close(m(x), up)

    def test_unshuffle_stem(self) -> None:
        """stem="unshuffle": the first convolution sees every pixel of each d x d block, the
        training path takes full-resolution images and gives forward's low-resolution logits."""
        m = _tiny(downsample=2, skip="add", stem="unshuffle").eval()
        assert m.encoder[0][0][0].in_channels == 12 and m.training_factor == 1
        x = torch.rand(2, 3, 32, 48)
        with torch.no_grad():
            low = m.forward_network_resolution(x)
            up = torch.nn.functional.interpolate(low, scale_factor=2, mode="bilinear")
            assert low.shape == (2, 5, 16, 24)
            torch.testing.assert_close(m(x), up)
            # a change inside one 2x2 block that keeps its average still changes the logits
            y = x.clone()
            y[:, :, 0, 0] += 0.1
            y[:, :, 0, 1] -= 0.1
            assert not torch.allclose(m(x), m(y))
            assert torch.allclose(_tiny(downsample=2)(x), _tiny(downsample=2)(y), atol=1e-5)
        assert _tiny(downsample=2).training_factor == 2
        assert _tiny(stem="unshuffle").stem == "average"  # no blocks at full resolution
        with pytest.raises(ValueError, match="model.stem"):
            _tiny(downsample=2, stem="space")

    def test_finer_unshuffle_stem(self) -> None:
        """A downsample-4 network's weights, its stem carried to downsample 2, compute on an
        image what the original computes on that image enlarged twice (nearest)."""
        coarse = _tiny(downsample=4, skip="add", stem="unshuffle").eval()
        fine = _tiny(downsample=2, skip="add", stem="unshuffle").eval()
        state = coarse.state_dict()
        state[STEM_CONV_KEY] = finer_unshuffle_stem(state[STEM_CONV_KEY], 4, 2)
        fine.load_state_dict(state)
        x = torch.rand(2, 3, 32, 48, generator=torch.Generator().manual_seed(1))
        big = x.repeat_interleave(2, dim=2).repeat_interleave(2, dim=3)
        with torch.no_grad():
            # float32 sums in another order: 1e-5 of rounding is seen on some hosts
            torch.testing.assert_close(fine.forward_network_resolution(x),
                                       coarse.forward_network_resolution(big),
                                       atol=1e-4, rtol=1e-4)
        w = torch.rand(4, 48, 3, 3)
        torch.testing.assert_close(finer_unshuffle_stem(w, 4, 4), w)
        torch.testing.assert_close(finer_unshuffle_stem(w, 4, 1), w.reshape(4, 3, 16, 3, 3)
                                   .sum(dim=2))
        with pytest.raises(ValueError, match="must divide"):
            finer_unshuffle_stem(w, 4, 3)
        with pytest.raises(ValueError, match="48 channels"):
            finer_unshuffle_stem(w, 2, 1)

    def test_sharpen_head(self) -> None:
        """head="sharpen": starts as plain bilinear logits (zero residual); once trained, its
        residual reads the full-resolution image, so a change within one 2x2 block moves the
        logits at that pixel."""
        m = _tiny(downsample=2, skip="add", stem="unshuffle", head="sharpen").eval()
        plain = _tiny(downsample=2, skip="add", stem="unshuffle").eval()
        plain.load_state_dict(m.state_dict(), strict=False)
        x = torch.rand(2, 3, 32, 48)
        with torch.no_grad():
            torch.testing.assert_close(m(x), plain(x))
            low = m.forward_network_resolution(x)
            torch.testing.assert_close(m.to_input_resolution(low, x), m(x))
            torch.nn.init.normal_(m.sharpen_head[-1].weight, std=0.1)
            assert not torch.allclose(m(x), plain(x))
            y = x.clone()
            y[:, :, 10, 10] += 0.5
            diff = (m.to_input_resolution(low, y) - m(x)).abs().amax(dim=(0, 1))
            assert diff[10, 10] > 0  # the head sees the full-resolution pixel ...
            diff[8:13, 8:13] = 0
            assert diff.max() == 0  # ... and only within its 5x5 reach
        assert "head=sharpen" in repr(m)
        with pytest.raises(ValueError, match="model.head=sharpen needs model.stem=unshuffle"):
            _tiny(downsample=2, head="sharpen")
        with pytest.raises(ValueError, match="model.head"):
            _tiny(head="cubic")
        assert _tiny(head="sharpen").sharpen_head is not None  # full resolution: any stem

    def test_sharpen_head_layers(self) -> None:
        """head_layers=2: one more hidden 3x3 convolution, so a pixel reaches 7x7 logits; the
        head still starts as the identity, and 0 layers is refused."""
        kw = dict(downsample=2, skip="add", stem="unshuffle", head="sharpen", head_channels=4)
        m = _tiny(head_layers=2, **kw).eval()
        assert sum(isinstance(c, nn.Conv2d) for c in m.sharpen_head) == 3
        g = torch.Generator().manual_seed(0)  # random weights can leave a path dead (ReLU)
        x = torch.rand(1, 3, 32, 48, generator=g)
        with torch.no_grad():
            low = m.forward_network_resolution(x)
            bilinear = nn.functional.interpolate(low, size=(32, 48), mode="bilinear")
            torch.testing.assert_close(m.to_input_resolution(low, x), bilinear)
            for p in m.sharpen_head.parameters():
                torch.nn.init.normal_(p, std=0.3, generator=g)
            y = x.clone()
            y[:, :, 10, 10] += 0.5
            diff = (m.to_input_resolution(low, y) - m.to_input_resolution(low, x)).abs()
            diff = diff.amax(dim=(0, 1))
            ring = diff[7:14, 7:14].clone()
            ring[1:6, 1:6] = 0
            assert ring.max() > 0  # 3 px away: the deeper reach ...
            diff[7:14, 7:14] = 0
            assert diff.max() == 0  # ... and no farther
        with pytest.raises(ValueError, match="model.head_layers"):
            _tiny(head_layers=0, **kw)

    def test_context_layers(self) -> None:
        """context_layers=2: a residual branch of two dilated convolutions at the bottleneck.
        It starts at zero (the same function as the network without it); with weights it
        changes the output everywhere (a bottleneck cell's view is the whole image); it adds
        no pooling stage; a negative count is refused."""
        plain = _tiny(skip="add")
        ctx = _tiny(skip="add", context_layers=2)
        assert plain.context is None and "context_layers=2" in repr(ctx)
        assert sum(isinstance(c, nn.Conv2d) for c in ctx.context.modules()) == 2
        assert all(c.dilation == (2, 2) for c in ctx.context.modules() if isinstance(c, nn.Conv2d))
        ctx.load_state_dict({**plain.state_dict(),
                             **{f"context.{k}": v for k, v in ctx.context.state_dict().items()}})
        x = torch.rand(1, 3, 64, 96, generator=torch.Generator().manual_seed(1))
        with torch.no_grad():
            torch.testing.assert_close(ctx(x), plain(x))
            out, idx = ctx.forward_with_indices(x)
            assert len(idx) == ctx.stages == 3 and out.shape == (1, 5, 64, 96)
            torch.nn.init.ones_(ctx.context[-1].weight)  # the last BatchNorm's scale
            diff = (ctx(x) - plain(x)).abs().amax(dim=1)
            assert (diff > 0).float().mean() > 0.9
        with pytest.raises(ValueError, match="model.context_layers"):
            _tiny(context_layers=-1)

    def test_skip_add_uses_encoder_features(self) -> None:
        """skip="add" changes the output of the same weights; "none" is plain SegNet."""
        plain, added = _tiny(), _tiny(skip="add")
        added.load_state_dict(plain.state_dict())
        x = torch.rand(1, 3, 32, 32)
        with torch.no_grad():
            assert not torch.allclose(plain(x), added(x))
        with pytest.raises(ValueError, match="model.skip"):
            _tiny(skip="concat")

    @pytest.mark.parametrize("bad", [0, 3])
    def test_bad_downsample(self, bad: int) -> None:
        with pytest.raises(ValueError, match="downsample"):
            _tiny(downsample=bad)

    def test_seeded_init(self) -> None:
        a, b = _tiny(), _tiny()
        for pa, pb in zip(a.parameters(), b.parameters(), strict=True):
            torch.testing.assert_close(pa, pb, rtol=0, atol=0)

    def test_imposed_own_indices_reproduce_output(self) -> None:
        m = _tiny()
        x = torch.rand(2, 3, 32, 40)
        with torch.no_grad():
            y, idx = m.forward_with_indices(x)
            y2, idx2 = m.forward_with_indices(x, idx)
        torch.testing.assert_close(y, y2, rtol=0, atol=0)
        assert all(torch.equal(a, b) for a, b in zip(idx, idx2, strict=True))


class TestUnpooling:
    def test_round_trip(self) -> None:
        """Unpooling puts each maximum back where it was and zeros elsewhere."""
        g = torch.Generator().manual_seed(1)
        x = torch.rand(2, 3, 8, 10, generator=g) + 0.1  # positive: zeros never win
        pool, unpool = nn.MaxPool2d(2, 2, return_indices=True), nn.MaxUnpool2d(2, 2)
        y, idx = pool(x)
        z = unpool(y, idx, output_size=x.shape[-2:])
        assert z.shape == x.shape
        keep = z != 0
        assert int(keep.sum()) == y.numel()  # one survivor per window (no ties)
        torch.testing.assert_close(z[keep], x[keep])
        torch.testing.assert_close(pool(z)[0], y)

    def test_hand_made_window(self) -> None:
        x = torch.tensor([[[[1.0, 5.0, 2.0, 0.0], [3.0, 4.0, 7.0, 6.0]]]])
        y, idx = nn.MaxPool2d(2, 2, return_indices=True)(x)
        assert y.flatten().tolist() == [5.0, 7.0]
        assert idx.flatten().tolist() == [1, 6]
        z = nn.MaxUnpool2d(2, 2)(y * 10, idx)
        assert z.tolist() == [[[[0.0, 50.0, 0.0, 0.0], [0.0, 0.0, 70.0, 0.0]]]]


class TestWindowPooling:
    """WindowMaxPool/Unpool compute exactly what MaxPool2d/MaxUnpool2d compute."""

    @staticmethod
    def _with_ties() -> torch.Tensor:
        g = torch.Generator().manual_seed(4)
        x = torch.randint(0, 3, (2, 3, 8, 12), generator=g).float()  # many exact ties
        return torch.where(x == 0, 0.0, x - 1.5)  # zeros, negatives and positives

    def test_matches_torch_pooling_with_ties(self) -> None:
        x = self._with_ties()
        y, idx = nn.MaxPool2d(2, 2, return_indices=True)(x)
        yw, code = WindowMaxPool()(x)
        torch.testing.assert_close(yw, y, rtol=0, atol=0)
        assert torch.equal(code_to_plane_index(code), idx)
        assert torch.equal(plane_index_to_code(idx), code)
        v = torch.randn(y.shape, generator=torch.Generator().manual_seed(5))
        torch.testing.assert_close(
            WindowMaxUnpool()(v, code), nn.MaxUnpool2d(2, 2)(v, idx), rtol=0, atol=0
        )

    def test_window_element_is_exact(self) -> None:
        """The one-hot depthwise convolution reads each window position bit for bit."""
        g = torch.Generator().manual_seed(7)
        x = torch.randn(2, 5, 6, 10, generator=g) * torch.logspace(-30, 30, 10)  # wide range
        x[0, 0, 0, :4] = torch.tensor([0.0, -0.0, 1e-45, -3e38])
        for dy in (0, 1):
            for dx in (0, 1):
                torch.testing.assert_close(
                    window_element(x, dy, dx), x[..., dy::2, dx::2], rtol=0, atol=0
                )

    def test_model_modes_agree(self) -> None:
        m = _tiny()
        x = torch.rand(2, 3, 30, 44, generator=torch.Generator().manual_seed(6))
        x[:, :, :10] = 0.5  # flat region: exact ties after every layer
        with torch.no_grad():
            a, ia = m.forward_with_indices(x)
            b, ib = m.set_pooling("window").forward_with_indices(x)
        torch.testing.assert_close(a, b, rtol=0, atol=0)
        assert all(torch.equal(p, q) for p, q in zip(ia, ib, strict=True))
        with pytest.raises(ValueError, match="pooling"):
            m.set_pooling("avg")
