"""The resolver benchmark (``benchmarks/bench``, in the checkout, not the wheel) in a tiny mode: schema, coverage of
every method on every robot kind, finite numbers, honest statuses, the PlaCo worker when a PlaCo interpreter exists.

No timing assertions (speed is reported by ``benchmarks/compare_resolvers.py``, never asserted).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from benchmarks.bench import (
    BATCH_METHODS,
    KNOWN_ROBOTS,
    METHODS,
    QUICK_ROBOTS,
    BenchConfig,
    BenchResult,
    CaseResult,
    markdown,
    ratio_lines,
    readme_table,
    run_benchmark,
    summarise,
    write_all,
)
from benchmarks.bench.harness import SCENARIOS as ALL_SCENARIOS
from benchmarks.bench.placo_peer import PlacoRunner, find_placo_python
from benchmarks.bench.runners import RedundikRunner, Runner
from benchmarks.bench.scenarios import SCENARIOS

import redundik as rk
from redundik.cli.main import main as cli_main
from redundik.errors import ConfigError
from redundik.peers import available
from redundik.resolvers.pinv import PinvResolver

REQUIRED = {
    "robot": str,
    "method": str,
    "backend": str,
    "median_us": float,
    "p90_us": float,
    "max_task_error": float,
    "limit_violations": int,
    "status": str,
}
PEERS_INSTALLED = available("mink") and available("mujoco") and available("pink")
ROOT = Path(__file__).resolve().parents[1]


TINY_ROBOTS = (
    "panda_circle", "panda_teleop", "panda_user_task", "panda_custom_task", "talos", "talos_teleop", "snake10",
    "panda_batch1000", "panda_shelf",
)  # fmt: skip
#: The default suite never depends on PlaCo (its own interpreter): the tiny run leaves it out.
TINY_METHODS = tuple(m for m in METHODS if m != "placo")


@pytest.fixture(scope="module")
def tiny():
    config = BenchConfig(
        robots=TINY_ROBOTS, methods=TINY_METHODS, steps=20, warmup=5, chunk=7, profile_steps=10,
        peer_backends=("daqp",), batch_steps=2, batch_problems=40,
    )  # fmt: skip
    return config, run_benchmark(config, log=lambda msg: None)


def test_every_method_runs_on_every_robot(tiny) -> None:
    _, result = tiny
    peers = {"mink", "pink"} if PEERS_INSTALLED else set()
    expected = {
        "panda_circle": {"pinv", "feedback", "wqp", "hqp"} | peers,
        "panda_teleop": {"pinv", "feedback", "wqp", "hqp"} | peers,  # the peers re-targeted every tick too
        "panda_user_task": {"pinv", "feedback", "wqp", "hqp"},  # its peers are panda_circle's (same task set)
        "panda_custom_task": {"pinv", "feedback", "wqp", "hqp"},  # no peer runs the user's own task
        "talos": {"pinv", "feedback", "wqp", "hqp"} | peers,
        "talos_teleop": {"pinv", "feedback", "wqp", "hqp"} | peers,
        "snake10": {"pinv", "wqp", "hqp"},
        "panda_batch1000": set(BATCH_METHODS),
        "panda_shelf": {"wqp"} | peers,
    }
    for robot, methods in expected.items():
        ran = {c.method for c in result.cases if c.robot == robot}
        assert ran == methods, (robot, ran, result.skipped)
    for robot in ("panda_circle", "talos"):
        qp = {c.backend for c in result.cases if c.robot == robot and c.method == "wqp"}
        assert len(qp) >= 2 and "osqp" in qp  # every installed backend, osqp at least among them
        assert sum(c.default_backend for c in result.cases if c.robot == robot and c.method == "wqp") == 1
    assert len([c for c in result.cases if c.robot == "snake10" and c.method == "wqp"]) == 1  # default backend only


def test_records_are_complete_and_finite(tiny) -> None:
    config, result = tiny
    for c in result.cases:
        if c.method in BATCH_METHODS:
            assert c.steps == (2 + config.batch_steps) * config.batch_problems  # warm-up + timed calls
            assert c.problems_per_s is not None and c.problems_per_s > 0
            assert c.extra["problems"] == config.batch_problems
            continue
        assert c.steps == config.warmup + config.steps  # round-robin ran every case to the end
        for key in ("median_us", "p90_us", "max_task_error", "mean_task_error", "max_violation", "subtask_final"):
            assert math.isfinite(getattr(c, key)), (c, key)
        assert c.median_us > 0 and c.p90_us >= c.median_us
        assert c.limit_violations >= 0
        if c.method not in ("mink", "pink"):
            assert c.failures == 0, c.first_failure  # redundik never raises in a loop
            assert c.stages_us is not None and set(c.stages_us) >= {"kinematics", "tasks", "build", "solve"}
        if c.method in ("wqp", "hqp"):
            assert c.limit_violations == 0, c  # the QP resolvers keep the limits


def test_batch_cases_agree_with_the_loop_and_shelf_reports_distances(tiny) -> None:
    _, result = tiny
    for method in ("wqp_batch", "pinv_batch", "wqp_steps", "pinv_steps"):
        (c,) = result.find("panda_batch1000", method)
        assert c.extra["loop_agreement"] <= 1e-9 and c.status == "ok", c.status
    (shelf,) = result.find("panda_shelf", "wqp")
    assert shelf.extra["min_collision_distance"] >= 0.0 and shelf.status == "ok", shelf.status
    names = {t["target"] for t in result.targets()}
    assert {"talos: wqp ≤ 1 × PlaCo", "snake: wqp growth exponent ≤ 1.3"} <= names
    assert any("batch ≥ 10 ×" in n for n in names)
    assert all(t["met"] is None for t in result.targets() if "PlaCo" in t["target"])  # not measured here


def test_json_schema_and_reports(tiny, tmp_path: Path) -> None:
    _, result = tiny
    paths = write_all(result, tmp_path / "out", "pytest", tmp_path / "summary.json")
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert doc == json.loads(paths["json"].read_text())
    assert doc["cases"]
    for case in doc["cases"]:
        for key, typ in REQUIRED.items():
            assert isinstance(case[key], typ), (key, case)
        assert case["status"] == "ok" or case["status"].startswith("failed: "), case["status"]
        assert case["method"] in METHODS
        assert case["robot"] in KNOWN_ROBOTS
        assert ("problems_per_s" in case) == (case["method"] in BATCH_METHODS)
    assert {t["target"] for t in doc["targets"]} and all("met" in t for t in doc["targets"])
    if PEERS_INSTALLED:
        assert doc["ratios"] and all(r["ratio"] > 0 for r in doc["ratios"] if r["ratio"] is not None)
    assert paths["plot"].stat().st_size > 1000
    md = markdown(result)
    assert md.count("\n| ") >= len(result.cases) and "Targets" in md


def test_cli_bench_explains_that_the_benchmark_runs_from_a_checkout(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["bench", "--quick", "--json", "x.json"]) == 5  # the CLI's "not installed" code
    err = capsys.readouterr().err
    assert "not part of the installed package" in err and "python benchmarks/compare_resolvers.py" in err


def test_the_harness_is_not_in_the_wheel() -> None:
    assert importlib.util.find_spec("redundik.peers.bench") is None
    assert not (ROOT / "src" / "redundik" / "peers" / "bench").exists()


def test_unknown_robot_or_method_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"unknown robots \['icub'\]"):
        BenchConfig(robots=("icub",)).check()
    with pytest.raises(ConfigError, match="methods"):
        BenchConfig(methods=("ik",)).check()


def _script():
    spec = importlib.util.spec_from_file_location("compare_resolvers", ROOT / "benchmarks" / "compare_resolvers.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["compare_resolvers"] = module
    spec.loader.exec_module(module)
    return module


def test_script_quick_smoke(tmp_path: Path) -> None:
    """``--quick`` (cut to a few steps, PlaCo left out): the quick robots, the JSON keys, honest statuses."""
    module = _script()
    methods = [m for m in METHODS if m != "placo"]
    args = ["--quick", "--steps", "5", "--batch-steps", "1", "--methods", *methods, "--out", str(tmp_path),
            "--json", str(tmp_path / "quick.json"), "--cold-start", "off"]  # fmt: skip
    assert module.main(args) == 0
    doc = json.loads((tmp_path / "quick.json").read_text())
    assert {c["robot"] for c in doc["cases"]} == set(QUICK_ROBOTS) - {"cold_start"}  # cold_start: not cases
    assert doc["cold_start"] == []  # --cold-start off
    for case in doc["cases"]:
        assert set(REQUIRED) <= set(case)
        assert case["status"] == "ok" or case["status"].startswith("failed: ")
    batch = {c["method"]: c for c in doc["cases"] if c["robot"] == "panda_batch1000"}
    assert set(batch) == set(BATCH_METHODS) and all(c["problems_per_s"] > 0 for c in batch.values())
    ik = doc["meta"]["ik_convergence"]  # rk.solve_ik on reachable poses, 200 per robot under --quick
    ours = [r for r in ik["rows"] if r["solver"] == "redundik solve_ik"]
    assert {r["robot"] for r in ours} == {"panda", "ur5", "xarm7"} and all(r["n"] == 200 for r in ours)
    assert all(r["limit_violations"] == 0 for r in ik["rows"])
    assert module.main(["--robots", "icub", "--out", str(tmp_path)]) == 2


PLACO_PYTHON, _PLACO_WHY = find_placo_python()


@pytest.mark.peers
@pytest.mark.skipif(
    PLACO_PYTHON is None and not os.environ.get("REDUNDIK_REQUIRE_PLACO"),
    reason="no PlaCo interpreter (.venv-placo or $REDUNDIK_PLACO_PYTHON); CI sets one and REDUNDIK_REQUIRE_PLACO=1",
)
def test_placo_worker_protocol_matches_wqp() -> None:
    """The PlaCo worker over its pipes, chunk by chunk: per-step times, q's measured by the common ruler, and the
    same motion as redundik's wqp on the identical task set (its position-level tasks matched)."""
    assert PLACO_PYTHON is not None, f"REDUNDIK_REQUIRE_PLACO is set but no PlaCo interpreter was found: {_PLACO_WHY}"
    sc = SCENARIOS["panda_circle"]()
    placo = PlacoRunner(sc, PLACO_PYTHON)
    wqp = RedundikRunner(sc, "wqp", None, {})
    try:
        for _ in range(3):
            placo.run(20)
            wqp.run(20)
        case = summarise(placo)
        assert case.steps == 60 and case.status == "ok", case.status
        assert all(ns > 0 for ns in placo.record.step_ns)
        np.testing.assert_allclose(placo.q, wqp.q, atol=1e-3)
    finally:
        placo.close()


