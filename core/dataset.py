"""The dataset layout on disk (docs/datagen.md) and readers for the later stages.

```
<dataset>/
  dataset.json                 schema, classes, camera, config, seed, counts, versions
  stats.json                   images_per_second, counts, render settings
  world/model.ply              structural mesh, face colour = class colour
  world/model.npz              vertices (V,3) f8, faces (F,3) i8, face_class (F,) u1
  world/edges.npz              segments (M,2,3) f8, classes (M,2) u1, crease_deg (M,) f8,
                               normals (M,2,3) f8 (core.imaging.outline); absent from a
                               training-only dataset (world.json num_edges null)
  world/world.json             the world's parameters, free space summary, lights
  world/free.npz               free space: the occupancy map of the flyable heights
  world_truth/                 with realism.map only: the rendered world (world/ is then the
                               map, the truth edited as dataset.json's map_error lists)
  train|val|test/rgb/NNNNNN.png, label/NNNNNN.png, depth/NNNNNN.npy (optional), poses.txt
  flights/<name>/rgb/, label/, groundtruth.txt, odometry.txt, flight.json, images.txt
```

A flight's groundtruth.txt holds every frame's true pose at its capture time i / fps. Without
images.txt (``realism.timing`` off) every frame is delivered at its capture time and
odometry.txt has a pose per frame. With it (``realism.timing``), images.txt lists the
delivered frames (``timestamp rgb/NNNNNN.png``; dropped frames are missing, and were never
rendered) with their timestamps, and odometry.txt is sampled at its own rate: ``Dataset.flight``
interpolates it at each delivered frame's timestamp, as a folder recording's reader does
(localize/recordings/folder.py).
"""

from __future__ import annotations

import glob
import json
import shlex
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from core.atomic import png_complete, read_png
from core.frames import Frame, delivered_frames, frame_count
from core.imaging.lens import Undistorter, coefficients
from core.occupancy import OccupancyMap
from core.poses import interpolate_poses, read_tum

SCHEMA_VERSION = 1
SPLITS = ("train", "val", "test")


def frame_name(index: int) -> str:
    return f"{index:06d}.png"


def read_json(path: Path) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found: is this a dataset made by `python -m datagen`?")
    return json.loads(path.read_text())


@dataclass(frozen=True)
class Camera:
    """Camera of a dataset: K (3,3), image size, body_from_cam (4,4)."""

    K: np.ndarray
    width: int
    height: int
    body_from_cam: np.ndarray


