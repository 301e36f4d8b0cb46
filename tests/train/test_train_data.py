"""Loading splits (with bad-input errors) and joint image/label augmentation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import train.data as data_module
from core import classes as C
from core.atomic import write_png
from core.config import typed
from core.dataset import Dataset, open_datasets
from core.imaging.colour import to_linear
from core.imaging.realism import load_realism
from train.data import (
    AugmentConfig,
    SplitData,
    augment_batch,
    batches,
    block_majority,
    check_classes,
    check_same_kind,
    downsample_split,
    load_split,
    load_splits,
    through_camera,
)

GEOMETRY_ONLY = dict(
    brightness=0.0, contrast=0.0, saturation=0.0, hue=0.0, blur_prob=0.0, noise_std=0.0
)


def _palette_batch(n: int = 4) -> tuple[torch.Tensor, torch.Tensor]:
    """Images whose colour is exactly the class colour of their label."""
    rng = np.random.default_rng(0)
    labels = np.zeros((n, 48, 64), dtype=np.uint8)
    for i in range(n):
        labels[i, :, :] = C.WALL
        labels[i, :12] = C.CEILING
        labels[i, 36:] = C.FLOOR
        x0 = int(rng.integers(0, 40))
        labels[i, 10:40, x0 : x0 + 14] = C.DOOR
    rgb = C.palette()[labels]
    return torch.from_numpy(rgb).permute(0, 3, 1, 2).contiguous(), torch.from_numpy(labels)


class TestAugment:
    def test_geometry_keeps_image_and_label_aligned(self) -> None:
        images, labels = _palette_batch()
        cfg = AugmentConfig(crop=(32, 48), scale=(0.8, 1.5), hflip=0.5, **GEOMETRY_ONLY)
        x, y = augment_batch(images, labels, cfg, torch.Generator().manual_seed(3))
        assert x.shape == (4, 3, 32, 48) and y.shape == (4, 32, 48)
        assert x.dtype == torch.float32 and y.dtype == torch.int64
        colour = torch.from_numpy(C.palette()[: C.NUM_CLASSES]).float() / 255.0  # (K, 3)
        dist = ((x.permute(0, 2, 3, 1)[..., None, :] - colour) ** 2).sum(-1)  # (B, h, w, K)
        agree = (dist.argmin(-1) == y).float().mean()
        assert agree > 0.97  # only bilinear-blended boundary pixels may differ

    def test_photometric_leaves_labels(self) -> None:
        images, labels = _palette_batch()
        cfg = AugmentConfig(crop=None, scale=(1.0, 1.0), hflip=0.0)
        x, y = augment_batch(images, labels, cfg, torch.Generator().manual_seed(0))
        assert torch.equal(y, labels.long())
        assert not torch.allclose(x, images.float() / 255.0)
        assert float(x.min()) >= 0.0 and float(x.max()) <= 1.0

    def test_seeded(self) -> None:
        images, labels = _palette_batch()
        cfg = AugmentConfig(crop=(32, 32))
        a = augment_batch(images, labels, cfg, torch.Generator().manual_seed(5))
        b = augment_batch(images, labels, cfg, torch.Generator().manual_seed(5))
        c = augment_batch(images, labels, cfg, torch.Generator().manual_seed(6))
        assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
        assert not torch.equal(a[0], c[0])

    @pytest.mark.parametrize("f", [2, 4])
    def test_finer_labels_follow_the_image_box(self, f: int) -> None:
        """Labels at f x the image resolution are cropped from the same box: each label pixel
        holds its own column index, and the image a ramp of the image column, so the label
        column of output pixel p must be where the image ramp puts it."""
        b, h, w = 6, 12, 16
        col = torch.arange(w, dtype=torch.float32)
        images = (col * 10).to(torch.uint8).expand(b, 3, h, w).contiguous()
        labels = torch.arange(f * w, dtype=torch.uint8).expand(b, f * h, f * w).contiguous()
        cfg = AugmentConfig(crop=(8, 10), scale=(1.0, 1.5), hflip=0.5, **GEOMETRY_ONLY)
        x, y = augment_batch(images, labels, cfg, torch.Generator().manual_seed(1))
        assert x.shape == (b, 3, 8, 10) and y.shape == (b, 8 * f, 10 * f)
        ramp = x[:, 0, 0] * 255 / 10  # (B, 10) image column at output columns 0..9
        step = ramp[:, 1:2] - ramp[:, :1]
        u = (torch.arange(10 * f) + 0.5) / f - 0.5  # output image coordinate of label pixels
        expect = f * (ramp[:, :1] + u * step + 0.5) - 0.5  # (B, 10 f) label column
        inside = (y[:, 0] != 255)
        assert inside.float().mean() > 0.9
        assert (y[:, 0][inside] - expect[inside]).abs().max() <= 0.5 + 0.05 * f
        # outside the labels (a box at the border) only: the 255s sit at the row ends
        assert ((y[:, 0] == 255) <= ((expect < -0.5) | (expect > f * w - 0.5))).all()

    def test_bad_shapes(self) -> None:
        with pytest.raises(ValueError, match="expected images"):
            augment_batch(
                torch.zeros(2, 3, 8, 8, dtype=torch.uint8),
                torch.zeros(2, 8, 9, dtype=torch.uint8),
                AugmentConfig(),
                torch.Generator(),
            )

    def test_unknown_key(self) -> None:
        with pytest.raises(ValueError, match="data.augment.rotate"):
            typed(AugmentConfig, {"rotate": 3}, "data.augment")


def test_batches() -> None:
    assert [b.tolist() for b in batches(5, 2)] == [[0, 1], [2, 3], [4]]
    assert [b.tolist() for b in batches(5, 2, drop_last=True)] == [[0, 1], [2, 3]]
    shuffled = torch.cat(list(batches(7, 3, torch.Generator().manual_seed(0))))
    assert sorted(shuffled.tolist()) == list(range(7))


def test_block_majority_hand_made() -> None:
    lab = torch.zeros(1, 4, 8, dtype=torch.uint8)
    lab[0, :, :5] = 1  # a boundary one pixel into the second block: it belongs to class 0
    lab[0, 0, 0] = 255
    assert block_majority(lab, 4).tolist() == [[[1, 0]]]
    lab[0, :, 5:] = 255  # the second block: one class-1 column and ignored pixels
    assert block_majority(lab, 4).tolist() == [[[1, 1]]]
    lab[0, :, 4:] = 255
    assert block_majority(lab, 4).tolist() == [[[1, 255]]]
    tie = torch.tensor([[[3, 3], [2, 2]]], dtype=torch.uint8)
    assert block_majority(tie, 2).tolist() == [[[2]]]


def test_block_majority_keeps_boundaries_in_place() -> None:
    """Labels downsampled and upsampled back (as the SegNet's logits are) stay centred."""
    lab = torch.zeros(1, 64, 64, dtype=torch.uint8)
    lab[0, 21:, :] = 1  # a horizontal boundary between rows 20 and 21
    small = block_majority(lab, 4)
    onehot = torch.nn.functional.one_hot(small.long(), 2).permute(0, 3, 1, 2).float()
    up = torch.nn.functional.interpolate(onehot, scale_factor=4, mode="bilinear").argmax(1)
    rows = (up[0] != lab[0]).any(dim=1).nonzero().flatten().tolist()
    assert all(abs(r - 20.5) <= 2 for r in rows), rows


def test_downsample_split() -> None:
    """Box-averaged images and block-majority labels."""
    images, labels = _palette_batch()
    half = downsample_split(SplitData(images, labels, []), 2)
    assert half.images.shape == (4, 3, 24, 32) and half.labels.shape == (4, 24, 32)
    assert half.images.dtype == torch.uint8
    torch.testing.assert_close(half.labels, block_majority(labels, 2))
    ref = torch.nn.functional.avg_pool2d(images.float(), 2)
    assert (half.images.float() - ref).abs().max() <= 0.5
    assert downsample_split(SplitData(images, labels, []), 1).images is images
    with pytest.raises(ValueError, match="multiple of model.downsample"):
        downsample_split(SplitData(images[..., :47, :], labels[:, :47], []), 2)


def test_downsample_split_in_chunks_is_the_whole(monkeypatch) -> None:
    """The split is averaged a chunk at a time (no float copy of it all): the same bytes."""
    images, labels = _palette_batch()
    whole = downsample_split(SplitData(images, labels, []), 2)
    monkeypatch.setattr(data_module, "CHUNK", 3)  # 4 images: a chunk of 3, then 1
    chunked = downsample_split(SplitData(images, labels, []), 2)
    assert torch.equal(chunked.images, whole.images)


class TestLoad:
    def test_load(self, synthetic_dataset: Path) -> None:
        data = load_split(Dataset(synthetic_dataset), "val", 8)
        assert data.images.shape == (6, 3, 48, 64) and data.images.dtype == torch.uint8
        assert data.labels.shape == (6, 48, 64)
        assert len(data) == 6 and data.paths[0].name == "000000.png"

    def test_missing_dataset(self, tmp_path: Path) -> None:
        with pytest.raises(FileNotFoundError, match="python -m datagen"):
            Dataset(tmp_path / "nope")

    def test_wrong_image_size(self, tmp_path: Path, make_dataset) -> None:
        root = make_dataset(tmp_path / "ds", {"train": 2, "val": 1, "test": 1})
        write_png(root / "train" / "rgb" / "000001.png", np.zeros((40, 64, 3), np.uint8))
        with pytest.raises(ValueError, match=r"000001.png.*does not match the dataset camera"):
            load_split(Dataset(root), "train", 8)

    def test_unknown_label_id(self, tmp_path: Path, make_dataset) -> None:
        root = make_dataset(tmp_path / "ds", {"train": 2, "val": 1, "test": 1})
        lab = np.full((48, 64), 9, np.uint8)
        write_png(root / "train" / "label" / "000000.png", lab)
        with pytest.raises(ValueError, match=r"label ids \[9\] are not among the 8 classes"):
            load_split(Dataset(root), "train", 8)

    def test_empty_split(self, tmp_path: Path, make_dataset) -> None:
        root = make_dataset(tmp_path / "ds", {"train": 1, "val": 0, "test": 0})
        with pytest.raises(FileNotFoundError, match="split 'val'.*no images"):
            load_split(Dataset(root), "val", 8)

    def test_missing_shard_is_not_trained_on(self, tmp_path: Path, make_dataset) -> None:
        """Frames dataset.json counts but the folder lacks (a shard never rendered) stop the
        loading, naming the split, the counts and the datagen command."""
        root = make_dataset(tmp_path / "ds", {"train": 6, "val": 1, "test": 1})
        for i in (4, 5):
            (root / "train" / "rgb" / f"{i:06d}.png").unlink()
            (root / "train" / "label" / f"{i:06d}.png").unlink()
        with pytest.raises(FileNotFoundError, match=r"split 'train' has 4 of the 6 frames .*"
                                                    r"frames 4-5.*python -m datagen"):
            load_split(Dataset(root), "train", 8)

    def test_temp_file_of_a_killed_write_is_ignored(self, tmp_path: Path, make_dataset) -> None:
        root = make_dataset(tmp_path / "ds", {"train": 2, "val": 1, "test": 1})
        (root / "train" / "rgb" / ".000001.png.k2j3h4g5.png").write_bytes(b"\x89PNG cut")
        data = load_split(Dataset(root), "train", 8)
        assert len(data) == 2 and [p.name for p in data.paths] == ["000000.png", "000001.png"]

    def test_cut_short_png_named(self, tmp_path: Path, make_dataset) -> None:
        root = make_dataset(tmp_path / "ds", {"train": 2, "val": 1, "test": 1})
        bad = root / "train" / "rgb" / "000001.png"
        bad.write_bytes(bad.read_bytes()[:100])
        with pytest.raises(ValueError, match=rf"cut-short PNG.*{bad}.*re-renders broken"):
            load_split(Dataset(root), "train", 8)

    def test_several_datasets(self, tmp_path: Path, make_dataset) -> None:
        """A glob pattern names several datasets, trained on together: their splits are
        concatenated in sorted order; folders without a dataset.json are not datasets."""
        b = make_dataset(tmp_path / "floor1", {"train": 3, "val": 1, "test": 1}, seed=1)
        a = make_dataset(tmp_path / "floor0", {"train": 2, "val": 1, "test": 1}, seed=0)
        (tmp_path / "floor2").mkdir()  # a dataset not begun
        found = open_datasets(tmp_path / "floor*")
        assert [d.root for d in found] == [a, b]
        assert [d.root for d in open_datasets(a)] == [a]
        check_same_kind(found)
        both = load_splits(found, "train", 8)
        one, two = load_split(found[0], "train", 8), load_split(found[1], "train", 8)
        assert len(both) == 5 and both.paths == one.paths + two.paths
        assert torch.equal(both.images, torch.cat([one.images, two.images]))
        assert torch.equal(both.labels, torch.cat([one.labels, two.labels]))
        with pytest.raises(FileNotFoundError, match=r"'.*nothing\*' matches no dataset"):
            open_datasets(tmp_path / "nothing*")

    def test_several_datasets_must_agree(self, tmp_path: Path, make_dataset) -> None:
        make_dataset(tmp_path / "a", {"train": 1, "val": 1, "test": 1})
        make_dataset(tmp_path / "b", {"train": 1, "val": 1, "test": 1}, height=32)
        with pytest.raises(ValueError, match=r"b/dataset.json: its classes or image size "
                                             r"\(64x32\) differ"):
            check_same_kind(open_datasets(tmp_path / "[ab]"))

    def test_class_count_mismatch(self) -> None:
        assert check_classes(C.as_json(), None, "x/dataset.json") == 8
        assert check_classes(C.as_json(), 8, "x/dataset.json") == 8
        with pytest.raises(ValueError, match="class-count mismatch: model.num_classes=5"):
            check_classes(C.as_json(), 5, "x/dataset.json")


class TestThroughCamera:
    def test_real_camera_changes_images_not_labels_and_repeats(self) -> None:
        images, labels = _palette_batch(6)
        data = SplitData(images, labels, [])
        real = load_realism("real")
        out = through_camera(data, real, seed=0, stream=0)
        assert out.images.shape == images.shape and out.images.dtype == torch.uint8
        assert out.labels is labels
        assert not torch.equal(out.images, images)
        torch.testing.assert_close(through_camera(data, real, 0, 0).images, out.images)
        assert not torch.equal(through_camera(data, real, 0, 1).images, out.images)
        # noise and JPEG keep the scene: the mean brightness of each image moves by at most
        # the exposure offset's gain (+/- max_ev stops in linear light)
        lin_in = to_linear(images.permute(0, 2, 3, 1).numpy()).mean(axis=(1, 2, 3))
        lin_out = to_linear(out.images.permute(0, 2, 3, 1).numpy()).mean(axis=(1, 2, 3))
        gain = lin_out / lin_in
        assert np.all(gain < 2.0 ** real.exposure.max_ev + 0.05)
        assert np.all(gain > 2.0 ** -real.exposure.max_ev - 0.05)
        assert gain.std() > 0.01  # each image its own exposure

    def test_noise_alone_is_unbiased(self) -> None:
        images = torch.full((4, 3, 48, 64), 128, dtype=torch.uint8)
        real = load_realism("real")
        real.exposure.step_ev = real.exposure.drift_ev = 0.0
        real.jpeg.quality = None
        out = through_camera(SplitData(images, torch.zeros(4, 48, 64, dtype=torch.uint8), []),
                             real, 0, 0).images.float()
        assert abs(out.mean().item() - 128.0) < 1.0
        assert 1.0 < out.std().item() < 10.0


def test_load_realism_names_the_presets() -> None:
    assert load_realism("ideal").noise.full_well_e == 0
    assert load_realism("real").jpeg.quality is not None
    with pytest.raises(ValueError, match=r"data.realism = 'nope'.*\['ideal', 'real'\]"):
        load_realism("nope", "data.realism")