def test_actuated_posture_leaves_the_floating_base_free() -> None:
    sc = SCENARIOS["talos"]()
    robot = sc.robot()
    task = sc.actuated_posture_task()
    q = sc.q0.copy()
    q[:3] += 0.3  # move the base: no posture error
    q[10] += 0.1  # and one actuated joint
    robot.update(q)
    term = task.evaluate(robot, 0.0)
    assert type(task) is rk.PostureTask and task.priority == 0
    assert term.J.shape == (robot.nv - 6, robot.nv)
    assert np.all(term.J[:, :6] == 0.0)
    np.testing.assert_allclose(term.J @ robot.difference(q, sc.q0), term.error)  # J picks the actuated rows
    np.testing.assert_allclose(np.abs(term.error).max(), 0.1)


# ---------------------------------------------------------------------------------------------- what users run
REDUNDIK = ("pinv", "feedback", "wqp", "hqp")


def test_user_cases_record_their_path_and_compare_with_the_built_in(tiny) -> None:
    """Every redundik case records ``result.info["path"]`` and the members it ran interpreted (JSON and table); the
    user's own task is named; the teleop cases track (a target left unmoved would trail the circle by > 1 mm); each
    user case has its built-in ratio."""
    _, result = tiny
    for c in result.cases:
        doc = c.as_json()
        if c.method in REDUNDIK:
            assert isinstance(doc["path"], str) and doc["path"], c
            assert isinstance(doc["interpreted"], list)
        elif c.method in ("mink", "pink"):
            assert "path" not in doc
    for c in result.cases:
        if c.robot == "panda_custom_task":
            assert "elbow_side" in c.extra["interpreted"], c.extra
        if c.robot.endswith("_teleop"):
            assert c.status == "ok", (c.robot, c.method, c.status)
    builtin = {(r["robot"], r["method"]): r for r in result.ratios() if r["builtin"] is not None}
    for robot, base in (("panda_teleop", "panda_circle"), ("panda_user_task", "panda_circle"),
                        ("talos_teleop", "talos"), ("panda_custom_task", "panda_circle")):  # fmt: skip
        for method in ("pinv", "wqp", "hqp"):
            r = builtin[(robot, method)]
            assert r["builtin"] == base and r["ratio_builtin"] > 0
    assert all(r["ratio"] is None for r in result.ratios() if r["robot"] == "panda_custom_task")  # no peer runs it
    assert result.meta["custom_task_evaluate_us"] > 0  # the user task's own evaluate, for its target
    custom = [t for t in result.targets() if t["target"].startswith("panda_custom_task:")]
    assert len(custom) == 3 and all(t["value"] is not None for t in custom)
    md = markdown(result)
    assert "What users run" in md and "| path |" in md and "elbow_side" in md


