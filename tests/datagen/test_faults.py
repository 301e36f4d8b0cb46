"""datagen under faults: two runs on one folder, a missing shard, a killed write, a cut PNG;
building models in the wrong units, with an include cycle or with NaN vertices."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

import datagen.generate as gen
from core.atomic import png_complete, read_png
from core.dataset import Dataset
from core.occupancy import OccupancyMap
from datagen.importers import load_building
from datagen.importers.__main__ import main as import_main
from datagen.worlds.site import build_site
from tests.datagen.building_files import open_room, visual, write_model, write_world
from tests.datagen.test_generate import SMALL, small_cfg

REPO = Path(__file__).resolve().parents[2]

#: A datagen run in its own process: argv[1] = JSON {out, overrides, gate, before}. With a
#: gate it stops after its first frame (``before``: before writing it) until ``<gate>.go``
#: exists (``<gate>.started`` says so).
CHILD = """
import json, sys, time
from pathlib import Path
import datagen.generate as gen
import datagen.rendering.frame as render_frame
from core.config import compose_config
try:
    import core.outputs
    core.outputs.RUN_WAIT_S = 1.0
except ImportError:
    pass
args = json.loads(sys.argv[1])
cfg = compose_config("datagen", args["overrides"])
if args["gate"]:
    real, gate = render_frame.write_frame, args["gate"]
    def paused(*a, **k):
        if not args["before"]:
            real(*a, **k)
        Path(gate + ".started").touch()
        while not Path(gate + ".go").exists():
            time.sleep(0.05)
        if args["before"]:
            real(*a, **k)
    render_frame.write_frame = paused
gen.run(cfg, progress=False)
"""


def child(out: Path, *extra: str, gate: Path | None = None,
          before: bool = False) -> subprocess.Popen:
    args = {"overrides": [*SMALL, f"out_dir={out}", *extra], "gate": str(gate or ""),
            "before": before}
    return subprocess.Popen([sys.executable, "-c", CHILD, json.dumps(args)], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_started(gate: Path, proc: subprocess.Popen, timeout: float = 300) -> None:
    deadline = time.monotonic() + timeout
    while not Path(f"{gate}.started").exists():
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        assert time.monotonic() < deadline, "the first run never wrote a frame"
        time.sleep(0.1)


def frames(root: Path) -> dict[str, np.ndarray]:
    return {str(p.relative_to(root)): read_png(p, rgb=False)
            for p in sorted(root.glob("**/*.png")) if not p.name.startswith(".")}


@pytest.mark.slow
class TestTwoRuns:
    def test_other_seed_refused_while_the_first_writes(self, tmp_path: Path) -> None:
        """A second run of another seed (even with overwrite=true) may not write into a folder
        a run is writing: it waits briefly, then refuses naming the first run's pid; the
        dataset is the first run's alone."""
        out, gate = tmp_path / "ds", tmp_path / "gate"
        first = child(out, gate=gate)
        try:
            wait_started(gate, first)
            second = child(out, "seed=1", "overwrite=true")
            _, err = second.communicate(timeout=300)
            assert second.returncode != 0, "the second run must not write"
            assert re.search(rf"another run is writing .*ds \(pid {first.pid}\); wait for it "
                             r"or pick another name=", err), err[-2000:]
        finally:
            Path(f"{gate}.go").touch()
            _, err = first.communicate(timeout=300)
        assert first.returncode == 0, err[-2000:]
        assert json.loads((out / "dataset.json").read_text())["seed"] == 0
        gen.run(small_cfg(tmp_path / "ref"), progress=False)
        got, ref = frames(out), frames(tmp_path / "ref")
        assert sorted(got) == sorted(ref)
        for k in ref:  # LLVM's threads may move a pixel by one level (docs/datagen.md)
            np.testing.assert_allclose(got[k], ref[k], atol=1, err_msg=k)

    def test_other_seed_refused_before_the_first_frame(self, tmp_path: Path) -> None:
        """Two runs started together on an empty folder: the first has claimed it (its
        dataset.json written, no frame yet); the second, of another seed, is refused naming
        the key, and the data never mixes."""
        out, gate = tmp_path / "ds", tmp_path / "gate"
        first = child(out, gate=gate, before=True)
        try:
            wait_started(gate, first)
            assert not list(out.glob("*/rgb/*.png"))
            second = child(out, "seed=1")
            _, err = second.communicate(timeout=300)
            assert second.returncode != 0, "the second run must not write"
            assert re.search(rf"being written by another run \(pid {first.pid}\) with another "
                             r"config: seed \(0 -> 1\)", err), err[-2000:]
        finally:
            Path(f"{gate}.go").touch()
            _, err = first.communicate(timeout=300)
        assert first.returncode == 0, err[-2000:]
        assert json.loads((out / "dataset.json").read_text())["seed"] == 0

    def test_shards_of_one_config_write_side_by_side(self, tmp_path: Path) -> None:
        out, gate = tmp_path / "ds", tmp_path / "gate"
        first = child(out, "shard=0", "num_shards=2", gate=gate)
        try:
            wait_started(gate, first)
            gen.run(small_cfg(out, "shard=1", "num_shards=2"), progress=False)
        finally:
            Path(f"{gate}.go").touch()
            _, err = first.communicate(timeout=300)
        assert first.returncode == 0, err[-2000:]
        ds = Dataset(out)
        assert len(ds.split("train")[0]) == 4 and len(ds.flight("cluttered").rgb) == 3


