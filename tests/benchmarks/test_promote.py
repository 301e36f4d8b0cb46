"""benchmarks/promote.py on constructed tables and corridor reports, in tmp folders: the
candidate is copied into the shipped folder only when better on every building and not worse
in the corridor; otherwise the blocking places are named and nothing is touched."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.promote import compare_corridor, corridor_errors, main
from benchmarks.thirdparty import onnx_digest
from core.atomic import file_sha256
from core.segmenter import INT8_NAME, QUANTIZE_REPORT

BUILDINGS = ("hospital", "bookstore", "floor101")
SHIPPED = {"hospital": 0.229, "bookstore": 0.128, "floor101": 0.040}


def model(folder: Path, tag: str) -> Path:
    """A model folder with the files a promotion copies (segnet.onnx's bytes name it)."""
    folder.mkdir(parents=True)
    (folder / "segnet.onnx").write_bytes(f"graph of {tag}".encode())
    for f in ("checkpoint_best.pt", "config.json", "localize.yaml", "train_log.csv"):
        (folder / f).write_text(f"{f} of {tag}")
    (folder / "metrics.json").write_text(json.dumps({"model": tag}))
    return folder


def table(path: Path, onnx: Path, errors: dict[str, float], lost: dict | None = None,
          seeds=(0,), frames=150) -> Path:
    """A thirdparty.json of ``onnx``: cnn mean error by building, two runs each."""
    lost = lost or {}
    results = {b: {"tracking": {"cnn": {"mean_m": e, "lost": lost.get(b, 0), "runs": 2},
                                "none": {"mean_m": 1.0, "lost": 0, "runs": 2}}}
               for b, e in errors.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"onnx": str(onnx), "onnx_sha256": onnx_digest(onnx),
                                "modes": ["none", "cnn"], "seeds": list(seeds),
                                "frames": frames, "finetune": 0, "results": results}))
    return path


def corridor(folder: Path, onnx: Path, per_seed: dict[str, list[float]],
             lost_rate: float = 0.0) -> Path:
    """A localize report folder of ``onnx`` on the demo's flights: per-seed cnn errors."""
    flights = {f: {"cnn": {"mean_position_error_m": sum(e) / len(e), "per_seed_mean_m": e,
                           "lost_rate": lost_rate, "seeds": list(range(len(e)))}}
               for f, e in per_seed.items()}
    folder.mkdir(parents=True)
    (folder / "metrics.json").write_text(json.dumps({
        "flights": flights, "dataset": "outputs/datasets/demo",
        "model": {"onnx_model": str(onnx), "onnx_sha256": onnx_digest(onnx)}}))
    return folder


CORRIDOR = {"paper": [0.034, 0.033, 0.035], "cluttered": [0.032, 0.031, 0.033]}


@pytest.fixture
def setup(tmp_path: Path):
    """The shipped folder (with its README) and its figures; a candidate folder. Returns a
    function: candidate figures -> (exit status of promote.py, shipped folder, candidate)."""
    shipped = model(tmp_path / "models" / "generalist", "shipped")
    (shipped / "README.md").write_text("the shipped model's README")
    cand = model(tmp_path / "outputs" / "models" / "generalist", "candidate")
    ship_table = table(tmp_path / "bench" / "thirdparty" / "thirdparty.json",
                       shipped / "segnet.onnx", SHIPPED)
    ship_corr = corridor(tmp_path / "reports" / "corridor_shipped", shipped / "segnet.onnx",
                         CORRIDOR)

    def promote(errors: dict, corridor_errors: dict = CORRIDOR, *extra: str, lost=None,
                seeds=(0,), corridor_lost: float = 0.0) -> int:
        cand_table = table(tmp_path / "bench" / "cand" / "thirdparty.json",
                           cand / "segnet.onnx", errors, lost, seeds)
        cand_corr = tmp_path / "reports" / "corridor_cand"
        if not cand_corr.exists():
            corridor(cand_corr, cand / "segnet.onnx", corridor_errors, corridor_lost)
        return main(["--candidate", str(cand), "--candidate-table", str(cand_table),
                     "--candidate-corridor", str(cand_corr), "--shipped", str(shipped),
                     "--shipped-table", str(ship_table), "--shipped-corridor",
                     str(ship_corr), *extra])

    return promote, shipped, cand


