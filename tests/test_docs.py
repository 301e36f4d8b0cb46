"""Every reference in README.md and docs/*.md resolves (docs/notes/ is a diary: not checked).

- a dotted name in backticks whose first part is a project package (`localize.filter.likelihood`,
  `localize.config.FilterConfig`): the module imports and each further part is an attribute;
  config key paths (`filter.likelihood.k`) start with no package and are not names;
- an import line of a ```python block (`from localize.localizer import Localizer`): the same;
- a relative link `[text](path#anchor)`: the file exists and a markdown file has the heading;
- a path in backticks under a project folder (`conf/filter/paper.yaml`, `models/generalist/`):
  it exists; paths under outputs/ are made at run time and placeholders (`<name>`) name none;
- a command `python -m X` (or `torchrun ... -m X`): X is found and runs (a package with a
  __main__ or a module with a main guard). The apps are not run.

Each failure is reported as file:line.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "datagen", "train", "localize", "benchmarks")
# A backticked path is the project's when it starts with one of these folders.
PROJECT_DIRS = (*PACKAGES, "conf", "models", "docs", "tests")
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# `localize.yaml`, `train.md`: a file name, not a module.
FILE_SUFFIXES = {"yaml", "yml", "py", "md", "json", "txt", "csv", "onnx", "npz", "png", "pt",
                 "ply", "toml", "rrd", "jpg"}

FENCE = re.compile(r"^\s*(```|~~~)")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
LINK = re.compile(r"!?\[[^\]]*\]\(\s*([^)\s]+)(?:\s+\"[^\"]*\")?\s*\)")
DOTTED = re.compile(rf"(?<![\w./$<{{-])((?:{'|'.join(PACKAGES)})(?:\.[A-Za-z_]\w*)+)(?![\w/])")
COMMAND = re.compile(r"\b(?:python3?|torchrun)(?:\s+--?[\w-]+(?:=\S+)?)*\s+-m\s+([A-Za-z_][\w.]*)")
IMPORT = re.compile(r"^\s*(?:from\s+([\w.]+)\s+import\s+\(?([\w\s,]+)\)?|import\s+([\w.,\s]+))\s*$")
PLACEHOLDER = re.compile(r"[<>$*]|\.\.\.")


@dataclass(frozen=True)
class Failure:
    where: str  # file:line
    what: str

    def __str__(self) -> str:
        return f"{self.where}: {self.what}"


# -- resolving ------------------------------------------------------------------------------------

def resolve_name(dotted: str) -> str | None:
    """None when `dotted` is an importable module plus a chain of attributes; else why not."""
    parts = dotted.split(".")
    try:
        obj = importlib.import_module(parts[0])
    except Exception as e:  # noqa: BLE001 (an import error anywhere is the finding)
        return f"cannot import {parts[0]}: {e!r}"
    name = parts[0]
    for part in parts[1:]:
        sub = f"{name}.{part}"
        if hasattr(obj, part):
            obj = getattr(obj, part)
        elif hasattr(obj, "__path__") and importlib.util.find_spec(sub) is not None:
            try:
                obj = importlib.import_module(sub)
            except Exception as e:  # noqa: BLE001
                return f"cannot import {sub}: {e!r}"
        else:
            return f"{name} has no {part!r}"
        name = sub
    return None


def resolve_command(module: str) -> str | None:
    """None when `python -m module` finds something to run; else why not."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError) as e:
        return f"{module} not found: {e!r}"
    if spec is None:
        return f"{module} not found"
    if spec.submodule_search_locations is not None:  # a package runs its __main__
        if importlib.util.find_spec(f"{module}.__main__") is None:
            return f"{module} is a package without __main__"
        return None
    if spec.origin and spec.origin.endswith(".py"):
        source = Path(spec.origin).read_text()
        if "__main__" not in source:
            return f"{module} has no main guard: nothing runs"
    return None


def expand_braces(path: str) -> list[str]:
    """`conf/x/{a,b}.yaml` -> [conf/x/a.yaml, conf/x/b.yaml]."""
    match = re.search(r"\{([^{}]*)\}", path)
    if not match:
        return [path]
    head, tail = path[: match.start()], path[match.end():]
    return [p for alt in match.group(1).split(",") for p in expand_braces(head + alt + tail)]


def project_paths(span: str) -> list[str]:
    """The paths in a code span that name a project file or folder."""
    found = []
    for token in span.split():
        token = token.split("=", 1)[-1].removesuffix("'s").strip(",;:.()[]'\"")  # key=path: path
        if "/" not in token or "://" in token or PLACEHOLDER.search(token):
            continue
        token = token.removeprefix("./")
        if token.split("/", 1)[0] in PROJECT_DIRS:
            found.extend(expand_braces(token))
    return found


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(text: str) -> set[str]:
    seen: dict[str, int] = {}
    out = set()
    for _, line, fenced in lines_of(text):
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if fenced or not match:
            continue
        base = slug(match.group(1))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def check_link(target: str, base: Path, own_text: str) -> str | None:
    if re.match(r"^[a-z][\w+.-]*:", target):  # https:, mailto:, ...
        return None
    path, _, anchor = target.partition("#")
    file = (base / path).resolve() if path else None
    if file is not None and not file.exists():
        return f"no file {path} (from {base.relative_to(ROOT) if base != ROOT else '.'}/)"
    if anchor and (file is None or file.suffix == ".md"):
        text = own_text if file is None else file.read_text()
        if anchor not in anchors(text):
            return f"no heading #{anchor} in {path or 'this file'}"
    return None


