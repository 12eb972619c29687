"""The import graph points one way: the application layers sit on the library, and inside the library every import
points down its layers, with no cycle.

Library: ``kinematics``, ``tasks``, ``resolvers``, ``simulation``, ``collision``, ``parallel``, ``ik`` and the top-level
modules (``errors``, ``shipped``, ...). Application: ``config`` (YAML), ``cli``, ``reporting`` (files, figures),
``viewer``, ``peers``, ``sweep``, and ``__main__`` (``python -m redundik``, the command itself). Every import is
checked, module level, lazy (function-level) and ``TYPE_CHECKING`` alike, from the source's syntax tree; every
subpackage must be in one of the two lists, so a new one is checked too.

Inside the library (:data:`CORE_RANK`): the base modules (errors, names, the kernel cache) < ``kinematics`` and
``parallel`` < ``tasks`` < ``collision`` < ``resolvers`` < ``simulation``, ``ik`` and ``control`` < the package's facade
(``redundik/__init__.py``, ``warmup``). A module may import its own package and anything ranked lower; so the tasks
and the collision layer never import a resolver (the compiled kernels they share live in ``kinematics`` and
``tasks``), and no two core packages import each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "redundik"
LIBRARY = ("kinematics", "tasks", "resolvers", "simulation", "collision", "parallel", "ik", "control")
APPLICATION = ("config", "cli", "reporting", "viewer", "peers", "sweep")
ENTRY_POINTS = ("__main__.py",)

#: The library's layers, lowest first: a module imports only its own unit or units of a lower rank. A unit is a
#: subpackage (``tasks``) or a top-level module (``errors``).
CORE_RANK: dict[str, int] = {
    "errors": 0,
    "_names": 0,
    "_version": 0,
    "_kernel_cache": 0,
    "_coldstart": 1,
    "_extras": 1,
    "_optional": 1,
    "shipped": 1,
    "kinematics": 2,
    "parallel": 2,
    "tasks": 3,
    "collision": 4,
    "resolvers": 5,
    "simulation": 6,
    "ik": 6,
    "__init__": 7,
}
#: Modules that are one unit with another: ``warmup`` is the facade's ``warm_up`` (it drives the public API through
#: ``import redundik``, and ``redundik/__init__.py`` exports it), ``warmup_collision`` its collision part; ``control``
#: is the facade's fixed-rate loop (it warms the resolvers up with ``warm_up`` before the first tick).
SAME_UNIT = {"warmup": "__init__", "warmup_collision": "__init__", "control": "__init__"}


def _resolve(module: str | None, level: int, path: Path) -> str | None:
    """The absolute name of an ``ImportFrom``'s module (a relative import resolved against ``path``)."""
    if level == 0:
        return module
    package = path.relative_to(SRC.parent).with_suffix("").parts[:-1]
    if path.name == "__init__.py":
        package = path.relative_to(SRC.parent).parts[:-1]
    base = list(package[: len(package) - (level - 1)])
    return ".".join(base + ([module] if module else []))


def _imported(path: Path) -> set[str]:
    """Every module ``path`` imports; ``from redundik.x import y`` counts as ``redundik.x.y`` when y is a module."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            module = _resolve(node.module, node.level, path)
            if not module:
                continue
            folder = SRC.parent.joinpath(*module.split("."))
            for alias in node.names:
                submodule = (folder / f"{alias.name}.py").exists() or (folder / alias.name / "__init__.py").exists()
                # ``from redundik import errors`` imports the module ``redundik.errors``; a name that is not a module
                # (``from redundik import solve``) is an import of the package ``redundik`` itself
                names.add(f"{module}.{alias.name}" if module.startswith("redundik") and submodule else module)
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


def _unit_of_module(name: str) -> str | None:
    """The core unit a ``redundik...`` module name belongs to (``import redundik``: the facade, ``__init__``;
    ``None``: not redundik)."""
    parts = name.split(".")
    if parts[0] != "redundik":
        return None
    unit = parts[1] if len(parts) > 1 else "__init__"
    return SAME_UNIT.get(unit, unit)


def _core_edges(root: Path = SRC) -> dict[tuple[str, str], list[str]]:
    """Unit → unit imports inside the library (``file:module`` witnesses per edge); ``import redundik`` counts as
    an import of the facade (``__init__``)."""
    edges: dict[tuple[str, str], list[str]] = {}
    files = [p for p in sorted(root.rglob("*.py")) if _unit_of_file_in(p, root) in CORE_RANK]
    for path in files:
        src = _unit_of_file_in(path, root)
        for name in _imported(path):
            dst = _unit_of_module(name)
            if dst is None or dst == src or dst not in CORE_RANK:
                continue
            edges.setdefault((src, dst), []).append(f"{path.relative_to(root).as_posix()}: {name}")
    return edges


def _unit_of_file_in(path: Path, root: Path) -> str:
    rel = path.relative_to(root)
    unit = rel.parts[0] if len(rel.parts) > 1 else rel.stem
    return SAME_UNIT.get(unit, unit)


def _cycles(edges: set[tuple[str, str]]) -> list[list[str]]:
    """The strongly connected components with more than one unit (Tarjan)."""
    graph: dict[str, list[str]] = {}
    for a, b in edges:
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_every_subpackage_is_classified() -> None:
    packages = {p.parent.name for p in SRC.glob("*/__init__.py")}
    assert packages == set(LIBRARY) | set(APPLICATION), "add the new package to LIBRARY or APPLICATION"


def test_every_library_unit_has_a_rank() -> None:
    top = {p.stem for p in SRC.glob("*.py") if p.name not in ENTRY_POINTS}
    assert set(LIBRARY) | top == set(CORE_RANK) | set(SAME_UNIT), (
        "give the new module or package its layer in CORE_RANK"
    )


def test_no_upward_import() -> None:
    found = sorted(_upward_imports())
    assert not found, f"library modules importing the application layer: {found}"


def test_core_imports_point_down() -> None:
    upward = {edge: where for edge, where in _core_edges().items() if CORE_RANK[edge[1]] >= CORE_RANK[edge[0]]}
    assert not upward, f"core imports of a layer not below the importer's (CORE_RANK): {upward}"


def test_tasks_and_collision_never_import_the_resolvers() -> None:
    edges = _core_edges()
    found = {e: w for e, w in edges.items() if e[0] in ("tasks", "collision", "kinematics") and e[1] == "resolvers"}
    assert not found, found


def test_no_cycle_among_core_packages() -> None:
    cycles = _cycles(set(_core_edges()))
    assert not cycles, f"import cycles among the core packages: {cycles}"


def test_the_check_sees_lazy_imports(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from redundik.config.loader import load_task\n    import redundik.cli\n")
    assert _imported(module) == {"redundik.config.loader", "redundik.cli"}


def test_the_check_sees_an_upward_core_import_and_a_cycle(tmp_path: Path) -> None:
    """A lazy ``from redundik.resolvers import fused_kernels`` in a task module (the import this test removed) is an
    upward edge; with the resolvers importing the tasks it is a cycle."""
    (tmp_path / "tasks").mkdir()
    (tmp_path / "resolvers").mkdir()
    (tmp_path / "tasks" / "trajectory.py").write_text("def f():\n    from redundik.resolvers import fused_kernels\n")
    (tmp_path / "resolvers" / "fused.py").write_text("from redundik.tasks.base import Task\n")
    edges = _core_edges(tmp_path)
    assert set(edges) == {("tasks", "resolvers"), ("resolvers", "tasks")}
    assert _cycles(set(edges)) == [["resolvers", "tasks"]]
    assert _cycles({("resolvers", "tasks")}) == []
