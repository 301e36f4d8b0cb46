"""The README's "From Python" snippet runs as pasted, on a small rendered dataset."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from core.config import TINY_DATAGEN, compose_config

ROOT = Path(__file__).resolve().parents[1]


def readme_snippet() -> str:
    """The python block of the README's "From Python" section."""
    text = (ROOT / "README.md").read_text()
    section = text.split("## From Python", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "README.md: no ```python block under ## From Python"
    return match.group(1)


@pytest.fixture(scope="module")
def demo_sized(tmp_path_factory) -> Path:
    """A dataset at the demo camera's 320 x 240 (the shipped SegNet's size): one 20-frame
    paper flight, no training images."""
    from datagen.generate import run

    out = tmp_path_factory.mktemp("datasets") / "readme"
    cfg = compose_config("datagen", [
        *TINY_DATAGEN, "name=readme", f"out_dir={out}", "camera.width=320",
        "camera.height=240", "splits.train=0", "splits.val=0", "splits.test=0",
        "flights.paper.num_frames=20", "render_flights=[paper]", "val_flights=[]"])
    return run(cfg, progress=False)


@pytest.mark.slow
def test_snippet_runs_as_pasted(demo_sized, monkeypatch, capsys):
    code = readme_snippet()
    line = 'DATASET = "outputs/datasets/demo"'
    assert line in code, f"README.md's snippet must set its dataset with {line!r}"
    monkeypatch.chdir(ROOT)  # the snippet's model path is the repository's
    scope: dict = {}
    exec(compile(code.replace(line, f'DATASET = "{demo_sized}"'), "README.md", "exec"), scope)
    assert "error" in capsys.readouterr().out
    assert scope["error"] < 0.5  # tracked from the true start over 20 frames