def test_user_stacks_are_made_of_public_classes() -> None:
    """The stacks of the built-in and user cases hold the library's classes (and the user's own in the user
    cases); ``talos_actuated``'s posture is the library's too, on the actuated joints."""
    from benchmarks.user_cases import ElbowSide, MyFrameTask

    for key in ("panda_circle", "talos", "panda_teleop", "talos_teleop", "panda_user_task", "panda_custom_task"):
        sc = ALL_SCENARIOS[key]()
        for method in sc.stacks:
            robot = sc.robot()
            robot.update(sc.q0)
            stack = sc.stack(method, robot)
            for task in stack.tasks:
                assert type(task).__module__.startswith("redundik.") or type(task) in (MyFrameTask, ElbowSide)
            if method in ("wqp", "hqp"):
                assert any(type(t) is rk.PostureTask for t in stack.tasks), (key, method)
            frames = [t for t in stack.tasks if isinstance(t, rk.FrameTask)]
            assert all(isinstance(t.trajectory, rk.Circle) != sc.teleop for t in frames), (key, method)
            assert all(type(t) is (MyFrameTask if key == "panda_user_task" else rk.FrameTask) for t in frames)
            assert any(type(t) is ElbowSide for t in stack.tasks) == (key == "panda_custom_task")
    sc = ALL_SCENARIOS["talos_actuated"]()
    assert any(type(t) is rk.PostureTask and t.joints == "actuated" for t in sc.stack("wqp", sc.robot()).tasks)