@dataclass(frozen=True)
class World:
    """The structural model the localizer uses.

    vertices (V,3) metres, faces (F,3), face_class (F,) class ids; segments (M,2,3) metres,
    segment_classes (M,2), crease_deg (M,); free: where a camera centre may be (an occupancy
    map of the flyable heights, ``free.band``); info: world.json; normals (M,2,3): for a
    crease its two faces' normals, NaN for other segments (``core.imaging.outline``; None:
    none).
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_class: np.ndarray
    segments: np.ndarray
    segment_classes: np.ndarray
    crease_deg: np.ndarray
    free: OccupancyMap
    info: dict
    normals: np.ndarray | None = None

    @property
    def z_range(self) -> np.ndarray:
        """(2,) m, the flyable heights (the free space's band)."""
        return np.array(self.free.band, dtype=np.float64)


#: The flight sets: ``test`` (``render_flights``) and ``val`` (``val_flights``, ``<name>_val``).
FLIGHT_SETS = ("test", "val")


@dataclass(frozen=True)
class Flight:
    """One evaluation flight as the localizer gets it: its delivered frames (T of them), a
    ``core.frames.FrameSource``.

    rgb, label: (T,) frame paths; timestamps: (T,) s, the images' timestamps; groundtruth:
    (T, 4, 4) world_from_body at each frame's capture; odometry: (T, 4, 4) world_from_body
    at each timestamp (interpolated where the odometry has its own rate); info: flight.json;
    frames: (T,) the delivered frames' indices (0..N-1 of the flight's frames).

    The frames on disk are those of the flight's camera: with lens distortion (flight.json's
    ``camera``: K, size, plumb_bob ``distortion``) they are distorted; ``image`` and
    ``labels`` give them undistorted to the pinhole K, the dataset's camera the localizer
    projects with.
    """

    name: str
    rgb: list[Path]
    label: list[Path]
    timestamps: np.ndarray
    groundtruth: np.ndarray  # (T, 4, 4)
    odometry: np.ndarray  # (T, 4, 4)
    info: dict
    frames: np.ndarray | None = None  # (T,) int; None: 0..T-1

    @property
    def flight_set(self) -> str:
        """``test`` or ``val`` (flight.json's ``set``; ``test`` for a flight that has none)."""
        return str(self.info.get("set", "test"))

    @property
    def distortion(self) -> np.ndarray:
        """(5,) plumb_bob coefficients (k1, k2, p1, p2, k3) of the frames' lens; zeros: a
        pinhole (flight.json without ``camera``)."""
        return coefficients((self.info.get("camera") or {}).get("distortion"))

    @cached_property
    def undistorter(self) -> Undistorter | None:
        """The frames' undistortion to their pinhole K (maps made once), None for a pinhole."""
        cam = self.info.get("camera")
        if not cam or not np.any(self.distortion):
            return None
        return Undistorter(np.array(cam["K"], dtype=np.float64), self.distortion,
                           int(cam["width"]), int(cam["height"]))

    def image(self, t: int) -> np.ndarray:
        """Frame t's (H, W, 3) uint8 RGB, undistorted to the pinhole K (bilinear)."""
        rgb = read_png(self.rgb[t])
        return rgb if self.undistorter is None else self.undistorter.image(rgb)

    def labels(self, t: int) -> np.ndarray:
        """Frame t's (H, W) uint8 true class ids, undistorted to the pinhole K (nearest;
        ignore where the lens sees nothing)."""
        label = read_png(self.label[t], rgb=False)
        return label if self.undistorter is None else self.undistorter.labels(label)

    def __len__(self) -> int:
        return len(self.timestamps)

    def steps(self, limit: int | None = None, *, images: bool = True,
               labels: bool = False) -> Iterator[Frame]:
        """The first ``limit`` frames (all: None) as ``core.frames.Frame``, each image and
        labels read when its frame is reached (``core.frames.FrameSource``)."""
        n = frame_count(self, limit)
        return delivered_frames(self, n, (self.image(t) for t in range(n)) if images else None,
                                (self.labels(t) for t in range(n)) if labels else None)


class Dataset:
    """Read access to a dataset directory made by ``python -m datagen``."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(
                f"dataset not found: {self.root}. Make one with `python -m datagen name=...`."
            )
        self.meta = read_json(self.root / "dataset.json")
        if self.meta.get("schema_version") != SCHEMA_VERSION:
            raise ValueError(
                f"{self.root / 'dataset.json'}: schema_version {self.meta.get('schema_version')}"
                f" is not {SCHEMA_VERSION}; regenerate the dataset with this version of datagen."
            )

    @property
    def classes(self) -> list[dict]:
        return self.meta["classes"]

    @property
    def realism(self) -> str:
        """The datagen ``realism`` preset the flights were made with (``ideal``, ``real``, ...;
        ``ideal`` for a dataset that records none)."""
        return str(self.meta.get("generator", {}).get("realism", {}).get("name", "ideal"))

    @property
    def camera(self) -> Camera:
        c = self.meta["camera"]
        return Camera(np.array(c["K"]), int(c["width"]), int(c["height"]),
                      np.array(c["body_from_cam"]))

    @property
    def camera_truth(self) -> Camera:
        """The camera the images were rendered with (``camera_truth``, written with
        realism.calibration); ``camera`` where the dataset records none."""
        if "camera_truth" not in self.meta:
            return self.camera
        c = self.meta["camera_truth"]
        return Camera(np.array(c["K"]), int(c["width"]), int(c["height"]),
                      np.array(c["body_from_cam"]))

    def split(self, name: str) -> tuple[list[Path], list[Path]]:
        """Paired (rgb, label) image paths of a split, by frame index.

        Raises:
            FileNotFoundError: a frame dataset.json counts is missing (naming the split, the
                counts and the datagen command that renders it).
            ValueError: a frame's PNG is cut short (naming the file and the fix).
        """
        if name not in SPLITS:
            raise ValueError(f"unknown split {name!r}; expected one of {SPLITS}")
        counts = self.meta.get("counts", {})
        if name not in counts:
            raise ValueError(f"{self.root / 'dataset.json'} has no counts.{name}; regenerate "
                             "the dataset with this version of datagen")
        d = self.root / name
        n = int(counts[name])
        rgb = [d / "rgb" / frame_name(i) for i in range(n)]
        label = [d / "label" / frame_name(i) for i in range(n)]
        self.check_frames(f"split {name!r}", rgb, label)
        return rgb, label

    def check_frames(self, what: str, rgb: list[Path], label: list[Path]) -> None:
        """Raise if a frame's rgb or label PNG is missing or cut short (see ``split``).

        Args:
            what: the frames' name for the message, e.g. ``"split 'train'"``.
            rgb, label: (N,) paths of frames 0..N-1 that dataset.json counts.
        """
        n = len(rgb)
        missing = np.array([not (a.is_file() and b.is_file())
                            for a, b in zip(rgb, label, strict=True)], dtype=bool)
        if missing.any():
            idx = np.flatnonzero(missing)
            first = next(p for p in (rgb[idx[0]], label[idx[0]]) if not p.is_file())
            raise FileNotFoundError(
                f"{self.root}: {what} has {n - len(idx)} of the {n} frames "
                f"{self.root / 'dataset.json'} counts; {len(idx)} missing (frames "
                f"{_ranges(idx)}, e.g. {first}). Render them: {self.datagen_command(idx, n)} "
                "(datagen re-run with the dataset's config renders only what is missing).")
        broken = [p for p in (*rgb, *label) if not png_complete(p)]
        if broken:
            frames = np.array([int(p.stem) for p in broken])
            raise ValueError(
                f"{self.root}: {what} has {len(broken)} cut-short PNG(s), e.g. {broken[0]} "
                "(no IEND chunk at its end: a killed copy or a full disk?). Re-render them: "
                f"{self.datagen_command(frames, n)} (datagen's resume re-renders broken "
                "frames).")

    def datagen_command(self, frames: np.ndarray, n: int) -> str:
        """The datagen command that renders ``frames`` (indices) of a split or flight of ``n``
        frames: the command the dataset was made with (dataset.json's ``command``) writing into
        this folder (its ``out_dir=`` is the folder loaded, wherever the dataset was made or
        copied from), for the shards holding those frames if it was rendered in shards
        (``stats/``)."""
        base = self.meta.get("command")
        if not base:
            return (f"`python -m datagen out_dir={self.root}` with the config in "
                    f"{self.root / 'dataset.json'} ('generator')")
        here = f"out_dir={shlex.quote(str(self.root))}"
        words = [w for w in base.split(" ") if not w.startswith("out_dir=")]
        base = " ".join([*words, here]) if here not in base.split(" ") else base
        totals = {int(p.stem.rsplit("-", 1)[-1])
                  for p in (self.root / "stats").glob("shard-*-of-*.json")}
        if len(totals) != 1 or totals == {1} or n == 0:
            return f"`{base}`"
        num = totals.pop()
        starts = np.arange(num) * n // num
        shards = np.unique(np.searchsorted(starts, frames, side="right") - 1)
        return " and ".join(f"`{base} shard={k} num_shards={num}`" for k in shards)

    def split_poses(self, name: str) -> np.ndarray:
        """(N, 4, 4) world_from_body of a split's frames."""
        return read_tum(self.root / name / "poses.txt")[1]

    def flight_names(self, flight_set: str | None = None) -> list[str]:
        """The flights' names; of one set (``FLIGHT_SETS``; flight.json's ``set``, ``test``
        where it has none) or all (None)."""
        if flight_set is not None and flight_set not in FLIGHT_SETS:
            raise ValueError(f"unknown flight set {flight_set!r}; use one of {FLIGHT_SETS}")
        d = self.root / "flights"
        names = sorted(p.name for p in d.iterdir() if p.is_dir()) if d.is_dir() else []
        if flight_set is None:
            return names
        return [n for n in names if self.flight_set(n) == flight_set]

    def flight_set(self, name: str) -> str:
        """``test`` or ``val``: the set flight ``name`` belongs to."""
        path = self.root / "flights" / name / "flight.json"
        return str(read_json(path).get("set", "test")) if path.is_file() else "test"

    def flight(self, name: str) -> Flight:
        """The flight's delivered frames with their timestamps, true poses and odometry
        (interpolated at the timestamps where images.txt lists them; module docstring)."""
        d = self.root / "flights" / name
        if not d.is_dir():
            raise FileNotFoundError(f"flight {name!r} not in {self.root / 'flights'}; "
                                    f"available: {self.flight_names()}")
        t, gt = read_tum(d / "groundtruth.txt")
        odo_t, odo = read_tum(d / "odometry.txt")
        frames = np.arange(len(t))
        if (d / "images.txt").is_file():
            frames, t = _images_list(d / "images.txt", len(gt))
            gt = gt[frames]
            odo = (interpolate_poses(t, odo_t, odo) if len(odo_t) > 1
                   else np.repeat(odo[:1], len(t), axis=0))
        rgb = [d / "rgb" / frame_name(i) for i in frames]
        label = [d / "label" / frame_name(i) for i in frames]
        self.check_frames(f"flight {name!r}", rgb, label)
        return Flight(name, rgb, label, t, gt, odo, read_json(d / "flight.json"), frames)

    def world(self) -> World:
        """The map the localizer reads (``world/``)."""
        return load_world(self.root / "world")

    def world_truth(self) -> World:
        """The rendered world (``world_truth/``, written with realism.map, with its
        built-in objects); ``world()`` where the dataset has none."""
        d = self.root / "world_truth"
        return load_world(d) if d.is_dir() else self.world()


def load_world(world_dir: str | Path) -> World:
    """Load ``world/`` (model.npz, edges.npz, free.npz, world.json)."""
    d = Path(world_dir)
    for f in ("model.npz", "edges.npz", "free.npz", "world.json"):
        if not (d / f).is_file():
            hint = "re-run datagen"
            if f == "edges.npz" and (d / "world.json").is_file() and \
                    read_json(d / "world.json").get("num_edges", 0) is None:
                hint = ("the dataset was rendered without model edges (no flights); make them: "
                        f"python -m datagen.mesh.rebuild_edges {d.parent}")
            raise FileNotFoundError(f"world model file missing: {d / f}; {hint}")
    m = np.load(d / "model.npz")
    e = np.load(d / "edges.npz")
    if "outline" in e:
        raise ValueError(f"{d / 'edges.npz'}: made by an older datagen (its 'outline' rows "
                         "are duplicates); rebuild it: python -m datagen.mesh.rebuild_edges "
                         f"{d.parent}")
    info = read_json(d / "world.json")
    return World(
        vertices=m["vertices"], faces=m["faces"], face_class=m["face_class"],
        segments=e["segments"], segment_classes=e["classes"], crease_deg=e["crease_deg"],
        free=OccupancyMap.load(d / "free.npz"), info=info,
        normals=e["normals"] if "normals" in e else None,
    )


def _images_list(path: Path, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(T,) frame indices and (T,) s timestamps of a flight's images.txt
    (``timestamp rgb/NNNNNN.png`` lines, ``#`` comments), checked: known frames, in order,
    timestamps strictly increasing."""
    frames, stamps = [], []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        try:
            stamp, name = float(parts[0]), Path(parts[1])
            frames.append(int(name.stem))
            stamps.append(stamp)
        except (ValueError, IndexError) as err:
            raise ValueError(f"{path} line {n}: expected `timestamp rgb/NNNNNN.png` ({err}); "
                             "re-run datagen") from None
    frames_a, stamps_a = np.asarray(frames, dtype=np.int64), np.asarray(stamps)
    if (not len(frames_a) or frames_a.min() < 0 or frames_a.max() >= num_frames
            or np.any(np.diff(frames_a) <= 0) or np.any(np.diff(stamps_a) <= 0)):
        raise ValueError(f"{path}: needs increasing frames in [0, {num_frames}) with strictly "
                         "increasing timestamps; re-run datagen")
    return frames_a, stamps_a


def _ranges(idx: np.ndarray, limit: int = 4) -> str:
    """``"0-3, 7, 9-10"`` for sorted indices (at most ``limit`` runs)."""
    cuts = np.flatnonzero(np.diff(idx) != 1) + 1
    runs = [(int(r[0]), int(r[-1])) for r in np.split(idx, cuts)]
    text = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs[:limit])
    return text + (", ..." if len(runs) > limit else "")


def open_datasets(pattern: str | Path) -> list[Dataset]:
    """The datasets that a folder or a glob pattern names, in sorted order.

    A plain path is one dataset. A pattern (``outputs/datasets/generalist/floor*``) is every
    matching folder that holds a dataset.json; matching none is an error naming the pattern.
    """
    text = str(pattern)
    if not any(c in text for c in "*?["):
        return [Dataset(text)]
    roots = sorted(p for p in glob.glob(text) if (Path(p) / "dataset.json").is_file())
    if not roots:
        raise FileNotFoundError(
            f"{text!r} matches no dataset folder (one holding a dataset.json); make them with "
            "`python -m datagen` or fix the pattern."
        )
    return [Dataset(r) for r in roots]
