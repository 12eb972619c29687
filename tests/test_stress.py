"""What a stress run found (issue 8, item 12), each as a test: zero-row QP blocks, never-empty limit boxes from
outside the limits with rate limits, hqp's null-space level on every backend, the stable gain range, divergence,
and a small version of ``benchmarks/stress_resolvers.py``."""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError, SolverError
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir, from_urdf
from redundik.resolvers.divergence import ERROR_STREAK, DivergenceWarning
from redundik.resolvers.linalg import damped_svd
from redundik.resolvers.qp import QPProblem, make_backend
from redundik.resolvers.qp.limits import JointLimits, LimitBox
from tests.test_qp_helpers import BACKENDS, CASE2_Q0, case2_robot, case2_stack, prepared, qp_tolerance

ROOT = Path(__file__).resolve().parents[1]


def _stress_module():
    spec = importlib.util.spec_from_file_location("stress_resolvers", ROOT / "benchmarks" / "stress_resolvers.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["stress_resolvers"] = module
    spec.loader.exec_module(module)
    return module


# ---------------------------------------------------------------------------------------------- zero-row blocks
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("g_shape", [(0, 3), (0, 0)])
@pytest.mark.parametrize("a_shape", [(0, 3), (0, 0)])
@pytest.mark.parametrize("bounded", [True, False])
def test_zero_row_blocks_of_any_shape(backend: str, g_shape, a_shape, bounded: bool) -> None:
    P, q = np.diag([1.0, 2.0, 4.0]), np.array([1.0, -2.0, 4.0])
    lb, ub = (np.full(3, -0.5), np.full(3, 0.5)) if bounded else (np.full(3, -np.inf), np.full(3, np.inf))
    prob = QPProblem(P, q, np.zeros(g_shape), np.zeros(0), np.zeros(a_shape), np.zeros(0), lb, ub, "zero rows")
    x = make_backend(backend).solve(prob).x
    expected = np.clip(-q / np.diag(P), lb, ub)  # separable: the clipped unconstrained optimum
    assert x.shape == (3,)
    np.testing.assert_allclose(x, expected, atol=qp_tolerance(backend, expected))


@pytest.mark.parametrize("backend", BACKENDS)
def test_constrained_wqp_step_with_a_subtask_never_falls_back(backend: str) -> None:
    robot = case2_robot(velocity=0.3)  # joint 3 hits its velocity limit: the backend is called
    res = rk.WeightedQPResolver(backend=backend)
    stack = case2_stack()
    prepared(res, robot, stack, CASE2_Q0)
    out = res.step(robot, stack, CASE2_Q0, 0.0, 0.01)
    assert out.info["qp"] == 1 and out.fallback is None and out.info["backend"] == res.backend.name
    ref = rk.WeightedQPResolver(backend="daqp")
    prepared(ref, robot, stack, CASE2_Q0)
    expected = ref.step(robot, stack, CASE2_Q0, 0.0, 0.01).dq
    assert expected[2] == pytest.approx(-0.3)  # joint 3 on its velocity limit
    np.testing.assert_allclose(out.dq, expected, atol=qp_tolerance(backend, expected))


# ---------------------------------------------------------------------------------------------- limit boxes
def test_the_box_is_never_empty_from_outside_the_limits_with_rate_limits() -> None:
    robot = case2_robot(lower=-0.1, upper=0.1, velocity=1.0)  # a short range and a small a_max: braking bites
    rng = np.random.default_rng(3)
    dt = 0.01
    for acc in (0.5, 1.0, 20.0):
        lim = JointLimits(acceleration=acc)
        lim.bind(robot)
        lo, hi = lim.lower_position, lim.upper_position
        for k in range(3000):
            q = rng.uniform(-0.4, 0.4, 3)  # mostly outside, by up to 0.3 rad
            box = lim.box(robot, q, dt, rng.uniform(-2, 2, 3) if k % 2 else None)
            assert np.all(box.lb <= box.ub), (acc, q, box.lb, box.ub)
            dq = box.clip(rng.uniform(-5, 5, 3))
            q1 = q + dq * dt
            inside = (q >= lo) & (q <= hi)
            assert np.all(np.abs(dq) <= 1.0 + 1e-12)  # velocity: hard
            assert np.all((q1[inside] >= lo[inside] - 1e-12) & (q1[inside] <= hi[inside] + 1e-12))  # position: hard
            out0 = np.maximum(lo - q, 0) + np.maximum(q - hi, 0)
            out1 = np.maximum(lo - q1, 0) + np.maximum(q1 - hi, 0)
            assert np.all(out1[~inside] <= out0[~inside] + 1e-12)  # from outside: never further out


@pytest.mark.parametrize("resolver", ["wqp", "hqp"])
def test_a_start_outside_the_limits_with_rate_limits_comes_back_inside(resolver: str) -> None:
    robot = case2_robot(lower=-0.6, upper=0.6, velocity=1.0)
    q = np.array([0.65, -0.62, 0.7])  # every joint 0.02 to 0.1 rad outside
    res = rk.make_resolver(resolver, limits={"acceleration": 2.0})
    stack = case2_stack()
    prepared(res, robot, stack, q)
    for k in range(100):
        out = res.step(robot, stack, q, k * 0.01, 0.01)
        assert out.fallback is None, out.fallback
        q = robot.integrate(q, out.dq, 0.01)
    assert np.all(np.abs(q) <= 0.6 + 1e-12)


# ---------------------------------------------------------------------------------------------- hqp, every backend
def test_hqp_null_space_level_is_solved_by_every_backend() -> None:
    """The stress episode where osqp and proxsuite called hqp's null-space gradient level (always feasible)
    infeasible / stalled: every backend now gives daqp's answer and no backend failure."""
    stress = _stress_module()
    episode = stress.make_episode(0, 50)
    for backend in BACKENDS:
        r = stress.run_pair("hqp", backend, [episode])
        assert r.violations == 0 and r.nans == 0, backend
        assert r.fallbacks.get(stress.FAILURE, 0) == 0, (backend, r.first)


# ---------------------------------------------------------------------------------------------- gain·dt
def _free_flyer() -> rk.RobotModel:
    return from_urdf(example_robot_data_dir() / EXAMPLE_ROBOTS["ur5"][0], free_flyer=True, name="ur5_ff")


def _hold_stack(robot: rk.RobotModel, q: np.ndarray, gain: float) -> tuple[rk.TaskStack, rk.FrameTask]:
    robot.update(q)
    task = rk.FrameTask("tool0", axes="pose", gain=gain)
    target = robot.frame_pose("tool0").homogeneous.copy()
    target[:3, 3] += [0.05, -0.03, 0.02]
    task.set_target(target)
    return rk.TaskStack([task]), task


def test_free_flyer_at_gain_dt_1_9_stays_bounded_and_2_5_is_refused() -> None:
    robot = _free_flyer()
    dt = 0.01
    q0 = robot.neutral()
    stack, _ = _hold_stack(robot, q0, 1.9 / dt)
    res = rk.PinvResolver()
    q, errors, speeds = q0.copy(), [], []
    with warnings.catch_warnings():
        warnings.simplefilter("error", DivergenceWarning)  # a bounded loop is never flagged
        for k in range(200):
            out = res.step(robot, stack, q, k * dt, dt)
            errors.append(out.task_error)
            speeds.append(float(np.abs(out.dq).max()))
            assert "diverging" not in out.info
            q = robot.integrate(q, out.dq, dt)
    assert max(speeds) < 20.0  # bounded: the first step's |q̇| is the largest
    assert errors[-1] < 1e-6 * errors[0]  # e ← (1 − 1.9) e = −0.9 e: oscillates and converges
    stack, _ = _hold_stack(robot, q0, 2.5 / dt)
    with pytest.raises(ResolverError, match=r"K·dt = 2.5 > 2 makes the first-order loop diverge"):
        rk.PinvResolver().step(robot, stack, q0, 0.0, dt)


def test_a_diverging_loop_is_flagged() -> None:
    """A plant integrated with 2.5× the dt the resolver is given (K·dt_true = 2.5) passes the gain check but
    diverges: the steps are flagged and a DivergenceWarning is issued once."""
    robot = _free_flyer()
    dt = 0.01
    q = robot.neutral()
    stack, _ = _hold_stack(robot, q, 1.0 / dt)
    res = rk.PinvResolver(max_joint_speed=None)  # (the default cap would bound q̇ and keep the loop from diverging)
    flagged = []
    with pytest.warns(DivergenceWarning, match="diverges") as record:
        for k in range(ERROR_STREAK + 2):
            out = res.step(robot, stack, q, k * dt, dt)
            flagged.append("diverging" in out.info)
            q = robot.integrate(q, out.dq, 2.5 * dt)  # the mistake: the plant's step is not the dt given
    assert not any(flagged[:ERROR_STREAK]) and all(flagged[ERROR_STREAK:])
    assert len([w for w in record if issubclass(w.category, DivergenceWarning)]) == 1


# ---------------------------------------------------------------------------------------------- small stress run
def test_small_stress_run_every_backend() -> None:
    """A few hundred steps per (resolver, backend) of the stress benchmark: no violation, no NaN, and fallbacks
    only where the problem is truly infeasible (classified), the same on every backend as on daqp."""
    stress = _stress_module()
    results = stress.run(200, episode_steps=40, seed=100, log=lambda msg: None)
    assert {r.backend for r in results} == set(BACKENDS)
    for r in results:
        assert r.steps == 200
        assert r.violations == 0 and r.nans == 0, (r.resolver, r.backend, r.max_violation)
        assert r.silent == 0, (r.resolver, r.backend, r.first)
        assert r.fallbacks.get(stress.FAILURE, 0) == 0, (r.resolver, r.backend, r.first)
        assert set(r.fallbacks) <= {stress.INFEASIBLE, stress.CONTRADICTED, stress.RETRIED, stress.FAILURE}
    assert any(r.fallbacks for r in results)  # the episodes do contain infeasible problems (the counts are real)


@pytest.mark.parametrize("backend", BACKENDS)
def test_hqp_levels_the_stress_run_found_hard_are_solved(backend: str) -> None:
    """Stress episodes whose hqp levels every backend once failed on although they are feasible by construction:
    joints whose box is one value (episode 14: proxsuite "primal infeasible" on a 3e-7-wide window), a slack of
    19.5 against a 1e-6 window for u (episode 25, step 9: proxsuite), a slack of 267 (episode 158, step 6: daqp
    exit flag 4 at primal_tol 1e-10), a degenerate vertex, 5 rows active in 4 unknowns (episode 209, step 37:
    daqp "infeasible"). Fallbacks there must be true infeasibility or contradiction, never a backend failure."""
    stress = _stress_module()
    episodes = [stress.make_episode(s, k) for s, k in ((14, 3), (25, 12), (158, 9), (209, 40))]
    r = stress.run_pair("hqp", backend, episodes)
    assert r.violations == 0 and r.nans == 0
    assert r.fallbacks.get(stress.FAILURE, 0) == 0, r.first
    assert r.fallbacks.get(stress.INFEASIBLE, 0) + r.fallbacks.get(stress.CONTRADICTED, 0) > 0


def test_pinned_joints_of_a_box() -> None:
    """``LimitBox.pinned``: a joint whose window is a single value (to 1e-12 relative), and no other."""
    lb = np.array([0.0, -1.0, 2.0, -np.inf, 0.5])
    ub = np.array([0.0, 1.0, 2.0 + 1e-13, 0.0, 0.5 + 1e-6])
    inf = np.full(5, np.inf)
    box = LimitBox(lb, ub, -inf, inf, inf)
    assert box.pinned().tolist() == [True, False, True, False, False]


@pytest.mark.parametrize("backend", BACKENDS)
def test_hqp_with_every_joint_pinned_still_reports_a_contradicted_bound(backend: str) -> None:
    """Every joint's box is one value (position limits squeezed onto q): no unknown is left, q̇ = 0 exactly, and
    the bound level below still reports its contradiction instead of being skipped unseen (an empty SVD raised
    here before, and a level with inequalities after the degrees of freedom ran out was never checked)."""
    robot = rk.from_dh([rk.DHRow(str(i + 1), a=1.0, lower=-2, upper=2, velocity=1.0) for i in range(3)])
    q = np.radians([30.0, 60.0, -30.0])
    pin = {str(i + 1): float(q[i]) for i in range(3)}
    res = rk.make_resolver("hqp", backend=backend, limits={"lower": pin, "upper": pin})
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], [rk.BoundSubtask(rk.JointSine2("3"), lower=0.9)]
    )
    robot.update(q)
    stack.reset(robot)
    step = res.step(robot, stack, q, 0.0, 0.01)
    assert np.array_equal(step.dq, np.zeros(3))
    assert step.fallback is None and 1 in step.info["contradicted_levels"]  # type: ignore[operator]
    assert step.relaxed == (stack.subtasks[0].name,)