def test_teleop_moves_the_target_every_tick() -> None:
    from benchmarks.bench.runners import teleop_poses

    runner = RedundikRunner(ALL_SCENARIOS["panda_teleop"](), "wqp", None, {})
    for k in range(4):
        runner.run(1)
        dt = runner.scenario.dt
        want = teleop_poses(runner.metrics.tasks, (k + 1) * dt)[0]  # the pose of t + dt, t = k·dt
        held = runner.stack.tasks[0].target
        np.testing.assert_allclose(held.homogeneous, want.homogeneous, atol=1e-12)
    assert sum(runner.record.paths.values()) == 4


def test_cold_start_records_a_fresh_process_and_reports_a_broken_one(monkeypatch: pytest.MonkeyPatch) -> None:
    from benchmarks.bench import cold_start

    (rec,) = cold_start.run_cold_start(["pinv"], mode="warm", peers=())
    assert rec["status"] == "ok", rec
    assert rec["robot"] == "cold_start" and rec["method"] == "pinv"
    assert rec["warm_first_dq_s"] >= rec["warm_first_step_s"] > 0 and rec["warm_process_s"] > 0
    assert isinstance(rec["warm_path"], str)
    monkeypatch.setattr(cold_start, "SCRIPT", "raise SystemExit('no redundik here')")
    (bad,) = cold_start.run_cold_start(["wqp"], mode="warm", peers=())
    assert bad["status"].startswith("failed: warm: exit 1") and "no redundik here" in bad["status"]


def test_repeat_summarises_per_run_ratios(tmp_path: Path) -> None:
    """``--repeat``: per case the median and range of the ratios taken inside each run."""
    from dataclasses import replace

    from benchmarks.bench.repeat import repeat_markdown, summarise_runs

    sc = SCENARIOS["planar3r"]()
    ours = _run(RedundikRunner(sc, "pinv", None, {}))
    peer = _run(RedundikRunner(sc, "pinv", None, {}))
    peer.method, peer.backend = "pink", "daqp"
    meta = {"robots": ["planar3r"], "steps": 40, "warmup": 0, "chunk": 40, "python": "", "platform": "",
            "processor": "", "wall_time_s": 0.0}  # fmt: skip
    runs = [
        BenchResult([replace(ours, median_us=m), replace(peer, median_us=100.0)], [], meta) for m in (10.0, 30.0, 20.0)
    ]
    summary = summarise_runs(runs)
    (row,) = [c for c in summary["cases"] if c["method"] == "pinv"]
    assert row["ratio"] == {"median": 0.2, "min": 0.1, "max": 0.3, "n": 3}
    assert row["ok_runs"] == row["runs"] == 3
    assert "0.20 (0.10–0.30)" in repeat_markdown(summary)
    module = _script()
    args = ["--robots", "planar3r", "--methods", "pinv", "--steps", "3", "--repeat", "2", "--cold-start", "off",
            "--out", str(tmp_path), "--json", str(tmp_path / "rep.json")]  # fmt: skip
    assert module.main(args) == 0
    doc = json.loads((tmp_path / "rep.json").read_text())
    assert doc["runs"] == 2 and (tmp_path / "run2" / "compare_resolvers.md").is_file()
    assert module.main(["--repeat", "0", "--out", str(tmp_path)]) == 2


