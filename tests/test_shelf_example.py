"""The shipped ``panda_shelf`` example keeps the joint limits and (where it avoids) the post, and the run table shows
limit violations and the smallest clearance of every run (issue 32, item 10)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rich.console import Console

from tests.conftest import TASKS

SHELF = TASKS / "panda_shelf.yaml"
AVOIDING = ("pinv_repulsive", "wqp", "hqp")


@pytest.fixture(scope="module")
def shelf() -> tuple[Any, dict[str, Any]]:
    """(plan, results) of every run of tasks/panda_shelf.yaml."""
    from redundik.config import load_task
    from redundik.config.runner import run_task

    plan = load_task(SHELF)
    return plan, run_task(plan)


def _table_text(summary: dict[str, Any]) -> str:
    from redundik.reporting.terminal import summary_table

    console = Console(record=True, width=240)
    console.print(summary_table(summary))
    return console.export_text()


def test_every_run_keeps_the_joint_limits(shelf: tuple[Any, dict[str, Any]]) -> None:
    plan, results = shelf
    robot = plan.robot.model
    assert set(results) == {"no_avoidance", *AVOIDING}
    for name, r in results.items():
        assert r.summary["limit_violations"] == 0, name
        assert r.summary["max_limit_violation"] == 0.0, name
        q = r.log.q
        assert np.all(q >= robot.lower_limits - 1e-9) and np.all(q <= robot.upper_limits + 1e-9), name
    fingers = results["pinv_repulsive"].log.q[:, 7:]
    assert np.all((fingers >= 0.0) & (fingers <= 0.04))  # was ±0.5 m on all 300 steps


def test_avoiding_runs_keep_clear_of_the_post(shelf: tuple[Any, dict[str, Any]]) -> None:
    _, results = shelf
    for name in AVOIDING:
        s = results[name].summary
        assert s["min_collision_distance"] > 0.005, name  # > 5 mm: clear of every obstacle and of itself
        assert s["penetrating_samples"] == 0, name
        assert s["final_task_error"] < 1e-3, name  # and the hand still reaches the bay
    # the baseline without avoidance is the example's point: its forearm goes through the post
    base = results["no_avoidance"].summary
    assert base["min_collision_distance"] < -0.03 and base["closest_pair"] == "panda_link5|post"


def test_table_has_limit_and_clearance_columns(shelf: tuple[Any, dict[str, Any]]) -> None:
    from redundik.config.runner import task_summary

    plan, results = shelf
    summary = task_summary(plan, results)
    text = _table_text(summary)
    assert "limit viol." in text and "min clear. [m]" in text
    for name, r in summary["runs"].items():
        row = next(line for line in text.splitlines() if f" {name} " in line)
        assert f"{r['min_collision_distance']:.3g}" in row, (name, row)
    assert "panda_link5|post" in text  # the closest pair under the distance


def test_table_shows_the_steps_and_the_largest_violation() -> None:
    run = {
        "resolver": "pinv",
        "max_task_error": 0.003,
        "final_task_error": 2.8e-5,
        "subtasks": {},
        "step_time_us": {"median": 133.0},
        "limit_violations": 300,
        "max_limit_violation": 0.5518,
        "min_collision_distance": -0.0583,
        "closest_pair": "panda_link5|post",
    }
    quiet = dict(run, limit_violations=0, max_limit_violation=0.0)
    no_world = {k: v for k, v in quiet.items() if k not in ("min_collision_distance", "closest_pair")}
    summary = {"task": "t", "robot": "r", "dt": 0.01, "steps": 300, "length_unit": "m"}
    text = _table_text(summary | {"runs": {"bad": run, "good": quiet, "plain": no_world}})
    lines = text.splitlines()
    bad = next(i for i, line in enumerate(lines) if " bad " in line)
    assert re.search(r"\b300\b", lines[bad]) and "-0.0583" in lines[bad]
    assert "max 0.55" in lines[bad + 1]
    plain = next(line for line in lines if " plain " in line)
    assert "–" in plain  # a run without a world: no clearance, said so
    # no run with a clearance: no clearance column at all
    assert "min clear." not in _table_text(summary | {"runs": {"plain": no_world}})


def test_cli_run_prints_the_columns(tmp_path: Path, cli: Callable[..., tuple[int, str, str]]) -> None:
    code, out, err = cli("run", SHELF, "--out", tmp_path, "--runs", "no_avoidance,pinv_repulsive", "--no-figures")
    assert code == 0, err
    assert "limit viol." in out and "min clear. [m]" in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    for r in summary["runs"].values():
        assert f"{r['min_collision_distance']:.3g}" in out
