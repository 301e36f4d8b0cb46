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
                "diagnostic_msgs", "std_msgs", "builtin_interfaces"}
ROS_FILES = {"localize/ros2/node.py", "localize/ros2/listen.py", "localize/ros2/__main__.py",
             "localize/ros2/play.py"}


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
