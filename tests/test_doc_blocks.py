"""Every ```python block of README.md and docs/ runs as written, on its own (issue 32, item 12).

Each block runs in a fresh interpreter, in an empty scratch folder (so it cannot lean on the checkout's files or on
another block), with a timeout; two run at a time. A block may be kept from running only by an explicit
``<!-- no-run: REASON -->`` comment on the line before it; the reasons are listed and the list is kept tiny. A
block that only includes an example (``--8<-- "examples/NAME.py"``) is that script, which
``tests/test_examples.py`` runs: it is checked to exist, not run twice.
"""

from __future__ import annotations

import functools
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Pages another part of the project owns, with why they are not checked here (keep empty when possible).
NOT_CHECKED: dict[str, str] = {}
#: Most blocks that may say ``<!-- no-run: ... -->``.
MAX_NO_RUN = 2
TIMEOUT = 300.0  # [s] per block (a first numba compile of the kernels takes 30-60 s on a loaded machine)
FENCE = re.compile(r"^(?P<indent>[ \t]*)```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$", re.M | re.S)
NO_RUN = re.compile(r"<!--\s*no-run:\s*(?P<reason>[^>]*?)\s*-->\s*$")
INCLUDE = re.compile(r'^--8<-- "(?P<path>[^"]+)"$')


@dataclass(frozen=True)
class Block:
    """One ```python block: where it is, its code, and why it does not run (``None``: it runs)."""

    page: str
    line: int
    code: str
    no_run: str | None

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"

    @property
    def includes(self) -> list[str]:
        """The files of a block made only of ``--8<--`` include lines, else ``[]``."""
        lines = [line.strip() for line in self.code.splitlines() if line.strip()]
        found = [INCLUDE.match(line) for line in lines]
        return [m.group("path") for m in found if m] if lines and all(found) else []


def _pages() -> list[Path]:
    docs = [p for p in sorted((ROOT / "docs").rglob("*.md")) if "_ext" not in p.parts]
    return [ROOT / "README.md", *docs]


def _blocks() -> list[Block]:
    blocks = []
    for page in _pages():
        rel = page.relative_to(ROOT).as_posix()
        if rel in NOT_CHECKED:
            continue
        text = page.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            if m.group("lang") != "python":
                continue
            before = text[: m.start()].rstrip("\n").splitlines()
            marker = NO_RUN.search(before[-1]) if before else None
            indent = m.group("indent")
            code = "".join(line.removeprefix(indent) for line in m.group("body").splitlines(keepends=True))
            line = text.count("\n", 0, m.start()) + 1
            blocks.append(Block(rel, line, code, marker.group("reason") if marker else None))
    return blocks


BLOCKS = _blocks()
RUNNABLE = [b for b in BLOCKS if b.no_run is None and not b.includes]


def _run(block: Block) -> subprocess.CompletedProcess[str]:
    env = dict(
        os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])
    )
    with tempfile.TemporaryDirectory(prefix="redundik-doc-") as tmp:
        try:
            return subprocess.run(
                [sys.executable, "-c", block.code], capture_output=True, text=True, timeout=TIMEOUT, cwd=tmp, env=env
            )
        except subprocess.TimeoutExpired as exc:
            return subprocess.CompletedProcess(exc.cmd, -1, "", f"timed out after {TIMEOUT:g} s")


@functools.cache
def _results() -> dict[str, subprocess.CompletedProcess[str]]:
    """Every runnable block, two at a time (the first test to ask starts them all)."""
    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(zip((b.id for b in RUNNABLE), pool.map(_run, RUNNABLE), strict=True))


def test_the_docs_have_python_blocks() -> None:
    assert len(RUNNABLE) >= 10
    assert {b.page for b in RUNNABLE} >= {"README.md", "docs/from-pink-and-mink.md", "docs/tutorials/urdf-robot.md"}


@pytest.mark.parametrize("block", RUNNABLE, ids=[b.id for b in RUNNABLE])
def test_block_runs_as_written(block: Block) -> None:
    proc = _results()[block.id]
    assert proc.returncode == 0, f"{block.id} failed:\n{block.code}\n--- stderr ---\n{proc.stderr[-3000:]}"


def test_included_examples_exist_and_are_run_by_test_examples() -> None:
    included = [path for b in BLOCKS for path in b.includes]
    assert included
    for path in included:
        assert path.startswith("examples/") and path.endswith(".py") and (ROOT / path).is_file(), path


def test_blocks_kept_from_running_are_few_and_say_why() -> None:
    skipped = [b for b in BLOCKS if b.no_run is not None]
    assert len(skipped) <= MAX_NO_RUN, [b.id for b in skipped]
    assert all(len(b.no_run or "") >= 10 for b in skipped), [(b.id, b.no_run) for b in skipped]


def test_the_extractor_sees_what_mkdocs_sees() -> None:
    text = "x\n<!-- no-run: needs a browser window -->\n```python\nprint(1)\n```\n\n    ```python\n    a = 1\n    ```\n"
    found = list(FENCE.finditer(text))
    assert [m.group("lang") for m in found] == ["python", "python"]
    assert NO_RUN.search(text.splitlines()[1]).group("reason") == "needs a browser window"  # type: ignore[union-attr]
    assert Block("p", 1, '--8<-- "examples/a.py"\n', None).includes == ["examples/a.py"]
    assert Block("p", 1, 'import a\n--8<-- "examples/a.py"\n', None).includes == []