def test_damped_svd_of_a_matrix_without_columns() -> None:

    d = damped_svd(np.zeros((3, 0)), epsilon=1e-2, max_damping=5e-2)
    assert d.solve(np.ones(3)).shape == (0,) and d.null_basis.shape == (0, 0) and d.rank == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_primal_infeasible_qp_is_never_returned_as_solved(backend: str) -> None:
    """The box 1.6 ≤ x₀ ≤ 1.6 against the row x₀ + x₁ ≤ −2 with |x₁| ≤ 0.1: infeasible. OSQP's answer is an
    infeasibility certificate (‖x‖ ≈ 1e9); verified on its scale, the polish accepted a point 1.3 outside (a
    silent wrong answer in the stress run's episode 161, where wqp then reported no fallback)."""
    lb, ub = np.array([1.6, -0.1, -1.0]), np.array([1.6, 0.1, 1.0])
    G, h = np.array([[1.0, 1.0, 0.0]]), np.array([-2.0])
    prob = QPProblem(np.eye(3), np.zeros(3), G, h, np.zeros((0, 3)), np.zeros(0), lb, ub, "infeasible")
    with pytest.raises(SolverError):
        make_backend(backend).solve(prob)


@pytest.mark.parametrize("backend", BACKENDS)
def test_wqp_reports_the_relaxation_of_an_infeasible_bound_on_every_backend(backend: str) -> None:
    stress = _stress_module()
    r = stress.run_pair("wqp", backend, [stress.make_episode(161, 1)])
    assert r.fallbacks.get(stress.INFEASIBLE, 0) == 1 and r.violations == 0, (r.fallbacks, r.first)