@pytest.mark.slow
def test_missing_shard_names_the_command_that_renders_it(tmp_path: Path) -> None:
    """Shard 0 of 2 rendered by the real CLI: loading names the split, the counts and the exact
    command of shard 1; that command finishes the dataset."""
    out = tmp_path / "ds"
    cli = [sys.executable, "-m", "datagen", *SMALL, f"out_dir={out}", "progress=false"]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    subprocess.run([*cli, "shard=0", "num_shards=2"], cwd=tmp_path, env=env, check=True,
                   capture_output=True)
    with pytest.raises(FileNotFoundError) as err:
        Dataset(out).split("train")
    msg = str(err.value)
    assert "split 'train' has 2 of the 4 frames" in msg, msg
    command = re.findall(r"`([^`]*)`", msg)
    assert len(command) == 1 and command[0].endswith("shard=1 num_shards=2"), msg
    assert "progress" not in command[0]
    argv = shlex.split(command[0])
    assert argv[:3] == ["python", "-m", "datagen"]
    subprocess.run([sys.executable, *argv[1:]], cwd=tmp_path, env=env, check=True,
                   capture_output=True)
    assert len(Dataset(out).split("train")[0]) == 4


@pytest.mark.slow
def test_resume_mends_killed_writes(tmp_path: Path) -> None:
    """A temp file of a killed write and a cut-short PNG: loading ignores the first and names
    the second; the resumed run deletes the first and renders the second again."""
    out = tmp_path / "ds"
    cfg = small_cfg(out, "render_flights=[]")
    gen.run(cfg, progress=False)
    label = out / "train" / "label" / "000001.png"
    good = label.read_bytes()
    label.write_bytes(good[: len(good) // 2])
    temp = out / "train" / "rgb" / ".000002.png.k2j3h4g5.png"
    temp.write_bytes(b"\x89PNG half a frame")
    with pytest.raises(ValueError, match=rf"cut-short PNG.*{label}.*python -m datagen"):
        Dataset(out).split("train")
    gen.run(cfg, progress=False)
    assert not temp.exists(), "the resumed run deletes stale temp files"
    assert png_complete(label)
    again = read_png(label, rgb=False)
    np.testing.assert_array_equal(again, cv2.imdecode(np.frombuffer(good, np.uint8),
                                                      cv2.IMREAD_UNCHANGED))
    assert len(Dataset(out).split("train")[0]) == 4


def test_full_disk_names_the_folder_and_the_fix(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """ENOSPC on a write (simulated): a DiskFullError naming the dataset's folder, the file
    and the fix, not a bare OSError."""
    import errno

    from core import atomic

    def replace(src, dst):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic.os, "replace", replace)
    out = tmp_path / "ds"
    with pytest.raises(atomic.DiskFullError, match=rf"writing \S+ into {out}(/\S+)? failed: "
                                                   r"the disk is full .* Free space"):
        gen.run(small_cfg(out), progress=False)


def test_millimetre_mesh_refused_before_the_free_space(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture) -> None:
    """An OBJ room of 10 x 8 x 3 m drawn in millimetres, read at the default 1 m per unit
    (10 km across): the import refuses it naming the file and the units to set, before the
    free space (whose cost grows with the model's area) is built."""
    room = open_room((10.0, 8.0, 3.0))
    room.vertices *= 1000.0
    path = tmp_path / "mm_room.obj"
    room.export(path)

    def never(*args, **kwargs):
        raise AssertionError("the free space of a model in the wrong units was built")

    monkeypatch.setattr(OccupancyMap, "from_mesh", never)
    fix = r"in mm it would be 10\.0 m across and 3\.0 m high: set world\.units=0\.001"
    with pytest.raises(ValueError, match=rf"{path}: .*10000\.0 m across.*{fix}"):
        build_site({"kind": "file", "path": str(path)})
    assert import_main([str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "--units 0.001" in err, err
    b = load_building(path, {"units": 0.001})
    np.testing.assert_allclose(b.vertices.max(axis=0)[:2], [10.0, 8.0], atol=1e-6)


@pytest.mark.parametrize("through", [False, True], ids=["itself", "through_another"])
def test_include_cycle_names_the_model_files(tmp_path: Path, through: bool) -> None:
    """A model including itself, directly or through another model: a ValueError naming the
    model files of the cycle, not a RecursionError."""
    models = tmp_path / "models"
    box = visual("<box><size>1 1 1</size></box>", "0 0 0.5 0 0 0")
    if through:
        write_model(models, "a", box + "<include><uri>model://b</uri></include>")
        write_model(models, "b", "<include><uri>model://a</uri></include>")
        cycle = [models / "a" / "model.sdf", models / "b" / "model.sdf",
                 models / "a" / "model.sdf"]
    else:
        write_model(models, "a", box + "<include><uri>model://a</uri></include>")
        cycle = [models / "a" / "model.sdf", models / "a" / "model.sdf"]
    world = write_world(tmp_path / "worlds" / "w.world",
                        "<include><uri>model://a</uri></include>")
    names = " -> ".join(str(p.resolve()) for p in cycle)
    with pytest.raises(ValueError, match=re.escape(f"{world}: <include> cycle: {names} ")):
        load_building(world)


def test_model_included_twice_is_no_cycle(tmp_path: Path) -> None:
    """One model included by the world and twice by another model is no cycle: each
    include is read."""
    models = tmp_path / "models"
    write_model(models, "box", visual("<box><size>1 1 1</size></box>", "0 0 0.5 0 0 0"))
    include = "<include><uri>model://box</uri><pose>{} 0 0 0 0 0</pose></include>"
    write_model(models, "pair", include.format(0) + include.format(2))
    floor = "<model name='ground'>" + visual("<plane><size>20 20</size></plane>") + "</model>"
    world = write_world(tmp_path / "worlds" / "w.world", floor + include.format(5)
                        + "<include><uri>model://pair</uri></include>")
    b = load_building(world)
    assert b.info["includes"] == 4
    np.testing.assert_allclose(b.vertices.max(axis=0), [5.5, 0.5, 1.0])


def test_nan_vertices_name_the_file_and_count(tmp_path: Path) -> None:
    """An OBJ with two NaN vertices (and one infinite): the import fails naming the file and
    the number of bad vertices, not a setting of the free space."""
    lines = open_room((10.0, 8.0, 3.0)).export(file_type="obj").splitlines()
    rows = [i for i, line in enumerate(lines) if line.startswith("v ")]
    for i, bad in zip(rows[:3], ("nan nan nan", "0 nan 0", "inf 0 0"), strict=True):
        lines[i] = f"v {bad}"
    path = tmp_path / "nan_room.obj"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=rf"{path}: 3 of {len(rows)} vertices are not finite"):
        build_site({"kind": "file", "path": str(path)})
