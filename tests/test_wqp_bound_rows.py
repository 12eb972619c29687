"""``wqp``'s fused step writes the damper rows of bound subtasks on clearances in one compiled call
(``resolvers/qp/wqp_bounds.py``, the kernel ``hqp``'s fused step uses), not each subtask's ``rows`` from Python: the
same q̇ and diagnostics bit for bit, on free and on QP steps, with edits between steps and results read late."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers.qp.wqp_bounds import PackedBoundRows
from tests.test_hqp_buffers import _clearance_stack, _edit_first_bound

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def test_packed_clearance_rows_equal_the_python_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    robot, twin = rk.load_example_robot("panda"), rk.load_example_robot("panda")
    calls = [0]
    rows = rk.BoundSubtask.rows

    def counted(self: rk.BoundSubtask, *args: Any) -> Any:
        calls[0] += 1
        return rows(self, *args)

    monkeypatch.setattr(rk.BoundSubtask, "rows", counted)
    packed_steps = qp_steps = 0
    for seed in range(12):
        a = _clearance_stack(robot, Q0, np.random.default_rng(seed))
        b = _clearance_stack(twin, Q0, np.random.default_rng(seed))
        ra, rb = rk.make_resolver("wqp"), rk.make_resolver("wqp")
        qa, qb = Q0.copy(), Q0.copy()
        held: list[tuple[rk.StepResult, rk.StepResult]] = []
        for k in range(60):
            if k == 30:  # a moving obstacle, a new margin and rate, on both
                _edit_first_bound(a, b)
            with monkeypatch.context() as m:
                m.setattr(PackedBoundRows, "_pack", _unpacked)  # the Python rows (each subtask's ``rows``)
                before = calls[0]
                want = rb.step(twin, b, qb, 0.01 * k, 0.01)
                python_calls = calls[0] - before
            before = calls[0]
            got = ra.step(robot, a, qa, 0.01 * k, 0.01)
            assert got.info["path"] == "compiled" or k == 0, got.info
            if k > 0:  # (a first step is not fused)
                assert ra._plan is not None and ra._plan.bound_rows.packed is not None
                assert calls[0] == before and python_calls == len(a.subtasks)  # (no subtask's rows from Python)
                packed_steps += 1
            qp_steps += bool(got.info["qp"])
            np.testing.assert_array_equal(got.dq, want.dq)
            assert got.fallback == want.fallback
            if k % 2:
                assert dict(got.info) == dict(want.info)
            else:  # read after later steps: the rows a QP step's result holds are its own
                held.append((got, want))
            qa, qb = robot.integrate(qa, got.dq, 0.01), twin.integrate(qb, want.dq, 0.01)
        for got, want in held:
            assert dict(got.info) == dict(want.info)
    assert packed_steps == 12 * 59 and qp_steps > 20, (packed_steps, qp_steps)


def _unpacked(self: PackedBoundRows, bounds: list[Any], robot: rk.RobotModel) -> None:
    self.packed, self.key = None, (rk.tasks.base.Edits.count, rk.tasks.base.Edits.layout, robot.data)


def test_a_bound_without_a_clearance_form_keeps_python_rows() -> None:
    """A bound on another potential (no clearance form) among clearance bounds: every bound's rows come from
    Python, as before (the packing is all or none)."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    centre = robot.frame_position("panda_link4") + np.array([0.0, 0.1, 0.0])
    stack = rk.TaskStack(
        [rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, ("y", "z")), gain=1.0), rk.PostureTask(Q0.copy(), gain=0.5)],
        [
            rk.BoundSubtask(rk.Clearance("panda_link4", centre, 0.05), lower=0.02),
            rk.BoundSubtask(rk.JointValue("panda_joint2", 0.0), lower=-1.5, upper=1.5),
        ],
    )
    stack.reset(robot)
    res, q = rk.make_resolver("wqp"), Q0.copy()
    for k in range(5):
        out = res.step(robot, stack, q, 0.01 * k, 0.01)
        q = robot.integrate(q, out.dq, 0.01)
    assert res._plan is not None and res._plan.bound_rows.packed is None
    assert np.isfinite(out.dq).all()


