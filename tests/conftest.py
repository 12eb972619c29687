"""Shared fixtures: the repository's task files and a way to write modified copies of them into tmp_path."""

from __future__ import annotations

import copy
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import settings

# Property tests are reproducible: the same examples on every machine and every run (no example database, no
# wall-clock randomness), so CI cannot meet a failure the developers never saw, nor hide one they did.
settings.register_profile("redundik", derandomize=True, database=None)
settings.load_profile("redundik")

# The suite checks the compiled path from a resolver's first step: its kernels compile in the test's thread
# (redundik._coldstart's background compilation is tested in tests/test_cold_start.py, in subprocesses).
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

ROOT = Path(__file__).resolve().parents[1]
TASKS = ROOT / "tasks"
CONFIGS = ROOT / "configs"
PLANAR_TASK = TASKS / "planar3r_line.yaml"


def load_yaml(path: Path) -> dict[str, Any]:
    """A YAML file as a mapping."""
    with path.open(encoding="utf-8") as fh:
        return yaml.safe_load(fh)


@pytest.fixture
def planar_task_data() -> dict[str, Any]:
    """The content of ``tasks/planar3r_line.yaml`` with its robot path made absolute (usable from tmp_path)."""
    data = load_yaml(PLANAR_TASK)
    data["robot"] = str((PLANAR_TASK.parent / data["robot"]).resolve())
    return copy.deepcopy(data)


@pytest.fixture
def write_yaml(tmp_path: Path) -> Callable[..., Path]:
    """``write_yaml(data, name="task.yaml")`` dumps a mapping (or raw text) into tmp_path and returns the path."""

    def write(data: dict[str, Any] | str, name: str = "task.yaml") -> Path:
        path = tmp_path / name
        text = data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
        path.write_text(text, encoding="utf-8")
        return path

    return write


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Callable[..., tuple[int, str, str]]:
    """``cli("run", FILE, ...)`` runs the ``redundik`` command in-process: (exit code, stdout, stderr)."""
    from redundik.cli.main import main

    def invoke(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        code = main([str(a) for a in args])
        out, err = capsys.readouterr()
        return code, out, err

    return invoke
