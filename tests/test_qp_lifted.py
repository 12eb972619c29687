"""A QP that carries its Gram factor (P = FᵀF + δI) is solved by daqp lifted to (x, s = F x): the dense problem's
optimum, from a diagonal Hessian; ``wqp``'s factor is its Hessian, on every path that hands a QP to the backend."""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import pytest

from redundik.resolvers.qp.backends import LIFT_MIN_N, TOLERANCE, DaqpBackend, polish
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.wqp import WeightedQPResolver
from redundik.tasks import BoundSubtask, FrameTask, GradientSubtask, PostureTask, TaskStack
from redundik.tasks.potentials import Clearance, JointCentering
from redundik.tasks.trajectory import Circle
from tests.helpers import random_dh_robot

pytest.importorskip("daqp")


def dense() -> DaqpBackend:
    """daqp on P as given (never lifted)."""
    be = DaqpBackend()
    be.lift_min_n = 10**9
    return be


class Spy(DaqpBackend):
    """daqp, recording a copy of each problem it is given (a resolver reuses its buffers) and whether the lifted
    solve answered it."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[tuple[QPProblem, bool]] = []
        self._lifted = False

    def _solve_lifted(self, problem: QPProblem) -> QPSolution | None:
        sol = super()._solve_lifted(problem)
        self._lifted = sol is not None
        return sol

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        self._lifted = False
        sol = super().solve(problem, warm)
        self.seen.append((copy.deepcopy(problem), self._lifted))
        return sol


def gram_problem(rng: np.random.Generator, n: int) -> QPProblem:
    """P = FᵀF + δI with k ≤ n/2 rows, a box that binds, inequality rows and (sometimes) equalities."""
    k = int(rng.integers(2, n // 2 + 1))
    F = rng.standard_normal((k, n)) * rng.uniform(0.2, 3.0)
    delta = float(10.0 ** rng.uniform(-4, 0))
    P = F.T @ F + delta * np.eye(n)
    q = 3.0 * rng.standard_normal(n)
    p = int(rng.integers(0, 6))
    G, h = rng.standard_normal((p, n)), rng.uniform(0.0, 0.5, p)
    e = int(rng.integers(0, 3))
    A, b = rng.standard_normal((e, n)), 0.1 * rng.standard_normal(e)
    lb, ub = -rng.uniform(0.05, 1.0, n), rng.uniform(0.05, 1.0, n)
    lb[rng.integers(n)] = -np.inf
    return QPProblem(P, q, G, h, A, b, lb, ub, "gram", factor=(F, delta))


@pytest.mark.parametrize("seed", range(3))
def test_the_lifted_qp_has_the_dense_problems_optimum(seed: int) -> None:
    """Random Gram problems (n = 40 … 120, constraints binding): the lifted solve is taken, and its x is the exact
    optimum (the KKT conditions of the dense problem verified from its active set, ``polish``) to daqp's tolerance —
    as is daqp's answer on the dense P."""
    rng = np.random.default_rng(seed)
    lifted, plain = Spy(), dense()
    checked = 0
    for _ in range(12):
        prob = gram_problem(rng, int(rng.integers(LIFT_MIN_N, 121)))
        x = lifted.solve(prob).x
        assert lifted.seen[-1][1]
        x_dense = plain.solve(prob).x
        exact = polish(prob, x_dense)
        assert exact is not None
        scale = max(1.0, float(np.max(np.abs(exact))))
        assert np.max(np.abs(x - exact)) <= TOLERANCE["daqp"] * scale
        assert np.max(np.abs(x_dense - exact)) <= TOLERANCE["daqp"] * scale
        assert prob.violation(x) <= 1e-9
        checked += 1
    assert checked == 12


def test_a_lifted_solve_daqp_refuses_falls_back_to_the_dense_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """When daqp fails the lifted problem (here: it raises on it), the problem as given is solved: the same
    optimum, no error."""
    rng = np.random.default_rng(7)
    prob = gram_problem(rng, 60)
    be = DaqpBackend()
    real = be._solve
    calls: list[int] = []

    def flaky(H: np.ndarray, *args: object, **kw: object) -> object:
        calls.append(H.shape[0])
        if H.shape[0] != prob.n:
            raise RuntimeError("refused")
        return real(H, *args, **kw)

    monkeypatch.setattr(be, "_solve", flaky)
    x = be.solve(prob).x
    assert calls[0] > prob.n and prob.n in calls  # lifted tried first, then the dense P
    np.testing.assert_allclose(x, dense().solve(prob).x, rtol=0.0, atol=1e-12)


