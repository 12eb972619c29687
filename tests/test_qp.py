"""wqp, tasks as QP rows, backends and fallbacks."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import redundik as rk
from redundik.errors import ResolverError, SolverError
from redundik.resolvers.qp import Backend, QPProblem, QPSolution, available_backends, build_levels
from redundik.resolvers.qp import make_backend as make_qp_backend
from tests.test_qp_helpers import (
    BACKENDS,
    CASE2_Q0,
    case2_robot,
    case2_stack,
    prepared,
    qp_tolerance,
    random_robot,
    tip,
)


# ---------------------------------------------------------------------------------------------- tasks as QP rows
def test_every_subtask_mode_becomes_the_documented_rows() -> None:
    robot = case2_robot()
    robot.update(CASE2_Q0)
    p3 = rk.JointSine2("3")
    p1 = rk.JointValue("1", 0.5, name="v1")
    dt = 0.01
    subs = [
        rk.GradientSubtask(p3, gain=2.0),
        rk.GradientSubtask(rk.JointCentering(center=[0, 0, 0], name="c"), gain=-1.0),
        rk.TargetSubtask(p1, target=0.3, rate=4.0, target_rate=0.1, weight=2.0, priority=2),
        rk.BoundSubtask(rk.JointValue("2", 0.0, name="b2"), lower=0.1, upper=0.9, rate=5.0, priority=2),
    ]
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], subs)
    stack.reset(robot)
    terms = stack.evaluate(robot, 0.0)
    levels = build_levels(robot, stack, terms, stack.layout(), dt)
    # main task at 0, the target and bound subtasks at their priority 2, the null-space objective last
    assert [lv.priority for lv in levels] == [0, 2, 3]
    np.testing.assert_array_equal(levels[0].J, robot.frame_jacobian("3")[:2])
    q = CASE2_Q0
    z = 2.0 * np.array([0, 0, np.sin(2 * q[2])]) - 1.0 * q  # Σ k η with η_centering = q − q_c
    np.testing.assert_allclose(levels[2].z, z, atol=1e-15)
    assert levels[2].pure_null_objective and levels[0].z is None and levels[1].z is None
    lv2 = levels[1]
    np.testing.assert_allclose(lv2.J, [[2 * (q[0] - 0.5), 0, 0]])
    np.testing.assert_allclose(lv2.v, [0.1 + 4.0 * (0.3 - (q[0] - 0.5) ** 2)])
    assert lv2.w.tolist() == [2.0]
    p2, eta2 = q[1] ** 2, 2 * q[1]
    gamma = min(5.0, 1 / dt)
    np.testing.assert_allclose(lv2.C, [[0, -eta2, 0], [0, eta2, 0]])
    np.testing.assert_allclose(lv2.d, [-gamma * (0.1 - p2), gamma * (0.9 - p2)])
    assert lv2.c_names == ["b2:lower", "b2:upper"]


def test_potential_task_drives_the_potential_at_rate_k() -> None:
    robot = case2_robot()
    stack = rk.TaskStack([rk.PotentialTask(rk.JointSine2("3", name="s"), target=0.9, rate=2.0)])
    for name in ("wqp", "hqp"):
        log = rk.simulate(robot, stack, rk.make_resolver(name, limits=False), CASE2_Q0, dt=0.001, steps=1000)
        e = log.task_errors["s"]  # |p_d − p|
        # ė = −K e: after 1 s the error is e0·exp(−2) (to the Euler step and the weighted QP's small damping)
        assert abs(e[-1] - e[0] * np.exp(-2.0)) < 2e-3 * abs(e[0]), name


# ---------------------------------------------------------------------------------------------- wqp
def test_wqp_unconstrained_equals_the_normal_equations() -> None:
    robot = case2_robot()
    stack = case2_stack()
    stack.tasks[0].weight = 7.0
    res = rk.WeightedQPResolver(limits=False, damping=1e-3)
    prepared(res, robot, stack, CASE2_Q0)
    out = res.step(robot, stack, CASE2_Q0, 0.0, 0.01)
    J = robot.frame_jacobian("3")[:2]
    z = np.array([0, 0, np.sin(2 * CASE2_Q0[2])])
    # minimise 7‖Jx − v‖² + ρ‖x − z‖² + 1e-3·ρ‖x‖² (ρ = 1e-4: the null-space objective is level 1; λ is relative to
    # the lowest level's weight) by stacked least squares (numpy's lstsq, not the resolver's solve)
    rho = 1e-4
    A = np.vstack([np.sqrt(7.0) * J, np.sqrt(rho) * np.eye(3), np.sqrt(1e-3 * rho) * np.eye(3)])
    b = np.concatenate([np.sqrt(7.0) * np.array([0.2, -0.4]), np.sqrt(rho) * z, np.zeros(3)])
    np.testing.assert_allclose(out.dq, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-12)
    assert out.info["qp"] == 0 and out.fallback is None


def test_wqp_approaches_hqp_as_the_weight_ratio_grows() -> None:
    robot = random_robot(np.random.default_rng(11), 7)
    q = robot.random_configuration(np.random.default_rng(12))
    stack = rk.TaskStack(
        [rk.FrameTask(tip(robot), rk.Line([0.1, -0.2, 0.05]), axes="position", gain=1.0)],
        [
            rk.GradientSubtask(rk.JointCentering(), gain=-2.0),
            rk.GradientSubtask(rk.JointSine2(robot.joint_names[2]), gain=1.0),
        ],
    )
    hqp = rk.HierarchicalQPResolver(limits=False)
    prepared(hqp, robot, stack, q)
    ref = hqp.step(robot, stack, q, 0.0, 0.01).dq
    diffs = []
    for rho in 10.0 ** -np.arange(0, 7):
        wqp = rk.WeightedQPResolver(limits=False, damping=0.0, level_ratio=min(float(rho), 0.999))
        prepared(wqp, robot, stack, q)
        diffs.append(float(np.linalg.norm(wqp.step(robot, stack, q, 0.0, 0.01).dq - ref)))
    assert all(b < a for a, b in itertools.pairwise(diffs)), diffs
    assert diffs[-1] < 1e-5 * diffs[0]


def test_wqp_with_limits_solves_a_qp_that_satisfies_the_kkt_conditions() -> None:
    robot = case2_robot(velocity=0.3)
    stack = case2_stack()
    res = rk.WeightedQPResolver()
    prepared(res, robot, stack, CASE2_Q0)
    prob = res.build(robot, stack, 0.0, 0.01).problem
    out = res.step(robot, stack, CASE2_Q0, 0.0, 0.01)
    x = out.dq
    assert out.info["qp"] == 1
    # bound-constrained QP optimality: gradient g = Px + q is 0 on free variables, ≤ 0 at an upper bound, ≥ 0 at a lower
    g = prob.P @ x + prob.q
    at_ub = np.isclose(x, prob.ub, atol=1e-9)
    at_lb = np.isclose(x, prob.lb, atol=1e-9)
    free = ~(at_ub | at_lb)
    assert at_lb.any() or at_ub.any()
    np.testing.assert_allclose(g[free], 0.0, atol=1e-9)
    assert np.all(g[at_ub] <= 1e-9) and np.all(g[at_lb] >= -1e-9)


# ---------------------------------------------------------------------------------------------- backends
def _random_qp(rng: np.random.Generator, n: int, p: int, e: int) -> QPProblem:
    M = rng.normal(size=(n + 2, n))
    P = M.T @ M + 0.1 * np.eye(n)
    x0 = rng.uniform(-0.5, 0.5, n)  # a feasible point
    G = rng.normal(size=(p, n))
    h = G @ x0 + rng.uniform(0.0, 0.5, p)
    A = rng.normal(size=(e, n))
    b = A @ x0
    lb = x0 - rng.uniform(0.0, 1.0, n)
    ub = x0 + rng.uniform(0.0, 1.0, n)
    lb[rng.random(n) < 0.3] = -np.inf
    return QPProblem(P, rng.normal(size=n) * 3, G, h, A, b, lb, ub, "random")


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 12), p=st.integers(0, 8), e=st.integers(0, 2))
def test_every_backend_gives_the_same_answer_within_its_tolerance(seed: int, n: int, p: int, e: int) -> None:
    prob = _random_qp(np.random.default_rng(seed), n, p, min(e, n - 1))
    answers = {name: make_qp_backend(name).solve(prob).x for name in BACKENDS}
    ref = answers["quadprog"]
    assert prob.violation(ref) < 1e-9
    for name, x in answers.items():
        tol = qp_tolerance(name, ref)
        np.testing.assert_allclose(x, ref, atol=tol, err_msg=name)
        assert prob.violation(x) < max(tol, 1e-9), name


def test_unknown_backend_lists_the_installed_ones() -> None:
    with pytest.raises(SolverError) as err:
        rk.WeightedQPResolver(backend="gurobo")
    msg = str(err.value)
    assert "unknown QP backend 'gurobo'" in msg
    for name in available_backends():
        assert name in msg
    with pytest.raises(ResolverError, match="gurobo"):
        rk.make_resolver("hqp", backend="gurobo")
    assert available_backends()[0] == "daqp"


def test_qpsolvers_prefixed_backend_and_problem_roundtrip(tmp_path) -> None:
    prob = _random_qp(np.random.default_rng(5), 6, 3, 1)
    via = make_qp_backend("qpsolvers:quadprog").solve(prob).x
    np.testing.assert_allclose(via, make_qp_backend("daqp").solve(prob).x, atol=1e-8)
    path = str(tmp_path / "p.npz")
    prob.save(path)
    back = QPProblem.load(path)
    np.testing.assert_array_equal(back.G, prob.G)
    assert back.label == "random"
    with pytest.raises(SolverError, match="not installed"):
        make_qp_backend("qpsolvers:not_a_solver")


# ---------------------------------------------------------------------------------------------- fallbacks
class _Raising(Backend):
    name = "raising"

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        raise RuntimeError("boom")


class _NaN(Backend):
    name = "nan"

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        return QPSolution(np.full(problem.n, np.nan))


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
@pytest.mark.parametrize("backend", [_Raising, _NaN])
@pytest.mark.parametrize("velocity", [0.3, 0.05])
def test_a_failing_backend_falls_back_within_the_limits(resolver: str, backend: type, velocity: float) -> None:
    """A backend that raises or returns NaN: every step reports it and q̇ stays finite within the limits. Under
    ``hqp`` a level whose own optimum keeps the limits needs no backend: at 0.3 rad/s the tip task (level 0) is
    solved exactly and only the null-space level that the limit cuts is skipped; at 0.05 rad/s the tip task itself
    needs the QP and the step falls back to the clipped closed form."""
    robot = case2_robot(velocity=velocity)  # the velocity limit is active: a QP is needed
    stack = case2_stack()
    log = rk.simulate(robot, stack, rk.make_resolver(resolver, backend=backend()), CASE2_Q0, dt=0.01, steps=50)
    assert len(log.fallbacks) == 50
    why = log.fallbacks[0][1]
    if resolver == "hqp" and velocity == 0.3:
        assert "level 1 skipped" in why and backend.name in why, why
    else:
        assert "closed form" in why, why
    assert np.all(np.isfinite(log.dq))
    assert np.all(np.abs(log.dq) <= velocity + 1e-12)


def test_infeasible_bound_subtask_in_wqp_is_relaxed_not_fatal() -> None:
    """θ1 must reach ≥ 3 rad within one step-rate (γ = 1/dt) while its velocity is limited to 0.3 rad/s: infeasible."""
    robot = case2_robot(velocity=0.3, lower=-np.pi, upper=np.pi)
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [rk.BoundSubtask(rk.JointValue("1", -10.0, name="far"), lower=13.0**2, rate=0.0)],
    )
    log = rk.simulate(robot, stack, rk.WeightedQPResolver(), CASE2_Q0, dt=0.01, steps=30)
    assert not log.fallbacks  # the documented relaxation of an infeasible QP: relaxed, not an alarm
    assert log.relaxed and all(names == ("far",) for _, names in log.relaxed)
    assert np.all(np.isfinite(log.dq)) and np.all(np.abs(log.dq) <= 0.3 + 1e-12)
    # hqp gives the same bound its slack instead, pushed as hard as the limits allow, and reports the contradiction
    log_h = rk.simulate(robot, stack, rk.HierarchicalQPResolver(), CASE2_Q0, dt=0.01, steps=30)
    assert not log_h.fallbacks and len(log_h.relaxed) == 30
    assert all("far" in names for _, names in log_h.relaxed)
    plain = rk.simulate(robot, rk.TaskStack(stack.tasks), rk.HierarchicalQPResolver(), CASE2_Q0, dt=0.01, steps=30)
    assert np.all(log_h.dq[:-1, 0] > plain.dq[:-1, 0] + 5e-3)  # θ1 is pushed up, as far as the tip task lets it
    assert log_h.max_task_error < plain.max_task_error + 1e-6  # ... without giving up level 0


def test_resolver_options_are_validated_with_clear_messages() -> None:
    with pytest.raises(ResolverError, match="damping"):
        rk.WeightedQPResolver(damping=-1.0)
    with pytest.raises(ResolverError, match="regularization"):
        rk.HierarchicalQPResolver(regularization=0.0)
    with pytest.raises(ResolverError, match=r"unknown option\(s\) \['speed'\]"):
        rk.WeightedQPResolver(limits={"speed": 1.0})
    with pytest.raises(ResolverError, match="appears in level 0 and level 1"):
        rk.HierarchicalQPResolver(levels=[["a"], ["a"]])
    assert "wqp" in rk.resolvers.RESOLVERS and "hqp" in rk.resolvers.RESOLVERS


@pytest.mark.parametrize("limits", [None, {"acceleration": 4.0}, {"position_gain": 0.5}])
def test_wqp_lean_path_equals_the_general_template(limits: dict | None) -> None:
    """The lean path of a stack of tasks (rows, box, optimum and box test in one compiled call) gives the step the
    general build → resolve → clip template gives, with and without an active limit and a rate window."""
    from redundik.resolvers.qp.base import QPResolverBase

    robot = rk.load_example_robot("panda")
    rng = np.random.default_rng(5)
    lean, general = rk.make_resolver("wqp", limits=limits), rk.make_resolver("wqp", limits=limits)
    hand = rk.FrameTask("panda_hand", gain=50.0)
    stack = rk.TaskStack([hand, rk.PostureTask(gain=1.0)])
    lo, hi = robot.lower_limits[:7], robot.upper_limits[:7]
    qp_steps = 0
    general_prev: np.ndarray | None = None
    home = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    for k in range(60):
        q = home + rng.normal(0.0, 0.05, 9)
        q[7:] = 0.02
        if k % 2:  # every other step anywhere in the range, often near a limit: the box binds
            q[:7] = lo + (hi - lo) * rng.uniform(0.02, 0.98, 7)
        robot.update(q)
        if k == 0:
            stack.reset(robot)
        pose = robot.frame_pose("panda_hand").copy()
        pose.translation = pose.translation + rng.normal(0.0, 0.01, 3)
        hand.set_target(pose)
        a = lean.step(robot, stack, q, 0.0, 0.01)
        lean_prev = None if lean._dq_prev is None else lean._dq_prev.copy()
        general._dq_prev = general_prev
        robot.update(q)
        b = QPResolverBase.solve(general, robot, stack, 0.0, 0.01)
        general_prev = general._dq_prev.copy()
        np.testing.assert_allclose(a.dq, b.dq, atol=1e-10)
        np.testing.assert_allclose(lean_prev, general_prev, atol=1e-10)
        assert a.info["qp"] == b.info["qp"] and a.fallback == b.fallback is None
        assert a.info["active_limits"] == b.info["active_limits"]
        assert a.sigma_min == pytest.approx(b.sigma_min, rel=1e-12)
        qp_steps += int(a.info["qp"])
    assert qp_steps > 5  # the backend branch was taken; and without a tight rate window the shortcut too
    assert qp_steps < 55 or (limits is not None and "acceleration" in limits)


@pytest.mark.parametrize("backend", available_backends())
def test_every_backend_solves_a_problem_held_in_read_only_arrays(backend: str) -> None:
    """A batch hands the backend rows of broadcast (read-only) arrays; daqp's typed buffers refused them, and the
    batch's limit-bound problems silently went the slow way round (the single-problem step)."""
    rng = np.random.default_rng(2)
    n = 5
    M = rng.normal(size=(n, n))
    P, q = M @ M.T + np.eye(n), rng.normal(size=n) * 10.0
    lb, ub = np.broadcast_to(-0.1, (3, n))[1], np.broadcast_to(0.1, (3, n))[1]
    for a in (P, q):
        a.setflags(write=False)
    prob = QPProblem(P, q, np.zeros((0, n)), np.zeros(0), np.zeros((0, n)), np.zeros(0), lb, ub, "read-only")
    x = make_qp_backend(backend).solve(prob).x
    assert np.all(x >= -0.1 - 1e-6) and np.all(x <= 0.1 + 1e-6)
    assert np.abs(x).max() > 0.099  # a bound is active (the unconstrained optimum lies far outside)


def test_daqp_solves_an_ill_conditioned_feasible_step_it_used_to_stall_on() -> None:
    """A stress-run wqp step (episode 266, step 19: cond(P) ≈ 7e10, a rate window of 2e-5–8e-5 rad/s, one
    bound row with a narrow margin): daqp stopped with exit flag 4 at every tolerance although the QP is feasible;
    it now retries with P + εI and keeps the answer only once polished to this problem's exact optimum."""
    from pathlib import Path

    prob = QPProblem.load(str(Path(__file__).parent / "data" / "daqp_stall_wqp.npz"))
    x = make_qp_backend("daqp").solve(prob).x
    assert prob.violation(x) <= 1e-9
    if "quadprog" in available_backends():
        np.testing.assert_allclose(x, make_qp_backend("quadprog").solve(prob).x, atol=1e-9)
