"""Atomic file writes: write to a temporary file in the same folder, then rename; and the
checks of a written file (complete images, its digest).

A write that fails for want of disk space raises ``DiskFullError`` naming the file, its folder,
the free space there and the fix.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

_UMASK = os.umask(0)
os.umask(_UMASK)

#: Names of ``atomic_write``'s temporary files: ``.<name>.<8 random chars><suffix>``.
TEMP_NAME = re.compile(r"^\..+\.[a-z0-9_]{8}(\.[A-Za-z0-9]+)?$")
#: The last 12 bytes of every complete PNG: the IEND chunk (length 0, type, CRC).
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"
#: The first bytes of every PNG (its signature) and of every JPEG (the SOI marker).
PNG_START = b"\x89PNG\r\n\x1a\n"
JPEG_START = b"\xff\xd8"
#: The last bytes of every complete JPEG: the EOI marker.
JPEG_END = b"\xff\xd9"


#: What to do about a full disk, unless a stage says better.
DISK_FULL_FIX = ("Free space (old outputs/ folders, outputs/hydra/) or write to a disk with "
                 "room (out_dir=), then run the same command again")


class DiskFullError(OSError):
    """A write failed for want of disk space (errno ENOSPC); its message names the file, the
    folder, the free space there and the fix.

    Attributes:
        where: what was being written where, and the free space (the message without the fix).
        fix: what the user does about it.
    """

    def __init__(self, where: str, fix: str):
        super().__init__(errno.ENOSPC, f"{where}. {fix}")
        self.where, self.fix = where, fix

    def __reduce__(self):
        return type(self), (self.where, self.fix)


def free_bytes(folder: str | Path) -> int:
    """Free space (bytes) on the file system of ``folder`` (or of its nearest existing parent)."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return shutil.disk_usage(folder).free


@contextmanager
def disk_full_guard(folder: str | Path, what: str, fix: str = DISK_FULL_FIX) -> Iterator[None]:
    """Turn an OSError ENOSPC raised inside into a ``DiskFullError`` that says where and what
    to do; a ``DiskFullError`` from an inner guard keeps its where and takes this ``fix`` (the
    stage's advice over a generic writer's).

    Args:
        folder: the folder written to.
        what: the files being written (for the message), e.g. ``"rgb/000001.png"``.
        fix: what the user does about it (the message's last sentence).
    """
    try:
        yield
    except DiskFullError as err:
        if err.fix == fix:
            raise
        raise DiskFullError(err.where, fix) from err.__cause__  # the outer writer's advice
    except OSError as err:
        if err.errno != errno.ENOSPC:
            raise
        folder = Path(folder)
        raise DiskFullError(f"writing {what} into {folder} failed: the disk is full "
                            f"({free_bytes(folder) / 1e6:.1f} MB free there)", fix) from err


def atomic_write(path: str | Path, write: Callable[[Path], None], suffix: str = "") -> None:
    """Call ``write(tmp_path)`` and rename the result onto ``path``.

    A crash leaves either the old file or none, never half a file.

    Raises:
        DiskFullError: the disk is full (naming ``path``'s folder); nothing is left behind.
    """
    path = Path(path)
    with disk_full_guard(path.parent, path.name):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix,
                                   dir=path.parent)
        os.close(fd)
        try:
            write(Path(tmp))
            os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the usual file mode
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    atomic_write(path, lambda p: p.write_bytes(data))


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | Path, obj) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def write_png(path: str | Path, image: np.ndarray) -> None:
    """Write an (H, W, 3) RGB uint8 image or an (H, W) uint8/uint16 map as PNG, atomically."""
    if image.dtype != np.uint8 and not (image.ndim == 2 and image.dtype == np.uint16):
        raise ValueError(f"{path}: PNG images must be uint8 (or 2-D uint16), got {image.dtype}")
    bgr = image[..., ::-1] if image.ndim == 3 else image
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(bgr))
    if not ok:
        raise OSError(f"could not encode PNG for {path}")
    atomic_write_bytes(path, buf.tobytes())


def read_png(path: str | Path, rgb: bool = True) -> np.ndarray:
    """Read a PNG written by ``write_png``: (H, W, 3) RGB uint8, or (H, W) uint8 if not rgb."""
    path = Path(path)
    img = cv2.imread(str(path), cv2.IMREAD_COLOR if rgb else cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FileNotFoundError(f"cannot read image {path}")
    return img[..., ::-1].copy() if rgb else img


def is_temp(path: str | Path) -> bool:
    """Whether ``path`` is named like a temporary file of ``atomic_write`` (one a killed write
    leaves behind)."""
    return bool(TEMP_NAME.match(Path(path).name))


def remove_temp_files(folder: str | Path) -> list[Path]:
    """Delete every ``atomic_write`` temporary file under ``folder`` (recursively).

    Only safe when no writer is live there (the caller holds the folder alone).

    Returns:
        The files removed.
    """
    found = [p for p in Path(folder).rglob(".*") if p.is_file() and is_temp(p)]
    for p in found:
        p.unlink(missing_ok=True)
    return found


def encoded_image_complete(data: bytes) -> bool:
    """Whether encoded image bytes end as a complete image does: a PNG with its IEND chunk, a
    JPEG with its EOI marker (NUL padding after it allowed). Bytes of another format: True
    (their decoder judges them).

    OpenCV decodes a cut-short JPEG without an error, grey below the cut; this finds bytes cut
    short (a killed copy, a full disk, a lost packet's tail), not bytes corrupted in place.
    """
    if data.startswith(PNG_START):
        return data.endswith(PNG_END)
    if data.startswith(JPEG_START):
        return data.rstrip(b"\x00").endswith(JPEG_END)
    return True


def png_complete(path: str | Path) -> bool:
    """Whether ``path`` is a PNG that ends with its IEND chunk (not truncated).

    A cheap check (one 12-byte read, ~20 us; decoding a 320x240 frame takes ~1.6 ms): it
    finds a file cut short by a killed copy or a full disk, not bytes corrupted in place.
    """
    try:
        with open(path, "rb") as f:
            f.seek(-len(PNG_END), os.SEEK_END)
            return f.read() == PNG_END
    except OSError:  # missing, or shorter than 12 bytes
        return False


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes (64 hex digits), read in 1 MiB blocks: a file's identity
    that holds on a fresh clone, where file times do not."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
