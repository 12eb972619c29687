"""hqp's lean steps hand the constrained cascade rows that are already in the plan's buffers.

When the unconstrained cascade is infeasible, the lean steps (the fused step, and the step that gathers its rows)
pass the constrained cascade an ``HQPBuild`` marked ``filled``: the cascade then reads the buffers as the step
wrote them, without copying the rows in again (``_Plan.fill``), and it builds the StepRows only if something asks
for them. These tests check, on every such step of the benchmark's hqp cases and of a stack that is not fused,
that ``fill`` would write exactly what the buffers already hold. They also check that the cascade's QPs, solved
by daqp straight from the kernel's buffer (``Backend.solve_stacked``), give the same q̇ as the general backend call.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers import hqp_kernels as HK
from redundik.resolvers.qp import backends, daqp_native
from redundik.resolvers.qp.hqp import HierarchicalQPResolver, HQPBuild, _Plan
from redundik.resolvers.qp.hqp_result import FusedHqpResult


def _buffers(plan: _Plan) -> tuple[np.ndarray, ...]:
    L = plan.meta.shape[1] - 1
    ms, cs = int(plan.meta[0, L]), int(plan.meta[1, L])
    return (plan.meta.copy(), plan.A[:ms].copy(), plan.b[:ms].copy(), plan.w[:ms].copy(), plan.C[:cs].copy(),
            plan.d[:cs].copy())  # fmt: skip


def _watch_fill(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Before each constrained cascade of a ``filled`` build, fill the buffers again and require no change. The
    fused step's lean cascade (``_native_cascade``, which reads the same buffers) is switched off so that every
    constrained cascade goes through the template and is seen here; :func:`test_native_cascade_result_equals_the_
    template` holds the lean one to the template."""
    seen = {"filled": 0, "other": 0}
    original = HierarchicalQPResolver._qp_cascade
    monkeypatch.setattr(HierarchicalQPResolver, "_native_cascade", lambda self, *args: None)

    def checked(self: HierarchicalQPResolver, built: HQPBuild, diag: Any) -> Any:
        if built.filled:
            plan = self._plan_for(built.layout, built.n)
            before = _buffers(plan)
            plan.fill(built.rows)
            after = _buffers(plan)
            for a, b in zip(before, after, strict=True):
                np.testing.assert_array_equal(a, b)
            seen["filled"] += 1
        else:
            seen["other"] += 1
        return original(self, built, diag)

    monkeypatch.setattr(HierarchicalQPResolver, "_qp_cascade", checked)
    return seen


@pytest.mark.parametrize("scenario", ["panda_tight", "snake10", "talos"])
def test_fused_qp_steps_find_their_rows_in_the_buffers(monkeypatch: pytest.MonkeyPatch, scenario: str) -> None:
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    seen = _watch_fill(monkeypatch)
    runner = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    runner.run(400)
    assert seen["filled"] > 10, seen  # the case solves level QPs, and from the lean step's buffers
    assert runner.record.fallbacks == 0


def test_gathered_qp_steps_find_their_rows_in_the_buffers(monkeypatch: pytest.MonkeyPatch) -> None:
    """A target subtask keeps the stack from being fused: the step gathers its rows (``_Plan.gather``)."""
    seen = _watch_fill(monkeypatch)
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    lim = rk.JointLimits(velocity_limits=dict.fromkeys(robot.joint_names, 0.3))
    stack = rk.TaskStack(
        [rk.FrameTask("panda_hand", rk.Circle(radius=0.15, omega=3.0), axes="position", priority=0),
         rk.PostureTask(q.copy(), priority=2)],
        [rk.TargetSubtask(rk.JointValue("panda_joint4", -1.2), target=0.0, rate=5.0, priority=1)],
    )  # fmt: skip
    res = HierarchicalQPResolver(limits=lim)
    dt = 0.01
    for k in range(150):
        step = res.step(robot, stack, q, k * dt, dt)
        assert step.fallback is None, step.fallback
        q = robot.integrate(q, step.dq, dt)
    assert seen["filled"] > 10, seen