# ---------------------------------------------------------------------------------------------- honest statuses
class _FrozenRunner(Runner):
    """A deliberately broken method: the robot never moves."""

    method, backend = "pinv", "-"

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        return 1000, self.q.copy()


class _DriftingRunner(Runner):
    """A deliberately broken method: the robot moves, but away from the line (a constant joint drift)."""

    method, backend = "pinv", "-"

    def _step(self, t: float) -> tuple[int, np.ndarray]:
        return 1000, self.q + 2e-3


class _FlakyPinv(PinvResolver):
    """pinv that tracks, but reports a fallback on every third step."""

    def __init__(self) -> None:
        super().__init__()
        self.calls = 0

    def solve(self, robot, stack, t, dt):  # type: ignore[no-untyped-def]
        res = super().solve(robot, stack, t, dt)
        self.calls += 1
        if self.calls % 3 == 0:
            res.fallback = "test: deliberately reported fallback"
        return res


def _run(runner: Runner, steps: int = 40) -> CaseResult:
    runner.run(steps)
    return summarise(runner)


def test_a_frozen_robot_is_failed() -> None:
    case = _run(_FrozenRunner(SCENARIOS["planar3r"]()))
    assert case.frozen_steps == case.steps == 40
    assert not case.ok and case.status.startswith("failed: ")
    assert "robot does not move on 40 of 40 steps" in case.status
    assert case.as_json()["status"] == case.status


def test_a_large_tracking_error_is_failed() -> None:
    case = _run(_DriftingRunner(SCENARIOS["planar3r"]()))
    assert case.frozen_steps == 0 and case.fallback_steps == 0  # it moves and never falls back ...
    assert case.max_task_error > case.error_tolerance == 1e-3  # ... but misses the line
    assert "tracking error" in case.status and "tolerance 0.001" in case.status
    assert "does not move" not in case.status


def test_frequent_fallbacks_are_failed_and_a_clean_run_is_ok() -> None:
    sc = SCENARIOS["planar3r"]()
    clean = _run(RedundikRunner(sc, "pinv", None, {}))
    assert clean.status == "ok", clean.status  # the same method without the fallbacks tracks: ok
    flaky = RedundikRunner(sc, "pinv", None, {})
    flaky.resolver = _FlakyPinv()
    case = _run(flaky)
    assert case.fallback_steps == 13 and case.max_task_error <= 1e-3  # it tracks, yet falls back on 1/3 of steps
    assert "falls back or raises on 13 of 40 steps" in case.status
    assert "deliberately reported fallback" in case.status


def test_failed_cases_are_left_out_of_ratios_and_targets() -> None:
    sc = SCENARIOS["planar3r"]()
    good = _run(RedundikRunner(sc, "pinv", None, {}))
    frozen = _run(_FrozenRunner(sc))
    frozen.method = "wqp"
    peer = _run(RedundikRunner(sc, "pinv", None, {}))
    peer.method, peer.backend = "pink", "daqp"
    bad_peer = _run(_FrozenRunner(sc))
    bad_peer.method, bad_peer.backend, bad_peer.median_us = "mink", "daqp", 1e-3  # "fastest", but frozen
    meta = {"robots": ["planar3r"], "steps": 40, "warmup": 0, "chunk": 40, "python": "", "platform": "",
            "processor": "", "wall_time_s": 0.0}  # fmt: skip
    result = BenchResult([good, frozen, peer, bad_peer], [], meta)
    assert result.faster_peer("planar3r") is peer  # the frozen peer is not the reference
    ratios = result.ratios()
    assert [(r["method"], r["peer"]) for r in ratios] == [("pinv", "pink/daqp")]
    md = markdown(result)
    assert md.count("**FAILED**") == 2 and "robot does not move" in md
    table = readme_table(result)
    assert "| planar3r | wqp | - |" in table and "**FAILED**: tracking error" in table
    assert "robot does not move" in table.split("| planar3r | wqp | - |")[1].splitlines()[0]
    assert any("FAILED" in line for line in ratio_lines(result))