def better(by: float = 0.9) -> dict:
    return {b: e * by for b, e in SHIPPED.items()}


def test_better_everywhere_is_promoted(setup, capsys) -> None:
    promote, shipped, cand = setup
    assert promote(better()) == 0
    out = capsys.readouterr().out
    assert "| hospital | 0.229 (0/2) | 0.206 (0/2) | better |" in out
    assert "| corridor | 0.033 (0/6) | 0.033 (0/6) | not worse |" in out
    assert "promoted: segnet.onnx, checkpoint_best.pt, metrics.json" in out
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of candidate"
    assert json.loads((shipped / "metrics.json").read_text()) == {"model": "candidate"}
    assert (shipped / "README.md").read_text() == "the shipped model's README"
    assert not [p for p in shipped.parent.iterdir() if p.name.startswith(".")]
    assert (cand / "segnet.onnx").is_file()  # copied, not moved


def test_one_building_worse_blocks(setup, capsys) -> None:
    promote, shipped, _ = setup
    assert promote(better() | {"bookstore": 0.159}) == 1
    out = capsys.readouterr().out
    assert "| bookstore | 0.128 (0/2) | 0.159 (0/2) | blocks: cnn 0.159 m, not below 0.128 m |" \
        in out
    assert out.strip().endswith("not promoted; blocked by bookstore (cnn 0.159 m, not below "
                                "0.128 m)")
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of shipped"


def test_equal_is_not_better_and_lost_runs_block(setup, capsys) -> None:
    promote, shipped, _ = setup
    assert promote(better() | {"floor101": 0.040}, lost={"hospital": 1}) == 1
    out = capsys.readouterr().out
    assert "floor101 (cnn 0.040 m, not below 0.040 m)" in out
    assert "hospital (1 lost runs against 0)" in out
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of shipped"


def test_a_building_missing_blocks(setup, capsys) -> None:
    promote, _, _ = setup
    errors = better()
    del errors["floor101"]
    assert promote(errors | {"floor104": 0.01}) == 1
    out = capsys.readouterr().out
    assert "floor101 (not in the candidate's table)" in out
    assert "floor104 (no shipped figure" in out


@pytest.mark.parametrize(("scale", "passes"), [(1.08, True), (1.2, False)])
def test_corridor_within_ten_per_cent_is_not_worse(setup, capsys, scale, passes) -> None:
    promote, shipped, _ = setup
    worse = {f: [e * scale for e in v] for f, v in CORRIDOR.items()}
    assert promote(better(), worse) == (0 if passes else 1)
    out = capsys.readouterr().out
    assert ("blocked by corridor (cnn 0.040 m, above 0.033 m + 0.003)" in out) != passes


def test_corridor_noise_widens_the_tolerance() -> None:
    """Seeds 0.02 m apart: a candidate 15 % worse on the mean is within 2 standard errors."""
    def metrics(per_seed):
        return {"flights": {"paper": {"cnn": {"mean_position_error_m": sum(per_seed) / 3,
                                              "per_seed_mean_m": per_seed, "lost_rate": 0.0}}}}

    shipped = metrics([0.02, 0.04, 0.06])
    mean, se, lost, runs = corridor_errors(shipped)
    assert (mean, lost, runs) == (pytest.approx(0.04), 0, 3)
    assert se == pytest.approx(0.02 / 3 ** 0.5)
    assert compare_corridor(shipped, metrics([0.026, 0.046, 0.066])).passes  # +0.006 m, 15 %
    quiet = metrics([0.039, 0.040, 0.041])
    assert not compare_corridor(quiet, metrics([0.045, 0.046, 0.047])).passes


