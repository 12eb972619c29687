"""Every script in ``examples/`` runs to completion in a fresh interpreter and reports success."""

from __future__ import annotations

import functools
import json
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


@pytest.mark.parametrize("resolver", ["pinv", "wqp", "hqp", "feedback"])
def test_control_loop_tracks_under_every_resolver(resolver: str) -> None:
    """The README's loop, one stack, four resolvers: within 1 mm of the circle, no fallback, the robot moves."""
    script = next(p for p in EXAMPLES if p.name == "control_loop.py")
    proc = subprocess.run(
        [sys.executable, str(script), "--resolver", resolver, "--quiet"], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rec = json.loads(proc.stdout.strip().splitlines()[-1])
    assert set(rec) >= {"resolver", "steps", "max_position_error_m", "fallback_steps", "max_abs_dq", "moved"}
    assert rec["resolver"] == resolver and rec["steps"] == 2000
    assert 0.0 < rec["max_position_error_m"] < 1e-3  # Euler leaves a small, nonzero error
    assert rec["fallback_steps"] == 0 and rec["moved"] is True
    assert 0.1 < rec["max_abs_dq"] < 5.0  # it really moved, and boundedly
    assert rec["limit_violation"] == 0.0


def test_control_loop_steps_option() -> None:
    script = next(p for p in EXAMPLES if p.name == "control_loop.py")
    proc = subprocess.run([sys.executable, str(script), "--steps", "50", "--quiet"], capture_output=True, text=True)
    assert json.loads(proc.stdout.strip().splitlines()[-1])["steps"] == 50
    bad = subprocess.run([sys.executable, str(script), "--resolver", "nope"], capture_output=True, text=True)
    assert bad.returncode == 2 and "invalid choice" in bad.stderr
