"""hqp's lean gather: the rows it lays out in its buffers (tasks, target and bound subtasks, the null-space
objective) are those of ``gather_rows`` + ``fill``; bound rows it does not write itself are left to their ``rows``;
identity levels, diagnostics read late, rows held across later gathers."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers.qp.hqp import HierarchicalQPResolver, HQPBuild
from tests.hqp_reference import _compare, _stack
from tests.test_qp_helpers import prepared, random_robot, tip


def _rich_stack(robot: rk.RobotModel, rng: np.random.Generator) -> rk.TaskStack:
    """Every kind of row the lean buffers take: tasks on three levels, a target subtask, two bound subtasks (one
    two-sided) on two levels, gradients (the null-space objective)."""
    names = robot.joint_names
    base = _stack(robot, rng, depth=4, bound=True)
    subs: list[rk.Subtask] = list(base.subtasks)
    subs.append(rk.TargetSubtask(rk.JointValue(names[3], 0.0, name="t4"), target=0.1, rate=2.0, priority=1))
    subs.append(rk.BoundSubtask(rk.JointValue(names[1], 0.0, name="b2"), lower=-0.4, upper=0.4, rate=5.0, priority=2))
    # lower bounds only (the row the lean gather writes itself): γ = 1/dt (rate 0), K, and K capped at 1/dt
    subs.append(rk.BoundSubtask(rk.JointValue(names[4], 0.0, name="b5"), lower=-0.3, priority=1))
    subs.append(rk.BoundSubtask(rk.JointCentering(name="c"), lower=0.05, rate=3.0, priority=2))
    subs.append(rk.BoundSubtask(rk.JointValue(names[5], 0.0, name="b6"), lower=-0.2, rate=500.0, priority=2))
    return rk.TaskStack(list(base.tasks), subs)


@pytest.mark.parametrize("mixed", [False, True])
def test_lean_gather_lays_out_the_rows_of_gather_rows_and_fill(mixed: bool) -> None:
    """The lean step's one-pass ``_Plan.gather`` writes the buffers ``gather_rows`` + ``_Plan.fill`` write, and its
    ``step_rows`` are those of ``gather_rows`` (the same arrays per level), over several states; ``mixed``: the
    null-space objective shares its level with a task (its identity rows after the task's)."""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(3)
    robot = random_robot(rng, 7)
    stack = _rich_stack(robot, rng)
    res = HierarchicalQPResolver()
    q = robot.random_configuration(rng)
    prepared(res, robot, stack, q)
    layout = res.layout(stack)
    if mixed:  # (a layout by hand: TaskStack.layout gives the objective a level of its own)
        from dataclasses import replace

        *above, last = layout.levels
        assert last.null_objective and not (last.tasks or last.targets or last.bounds)
        above[-1] = replace(above[-1], null_objective=True)
        layout = replace(layout, levels=above)
    assert any(_Plan(layout, robot.nv, np.zeros(5)).mixed) == mixed
    lean, ref = _Plan(layout, robot.nv, np.zeros(5)), _Plan(layout, robot.nv, np.zeros(5))
    for k in range(4):
        q = robot.random_configuration(rng)
        robot.update(q)
        terms = stack.evaluate(robot, 0.1 * k)
        z, targets, bounds = lean.gather(robot, stack, terms, 0.01)
        assert sum(type(b[1]) is slice for b in bounds) == 5  # every bound on a potential: written by rows_into
        rows = gather_rows(robot, stack, terms, layout, 0.01)
        ref.fill(rows)
        np.testing.assert_array_equal(lean.meta, ref.meta)
        M, P = int(ref.meta[0, -1]), int(ref.meta[1, -1])
        assert M and P
        for a, b in ((lean.A, ref.A), (lean.b, ref.b), (lean.w, ref.w)):
            np.testing.assert_array_equal(a[:M], b[:M])
        for a, b in ((lean.C, ref.C), (lean.d, ref.d)):
            np.testing.assert_array_equal(a[:P], b[:P])
        got = lean.step_rows(terms, z, targets, bounds)
        np.testing.assert_array_equal(got.z, rows.z)
        for la, lb_ in zip(got.levels, rows.levels, strict=True):
            assert (la.priority, la.names, la.c_names) == (lb_.priority, lb_.names, lb_.c_names)
            for f in ("J", "v", "w", "C", "d"):
                np.testing.assert_array_equal(getattr(la, f), getattr(lb_, f))
            assert (la.z is None) == (lb_.z is None)


class _BarrierPotential(rk.Barrier, rk.Potential):
    """A source that is both (as the collision and balance barriers): ``BoundSubtask.values`` reads it as a barrier."""

    name = "both"

    def __init__(self, joint: int) -> None:
        self.joint = joint

    def value(self, robot: rk.RobotModel) -> float:
        return float(robot.q[self.joint])

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        g = np.zeros(robot.nv)
        g[self.joint] = 1.0
        return g

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        h = np.array([0.5 - robot.q[self.joint], 0.7 + robot.q[self.joint]])
        H = np.zeros((2, robot.nv))
        H[0, self.joint], H[1, self.joint] = -1.0, 1.0
        return rk.BarrierTerm(h, H, ["hi", "lo"], np.array([3.0, 400.0]))


def test_lean_gather_leaves_other_bound_rows_to_rows() -> None:
    """The lean gather lets ``BoundSubtask.rows_into`` write a potential's rows (an upper and a two-sided bound here)
    but takes ``rows()`` for a barrier that is also a potential, and the buffers hold the rows of ``gather_rows``
    bitwise; the step agrees with the general path on such a stack. (A lower bound assigned to the barrier's subtask
    after construction, which this test used to set to see it ignored, is now refused as the constructor refuses
    it.)"""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(11)
    robot = random_robot(rng, 6)
    names = robot.joint_names
    barrier = rk.BoundSubtask(_BarrierPotential(2), priority=1)
    with pytest.raises(rk.TaskError, match="a barrier is kept ≥ 0"):
        barrier.lower = 0.0
    assert barrier.lower is None
    subs: list[rk.Subtask] = [
        barrier,
        rk.BoundSubtask(rk.JointValue(names[1], 0.0, name="u"), upper=0.3, rate=5.0, priority=1),
        rk.BoundSubtask(rk.JointValue(names[3], 0.0, name="two"), lower=-1.0, upper=0.4, priority=1),
        rk.GradientSubtask(rk.JointCentering(), gain=-1.0),
    ]
    stack = rk.TaskStack([rk.FrameTask(tip(robot), rk.Line([0.1, 0.2, -0.1]), axes="position", gain=1.0)], subs)
    res = HierarchicalQPResolver()
    q = robot.random_configuration(rng)
    prepared(res, robot, stack, q)
    layout = res.layout(stack)
    plan = _Plan(layout, robot.nv, np.zeros(5))
    terms = stack.evaluate(robot, 0.0)
    _, _, bounds = plan.gather(robot, stack, terms, 0.01)
    assert [type(b[1]) is slice for b in bounds] == [False, True, True]  # the barrier's rows from rows()
    rows = gather_rows(robot, stack, terms, layout, 0.01)
    P = int(plan.meta[1, -1])
    assert P == 5
    np.testing.assert_array_equal(plan.C[:P], np.vstack([r[0] for lv in rows.ineq for r in lv]))
    np.testing.assert_array_equal(plan.d[:P], np.concatenate([r[1] for lv in rows.ineq for r in lv]))
    for seed in range(4):
        _compare(robot, stack, robot.random_configuration(np.random.default_rng(seed)), steps=2)


@pytest.mark.parametrize(
    ("weight", "first", "epsilon", "applies"),
    [
        (1.0, False, 1e-2, True),
        (0.01, False, 1e-2, True),
        (0.01, True, 1e-2, True),
        (2e-5, False, 1e-2, True),
        (1e-4, True, 1e-2, True),
        (0.3, False, 1.0, False),
        (0.3, True, 2.0, False),
    ],
)
def test_lean_identity_level_equals_the_general_path(weight: float, first: bool, epsilon: float, applies: bool) -> None:
    """A posture given a level of its own (rows √w I): the lean cascade solves it as Zᵀ(b − x) without a
    factorisation where its singular values √w are not damped — at every weight, the rule being relative to the
    level's largest weight (σ/√w = 1 ≥ ε) — and not where ε = 1 (the margin) or ε > 1 (damped), with the same q̇ and
    diagnostics as the general path, at the top level (``first``) or below a frame task and a bound level, inside
    the box and against the limits."""
    from redundik.resolvers.hqp_kernels import identity_rows

    rng = np.random.default_rng(21)
    robot = random_robot(rng, 7)
    posture = rk.PostureTask(gain=2.0, weight=weight, priority=0 if first else 2)
    subs: list[rk.Subtask] = [] if first else [
        rk.BoundSubtask(rk.JointValue(robot.joint_names[2], 0.0, name="b3"), upper=0.6, rate=10.0, priority=1)
    ]  # fmt: skip
    tasks: list[rk.Task] = [posture] if first else [
        rk.FrameTask(tip(robot), rk.Line([0.2, -0.1, 0.1]), axes="position", gain=1.0), posture
    ]  # fmt: skip
    stack = rk.TaskStack(tasks, subs)
    qp_steps = 0
    for seed in range(6):
        q = robot.random_configuration(np.random.default_rng(seed))
        posture.set_target(robot.random_configuration(np.random.default_rng(50 + seed)))
        res = HierarchicalQPResolver(epsilon=epsilon)
        prepared(res, robot, stack, q)
        plan = res._plan_for(res.layout(stack), robot.nv)
        plan.gather(robot, stack, stack.evaluate(robot, 0.0), 0.01)
        k = len(plan.members) - 1
        s = int(plan.meta[0, k])
        assert bool(identity_rows(plan.A, plan.w, s, robot.nv, res.epsilon * np.sqrt(weight))) == applies
        tight = rk.JointLimits(velocity_limits={n: 0.3 for n in robot.joint_names}) if seed % 2 else None
        _compare(robot, stack, q, steps=2, limits=tight, epsilon=epsilon)
        if seed % 2:  # the constrained cascade: the posture level factored exactly, not by an SVD, where it applies
            from redundik.resolvers.hqp_kernels import QS_DAMPING, QS_SIGMA, QS_SOLVED

            qp = HierarchicalQPResolver(
                limits=rk.JointLimits(velocity_limits=dict.fromkeys(robot.joint_names, 0.3)), epsilon=epsilon
            )
            prepared(qp, robot, stack, q)
            qp._native_cascade = lambda *args: None  # type: ignore[method-assign]  # (the template, seen below)
            seen: list[HQPBuild] = []
            cascade = qp._qp_cascade
            qp._qp_cascade = lambda built, diag, seen=seen, cascade=cascade: (  # type: ignore[method-assign]
                seen.append(built),
                cascade(built, diag),
            )[1]
            if qp.step(robot, stack, q, 0.0, 0.01).info["qp"]:
                qp_steps += 1
                stats = seen[-1].qp_stats
                assert stats is not None
                posture_level = stats[len(plan.members) - 1]
                if posture_level[QS_SOLVED]:
                    if applies:  # the exact factors (Z, √w, I): σ = √w to the bit, nothing damped
                        assert posture_level[QS_SIGMA] == np.sqrt(weight) and posture_level[QS_DAMPING] == 0.0
                    elif epsilon > 1.0:  # the SVD, damped (σ/√w = 1 < ε)
                        assert posture_level[QS_DAMPING] > 0.0
    assert qp_steps


class _BufferedGradient(rk.Potential):
    """A potential that returns one gradient array, rewritten at every call (a user's preallocated buffer)."""

    name = "buffered"

    def __init__(self, joint: int) -> None:
        self.joint = joint
        self._g: np.ndarray | None = None

    def value(self, robot: rk.RobotModel) -> float:
        return float(np.sum(robot.q[: self.joint + 1]))

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        if self._g is None:
            self._g = np.zeros(robot.nv)
        self._g[:] = 0.0
        self._g[: self.joint + 1] = 1.0 + robot.q[: self.joint + 1] ** 2
        return self._g


def test_lean_diagnostics_read_late_are_those_of_their_step() -> None:
    """Diagnostics read after later steps are those the step would have reported at once, also when a bound
    subtask's potential rewrites its gradient array in place at every call (the lean row keeps its own copy)."""
    rng = np.random.default_rng(31)
    robot = random_robot(rng, 6)
    stack = rk.TaskStack(
        [rk.FrameTask(tip(robot), rk.Line([0.1, 0.0, -0.1]), axes="position", gain=1.0)],
        [rk.BoundSubtask(_BufferedGradient(3), lower=-50.0, rate=2.0, priority=1),
         rk.GradientSubtask(rk.JointCentering(), gain=-1.0)],
    )  # fmt: skip
    q0 = robot.random_configuration(rng)
    bound = stack.subtasks[0]
    assert isinstance(bound, rk.BoundSubtask)
    for lower, limits in (
        (-50.0, False),
        (float(np.sum(q0[:4])) + 10.0, {"velocity_limits": dict.fromkeys(robot.joint_names, 0.3)}),
    ):
        # inactive (the closed form), then out of reach at 0.3 rad/s (the QPs: the level contradicted, its residual
        # read from its rows)
        bound.lower = lower
        now, late = HierarchicalQPResolver(limits=limits), HierarchicalQPResolver(limits=limits)
        prepared(now, robot, stack, q0)
        prepared(late, robot, stack, q0)
        q, eager, pending = q0, [], []
        for k in range(3):
            a = now.step(robot, stack, q, 0.01 * k, 0.01)
            eager.append((dict(a.info), a.fallback))
            pending.append(late.step(robot, stack, q, 0.01 * k, 0.01))
            q = robot.integrate(q, a.dq, 0.01)
        closed = lower < 0
        assert all((e["qp"] == 0) == closed for e, _ in eager)
        assert closed or all(e["residual_L1"] > 1e-3 for e, _ in eager)
        for (e, fallback), res in zip(eager, pending, strict=True):
            assert dict(res.info) == e and res.fallback == fallback


def test_lean_gather_rows_held_across_later_gathers_and_fills() -> None:
    """The rows ``rows_into`` wrote into the plan's buffers are copied before the buffers are written again while
    a step's record is held: its ``step_rows`` read after later gathers (and a fill) are those of its own state."""
    from redundik.resolvers.qp.hqp import _Plan
    from redundik.resolvers.qp.terms import gather_rows

    rng = np.random.default_rng(41)
    robot = random_robot(rng, 7)
    stack = _rich_stack(robot, rng)
    res = HierarchicalQPResolver()
    prepared(res, robot, stack, robot.random_configuration(rng))
    layout = res.layout(stack)
    plan = _Plan(layout, robot.nv, np.zeros(5))
    held, refs = [], []
    for k in range(3):
        robot.update(robot.random_configuration(rng))
        terms = stack.evaluate(robot, 0.1 * k)
        held.append((terms, *plan.gather(robot, stack, terms, 0.01)))
        refs.append(gather_rows(robot, stack, terms, layout, 0.01))
        if k == 1:
            plan.fill(refs[0])
    for (terms, z, targets, bounds), ref in zip(held, refs, strict=True):
        got = plan.step_rows(terms, z, targets, bounds)
        for la, lb_ in zip(got.levels, ref.levels, strict=True):
            np.testing.assert_array_equal(la.C, lb_.C)
            np.testing.assert_array_equal(la.d, lb_.d)
            assert la.c_names == lb_.c_names
