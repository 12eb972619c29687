"""Alarms that mean something (issue 33, item 6): ``result.fallback`` only when the answer is not what the stack asked
beyond its documented relaxations; the relaxations themselves (an ``hqp`` level contradicted by those above, bound
subtasks ``wqp`` drops from an infeasible QP, a QP a documented retry solved) in ``result.relaxed``."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.errors import SolverError
from redundik.resolvers.qp import QPProblem, QPSolution, available_backends
from redundik.resolvers.qp.daqp_native import NativeDaqp
from redundik.resolvers.qp.problem import infeasible

BACKENDS = available_backends()
TIP = "panda_hand_tcp"
DT = 0.01


@pytest.fixture(scope="module")
def panda() -> rk.RobotModel:
    return rk.load_example_robot("panda")


def conflict_problem(
    robot: rk.RobotModel, rng: np.random.Generator, depth: int
) -> tuple[np.ndarray, rk.TaskStack, dict[str, int]]:
    """A random ``depth``-level (3 or 4) hqp problem: a tip position task on level 0, a random joint bound on each of
    levels 1 and 2 (keep a joint inside or outside a random radius of a random value, at a random rate: often beyond
    what the velocity limits, or the level above, allow), and a posture on level 3 when ``depth`` is 4."""
    arm = robot.joint_names[:7]
    lo, hi = robot.lower_limits, robot.upper_limits
    q = rng.uniform(lo, hi)
    robot.update(rng.uniform(lo, hi))
    task = rk.FrameTask(TIP, axes="position", gain=float(rng.uniform(1.0, 50.0)), name="tip")
    task.set_target(robot.frame_position(TIP))
    subs: list[rk.Subtask] = []
    levels: dict[str, int] = {}
    for k in (1, 2):
        j = str(rng.choice(arm))
        i = robot.joint_names.index(j)
        centre, radius = float(rng.uniform(lo[i], hi[i])), float(rng.uniform(0.05, 0.5) * (hi[i] - lo[i]))
        key = "lower" if rng.random() < 0.5 else "upper"
        pot = rk.JointValue(j, centre)
        subs.append(rk.BoundSubtask(pot, **{key: radius**2}, rate=float(rng.uniform(0.0, 20.0)), name=f"b{k}"))
        levels[f"b{k}"] = k
    tasks: list[rk.Task] = [task]
    if depth == 4:
        tasks.append(rk.PostureTask(gain=1.0, name="posture"))
    return q, rk.TaskStack(tasks, subs), levels


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("backend", BACKENDS)
def test_conflicting_inequality_levels_are_relaxed_not_an_alarm(panda: rk.RobotModel, backend: str, fuse: bool) -> None:
    """Random 3–4-level problems whose bound levels often cannot all be met: every step with a contradicted level
    names its members in ``relaxed`` and raises no ``fallback`` (before: ``fallback`` on every such step)."""
    rng = np.random.default_rng(33)
    contradicted = 0
    paths = set()
    for _ in range(40):
        q, stack, levels = conflict_problem(panda, rng, int(rng.integers(3, 5)))
        res = rk.make_resolver("hqp", backend=backend, levels=levels)
        res.fuse = fuse
        panda.update(q)
        stack.reset(panda)
        step = res.step(panda, stack, q, 0.0, DT)
        paths.add(step.info["path"])
        assert step.fallback is None, step.fallback
        members = {s.name for s in stack.subtasks}
        if step.info.get("contradicted_levels"):
            contradicted += 1
            assert set(step.relaxed) & members, step.relaxed
        retried = {r for r in step.relaxed if r.endswith("(backend retried)")}
        assert set(step.relaxed) - retried <= members, step.relaxed
        assert bool(retried) == ("retries" in step.info)
    assert contradicted >= 20  # the problems do conflict (the assertions above are not vacuous)
    assert paths == {"compiled" if fuse else "interpreted"}


# ------------------------------------------------------------------------------------------- forced backend failures
def far_target_problem(robot: rk.RobotModel, bounds: str) -> tuple[np.ndarray, rk.TaskStack]:
    """The Panda asked to move its tip 0.5 m in one step: the velocity limits bind, so a QP is posed. ``bounds``:
    ``"inactive"``, a bound subtask the answer keeps anyway (joint 1 kept within 2 rad of 0); ``"binding"``, two
    that hold q̇₁ within ±1e-3 rad/s (joint 1 at 0.009 rad kept within 0.01 rad of 0 and of 0.018, at rate 1 /s):
    feasible, and binding; ``""``: none."""
    q = np.array([0.009, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8, 0.02, 0.02])
    robot.update(q)
    task = rk.FrameTask(TIP, axes="position", gain=0.5 / DT, name="tip")
    task.set_target(robot.frame_position(TIP) + np.array([0.3, 0.3, -0.3]))
    subs: list[rk.Subtask] = []
    if bounds == "inactive":
        subs.append(rk.BoundSubtask(rk.JointValue("panda_joint1", 0.0), upper=2.0**2, name="keep_j1"))
    elif bounds == "binding":
        for name, centre in (("j1_hi", 0.0), ("j1_lo", 0.018)):
            subs.append(rk.BoundSubtask(rk.JointValue("panda_joint1", centre), upper=0.01**2, rate=1.0, name=name))
    return q, rk.TaskStack([task], subs)


@contextmanager
def failing(res: Any, failures: int | None, mode: str = "raise") -> Iterator[list[int]]:
    """The resolver's backend made to fail on its next ``failures`` QPs (``None``: on all), by raising or by
    returning ``None``; daqp's compiled calls (the one-call cascade and the stacked form) are switched off, so that
    every QP reaches the Python ``solve`` — where a QP they do not solve goes too. Yields [calls, failures made]."""
    backend = res.backend
    solve = backend.solve
    seen = [0, 0]

    def broken(problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution | None:
        seen[0] += 1
        if failures is None or seen[1] < failures:
            seen[1] += 1
            if mode == "raise":
                raise SolverError(f"forced failure on {problem.label}", problem)
            return None
        return solve(problem, warm)

    backend.solve = broken
    backend.solve_stacked = lambda *args, **kwargs: None
    original = NativeDaqp.for_backend
    NativeDaqp.for_backend = classmethod(lambda cls, *args: None)  # type: ignore[method-assign, assignment]
    try:
        yield seen
    finally:
        NativeDaqp.for_backend = original  # type: ignore[method-assign]
        del backend.solve, backend.solve_stacked


ROUTES = [("wqp", True, ""), ("wqp", False, ""), ("wqp", False, "inactive"), ("wqp", False, "binding"),
          ("hqp", True, ""), ("hqp", False, ""), ("hqp", False, "inactive"), ("hqp", False, "binding")]  # fmt: skip


def _route(robot: rk.RobotModel, resolver: str, fuse: bool, bounds: str, backend: str) -> tuple[Any, Callable]:
    q, stack = far_target_problem(robot, bounds)
    res = rk.make_resolver(resolver, backend=backend)
    res.fuse = fuse
    stack.reset(robot)
    return res, lambda: res.step(robot, stack, q, 0.0, DT)


@pytest.mark.parametrize("mode", ["raise", "none"])
@pytest.mark.parametrize(("resolver", "fuse", "bounds"), ROUTES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_backend_that_keeps_failing_is_a_fallback_on_every_route(
    panda: rk.RobotModel, backend: str, resolver: str, fuse: bool, bounds: str, mode: str
) -> None:
    """Every QP of the step fails (raised, or no answer): the step falls back, says so, and q̇ stays finite."""
    res, step = _route(panda, resolver, fuse, bounds, backend)
    with failing(res, None, mode) as seen:
        out = step()
    assert seen[1] >= 1  # the route reached the backend
    assert out.fallback is not None and "closed form" in out.fallback, out.fallback
    assert np.all(np.isfinite(out.dq))


@pytest.mark.parametrize(("resolver", "fuse", "bounds"), ROUTES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_backend_failure_a_retry_rescued_is_counted(
    panda: rk.RobotModel, backend: str, resolver: str, fuse: bool, bounds: str
) -> None:
    """The backend fails once. ``hqp`` solves the level again with a stronger regulariser (documented), and ``wqp``
    solves the QP without its bound rows, whose optimum keeps them when they were not binding: counted in
    ``relaxed`` and told in ``info["retries"]``, not an alarm (before: ``hqp``'s only in
    ``info["regularization_retry"]``, read with the diagnostics; ``wqp``'s a fallback). ``wqp`` without bound
    subtasks falls back to the closed form, and with binding ones relaxes a QP that was feasible: both an alarm."""
    res, step = _route(panda, resolver, fuse, bounds, backend)
    with failing(res, 1) as seen:
        out = step()
    assert seen[1] == 1 and seen[0] >= (1 if resolver == "wqp" and not bounds else 2)  # (then solved again)
    if resolver == "hqp" or bounds == "inactive":
        assert out.fallback is None, out.fallback
        assert f"{'hqp level 0' if resolver == 'hqp' else 'wqp'} (backend retried)" in out.relaxed, out.relaxed
        assert any("forced failure" in note for note in out.info["retries"])  # type: ignore[attr-defined]
    else:
        assert out.fallback is not None
        assert ("feasible QP the backend failed on" in out.fallback) == (bounds == "binding"), out.fallback
        assert out.relaxed == (("j1_hi", "j1_lo") if bounds else ())


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_a_backends_own_retry_is_counted(panda: rk.RobotModel, resolver: str) -> None:
    """A backend whose answer came from a retry of its own (``QPSolution.retried``) is counted in ``relaxed``."""
    res, step = _route(panda, resolver, False, False, "quadprog")
    solve = res.backend.solve

    def retried(problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        sol = solve(problem, warm)
        sol.retried = "first attempt stalled (forced)"
        return sol

    res.backend.solve = retried
    out = step()
    assert out.fallback is None
    assert any(r.endswith("(backend retried)") for r in out.relaxed), out.relaxed
    assert any("stalled (forced)" in note for note in out.info["retries"])  # type: ignore[attr-defined]


def test_an_infeasible_wqp_is_relaxed_without_an_alarm(panda: rk.RobotModel) -> None:
    """A bound subtask the velocity limits cannot meet (joint 1 to leave a 2.5 rad radius of where it is, at once):
    the QP is infeasible (a linear program says so), the bound dropped is named in ``relaxed``, no fallback."""
    q = np.zeros(9)
    stack = rk.TaskStack(
        [rk.FrameTask(TIP, axes="position", gain=1.0, name="tip")],
        [rk.BoundSubtask(rk.JointValue("panda_joint1", 0.0), lower=2.5**2, rate=0.0, name="leave")],
    )
    panda.update(q)
    stack.reset(panda)
    out = rk.make_resolver("wqp").step(panda, stack, q, 0.0, DT)
    assert out.relaxed == ("leave",) and out.fallback is None, (out.relaxed, out.fallback)


def test_infeasible_reads_the_constraints() -> None:
    """``infeasible``: x₀ + x₁ ≤ −2 against |x| ≤ 0.5 has no point; with ≤ −0.5 it has (a row at a time, in closed
    form)."""
    P, c = np.eye(2), np.zeros(2)
    none = np.zeros((0, 2))
    box = (-0.5 * np.ones(2), 0.5 * np.ones(2))
    assert infeasible(QPProblem(P, c, np.array([[1.0, 1.0]]), np.array([-2.0]), none, np.zeros(0), *box))
    assert not infeasible(QPProblem(P, c, np.array([[1.0, 1.0]]), np.array([-0.5]), none, np.zeros(0), *box))
    # two rows the box meets one by one (x₀ ≥ 0.4, x₀ ≤ 0.3): only together infeasible (the linear program)
    G = np.array([[-1.0, 0.0], [1.0, 0.0]])
    assert infeasible(QPProblem(P, c, G, np.array([-0.4, 0.3]), none, np.zeros(0), *box))
    assert not infeasible(QPProblem(P, c, G, np.array([-0.2, 0.3]), none, np.zeros(0), *box))


# ------------------------------------------------------------------------------------------------------- stress
def test_no_fallback_in_a_stress_where_no_backend_failed(panda: rk.RobotModel) -> None:
    """A few thousand steps of random target jumps and conflicting bound levels on the Panda, ``wqp`` and ``hqp``,
    every backend: a step whose backend never failed (a refused QP that was infeasible is no failure) reports no
    fallback; the relaxations are there, and counted in ``relaxed``."""
    rng = np.random.default_rng(7)
    steps = relaxed = 0
    for resolver in ("wqp", "hqp"):
        for backend in BACKENDS:
            res = rk.make_resolver(resolver, backend=backend, limits={"acceleration": 20.0})
            failed = [False]
            solve = res.backend.solve

            def watched(
                problem: QPProblem, warm: np.ndarray | None = None, solve: Any = solve, failed: list[bool] = failed
            ) -> QPSolution:
                try:
                    return solve(problem, warm)
                except SolverError:
                    failed[0] |= not infeasible(problem)
                    raise

            res.backend.solve = watched
            for _episode in range(6):
                q, stack, levels = conflict_problem(panda, rng, int(rng.integers(3, 5)))
                if resolver == "hqp":
                    res.levels = levels
                res.reset()
                panda.update(q)
                stack.reset(panda)
                for k in range(50):
                    if k % 10 == 0:  # a target jump
                        panda.update(rng.uniform(panda.lower_limits, panda.upper_limits))
                        stack.tasks[0].set_target(panda.frame_position(TIP))
                    failed[0] = False
                    out = res.step(panda, stack, q, k * DT, DT)
                    steps += 1
                    relaxed += bool(out.relaxed)
                    if not failed[0]:
                        assert out.fallback is None, (resolver, backend, k, out.fallback)
                    q = panda.integrate(q, out.dq, DT)
    assert steps == 2 * len(BACKENDS) * 300
    assert relaxed > steps // 20  # the stress does relax (the no-fallback assertion is not vacuous)


# ------------------------------------------------------------------------------------------------ run summary, CSV
def test_run_summary_and_csv_count_fallbacks_and_relaxations(
    planar_task_data: dict[str, Any], write_yaml: Callable[..., Path], tmp_path: Path
) -> None:
    """A task file whose bound sin²θ3 ≥ 1.5 can never hold: the ``hqp`` and ``wqp`` runs relax it at every step.
    ``summary.json`` counts ``relaxed_steps`` (and names ``relaxed_members``) beside ``fallbacks``, the CSV has a
    ``fallback`` and a ``relaxed`` column per step, and the two agree."""
    import csv
    import json

    from redundik.cli.main import main

    data = planar_task_data
    data["steps"] = 40
    data["runs"] = {
        name: {"resolver": name, "subtasks": {"sin2_q3": {"kind": "bound", "lower": 1.5}}} for name in ("hqp", "wqp")
    }
    out = tmp_path / "out"
    assert main(["run", str(write_yaml(data)), "--out", str(out), "--quiet", "--no-figures"]) == 0
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    for name in ("hqp", "wqp"):
        run = summary["runs"][name]
        assert (run["fallbacks"], run["relaxed_steps"], run["relaxed_members"]) == (0, 40, ["sin2_q3"]), run
        with (out / f"{name}.csv").open(encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        assert [r["relaxed"] for r in rows] == ["1"] * 40 + [""]
        assert [r["fallback"] for r in rows] == ["0"] * 40 + [""]


def test_a_batch_counts_a_backend_retry(panda: rk.RobotModel) -> None:
    """The batch form of ``wqp`` (``BatchResolver``) counts a QP a backend retry solved in its ``relaxed``, per
    problem, as the single step does; problems that solved no QP relax nothing."""
    from redundik.resolvers.batch import BatchResolver

    resolver = rk.make_resolver("wqp", backend="quadprog")
    solve = resolver.backend.solve

    def retried(problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        sol = solve(problem, warm)
        sol.retried = "first attempt stalled (forced)"
        return sol

    resolver.backend.solve = retried
    batch = BatchResolver(resolver, panda, TIP, axes="position", gain=0.5 / DT, posture_gain=0.0)
    rng = np.random.default_rng(3)
    q = np.array([rng.uniform(panda.lower_limits, panda.upper_limits) for _ in range(8)])
    targets = np.repeat(np.eye(4)[None], 8, axis=0)
    targets[:, :3, 3] = [0.3, 0.3, 0.5]  # (a position task reads only the translation)
    out = batch.solve(q, targets, DT)
    assert out.qp.any()  # the limits bind on some problems (the assertion below is not vacuous)
    assert out.relaxed == [("wqp (backend retried)",) if used else () for used in out.qp]
    assert out.fallback == [None] * 8
