"""Every public name exists, the console entry point runs, and the core never imports the CLI/YAML/plots."""

from __future__ import annotations

import importlib
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import redundik

PACKAGES = ["redundik", "redundik.kinematics", "redundik.tasks", "redundik.resolvers", "redundik.simulation"]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_is_defined(package: str) -> None:
    mod = importlib.import_module(package)
    for name in mod.__all__:
        assert hasattr(mod, name), f"{package}.__all__ lists {name!r} but it is not defined"


def test_core_does_not_import_cli_yaml_or_plotting() -> None:
    code = (
        "import sys, redundik, redundik.kinematics, redundik.tasks, redundik.resolvers, redundik.simulation\n"
        "bad = [m for m in ('redundik.cli', 'redundik.config', 'redundik.reporting', 'matplotlib', 'yaml',"
        " 'typer') if m in sys.modules]\n"
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"the core imported: {out.stdout.strip()}"


def _tool(name: str) -> str | None:
    """A console script of this environment (next to the interpreter), else from PATH."""
    local = Path(sys.executable).parent / name
    return str(local) if local.exists() else shutil.which(name)


def test_console_entry_point_runs() -> None:
    exe = _tool("redundik")
    cmd = [exe] if exe else [sys.executable, "-m", "redundik.cli.main"]
    out = subprocess.run([*cmd, "--help"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "run" in out.stdout


def test_version_is_a_string() -> None:
    assert isinstance(redundik.__version__, str)


def test_lint_is_clean() -> None:
    ruff = _tool("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (it is part of the test extra)")
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run(
        [ruff, "check", "src", "tests", "benchmarks", "examples"], cwd=root, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stdout[-3000:]
    out = subprocess.run(
        [ruff, "format", "--check", "src", "tests", "benchmarks", "examples"], cwd=root, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stdout[-3000:]  # ruff is pinned in the test extra, so this cannot drift


def test_usage_error_is_one_message_not_a_traceback() -> None:
    exe = _tool("redundik")
    cmd = [exe] if exe else [sys.executable, "-m", "redundik.cli.main"]
    out = subprocess.run([*cmd, "run"], capture_output=True, text=True)  # missing FILE
    assert out.returncode == 2
    assert "Traceback" not in out.stderr and "Missing argument" in out.stderr