@pytest.mark.parametrize("scenario", ["panda_tight", "snake10", "snake40"])
def test_native_and_stacked_daqp_solves_equal_the_general_daqp_call(
    monkeypatch: pytest.MonkeyPatch, scenario: str
) -> None:
    """The same run three ways: daqp called from the compiled cascade (``daqp_native``), then with that off (the
    buffer handed to ``solve_stacked``), then with ``solve_stacked`` off too (QPProblem, row assembly): the same q̇
    at every step, bit for bit, the same QP and iteration counts."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    assert daqp_native.status().startswith("on"), daqp_native.status()
    calls = {"stacked": 0, "general": 0}
    stacked, general = backends.DaqpBackend.solve_stacked, backends.DaqpBackend.solve

    def counted_stacked(self: Any, *args: Any) -> Any:
        calls["stacked"] += 1
        return stacked(self, *args)

    def counted_general(self: Any, *args: Any, **kw: Any) -> Any:
        calls["general"] += 1
        return general(self, *args, **kw)

    monkeypatch.setattr(backends.DaqpBackend, "solve_stacked", counted_stacked)
    monkeypatch.setattr(backends.DaqpBackend, "solve", counted_general)

    joint_space = {"steps": 0}  # QP steps whose last level QP was posed in joint space (the complement mode)

    def run() -> tuple[np.ndarray, list[tuple[object, object]], dict[str, int]]:
        calls.update(stacked=0, general=0)
        joint_space["steps"] = 0
        runner = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
        dqs, counts = [], []
        res = runner.resolver
        for k in range(300):
            step = res.step(runner.robot, runner.stack, runner.q, k * runner.scenario.dt, runner.scenario.dt)
            dqs.append(step.dq.copy())
            counts.append((step.info["qp"], step.info["iterations"]))
            runner.q = runner.robot.integrate(runner.q, step.dq, runner.scenario.dt)
            cascade = res._plan._cascade if res._plan is not None else None
            if step.info["qp"] and cascade is not None and cascade[5][HK.ST_NEQ] > 0:
                joint_space["steps"] += 1
        return np.array(dqs), counts, dict(calls)

    native, native_counts, native_calls = run()
    solved = sum(int(c[0]) for c in native_counts)  # type: ignore[call-overload]
    assert solved > 10 and native_calls["stacked"] < solved / 10, (solved, native_calls)
    # the snake of 40 joints (nv ≥ complement_min_n) poses its level QPs in joint space: equalities reach each path
    assert (joint_space["steps"] > 10) == (scenario == "snake40"), joint_space
    monkeypatch.setattr(daqp_native, "enabled", False)
    buffered, buffered_counts, buffered_calls = run()
    assert buffered_calls["stacked"] >= solved
    monkeypatch.setattr(backends.DaqpBackend, "solve_stacked", lambda self, *args: None)
    assembled, assembled_counts, assembled_calls = run()
    assert assembled_calls["general"] >= solved
    np.testing.assert_array_equal(native, buffered)
    np.testing.assert_array_equal(native, assembled)
    assert native_counts == buffered_counts == assembled_counts


def test_native_daqp_is_off_for_an_unchecked_daqp_version(monkeypatch: pytest.MonkeyPatch) -> None:
    """Another daqp version than those whose struct layouts were read: no native call, and the reason said."""
    monkeypatch.setattr(daqp_native, "_decided", False)
    monkeypatch.setattr(daqp_native, "_entry", None)
    import importlib.metadata

    monkeypatch.setattr(importlib.metadata, "version", lambda name: "99.0")
    assert daqp_native.entry() == 0
    assert "daqp 99.0" in daqp_native.status() and "not checked" in daqp_native.status()
    monkeypatch.undo()
    monkeypatch.setattr(daqp_native, "_decided", False)
    assert daqp_native.entry() != 0  # decided again on this daqp: on


def test_fused_qp_step_diagnostics_read_late_are_those_of_their_step() -> None:
    """The rows of a fused QP step are built when first read: read after later steps, its diagnostics are the ones
    read at once in a twin run."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    now = RedundikRunner(SCENARIOS["snake10"](), "hqp", None, {})
    late = RedundikRunner(SCENARIOS["snake10"](), "hqp", None, {})
    dt = now.scenario.dt
    eager, held = [], []
    for k in range(200):
        a = now.resolver.step(now.robot, now.stack, now.q, k * dt, dt)
        b = late.resolver.step(late.robot, late.stack, late.q, k * dt, dt)
        if a.info["qp"]:
            eager.append((dict(a.info), a.fallback))
            held.append(b)
        now.q = now.robot.integrate(now.q, a.dq, dt)
        late.q = late.robot.integrate(late.q, b.dq, dt)
    assert len(held) > 10
    for (info, fallback), res in zip(eager, held, strict=True):
        assert dict(res.info) == info and res.fallback == fallback


