"""core.dataset: a split or flight is checked against dataset.json's counts when it is read."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from core.atomic import (
    atomic_write_json,
    encoded_image_complete,
    is_temp,
    png_complete,
    remove_temp_files,
    write_png,
)
from core.dataset import Dataset, _ranges

COMMAND = "python -m datagen name=mini splits.train=6"


def mini_dataset(root: Path, train: int = 6, shards: int = 2) -> Path:
    """dataset.json (counts, command), ``train`` frames of 8x6 and the shards' stats files."""
    rng = np.random.default_rng(0)
    for i in range(train):
        write_png(root / "train" / "rgb" / f"{i:06d}.png",
                  rng.integers(0, 255, (6, 8, 3), dtype=np.uint8))
        write_png(root / "train" / "label" / f"{i:06d}.png", np.full((6, 8), 2, np.uint8))
    for k in range(shards):
        atomic_write_json(root / "stats" / f"shard-{k}-of-{shards}.json", {"shard": k})
    atomic_write_json(root / "dataset.json", {
        "schema_version": 1, "name": "mini", "command": COMMAND,
        "counts": {"train": train, "val": 0, "test": 0, "flights": {}}})
    return root


class TestSplit:
    def test_complete(self, tmp_path: Path) -> None:
        rgb, label = Dataset(mini_dataset(tmp_path)).split("train")
        assert [p.name for p in rgb] == [f"{i:06d}.png" for i in range(6)]
        assert [p.parent.name for p in label] == ["label"] * 6

    def test_missing_shard_names_split_counts_and_command(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path)
        for i in (3, 4, 5):  # shard 1 of 2 never rendered
            (root / "train" / "rgb" / f"{i:06d}.png").unlink()
        with pytest.raises(FileNotFoundError) as err:
            Dataset(root).split("train")
        msg = str(err.value)
        assert "split 'train' has 3 of the 6 frames" in msg and "frames 3-5" in msg
        assert f"`{COMMAND} out_dir={root} shard=1 num_shards=2`" in msg
        assert "shard=0" not in msg

    def test_missing_label(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path, shards=1)
        (root / "train" / "label" / "000001.png").unlink()
        with pytest.raises(FileNotFoundError, match=r"5 of the 6 .*label/000001.png.*"
                                                    rf"`{COMMAND} out_dir={root}`"):
            Dataset(root).split("train")

    def test_temp_files_are_ignored(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path)
        temp = root / "train" / "rgb" / ".000002.png.k2j3h4g5.png"
        temp.write_bytes((root / "train" / "rgb" / "000002.png").read_bytes()[:20])
        rgb, _ = Dataset(root).split("train")
        assert temp not in rgb and len(rgb) == 6

    def test_truncated_png_named(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path)
        bad = root / "train" / "label" / "000004.png"
        bad.write_bytes(bad.read_bytes()[:-20])
        with pytest.raises(ValueError, match=rf"cut-short PNG.*{bad}.*shard=1 num_shards=2"):
            Dataset(root).split("train")

    def test_copied_dataset_names_the_folder_loaded(self, tmp_path: Path) -> None:
        """A dataset made in one folder and copied to another: the repair command writes into
        the copy."""
        made = mini_dataset(tmp_path / "made")
        meta = json.loads((made / "dataset.json").read_text())
        atomic_write_json(made / "dataset.json", {**meta, "command": f"{COMMAND} out_dir={made}"})
        copy = tmp_path / "copy"
        made.rename(copy)
        (copy / "train" / "rgb" / "000004.png").unlink()
        with pytest.raises(FileNotFoundError) as err:
            Dataset(copy).split("train")
        msg = str(err.value)
        assert f"`{COMMAND} out_dir={copy} shard=1 num_shards=2`" in msg, msg
        assert str(made) not in msg.split("`")[1]

    def test_without_command(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path)
        meta = json.loads((root / "dataset.json").read_text())
        atomic_write_json(root / "dataset.json", {**meta, "command": None})
        (root / "train" / "rgb" / "000000.png").unlink()
        with pytest.raises(FileNotFoundError, match=r"python -m datagen out_dir=.*'generator'"):
            Dataset(root).split("train")

    def test_no_counts(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path)
        atomic_write_json(root / "dataset.json", {"schema_version": 1})
        with pytest.raises(ValueError, match="no counts.train"):
            Dataset(root).split("train")


class TestFlight:
    def test_missing_flight_frame(self, tmp_path: Path) -> None:
        root = mini_dataset(tmp_path, train=0, shards=1)
        d = root / "flights" / "paper"
        d.mkdir(parents=True)
        lines = "".join(f"{t} 0 0 0 0 0 0 1\n" for t in range(3))
        (d / "groundtruth.txt").write_text(lines)
        (d / "odometry.txt").write_text(lines)
        atomic_write_json(d / "flight.json", {"name": "paper"})
        for i in range(2):
            write_png(d / "rgb" / f"{i:06d}.png", np.zeros((6, 8, 3), np.uint8))
            write_png(d / "label" / f"{i:06d}.png", np.zeros((6, 8), np.uint8))
        with pytest.raises(FileNotFoundError, match="flight 'paper' has 2 of the 3 frames"):
            Dataset(root).flight("paper")


class TestAtomicHelpers:
    def test_is_temp(self) -> None:
        assert is_temp(".000001.png.k2j3h4g5.png") and is_temp(".dataset.json.abc_1234.json")
        assert not any(is_temp(n) for n in ("000001.png", ".lock", ".lock-setup", ".hydra"))

    def test_remove_temp_files(self, tmp_path: Path) -> None:
        keep = tmp_path / "a" / "000001.png"
        write_png(keep, np.zeros((2, 2), np.uint8))
        temp = keep.parent / ".000001.png.k2j3h4g5.png"
        temp.write_bytes(b"x")
        assert remove_temp_files(tmp_path) == [temp]
        assert keep.is_file() and not temp.exists()

    def test_png_complete(self, tmp_path: Path) -> None:
        p = tmp_path / "x.png"
        write_png(p, np.zeros((4, 4, 3), np.uint8))
        assert png_complete(p)
        data = p.read_bytes()
        p.write_bytes(data[:-1])
        assert not png_complete(p)
        p.write_bytes(b"abc")
        assert not png_complete(p) and not png_complete(tmp_path / "none.png")

    def test_encoded_image_complete(self) -> None:
        """A PNG or JPEG cut short is found; NUL padding after a JPEG's end marker is allowed;
        other bytes are the decoder's to judge."""
        image = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
        for ext in (".png", ".jpg"):
            data = cv2.imencode(ext, image)[1].tobytes()
            assert encoded_image_complete(data), ext
            cut = data[: len(data) * 2 // 3]
            assert not encoded_image_complete(cut), ext
            assert not encoded_image_complete(data[:-1]), ext
        assert encoded_image_complete(data + b"\x00" * 16)
        assert encoded_image_complete(b"not an image")


def test_ranges() -> None:
    assert _ranges(np.array([0, 1, 2, 5, 7, 8])) == "0-2, 5, 7-8"
    assert _ranges(np.array([1, 3, 5, 7, 9])) == "1, 3, 5, 7, ..."
