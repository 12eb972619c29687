"""Every script in ``examples/`` runs to completion in a fresh interpreter and reports success."""

from __future__ import annotations

import functools
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))


@functools.cache
def _run(script: Path) -> subprocess.CompletedProcess[str]:
    """Run a script once per test session (from a scratch folder, so it cannot rely on the cwd)."""
    return subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=script.parent.parent / "tests"
    )


def test_there_are_examples() -> None:
    assert any(p.name == "control_loop.py" for p in EXAMPLES)


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script: Path) -> None:
    proc = _run(script)
    assert proc.returncode == 0, f"{script.name} failed:\n{proc.stdout}\n{proc.stderr}"
    assert "Traceback" not in proc.stderr
    assert proc.stdout.strip(), f"{script.name} printed nothing"


def test_control_loop_reports_tracking() -> None:
    proc = _run(next(p for p in EXAMPLES if p.name == "control_loop.py"))
    lines = proc.stdout.splitlines()
    assert lines[-1] == "OK", proc.stdout
    # the printed error table: 6 samples, every position error below 1 mm
    rows = [ln.split() for ln in lines if ln.strip() and ln.strip()[0].isdigit()]
    assert len(rows) == 6
    assert all(float(r[1]) < 1.0 for r in rows)
    assert any(float(r[1]) > 0.0 for r in rows)  # the loop really ran (Euler leaves a small error)