def _run_native(enabled: bool, seed: int, monkeypatch: pytest.MonkeyPatch) -> tuple[list[tuple[Any, ...]], int]:
    """A random clearance stack under ``wqp`` with daqp's native call on or off; each step's answers, and how many
    steps the native call answered with bound rows."""
    from redundik.resolvers.qp import daqp_native, wqp

    monkeypatch.setattr(daqp_native, "enabled", enabled)
    taken = [0]
    original = wqp.native_box_step

    def counting(*args: Any, **kwargs: Any) -> Any:
        res = original(*args, **kwargs)
        taken[0] += res is not None and args[8] is not None  # (its bound rows)
        return res

    monkeypatch.setattr(wqp, "native_box_step", counting)
    robot = rk.load_example_robot("panda")
    stack = _clearance_stack(robot, Q0, np.random.default_rng(seed))
    res, q, out = rk.make_resolver("wqp"), Q0.copy(), []
    held = []
    for k in range(60):
        step = res.step(robot, stack, q, 0.01 * k, 0.01)
        if k % 2:
            held.append((k, step))  # (its diagnostics read after later steps)
        else:
            out.append((k, step.dq.copy(), res._dq_prev.copy(), dict(step.info), step.relaxed, step.fallback))
        q = robot.integrate(q, step.dq, 0.01)
    out += [(k, s.dq.copy(), None, dict(s.info), s.relaxed, s.fallback) for k, s in held]
    return out, taken[0]


def _assert_same_steps(native: list[tuple[Any, ...]], template: list[tuple[Any, ...]], seed: int) -> None:
    """Each step's q̇, kept q̇ (when recorded), info, relaxations and fallback, bit for bit."""
    for a, b in zip(native, template, strict=True):
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"seed {seed}, step {a[0]}")
        if a[2] is not None:
            np.testing.assert_array_equal(a[2], b[2])
        assert a[3:] == b[3:], (seed, a[0])


def test_bound_rows_qp_through_daqps_native_call_is_the_templates_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    """A step whose bound rows bind solves its QP (box and rows) through daqp's C entry point: the template's
    q̇ bit for bit, its kept q̇, info (``bound_violation`` included), relaxations and fallbacks."""
    from redundik.resolvers.qp import daqp_native

    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")  # (CI installs daqp 0.11.0)
    native_steps = 0
    for seed in range(8):
        native, taken = _run_native(True, seed, monkeypatch)
        template, taken_off = _run_native(False, seed, monkeypatch)
        native_steps += taken
        assert taken_off == 0
        _assert_same_steps(native, template, seed)
    assert native_steps > 20, native_steps