def _stacks(robot_n: int) -> dict[str, Callable[[], TaskStack]]:
    tip = f"j{robot_n}"

    def pose_and_posture() -> TaskStack:  # the fused path; the posture given a level is an identity block
        circle = Circle(0.2, 2.0, ("x", "y"))
        return TaskStack([FrameTask(tip, circle, gain=5.0), PostureTask(gain=1.0, weight=0.3, priority=1)])

    def bounds() -> TaskStack:  # the template's build, with bound rows (the snake's set)
        clear = Clearance(f"j{robot_n // 2}", [0.3, 0.2, 0.1], 0.05)
        subs = [BoundSubtask(clear, lower=0.02, rate=2.0, priority=1), GradientSubtask(JointCentering(), gain=-1.0)]
        return TaskStack([FrameTask(tip, Circle(0.2, 2.0, ("x", "y")), gain=5.0)], subs)

    def two_frames_null_posture() -> TaskStack:  # the per-task lean path (lm_damping set: not fused)
        tasks = [
            FrameTask(tip, Circle(0.1, 2.0, ("x", "z")), axes="position", gain=5.0),
            FrameTask(f"j{robot_n - 8}", axes="orientation", weight=0.5),
            PostureTask(gain=2.0),
        ]
        return TaskStack(tasks)

    return {"pose_and_posture": pose_and_posture, "bounds": bounds, "two_frames": two_frames_null_posture}


@pytest.mark.parametrize("case", ["pose_and_posture", "bounds", "two_frames"])
def test_wqp_gives_its_hessians_factor_and_steps_as_with_the_dense_qp(case: str) -> None:
    """A 48-joint chain under tight velocity limits, on the three paths that hand a QP to the backend: every QP
    carries (F, δ) with FᵀF + δI = P (to 1e-12 relative), nearly all are solved lifted, and each step's q̇ is the
    exact optimum of its QP as closely as daqp's answer on the dense P is (both checked against the verified KKT
    optimum)."""
    n = 48
    rng = np.random.default_rng(3)
    robot = random_dh_robot(rng, n, with_prismatic=False)
    stack = _stacks(n)[case]()
    spy = Spy()
    options = {"lm_damping": 0.1} if case == "two_frames" else {}
    slow = {"velocity_limits": {f"j{i + 1}": 0.02 for i in range(n)}}
    res = WeightedQPResolver(backend=spy, limits=slow, **options)
    q = rng.uniform(-1.0, 1.0, n)
    robot.update(q)
    stack.reset(robot)
    plain = dense()
    solved = 0
    for k in range(40):
        out = res.step(robot, stack, q, 0.01 * k, 0.01)
        assert out.fallback is None
        q = robot.integrate(q, out.dq, 0.01)
    assert spy.seen, "no QP was solved: the case does not test the lifted path"
    lifted_solves = sum(lifted for _, lifted in spy.seen)
    # (a lifted problem daqp does not solve — exit flag −2, cycling, on 1 of the 40 bound-row QPs at δ = 1e-8 — is
    # solved dense: the test below holds that answer to the same accuracy)
    assert lifted_solves >= 0.8 * len(spy.seen)
    for prob, _ in spy.seen:
        assert prob.factor is not None
        F, delta = prob.factor
        scale = float(np.max(np.abs(prob.P)))
        assert np.max(np.abs(F.T @ F + delta * np.eye(n) - prob.P)) <= 1e-12 * scale
        x_lift, x_dense = DaqpBackend().solve(prob).x, plain.solve(prob).x
        exact = polish(prob, x_dense)
        if exact is None:
            continue
        err_lift, err_dense = np.max(np.abs(x_lift - exact)), np.max(np.abs(x_dense - exact))
        assert err_lift <= max(4.0 * err_dense, 1e-9)
        solved += 1
    assert solved >= len(spy.seen) // 2