# -- scanning -------------------------------------------------------------------------------------

def lines_of(text: str):
    """(line number, line, inside a fenced block and its language or None)."""
    fence: str | None = None
    for number, line in enumerate(text.splitlines(), 1):
        match = FENCE.match(line)
        if match:
            if fence is None:
                fence = line.strip()[3:].strip() or "text"
                yield number, line, None
            else:
                fence = None
                yield number, line, None
            continue
        yield number, line, fence


def check_text(text: str, name: str, base: Path) -> list[Failure]:
    """Every broken reference of a markdown text; links resolve from `base`."""
    failures = []

    def fail(number: int, what: str) -> None:
        failures.append(Failure(f"{name}:{number}", what))

    for number, line, fence in lines_of(text):
        for module in COMMAND.findall(line):
            if (why := resolve_command(module)) is not None:
                fail(number, f"python -m {module}: {why}")
        if fence is not None:
            match = IMPORT.match(line) if fence == "python" else None
            if match:
                for dotted in imported_names(*match.groups()):
                    if (why := resolve_name(dotted)) is not None:
                        fail(number, f"import {dotted}: {why}")
            continue
        for _, span in CODE_SPAN.findall(line):
            commands = set(COMMAND.findall(span))  # checked as commands above
            for dotted in DOTTED.findall(span):
                if dotted.rsplit(".", 1)[-1] in FILE_SUFFIXES or dotted in commands:
                    continue
                if (why := resolve_name(dotted)) is not None:
                    fail(number, f"`{dotted}`: {why}")
            for path in project_paths(span):
                if not (ROOT / path).exists():
                    fail(number, f"`{path}`: no such file or folder")
        for target in LINK.findall(CODE_SPAN.sub("", line)):
            if (why := check_link(target, base, text)) is not None:
                fail(number, f"link ({target}): {why}")
    return failures


def imported_names(module: str | None, names: str | None, plain: str | None) -> list[str]:
    """The project names an import line binds: `from a.b import c, d` -> [a.b.c, a.b.d]."""
    if plain:
        dotted = [m.split(" as ")[0].strip() for m in plain.split(",")]
    else:
        dotted = [f"{module}.{n.split(' as ')[0].strip()}" for n in names.split(",") if n.strip()]
    return [d for d in dotted if d.split(".")[0] in PACKAGES]


# -- tests ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_references_resolve(doc: Path):
    failures = check_text(doc.read_text(), str(doc.relative_to(ROOT)), doc.parent)
    report = "\n".join(map(str, failures))
    assert not failures, f"{len(failures)} broken reference(s):\n{report}"


def test_checker_finds_broken_references():
    text = "\n".join([
        "# Title",
        "## A section (`x`)",
        "`localize.localizer.Localizer`, `localize.nonexistent`, `localize.config.NoSuchConfig`",
        "key paths are not names: `filter.likelihood.k`, `edges.cnn.snap_px`; `localize.yaml`",
        "[ok](outputs.md) [gone](no_such_page.md) [anchor](#a-section-x) [bad](#no-section)",
        "`conf/filter/paper.yaml`, `conf/filter/{paper,default}.yaml`, `conf/no_such.yaml`",
        "`outputs/datasets/x`, `conf/world/<name>.yaml`, `models/generalist/`, `models/nothing/`",
        "`python -m localize.recordings.export`, `python -m localize.no_such_tool`",
        "`python -m localize.config`",
        "```bash",
        "python -m datagen.importers FILE",
        "python -m train.nothing",
        "```",
        "```python",
        "from localize.localizer import Localizer, Nothing",
        "import core.poses, core.nothing",
        "```",
        "`not_a_link(x)` [x](no_such_page.md) inside no span: `[x](also_no_page.md)`",
    ])
    failures = check_text(text, "synthetic.md", ROOT / "docs")
    found = {(f.where, f.what.split(":")[0]) for f in failures}
    assert found == {
        ("synthetic.md:3", "`localize.nonexistent`"),
        ("synthetic.md:3", "`localize.config.NoSuchConfig`"),
        ("synthetic.md:5", "link (no_such_page.md)"),
        ("synthetic.md:5", "link (#no-section)"),
        ("synthetic.md:6", "`conf/no_such.yaml`"),
        ("synthetic.md:7", "`models/nothing/`"),
        ("synthetic.md:8", "python -m localize.no_such_tool"),
        ("synthetic.md:9", "python -m localize.config"),
        ("synthetic.md:12", "python -m train.nothing"),
        ("synthetic.md:15", "import localize.localizer.Nothing"),
        ("synthetic.md:16", "import core.nothing"),
        ("synthetic.md:18", "link (no_such_page.md)"),
    }, "\n".join(map(str, failures))