def test_a_fused_qp_step_whose_backend_fails_reports_its_fallback(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fused QP step's result (terms built on read, the compiled task error) carries the template's fallback:
    every level QP failing, the step skips the level (or, at the top level, falls back to the damped closed form
    clipped to the limits) and says so."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    from redundik.errors import SolverError

    def failing(self: Any, problem: Any, warm: Any = None) -> Any:
        raise SolverError("refused for the test", problem)

    monkeypatch.setattr(daqp_native, "enabled", False)  # daqp is not called from the cascade, but through these:
    monkeypatch.setattr(backends.DaqpBackend, "solve_stacked", lambda self, *a: None)
    monkeypatch.setattr(backends.DaqpBackend, "solve", failing)
    runner = RedundikRunner(SCENARIOS["snake10"](), "hqp", None, {})
    res, robot, dt = runner.resolver, runner.robot, runner.scenario.dt
    box_checked = 0
    for k in range(200):
        step = res.step(robot, runner.stack, runner.q, k * dt, dt)
        if step.fallback is not None:
            # a failed top level: the closed form; a failed level below it: that level skipped (said which)
            closed = step.fallback.startswith("hqp failed, damped closed form clipped to the limits: ")
            assert closed or re.fullmatch(r"hqp: level \d+ skipped \(refused for the test\)", step.fallback)
            assert "refused for the test" in step.fallback
            assert np.isfinite(step.task_error) and (step.info["backend"] == "fallback") == closed
            terms = step.terms  # built on first read: the step's own
            assert [t.name for t in terms] == [t.name for t in runner.stack.tasks]
            main_error = np.sqrt(sum(float(terms[i].error @ terms[i].error) for i in step.main))
            assert step.task_error == pytest.approx(main_error, rel=1e-12, abs=1e-15)
            box_checked += 1
        runner.q = robot.integrate(runner.q, step.dq, dt)
    assert box_checked > 10


@pytest.mark.parametrize("scenario", ["snake10", "snake40"])
def test_a_level_qp_daqp_fails_natively_goes_back_to_python_as_written(
    monkeypatch: pytest.MonkeyPatch, scenario: str
) -> None:
    """With an iteration limit of 1 daqp fails level QPs: called from the cascade, such a QP goes back to Python,
    which poses it with every retry, from the buffer as the cascade wrote it (daqp's failed call changed nothing):
    the same q̇, fallbacks, QP and iteration counts as with the native call off."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    def run() -> list[tuple[np.ndarray, object, object, object]]:
        runner = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
        res = runner.resolver
        res.backend.iter_limit = 1  # type: ignore[attr-defined]
        out = []
        for k in range(200):
            step = res.step(runner.robot, runner.stack, runner.q, k * runner.scenario.dt, runner.scenario.dt)
            out.append((step.dq.copy(), step.fallback, step.info["qp"], step.info["iterations"]))
            runner.q = runner.robot.integrate(runner.q, step.dq, runner.scenario.dt)
        return out

    native = run()
    monkeypatch.setattr(daqp_native, "enabled", False)
    python = run()
    assert sum(s[1] is not None for s in native) > 10  # levels did fail (skipped, or the top level's fallback)
    for a, b in zip(native, python, strict=True):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_copied_or_pickled_resolver_steps_as_the_original(method: str) -> None:
    """A deep copy or a pickle of a resolver that has stepped (limits bound, bound subtasks' rows written, level QPs
    solved) steps as the original does. hqp's native arrays hold addresses (this object's buffers, this process's
    daqp): the copy's are empty, laid out again at first use; the limits' weak reference to their robot and hqp's to
    its last rows are not copied (they made the pickle fail)."""
    import copy
    import pickle

    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    runner = RedundikRunner(SCENARIOS["snake10"](), method, None, {})
    res, robot, stack, dt = runner.resolver, runner.robot, runner.stack, runner.scenario.dt
    q = runner.q
    solved = 0
    for k in range(150):
        step = res.step(robot, stack, q, k * dt, dt)
        solved += int(step.info.get("qp", 0))  # type: ignore[call-overload]
        q = robot.integrate(q, step.dq, dt)
    if method == "hqp":
        plan = res._plan  # type: ignore[attr-defined]
        assert solved > 0 and plan is not None and plan._native is not None
    for twin in (copy.deepcopy(res), pickle.loads(pickle.dumps(res))):
        if method == "hqp":
            native = twin._plan._native  # type: ignore[attr-defined]
            assert native is None or native.ctl.shape == (0,)
        qa, qb = q.copy(), q.copy()
        original = copy.deepcopy(res)  # (the original's state at the copy, stepped beside the twin)
        for k in range(150, 250):
            a = original.step(robot, stack, qa, k * dt, dt)
            b = twin.step(robot, stack, qb, k * dt, dt)
            np.testing.assert_array_equal(a.dq, b.dq)
            qa, qb = robot.integrate(qa, a.dq, dt), robot.integrate(qb, b.dq, dt)


def _clearance_stack(robot: rk.RobotModel, q0: np.ndarray, rng: np.random.Generator) -> rk.TaskStack:
    """The Panda circle with 1–3 clearance bounds of random kinds: lower, upper or both, 1–3 axes, rate 0 or not,
    some active at the start (a centre near the link), at levels 1 and 2."""
    robot.update(q0)
    bounds: list[rk.Subtask] = []
    for i in range(int(rng.integers(1, 4))):
        frame = str(rng.choice(["panda_link3", "panda_link4", "panda_link6", "panda_hand"]))
        axes = [("x", "y"), ("x", "y", "z"), ("z",)][int(rng.integers(3))]
        centre = robot.frame_position(frame) + rng.normal(0.0, 0.15, 3)
        kind = int(rng.integers(3))
        lower = float(rng.uniform(0.0, 0.2)) if kind != 1 else None
        upper = float(rng.uniform(0.3, 0.6)) if kind != 0 else None
        rate = 0.0 if rng.random() < 0.3 else float(rng.uniform(1.0, 50.0))
        clear = rk.Clearance(frame, centre, radius=float(rng.uniform(0.0, 0.05)), axes=axes, name=f"c{i}")
        bounds.append(rk.BoundSubtask(clear, lower=lower, upper=upper, rate=rate, priority=int(rng.integers(1, 3))))
    hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, ("y", "z")), gain=1.0, priority=0)
    return rk.TaskStack([hand, rk.PostureTask(q0.copy(), gain=0.5, priority=3)], bounds)


def _edit_first_bound(*stacks: rk.TaskStack) -> None:
    """A moving obstacle, a new margin and rate: the first bound subtask of each stack edited alike."""
    for stack in stacks:
        sub = stack.subtasks[0]
        sub.source.center = sub.source.center + np.array([0.0, 0.02, -0.01])
        sub.rate = 5.0
        if sub.lower is not None:
            sub.lower = sub.lower + 0.01


def test_packed_clearance_rows_equal_the_python_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fused step's compiled damper rows of clearance bounds (``hqp_fused.clearance_rows``) are bitwise those
    ``BoundSubtask.rows_into`` writes: the same q̇ and the same diagnostics over random stacks, on closed-form and on
    QP steps, with a centre, a bound and a rate assigned between steps."""
    robot, twin = rk.load_example_robot("panda"), rk.load_example_robot("panda")
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    packed_steps = qp_steps = 0
    for seed in range(12):
        a, b = (
            _clearance_stack(robot, q0, np.random.default_rng(seed)),
            _clearance_stack(twin, q0, np.random.default_rng(seed)),
        )
        ra, rb = rk.make_resolver("hqp"), rk.make_resolver("hqp")
        qa, qb = q0.copy(), q0.copy()
        for k in range(60):
            if k == 30:  # a moving obstacle, a new margin and rate, on both
                _edit_first_bound(a, b)
            with monkeypatch.context() as m:
                m.setattr(_Plan, "_pack_bounds", lambda self, robot: None)  # the Python rows (fused_bounds)
                want = rb.step(twin, b, qb, 0.01 * k, 0.01)
            got = ra.step(robot, a, qa, 0.01 * k, 0.01)
            assert ra._plan is not None and rb._plan is not None
            packed_steps += ra._plan._packed is not None
            qp_steps += bool(got.info["qp"])
            np.testing.assert_array_equal(got.dq, want.dq)
            assert dict(got.info) == dict(want.info) and got.fallback == want.fallback
            qa, qb = robot.integrate(qa, got.dq, 0.01), twin.integrate(qb, want.dq, 0.01)
    assert packed_steps >= 12 * 59 and qp_steps > 20, (packed_steps, qp_steps)  # (a first step is not fused)


