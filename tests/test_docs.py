"""The docs stay in step with the code: every public name has a reference entry, every page is in the nav, every
tutorial includes a runnable example, and CI runs the README's test command verbatim. (The strict build itself,
``mkdocs build --strict``, runs in ``.ci/run`` with the docs extra.)"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

import redundik

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _nav_pages(node: object) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [page for item in node for page in _nav_pages(item)]
    if isinstance(node, dict):
        return [page for value in node.values() for page in _nav_pages(value)]
    return []


def _config() -> dict[str, object]:
    # mkdocs.yml uses no custom YAML tags, so the safe loader reads it
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    assert isinstance(config, dict)
    return config


def test_every_page_is_in_the_nav() -> None:
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md") if "_ext" not in p.parts}
    nav = set(_nav_pages(_config()["nav"]))
    assert pages - nav == set(), "pages missing from mkdocs.yml's nav"
    assert nav - pages == set(), "nav entries without a page"


def test_every_public_name_is_in_the_top_level_reference() -> None:
    page = (DOCS / "api" / "index.md").read_text(encoding="utf-8")
    linked = set(re.findall(r"\[`(\w+)`\]\[redundik\.[\w.]+\]", page))
    missing = sorted(set(redundik.__all__) - {"__version__"} - linked)
    assert missing == [], f"add these names to docs/api/index.md: {missing}"


def test_every_tutorial_includes_an_existing_example() -> None:
    tutorials = sorted((DOCS / "tutorials").glob("*.md"))
    assert len(tutorials) >= 4
    for page in tutorials:
        included = re.findall(r'--8<-- "(examples/[\w.]+\.py)"', page.read_text(encoding="utf-8"))
        assert included, f"{page.name} includes no example"
        for rel in included:
            assert (ROOT / rel).is_file(), f"{page.name}: {rel} does not exist"


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    commands = [line for line in readme.splitlines() if line.strip().endswith("pytest -q")]
    assert len(commands) == 1, commands
    assert commands[0].strip() in [line.strip() for line in ci.splitlines()]
    assert "mkdocs build --strict" in ci


API_PAGES = {
    "redundik.tasks": "tasks.md",
    "redundik.resolvers": "resolvers.md",
    "redundik.resolvers.qp": "qp.md",
    "redundik.kinematics": "kinematics.md",
    "redundik.simulation": "simulation.md",
    "redundik.parallel": "parallel.md",
    "redundik.ik": "ik.md",
    "redundik.control": "control.md",
}


def test_every_module_of_the_reference_has_its_notes() -> None:
    """A new module in a documented package gets an entry (its docstring carries the equations and references)."""
    missing = []
    for package, page in API_PAGES.items():
        text = (DOCS / "api" / page).read_text(encoding="utf-8")
        folder = ROOT / "src" / Path(*package.split("."))
        for module in sorted(folder.glob("*.py")):
            if not module.stem.startswith("_") and f"::: {package}.{module.stem}\n" not in text:
                missing.append(f"{package}.{module.stem} (docs/api/{page})")
        assert f"::: {package}\n" in text
    assert missing == [], f"add a '::: module' entry for: {missing}"
