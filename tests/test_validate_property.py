"""Property (issue 9): for generated mutants of the shipped files, ``validate`` fails ⇔ ``run`` fails before its
first step — whatever ``run`` would trip on at load time, ``validate`` reports first; and both only ever fail
with a one-line :class:`~redundik.errors.RedundikError`. Plus a fast subset of the fuzz of ``tests/fuzz_configs``.
"""

from __future__ import annotations

import random
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from redundik.config import load_task
from redundik.config.anyfile import validate_file
from redundik.config.runner import run_one
from redundik.errors import RedundikError, SimulationError
from redundik.reporting.outputs import write_outputs
from tests.fuzz_configs import Tally, check, fuzz, mutate, shipped_files

# the quick task files (the humanoid and dual-arm ones load slowly; the fuzz script covers them)
QUICK = [
    (k, p)
    for k, p in shipped_files()
    if p.stem in {"planar3r_line", "rpr_corner", "track7_posture", "exercise1_prrp", "planar3r", "stewart33", "delta"}
]


@settings(max_examples=40, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
@given(index=st.integers(0, len(QUICK) - 1), seed=st.integers(0, 2**31 - 1))
def test_validate_fails_iff_run_fails_before_its_first_step(index: int, seed: int) -> None:
    kind, source = QUICK[index]
    mutant = mutate(kind, source, random.Random(seed))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mutant.yaml"
        if isinstance(mutant.content, bytes):
            path.write_bytes(mutant.content)
        else:
            path.write_text(mutant.content, encoding="utf-8")
        try:
            validate_file(path)
            valid = True
        except RedundikError as exc:
            assert "\n" not in str(exc)
            valid = False
        if kind != "task":
            return
        try:  # what `run` does up to and including its first step
            plan = load_task(path)
        except RedundikError:
            assert not valid, f"run failed at load, validate passed: {mutant.what}"
            return
        assert valid, f"validate failed, run loaded: {mutant.what}"
        plan.steps = 1
        results = {}
        for name, run in plan.runs.items():
            try:
                results[name] = run_one(plan, run)
            except SimulationError:  # a run diverging at its first step is a run-time failure, not a load failure
                return
        write_outputs(plan, results, Path(tmp) / "out")


@pytest.mark.parametrize("seed", [1, 2])
def test_fuzz_subset_finds_nothing(seed: int, tmp_path: Path) -> None:
    tally: Tally = fuzz(24, seed, tmp_path)
    assert tally.calls >= 24
    assert dict(tally.problems) == {}, tally.examples


def test_fuzz_counts_what_it_should(tmp_path: Path) -> None:
    """The fuzz harness itself can fail: a traceback in a command is counted."""
    from tests import fuzz_configs

    mutant = fuzz_configs.Mutant("task", "x", "not even YAML", "a: [")
    tally = Tally()
    check(mutant, tmp_path, tally)
    assert tally.clean_errors == 2 and not tally.problems
    assert fuzz_configs._has_null({"a": [1, None]}) and not fuzz_configs._has_null({"a": [1.0]})
