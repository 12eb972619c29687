"""The closed-form resolvers: Moore–Penrose conditions (5.4), rank/null split (5.7, 5.8), the state-feedback law."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from redundik.errors import ResolverError
from redundik.kinematics import DHRow, from_dh
from redundik.resolvers import FeedbackResolver, PinvResolver, pseudo_inverse
from redundik.simulation import simulate
from redundik.tasks import (
    BoundSubtask,
    FrameTask,
    GradientSubtask,
    JointCentering,
    JointSine2,
    Line,
    TargetSubtask,
    TaskStack,
    VirtualPoint,
)

from .helpers import planar3r, random_dh_robot


@settings(max_examples=60, deadline=None)
@given(
    m=st.integers(1, 6),
    n=st.integers(1, 9),
    rank_drop=st.integers(0, 2),
    seed=st.integers(0, 2**31 - 1),
)
def test_moore_penrose_conditions(m: int, n: int, rank_drop: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = max(min(m, n) - rank_drop, 1)
    A = rng.normal(size=(m, r)) @ rng.normal(size=(r, n))  # rank r, possibly deficient
    P = pseudo_inverse(A, epsilon=0.0)  # undamped
    X = P.pinv
    tol = 1e-8 * max(1.0, np.linalg.norm(A) * np.linalg.norm(X)) ** 2
    np.testing.assert_allclose(A @ X @ A, A, atol=tol)  # (1) A A⁺ A = A
    np.testing.assert_allclose(X @ A @ X, X, atol=tol)  # (2) A⁺ A A⁺ = A⁺
    np.testing.assert_allclose((A @ X).T, A @ X, atol=tol)  # (3) (A A⁺)ᵀ = A A⁺
    np.testing.assert_allclose((X @ A).T, X @ A, atol=tol)  # (4) (A⁺ A)ᵀ = A⁺ A
    assert P.rank == np.linalg.matrix_rank(A)
    Pn = P.null_projector
    np.testing.assert_allclose(Pn @ Pn, Pn, atol=1e-10)  # idempotent
    np.testing.assert_allclose(A @ Pn, 0, atol=1e-9 * max(1.0, np.linalg.norm(A)))  # A(I − A⁺A) = 0


def test_full_row_rank_pinv_is_the_chapter_closed_form() -> None:
    J = np.random.default_rng(0).normal(size=(2, 3))
    np.testing.assert_allclose(pseudo_inverse(J).pinv, J.T @ np.linalg.inv(J @ J.T), atol=1e-12)  # J⁺ = Jᵀ(JJᵀ)⁻¹


def test_damping_bounds_the_velocity_near_singularity_and_is_reported() -> None:
    J = np.array([[1.0, 0.0, 0.0], [0.0, 1e-6, 0.0]])
    und = pseudo_inverse(J, epsilon=0.0)
    dmp = pseudo_inverse(J, epsilon=1e-2, max_damping=5e-2)
    assert not und.damped and dmp.damped and dmp.damping == pytest.approx(5e-2, rel=1e-6)
    v = np.array([0.0, 1.0])
    assert np.linalg.norm(und.pinv @ v) > 1e5
    assert np.linalg.norm(dmp.pinv @ v) <= 1.0 / (2 * dmp.damping) + 1e-12  # ‖J⁺_λ‖ ≤ 1/(2λ)
    # far from the singularity the rule gives the exact pseudo-inverse
    assert not pseudo_inverse(np.eye(2, 3), epsilon=1e-2).damped


def _stack_3r(gain: float = 1.0) -> TaskStack:
    subs = [GradientSubtask(JointSine2("3"), gain=gain)] if gain else []
    return TaskStack([FrameTask("3", Line([0.2, -0.4]), axes="planar")], subs)


@pytest.mark.parametrize("seed", range(5))
def test_rank_and_null_parts_are_orthogonal_and_null_part_does_not_move_the_task(seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = random_dh_robot(rng)
    q = robot.random_configuration(rng)
    robot.update(q)
    stack = TaskStack(
        [FrameTask("j7", Line([0.1, 0.0, -0.2]), axes="position")],
        [GradientSubtask(JointCentering(), gain=-1.0), GradientSubtask(VirtualPoint("j3", [0.5, 0.5, 0.5]), gain=-0.5)],
    )
    stack.reset(robot)
    res = PinvResolver().solve(robot, stack, 0.0, 0.01)
    J = robot.frame_jacobian("j7")[:3]
    assert res.dq_rank @ res.dq_null == pytest.approx(0.0, abs=1e-10)  # q̇_r ⊥ q̇_n
    np.testing.assert_allclose(J @ res.dq_null, 0.0, atol=1e-10)  # J q̇_n = 0
    np.testing.assert_allclose(J @ res.dq, [0.1, 0.0, -0.2], atol=1e-10)  # main task met exactly
    np.testing.assert_allclose(res.dq, res.dq_rank + res.dq_null)


@pytest.mark.parametrize("k", [0.5, 1.0, -1.0])
def test_null_motion_moves_the_potential_in_the_sign_of_k(k: float) -> None:
    # ṗ_n = k ηᵀ(I − J⁺J)η ≥ 0 for k > 0 (≤ 0 for k < 0), at many random configurations
    rng = np.random.default_rng(11)
    robot = planar3r()
    pot = JointSine2("3")
    for _ in range(50):
        q = robot.random_configuration(rng)
        robot.update(q)
        stack = TaskStack([FrameTask("3", Line([0.2, -0.4]), axes="planar")], [GradientSubtask(pot, gain=k)])
        stack.reset(robot)
        res = PinvResolver().solve(robot, stack, 0.0, 0.01)
        pdot_n = pot.gradient(robot) @ res.dq_null
        assert np.sign(k) * pdot_n >= -1e-12


def test_chapter_3r_case_2_drives_theta3_towards_minus_90() -> None:
    robot = planar3r()
    q0 = np.deg2rad([110.0, -40.0, -30.0])
    rank = simulate(robot, _stack_3r(0.0), PinvResolver(), q0, dt=0.01, steps=500)
    null = simulate(robot, _stack_3r(1.0), PinvResolver(), q0, dt=0.01, steps=500)
    assert np.rad2deg(null.q[-1, 2]) == pytest.approx(-90.0, abs=5.0)
    assert abs(np.rad2deg(rank.q[-1, 2]) + 90.0) > 20.0
    # both keep the tip on the line within a few millimetres (open-loop Euler drift only)
    assert rank.max_task_error < 5e-3 and null.max_task_error < 5e-3


def test_feedback_law_converges_at_rate_k() -> None:
    robot = planar3r()
    q0 = np.deg2rad([110.0, -40.0, -30.0])
    K, pd = 2.0, 0.9
    stack = TaskStack(
        [FrameTask("3", Line([0.2, -0.4]), axes="planar", gain=5.0)],
        [TargetSubtask(JointSine2("3"), target=pd, rate=K)],
    )
    dt = 1e-3
    log = simulate(robot, stack, FeedbackResolver(), q0, dt=dt, steps=1500)
    p = log.potentials["sin2_3"]
    expected = pd + (p[0] - pd) * np.exp(-K * log.t)  # y − y_d decays as e^{−Kt}
    np.testing.assert_allclose(p, expected, atol=2e-3)
    # and the decay rate is K, not just the end value: fit log|p − p_d|
    sel = slice(100, 1000)
    rate = -np.polyfit(log.t[sel], np.log(np.abs(p[sel] - pd)), 1)[0]
    assert rate == pytest.approx(K, rel=0.02)


def test_feedback_refuses_more_subtasks_than_null_space_dimension() -> None:
    robot = planar3r()
    robot.update(np.deg2rad([110.0, -40.0, -30.0]))
    stack = TaskStack(
        [FrameTask("3", Line([0.2, -0.4]), axes="planar")],
        [
            TargetSubtask(JointSine2("3"), target=1.0),
            TargetSubtask(JointSine2("2"), target=1.0),
        ],
    )
    stack.reset(robot)
    with pytest.raises(ResolverError, match=r"2 target subtasks but the null space of the 2×3 .* has dimension 1"):
        FeedbackResolver().check(robot, stack)


def test_feedback_with_singular_decoupling_matrix_gives_no_nan() -> None:
    robot = planar3r()
    q = np.array([0.3, 0.4, 0.0])  # η = (0, 0, sin 2θ3) = 0 at θ3 = 0: D = 0
    robot.update(q)
    stack = TaskStack(
        [FrameTask("3", Line([0.2, -0.4]), axes="planar")],
        [TargetSubtask(JointSine2("3"), target=1.0)],
    )
    stack.reset(robot)
    res = FeedbackResolver().solve(robot, stack, 0.0, 0.01)
    # D = 0 exactly: the kernel truncates the zero direction (k = 0), no damping, no 0/0, and q̇ = J⁺V
    assert np.all(np.isfinite(res.dq)) and res.fallback is None and res.info["D_rank"] == 0
    np.testing.assert_allclose(res.gains, [0.0])
    J = res.terms[0].J
    np.testing.assert_allclose(res.dq, np.linalg.pinv(J) @ res.terms[0].v, atol=1e-12)


def test_pinv_near_singularity_stays_bounded_and_says_it_damped() -> None:
    robot = from_dh([DHRow("1", a=1), DHRow("2", a=1), DHRow("3", a=1)])
    q = np.array([0.2, 1e-5, -1e-5])  # almost stretched: J has a tiny singular value
    robot.update(q)
    stack = TaskStack([FrameTask("3", Line([-1.0, 0.0]), axes="planar")])
    stack.reset(robot)
    res = PinvResolver().solve(robot, stack, 0.0, 0.01)
    assert res.damped and np.all(np.isfinite(res.dq)) and np.linalg.norm(res.dq) < 50


def test_pinv_refuses_bounds_subtasks() -> None:
    robot = planar3r()
    robot.update(robot.neutral())
    stack = TaskStack([], [BoundSubtask(JointSine2("3"), lower=0.1)])
    with pytest.raises(ResolverError, match="'sin2_3' is a bound subtask; pinv accepts gradient subtasks"):
        PinvResolver().check(robot, stack)