def test_corridor_lost_runs_block(setup, capsys) -> None:
    promote, _, _ = setup
    assert promote(better(), CORRIDOR, corridor_lost=1 / 3) == 1
    assert "corridor (2 lost runs against 0)" in capsys.readouterr().out


def test_dry_run_copies_nothing(setup, capsys) -> None:
    promote, shipped, _ = setup
    assert promote(better(), CORRIDOR, "--dry-run") == 0
    assert "it would be promoted" in capsys.readouterr().out
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of shipped"


def test_figures_of_another_model_or_other_runs_are_refused(setup, capsys, tmp_path) -> None:
    promote, shipped, cand = setup
    assert promote(better(), CORRIDOR, seeds=(0, 1)) == 2
    assert "the tables ran other seeds: [0] (shipped) and [0, 1] (candidate)" in (
        capsys.readouterr().err)
    (cand / "segnet.onnx").write_bytes(b"retrained since")  # the corridor report is stale
    assert promote(better()) == 2
    err = capsys.readouterr().err
    assert "--candidate-corridor: the report's cnn runs used another SegNet" in err
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of shipped"


def test_a_promotion_stopped_between_its_renames_is_finished(setup, capsys) -> None:
    promote, shipped, _ = setup
    shipped.rename(shipped.parent / ".generalist.old")  # the old folder moved aside, no new
    assert promote(better()) == 0
    assert "put back from" in capsys.readouterr().out
    assert (shipped / "README.md").is_file()
    assert (shipped / "segnet.onnx").read_bytes() == b"graph of candidate"


def test_an_int8_copy_is_what_is_compared_and_shipped(tmp_path, capsys) -> None:
    """A candidate with a valid int8 copy beside it (what localize runs by default) is
    compared by that copy's figures, and the copy ships with it; a later candidate without
    one leaves no stale copy behind."""
    shipped = model(tmp_path / "models" / "generalist", "shipped")
    cand = model(tmp_path / "cand", "candidate")
    (cand / INT8_NAME).write_bytes(b"int8 graph of candidate")
    (cand / QUANTIZE_REPORT).write_text(json.dumps(
        {"model": str(cand / "segnet.onnx"), "model_sha256": file_sha256(cand / "segnet.onnx")}))
    ship_t = table(tmp_path / "ship.json", shipped / "segnet.onnx", SHIPPED)
    ship_c = corridor(tmp_path / "ship_corr", shipped / "segnet.onnx", CORRIDOR)

    def promote(candidate: Path, onnx: Path, name: str) -> int:
        cand_t = table(tmp_path / f"{name}.json", onnx, better())
        cand_c = corridor(tmp_path / f"{name}_corr", onnx, CORRIDOR)
        return main(["--candidate", str(candidate), "--candidate-table", str(cand_t),
                     "--candidate-corridor", str(cand_c), "--shipped", str(shipped),
                     "--shipped-table", str(ship_t), "--shipped-corridor", str(ship_c)])

    assert promote(cand, cand / "segnet.onnx", "float") == 2  # figures of the float graph
    assert "made with another SegNet" in capsys.readouterr().err
    assert promote(cand, cand / INT8_NAME, "int8") == 0
    assert (shipped / INT8_NAME).read_bytes() == b"int8 graph of candidate"
    assert (shipped / QUANTIZE_REPORT).is_file()
    plain = model(tmp_path / "plain", "plain")
    ship_t = table(tmp_path / "ship2.json", shipped / INT8_NAME, SHIPPED)
    ship_c = corridor(tmp_path / "ship2_corr", shipped / INT8_NAME, CORRIDOR)
    assert promote(plain, plain / "segnet.onnx", "plain") == 0
    assert not (shipped / INT8_NAME).exists() and not (shipped / QUANTIZE_REPORT).exists()