def _snake_run(n: int, native: bool, bounds: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[list[Any], int]:
    """The benchmark's snake of n joints under ``wqp`` (its clearance bounds, or none and velocity limits of
    0.01 rad/s that bind), daqp's native call on or off: each step's answers, and the steps the native call took."""
    from benchmarks.bench.scenarios import snake_scenario

    from redundik.resolvers.qp import daqp_native, wqp

    monkeypatch.setattr(daqp_native, "enabled", native)
    taken = [0]
    original = wqp.native_box_step

    def counting(*args: Any, **kwargs: Any) -> Any:
        res = original(*args, **kwargs)
        taken[0] += res is not None
        return res

    monkeypatch.setattr(wqp, "native_box_step", counting)
    sc = snake_scenario(n)
    robot, q = sc.robot(), sc.q0.copy()
    robot.update(q)
    stack = sc.stacks["wqp"](robot)
    limits = None
    if not bounds:
        stack = rk.TaskStack(stack.tasks, [s for s in stack.subtasks if not isinstance(s, rk.BoundSubtask)])
        limits = {"velocity_limits": {str(j + 1): 0.01 for j in range(n)}}
    stack.reset(robot)
    res, out = rk.make_resolver("wqp", limits=limits), []
    for k in range(150):
        step = res.step(robot, stack, q, k * sc.dt, sc.dt)
        out.append((step.dq.copy(), res._dq_prev.copy(), dict(step.info), step.relaxed, step.fallback))
        q = robot.integrate(q, step.dq, sc.dt)
    return out, taken[0]


@pytest.mark.parametrize("bounds", [True, False], ids=["clearance_rows", "box_only"])
def test_a_lifted_qp_through_daqps_native_call_is_the_templates_answer(
    bounds: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From daqp's lift size on (n ≥ 40) the template gives the backend the Gram factor of P and daqp solves the QP
    lifted (``DaqpBackend._solve_lifted``); the native call poses the same lifted QP (``lifted_rows_qp_native_into``):
    the same q̇ bit for bit, kept q̇, info, relaxations and fallbacks — with bound rows, and with the box alone."""
    from redundik.resolvers.qp import daqp_native

    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")  # (CI installs daqp 0.11.0)
    native, taken = _snake_run(40, True, bounds, monkeypatch)
    template, taken_off = _snake_run(40, False, bounds, monkeypatch)
    qp_steps = sum(1 for step in native if step[2]["qp"])
    assert qp_steps >= 20 and taken == qp_steps and taken_off == 0, (qp_steps, taken, taken_off)
    for k, (a, b) in enumerate(zip(native, template, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"q̇, step {k}")
        np.testing.assert_array_equal(a[1], b[1], err_msg=f"kept q̇, step {k}")
        assert a[2:] == b[2:], f"info, relaxed, fallback, step {k}"


class _Floor(rk.Barrier):
    """A user's safety barrier (``critical``, as a collision damper's rows): keep a frame's height above z_min,
    h = z − z_min, H = its frame Jacobian's z row."""

    critical = True

    def __init__(self, frame: str, z_min: float) -> None:
        self.name, self.frame, self.z_min = f"floor_{frame}", frame, z_min

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        h = np.array([robot.frame_position(self.frame)[2] - self.z_min])
        return rk.BarrierTerm(h, robot.frame_jacobian(self.frame)[2:3].copy(), ["z"])


def _safety_run(enabled: bool, seed: int, monkeypatch: pytest.MonkeyPatch) -> tuple[list[tuple[Any, ...]], int]:
    """A clearance stack of ``_clearance_stack`` with a safety barrier that binds (the hand's circle dips below
    its floor) under ``wqp``, daqp's native call on or off: each step's answers, and how many steps the native call
    answered with the safety rows among the bound rows."""
    from redundik.resolvers.qp import daqp_native, wqp

    monkeypatch.setattr(daqp_native, "enabled", enabled)
    taken = [0]
    original = wqp.native_box_step

    def counting(*args: Any, **kwargs: Any) -> Any:
        res = original(*args, **kwargs)
        bounds = args[8] if len(args) > 8 else kwargs.get("bounds")
        taken[0] += res is not None and bounds is not None and bool(bounds[3] is not None and bounds[3].any())
        return res

    monkeypatch.setattr(wqp, "native_box_step", counting)
    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(seed)
    base = _clearance_stack(robot, Q0, rng)
    robot.update(Q0)
    z0 = float(robot.frame_position("panda_hand")[2])
    floor = rk.BoundSubtask(_Floor("panda_hand", z0 - float(rng.uniform(0.0, 0.03))), rate=float(rng.uniform(5, 50)))
    stack = rk.TaskStack(list(base.tasks), [*base.subtasks, floor])
    stack.reset(robot)
    res, q, out, held = rk.make_resolver("wqp"), Q0.copy(), [], []
    for k in range(60):
        step = res.step(robot, stack, q, 0.02 * k, 0.01)
        if k % 2:
            held.append((k, step))
        else:
            out.append((k, step.dq.copy(), res._dq_prev.copy(), dict(step.info), step.relaxed, step.fallback))
        q = robot.integrate(q, step.dq, 0.01)
    out += [(k, s.dq.copy(), None, dict(s.info), s.relaxed, s.fallback) for k, s in held]
    return out, taken[0]


@pytest.mark.parametrize("declines", [False, True], ids=["keeps", "breaks"])
def test_a_qp_with_safety_rows_through_daqps_native_call_is_the_templates_answer(
    declines: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A step whose bound rows include a safety barrier's (``critical``: the template's last guard scales q̇ to keep
    them) solves its QP through daqp's C entry point when the answer keeps them: the template's q̇ bit for bit, its
    kept q̇, info, relaxations and fallbacks. ``breaks``: with the guard's tolerance made −∞ for the native call
    only, every native answer counts as breaking them, the native call declines each such step and the template
    answers, unchanged."""
    from redundik.resolvers.qp import daqp_native, wqp_native

    if not daqp_native.entry():
        pytest.skip(f"daqp's native call is off here: {daqp_native.status()}")  # (CI installs daqp 0.11.0)
    if declines:
        monkeypatch.setattr(wqp_native, "SAFETY_TOLERANCE", -np.inf)
    native_steps = 0
    for seed in range(6):
        native, taken = _safety_run(True, seed, monkeypatch)
        template, taken_off = _safety_run(False, seed, monkeypatch)
        native_steps += taken
        assert taken_off == 0
        _assert_same_steps(native, template, seed)
    if declines:
        assert native_steps == 0
    else:
        assert native_steps > 20, native_steps
