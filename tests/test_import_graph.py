"""The import graph points one way: the library layers never import the application layers.

Library: ``kinematics``, ``tasks``, ``resolvers``, ``simulation``, ``collision``, ``parallel``, ``robots``,
``errors``. Application: ``config`` (YAML), ``cli``, ``reporting`` (files, figures), ``viewer``, ``peers``, ``sweep``.
Every import is checked, module level and lazy (function-level) alike, from the source's syntax tree.

``KNOWN`` lists the upward arrows that remain until the layout item of issue 10 lands (``robots/`` dissolved into
tasks/, kinematics/, cli/ and examples/; the plant's option record moved out of ``config``). The test fails on any
arrow not listed — and on a listed one that has gone, so the list can only shrink.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "redundik"
LIBRARY = ["kinematics", "tasks", "resolvers", "simulation", "collision", "parallel"]
APPLICATION = ("config", "cli", "reporting", "viewer", "peers", "sweep")

KNOWN = {
    ("simulation/mujoco_plant.py", "redundik.config.schema"),  # PlantSpec: the plant's options record
    ("simulation/mujoco_plant.py", "redundik.peers.mujoco_model"),  # the URDF → MuJoCo builder
    ("simulation/plant.py", "redundik.config.loader"),
    ("simulation/plant.py", "redundik.config.schema"),
}


def _upward_imports() -> set[tuple[str, str]]:
    upper = tuple(f"redundik.{name}" for name in APPLICATION)
    found = set()
    files = [SRC / "errors.py"] + [p for pkg in LIBRARY for p in sorted((SRC / pkg).rglob("*.py"))]
    for path in files:
        rel = path.relative_to(SRC).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            for name in names:
                if name == "redundik" or any(name == u or name.startswith(u + ".") for u in upper):
                    if name != "redundik":
                        found.add((rel, name))
    return found


def test_no_new_upward_import() -> None:
    new = sorted(_upward_imports() - KNOWN)
    assert not new, f"library modules importing the application layer: {new}"


def test_the_known_list_only_shrinks() -> None:
    gone = sorted(KNOWN - _upward_imports())
    assert not gone, f"these upward imports are gone: remove them from KNOWN: {gone}"
