"""Checkpoints: same seed, same weights; a full disk named as such (folder, free space, fix)."""

from __future__ import annotations

import errno
import re
from pathlib import Path

import pytest
import torch

import train.deploy.export as ex
import train.loop.checkpoint as ck
import train.run as tt
from core.atomic import DiskFullError, free_bytes


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


class TestDiskFull:
    def test_save_torch(self, tmp_path: Path, monkeypatch) -> None:
        monkeypatch.setattr(ck, "atomic_write_bytes", _enospc)
        with pytest.raises(DiskFullError) as info:
            ck.save_torch(tmp_path / "checkpoint_last.pt", {"w": torch.zeros(3)})
        msg = str(info.value)
        assert f"checkpoint_last.pt into {tmp_path}" in msg
        assert re.search(r"\d+\.\d MB free there", msg) and "out_root=" in msg
        assert info.value.errno == errno.ENOSPC and isinstance(info.value.__cause__, OSError)

    def test_rerun_advice_follows_the_checkpoint(self, tmp_path: Path, monkeypatch) -> None:
        """Before the first checkpoint a re-run starts over; after it, it resumes."""
        monkeypatch.setattr(ck, "atomic_write_bytes", _enospc)
        with pytest.raises(DiskFullError) as info:
            ck.save_torch(tmp_path / "checkpoint_best.pt", {})
        assert "starts again from its first epoch" in str(info.value)
        assert "resumes" not in str(info.value)
        (tmp_path / ck.LAST_CHECKPOINT).write_bytes(b"")
        with pytest.raises(DiskFullError) as info:
            ck.save_torch(tmp_path / "checkpoint_best.pt", {})
        assert "training resumes from the last checkpoint" in str(info.value)

    def test_first_epoch_starts_over(self, synthetic_dataset, compose_train, tmp_path,
                                     monkeypatch) -> None:
        """A full disk at the first epoch's checkpoint leaves nothing to resume from."""
        monkeypatch.setattr(ck, "atomic_write_bytes", _enospc)
        with pytest.raises(DiskFullError, match="no checkpoint was written yet"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=1", "export.int8=false"))
        assert not (tmp_path / "demo" / ck.LAST_CHECKPOINT).exists()

    def test_other_errors_pass(self, tmp_path: Path, monkeypatch) -> None:
        def denied(*args, **kwargs):
            raise PermissionError(errno.EACCES, "Permission denied")

        monkeypatch.setattr(ck, "atomic_write_bytes", denied)
        with pytest.raises(PermissionError):
            ck.save_torch(tmp_path / "x.pt", {})

    def test_free_bytes_of_a_folder_not_made_yet(self, tmp_path: Path) -> None:
        assert free_bytes(tmp_path / "a" / "b") == free_bytes(tmp_path) > 0

    def test_during_training(self, synthetic_dataset, compose_train, tmp_path, monkeypatch
                             ) -> None:
        monkeypatch.setattr(ck, "atomic_write_bytes", _enospc)
        with pytest.raises(DiskFullError, match=rf"checkpoint_best.pt into "
                                                   rf"{tmp_path / 'demo'} failed: the disk is "
                                                   r"full \(.* MB free there\)"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=1", "export.int8=false"))

    @pytest.mark.slow
    def test_during_export(self, synthetic_dataset, compose_train, tmp_path, monkeypatch
                           ) -> None:
        monkeypatch.setattr(ex, "atomic_write", _enospc)
        with pytest.raises(DiskFullError,
                           match=rf"segnet.onnx into {tmp_path / 'demo'}") as info:
            tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=1", "export.int8=false"))
        assert (tmp_path / "demo" / "checkpoint_best.pt").is_file()  # a re-run resumes
        assert "training resumes from the last checkpoint" in str(info.value)


@pytest.mark.slow
def test_same_seed_same_weights(synthetic_dataset, compose_train, tmp_path) -> None:
    """Two runs of one config in two folders end with equal checkpoints and test scores."""
    runs = []
    for root in ("a", "b"):
        m = tt.run(compose_train(synthetic_dataset, tmp_path / root, "export.int8=false"))
        runs.append((m, {f: torch.load(tmp_path / root / "demo" / f, weights_only=False)
                         for f in ("checkpoint_best.pt", "checkpoint_last.pt")}))
    (m_a, a), (m_b, b) = runs
    for f in a:
        assert a[f]["model"].keys() == b[f]["model"].keys()
        for k, v in a[f]["model"].items():
            assert torch.equal(v, b[f]["model"][k]), (f, k)
    for k, v in a["checkpoint_last.pt"]["ema"].items():
        if isinstance(v, torch.Tensor):
            assert torch.equal(v, b["checkpoint_last.pt"]["ema"][k]), k
    assert m_a["test"] == m_b["test"]