# talos_actuated: the benchmark-only actuated-joint posture (the library's PostureTask on Talos's free flyer does
# not take the fused step yet, issue 31 item 3)
@pytest.mark.parametrize("scenario", ["panda_tight", "snake10", "talos_actuated"])
def test_native_cascade_result_equals_the_template(scenario: str) -> None:
    """A fused QP step whose cascade daqp settles from the compiled call (``_native_cascade``, ``_native_result``)
    against the template on the same run (``_settle`` over an ``HQPBuild``): q̇ bit for bit, the fallback, the
    kept q̇ (the next step's rate window), and the whole info with its diagnostics — read at once on some steps,
    after later steps on others (the rows the lean result holds are its step's)."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    runs = [RedundikRunner(SCENARIOS[scenario](), "hqp", None, {}) for _ in range(2)]
    template = runs[1].resolver
    lean_steps = [0]
    native = HierarchicalQPResolver._native_cascade

    def counted(self: HierarchicalQPResolver, *args: Any) -> Any:
        out = native(self, *args)
        lean_steps[0] += out is not None
        return out

    runs[0].resolver._native_cascade = counted.__get__(runs[0].resolver)  # type: ignore[method-assign]
    template._native_cascade = lambda *args: None  # type: ignore[method-assign]
    held: list[tuple[rk.StepResult, rk.StepResult]] = []
    dt = runs[0].scenario.dt
    for k in range(300):
        a, b = (r.resolver.step(r.robot, r.stack, r.q, k * dt, dt) for r in runs)
        np.testing.assert_array_equal(a.dq, b.dq)
        assert a.fallback == b.fallback
        np.testing.assert_array_equal(runs[0].resolver._dq_prev, template._dq_prev)
        if k % 3 == 0:
            assert dict(a.info) == dict(b.info)
            assert a.sigma_min == b.sigma_min and a.damped == b.damped
        elif k % 3 == 1:
            held.append((a, b))
        for r, res in zip(runs, (a, b), strict=True):
            r.q = r.robot.integrate(r.q, res.dq, dt)
    for a, b in held:
        assert dict(a.info) == dict(b.info)
    assert lean_steps[0] > 10, lean_steps


@pytest.mark.parametrize("scenario", ["panda_circle", "snake10"])
def test_packed_bound_rows_read_late_are_those_of_their_step(scenario: str) -> None:
    """Bound subtasks on clearances are written by the compiled step into the plan's inequality buffers (no new
    buffers a step): a step's diagnostics read after later steps — the bound level's residual and σ_min among them —
    are those read at once in a twin run, on every step, closed-form or not."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    now = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    late = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    assert any(level.bounds for level in now.stack.layout().levels)
    dt = now.scenario.dt
    eager, held = [], []
    for k in range(120):
        a = now.resolver.step(now.robot, now.stack, now.q, k * dt, dt)
        b = late.resolver.step(late.robot, late.stack, late.q, k * dt, dt)
        eager.append(dict(a.info))
        held.append(b)
        now.q = now.robot.integrate(now.q, a.dq, dt)
        late.q = late.robot.integrate(late.q, b.dq, dt)
    assert {info["path"] for info in eager} == {"compiled"}
    for info, res in zip(eager, held, strict=True):
        assert dict(res.info) == info


