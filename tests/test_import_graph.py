"""The import graph points one way: the library layers never import the application layers.

Library: ``kinematics``, ``tasks``, ``resolvers``, ``simulation``, ``collision``, ``parallel``, ``ik`` and the top-level
modules (``errors``, ``shipped``, ...). Application: ``config`` (YAML), ``cli``, ``reporting`` (files, figures),
``viewer``, ``peers``, ``sweep``, and ``__main__`` (``python -m redundik``, the command itself). Every import is
checked, module level, lazy (function-level) and ``TYPE_CHECKING`` alike, from the source's syntax tree; every
subpackage must be in one of the two lists, so a new one is checked too.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "redundik"
LIBRARY = ("kinematics", "tasks", "resolvers", "simulation", "collision", "parallel", "ik", "control")
APPLICATION = ("config", "cli", "reporting", "viewer", "peers", "sweep")
ENTRY_POINTS = ("__main__.py",)


def _imported(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return names


def _upward_imports() -> set[tuple[str, str]]:
    upper = tuple(f"redundik.{name}" for name in APPLICATION)
    top = [p for p in sorted(SRC.glob("*.py")) if p.name not in ENTRY_POINTS]
    files = top + [p for pkg in LIBRARY for p in sorted((SRC / pkg).rglob("*.py"))]
    return {
        (path.relative_to(SRC).as_posix(), name)
        for path in files
        for name in _imported(path)
        if any(name == u or name.startswith(u + ".") for u in upper)
    }


def test_every_subpackage_is_classified() -> None:
    packages = {p.parent.name for p in SRC.glob("*/__init__.py")}
    assert packages == set(LIBRARY) | set(APPLICATION), "add the new package to LIBRARY or APPLICATION"


def test_no_upward_import() -> None:
    found = sorted(_upward_imports())
    assert not found, f"library modules importing the application layer: {found}"


def test_the_check_sees_lazy_imports(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from redundik.config.loader import load_task\n    import redundik.cli\n")
    assert _imported(module) == {"redundik.config.loader", "redundik.cli"}
