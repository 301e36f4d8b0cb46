"""The stages import only downward: core <- datagen, core <- train, core <- localize,
everything but tests <- benchmarks.

Walks every .py file of the five packages with ``ast`` (imports at module level and inside
functions, ``import x`` and ``from x import y``) and fails naming file:line of each import of a
package the file's own may not use.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The project's top-level packages.
PACKAGES = {"core", "datagen", "train", "localize", "benchmarks", "tests"}
#: Package -> the project's packages its files may import.
ALLOWED = {
    "core": {"core"},
    "datagen": {"core", "datagen"},
    "train": {"core", "train"},
    "localize": {"core", "localize"},
    "benchmarks": {"core", "datagen", "train", "localize", "benchmarks"},
}


def imported_modules(tree: ast.AST, package: str, file: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``tree`` (relative ones resolved
    against ``file``'s package path)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = file.relative_to(ROOT).with_suffix("").parts[:-node.level]
                base = ".".join(parts)
                module = f"{base}.{node.module}" if node.module else base
            else:
                module = node.module or ""
            out.append((node.lineno, module))
    return out


def violations() -> list[str]:
    """``file:line imports module`` of every upward or sideways import."""
    found = []
    for package, allowed in ALLOWED.items():
        for file in sorted((ROOT / package).rglob("*.py")):
            rel = file.relative_to(ROOT).as_posix()
            tree = ast.parse(file.read_text(encoding="utf-8"), filename=rel)
            for line, module in imported_modules(tree, package, file):
                top = module.split(".")[0]
                if top in PACKAGES and top not in allowed:
                    found.append(f"{rel}:{line} imports {module} ({package} may import "
                                 f"{', '.join(sorted(allowed))} only)")
    return found


#: The ROS 2 client library and the message packages: only the live node's rclpy side imports
#: them (the core, the stages and the node's pure parts run without the ``ros`` extra).
ROS_PACKAGES = {"rclpy", "sensor_msgs", "geometry_msgs", "nav_msgs", "std_srvs",
                "diagnostic_msgs", "std_msgs", "builtin_interfaces", "visualization_msgs",
                "lifecycle_msgs", "rcl_interfaces"}
ROS_FILES = {"localize/ros2/node.py", "localize/ros2/listen.py", "localize/ros2/__main__.py",
             "localize/ros2/play.py", "localize/ros2/world_display.py"}


def ros_imports() -> list[str]:
    """``file:line imports module`` of every import of a ROS package outside ``ROS_FILES``."""
    found = []
    for package in ALLOWED:
        for file in sorted((ROOT / package).rglob("*.py")):
            rel = file.relative_to(ROOT).as_posix()
            tree = ast.parse(file.read_text(encoding="utf-8"), filename=rel)
            for line, module in imported_modules(tree, package, file):
                if module.split(".")[0] in ROS_PACKAGES and rel not in ROS_FILES:
                    found.append(f"{rel}:{line} imports {module}")
    return found


def test_only_the_live_node_imports_rclpy() -> None:
    bad = ros_imports()
    assert not bad, ("ROS imports outside " + ", ".join(sorted(ROS_FILES)) + ":\n"
                     + "\n".join(bad))


def test_stages_import_only_downward() -> None:
    bad = violations()
    assert not bad, "upward or sideways imports:\n" + "\n".join(bad)



def test_the_walk_sees_every_kind_of_import() -> None:
    """Module-level, function-level, ``import x`` and relative ``from . import`` are all read."""
    code = ("import datagen.rendering.render\n"
            "def f():\n    from train.deploy.predict import OnnxSegmenter\n"
            "from .frontend import sources\n")
    file = ROOT / "localize" / "example.py"
    got = imported_modules(ast.parse(code), "localize", file)
    assert sorted(got) == [(1, "datagen.rendering.render"), (3, "train.deploy.predict"),
                           (4, "localize.frontend")]


# --------------------------------------------------------------------------- the layout

#: Most modules (``__init__`` and ``__main__`` included) a package's own folder may hold: a
#: larger one is split into sub-packages by concern.
MAX_MODULES = 12
#: What the live loop may not import: the offline runner and the bag reader.
LIVE_FORBIDDEN = ("localize.offline", "localize.recordings.bag")


def module_graph() -> dict[str, set[str]]:
    """Project module -> the project modules it imports (module level and in functions)."""
    files = {}
    for package in ("core", "datagen", "train", "localize"):
        for file in (ROOT / package).rglob("*.py"):
            parts = file.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            files[name] = file
    graph = {}
    for name, file in files.items():
        deps = set()
        tree = ast.parse(file.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                wanted = [f"{node.module}.{a.name}" for a in node.names]
                wanted = [w if w in files else node.module for w in wanted]
            elif isinstance(node, ast.Import):
                wanted = [a.name for a in node.names]
            else:
                continue
            for w in wanted:
                while w and w not in files:
                    w = w.rpartition(".")[0]
                if w and w != name:
                    deps.add(w)
        graph[name] = deps
    return graph


def cycles_inside_packages(graph: dict[str, set[str]]) -> list[list[str]]:
    """Import cycles among the modules of one package (a module and its siblings)."""
    found = []
    for start in graph:
        parent = start.rpartition(".")[0]
        stack = [(start, [start])]
        while stack:
            node, path = stack.pop()
            for dep in graph[node]:
                if dep.rpartition(".")[0] != parent:
                    continue
                if dep == start:
                    found.append(path)
                elif dep not in path and dep > start:  # each cycle once, from its least module
                    stack.append((dep, path + [dep]))
    return found


def test_no_import_cycle_inside_a_package() -> None:
    bad = cycles_inside_packages(module_graph())
    assert not bad, "import cycles:\n" + "\n".join(" -> ".join(c + c[:1]) for c in bad)


def test_the_cycle_check_finds_a_cycle() -> None:
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "q.x": {"p.a"}}
    assert cycles_inside_packages(graph) == [["p.a", "p.b", "p.c"]]


def test_package_roots_are_small() -> None:
    big = [f"{d.relative_to(ROOT)}: {n} modules" for d in (ROOT / p for p in ALLOWED)
           for d in [d, *d.rglob("*")] if (d / "__init__.py").is_file()
           and (n := len(list(d.glob("*.py")))) > MAX_MODULES]
    assert not big, f"more than {MAX_MODULES} modules in a package's folder:\n" + "\n".join(big)


def test_no_public_class_name_defined_twice() -> None:
    where: dict[str, list[str]] = {}
    for package in ("core", "datagen", "train", "localize"):
        for file in sorted((ROOT / package).rglob("*.py")):
            for node in ast.parse(file.read_text(encoding="utf-8")).body:
                if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                    where.setdefault(node.name, []).append(file.relative_to(ROOT).as_posix())
    twice = {name: files for name, files in where.items() if len(files) > 1}
    assert not twice, f"class names defined more than once: {twice}"


def test_the_live_loop_is_free_of_the_offline_runner_and_the_bag_reader() -> None:
    graph = module_graph()
    reach, todo = set(), ["localize.live.loop"]
    while todo:
        for dep in graph[todo.pop()] - reach:
            reach.add(dep)
            todo.append(dep)
    bad = sorted(m for m in reach if m.startswith(LIVE_FORBIDDEN))
    assert not bad, f"localize.live.loop reaches {bad}"