@pytest.mark.parametrize("scenario", ["panda_circle", "snake10"])
def test_packed_bound_records_are_reused_only_when_nobody_holds_them(scenario: str) -> None:
    """A control loop that drops each result gets the same bound-row records every step (none made a step); a
    result that is held, or whose diagnostics were read while it was the latest, keeps rows of its own step: its
    diagnostics read after later steps are those read at once in a twin run, whatever was dropped in between."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    now = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    late = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    dt = now.scenario.dt
    eager: dict[int, dict[str, object]] = {}
    held: dict[int, Any] = {}
    reused = 0
    for k in range(150):
        a = now.resolver.step(now.robot, now.stack, now.q, k * dt, dt)
        plan = late.resolver._plan
        before = None if plan is None else plan._last_written
        b = late.resolver.step(late.robot, late.stack, late.q, k * dt, dt)
        after = late.resolver._plan._last_written
        reused += before is not None and after is not None and after[1] is before[1]
        eager[k] = dict(a.info)
        if k % 4 == 0:  # held while the loop goes on
            held[k] = b
        elif k % 7 == 1:  # read while the latest, then dropped: its rows copied, the next step makes new records
            assert dict(b.info) == eager[k]
        now.q = now.robot.integrate(now.q, a.dq, dt)
        late.q = late.robot.integrate(late.q, b.dq, dt)
        del a, b
    assert {info["path"] for info in eager.values()} == {"compiled"}
    assert reused > 50, reused  # (the loop's dropped results: their records described the next step's rows)
    for k, res in held.items():
        assert dict(res.info) == eager[k], k


def _bound_rows_of(res: Any) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """The bound subtasks' rows (C, d) a fused ``hqp`` result of the closed form reads, as its diagnostics would
    read them (``None``: another kind of result)."""
    if type(res) is not FusedHqpResult:
        return None
    rows = []
    for record, sl, _ in res.__dict__["_step"][9]:  # (``FusedHqpResult.of``: the bound records)
        record.keep()
        rows.append((record.C[sl].copy(), record.d[sl].copy()))
    return rows


@pytest.mark.parametrize("scenario", ["panda_circle", "snake10"])
def test_a_loop_that_keeps_its_last_result_makes_no_bound_record_and_reads_its_own_rows(
    scenario: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A control loop ``res = step(...)`` holds the last result while it steps: the step writes the spare
    inequality buffers, so that no record is made and no row copied a step; and a result read one step late (its
    rows in the other buffers) or two steps late reads the bound rows and diagnostics of its own step, those a twin
    run read at once."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    from redundik.resolvers.qp import hqp_bounds, hqp_plan

    made = [0]

    class Counted(hqp_bounds.WrittenRows):
        __slots__ = ()

        def __init__(self) -> None:
            made[0] += 1
            super().__init__()

    monkeypatch.setattr(hqp_plan, "WrittenRows", Counted)
    now = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    late = RedundikRunner(SCENARIOS[scenario](), "hqp", None, {})
    dt = now.scenario.dt
    eager: list[tuple[dict[str, object], list[tuple[np.ndarray, np.ndarray]]]] = []
    res = older = None
    quiet = compared = 0
    for k in range(160):
        a = now.resolver.step(now.robot, now.stack, now.q, k * dt, dt)
        eager.append((dict(a.info), _bound_rows_of(a)))  # (read at once: this twin's records are made every step)
        if k < 100:  # the loop keeps only its last result
            older = None
        before = made[0]
        older, res = res, late.resolver.step(late.robot, late.stack, late.q, k * dt, dt)
        if k < 100:
            quiet += made[0] == before  # (steps 0–99: the result is kept, never read)
        elif k % 3 != 2 and older is not None:  # read one step late (k % 3 == 0) or two steps late (held meanwhile)
            info, rows = eager[k - 1]
            got = _bound_rows_of(older)
            assert (got is None) == (rows is None), k
            if rows is not None and got is not None:
                assert rows and len(got) == len(rows), k
                for (C, d), (Cg, dg) in zip(rows, got, strict=True):
                    assert np.array_equal(C, Cg) and np.array_equal(d, dg), k
                compared += 1
            assert dict(older.info) == info, k
        now.q = now.robot.integrate(now.q, a.dq, dt)
        late.q = late.robot.integrate(late.q, res.dq, dt)
    assert {info["path"] for info, _ in eager} == {"compiled"}
    assert quiet >= 95, quiet  # (the first steps make the records of the two pairs of buffers)
    assert compared > 15, compared


@pytest.mark.parametrize(("n", "levels", "r_size"), [(9, 3, 16), (7, 1, 0), (38, 5, 49), (1, 2, 1)])
def test_the_cascade_blocks_are_sliced_alike_in_python_and_in_compiled_code(n: int, levels: int, r_size: int) -> None:
    """``_Plan.cascade_outputs`` (Python) and ``cascade_out_views`` (the compiled call's) name the same parts of
    ``out``; ``cascade_buffers``' views are the parts of the blocks ``qp_cascade_call`` takes."""
    from types import SimpleNamespace

    def where(a: np.ndarray) -> tuple[int | None, tuple[int, ...]]:  # (an empty part's address is no place)
        return (a.__array_interface__["data"][0] if a.size else None), a.shape

    out, *parts = _Plan.cascade_outputs(SimpleNamespace(n=n, r_size=r_size), levels)  # type: ignore[arg-type]
    assert [where(p) for p in parts] == [where(p) for p in HK.cascade_out_views(out, n, levels)]
    plan = SimpleNamespace(n=n, _cascade=None)
    bufs = _Plan.cascade_buffers(plan, 5)  # type: ignore[arg-type]
    fwork, iwork, free = plan.cascade_blocks
    Z, N, F, f, slack, state, free_, sel = bufs
    assert free_ is free and [where(a) for a in (Z, N, F, f, slack, state, sel)] == [
        where(a) for a in HK.cascade_work_views(fwork, iwork, n)
    ]


def test_the_fused_step_block_is_sliced_alike_in_python_and_in_compiled_code() -> None:
    """``_fused_solve`` slices (e, v), z, q̇ and the kept q̇ of a fused step's ``work`` itself: at the places
    ``hqp_fused.step_work_views`` (the compiled call's) gives them."""
    from redundik.resolvers import hqp_fused
    from redundik.resolvers.hqp_layout import OUT_DQ, OUT_KEPT

    K, m, n, levels = 2, 13, 9, 3
    work = np.zeros(hqp_fused.step_work_size(K, m, n, levels))
    ev, z, out, Jf, stats = hqp_fused.step_work_views(work, K, m, n, levels)
    o = 2 * m + n
    for mine, theirs in (
        (work[: 2 * m].reshape(2, m), ev),
        (work[2 * m : 2 * m + n], z),
        (work[o + OUT_DQ * n : o + (OUT_DQ + 1) * n], out[OUT_DQ, 0]),
        (work[o + OUT_KEPT * n : o + (OUT_KEPT + 1) * n], out[OUT_KEPT, 0]),
    ):
        assert mine.__array_interface__["data"][0] == theirs.__array_interface__["data"][0]
        assert mine.shape == theirs.shape
    assert Jf.shape == (K, 6, n) and stats.shape == (levels, 4)
    assert stats.__array_interface__["data"][0] + stats.nbytes == work.__array_interface__["data"][0] + work.nbytes
