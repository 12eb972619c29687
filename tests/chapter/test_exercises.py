"""Exercises 1–3 (section 5.5.2): the task runs and one-shot answers against hand formulas from the statements.

Hand formulas (geometry chosen in the configs, figures lost):
* PRRP (a2 = 1): p = (a2 c2 + d4 c23, a2 s2 + d4 s23, d1);
* RRP (a1 = 1): w = a1 (c1, s1) + d3 (c12, s12), z3 = (c12, s12);
* RPR (a3 = 1): tip = d2 (c1, s1) + a3 (c13, s13), elbow = d2 (c1, s1).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.errors import MechanismError, TaskError
from redundik.kinematics import analysis as ex

ROOT = Path(__file__).resolve().parents[2]
DEG = np.pi / 180


def _fd_jacobian(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = [(f(q + h * e) - f(q - h * e)) / (2 * h) for e in np.eye(len(q))]
    return np.array(cols).T


def _u(a: float) -> np.ndarray:
    return np.array([np.cos(a), np.sin(a)])


def _perp(a: float) -> np.ndarray:
    return np.array([-np.sin(a), np.cos(a)])


# ---------------------------------------------------------------- exercise 1: PRRP beam-hanging arm
A2 = 1.0


def _prrp_tip(q: np.ndarray) -> np.ndarray:
    d1, t2, t3, d4 = q
    return np.array([A2 * np.cos(t2) + d4 * np.cos(t2 + t3), A2 * np.sin(t2) + d4 * np.sin(t2 + t3), d1])


def _prrp_jacobian(q: np.ndarray) -> np.ndarray:
    """∂p/∂(d1, θ2, θ3, d4) written out (exercise 1c)."""
    _, t2, t3, d4 = q
    s2, c2, s23, c23 = np.sin(t2), np.cos(t2), np.sin(t2 + t3), np.cos(t2 + t3)
    return np.array(
        [
            [0.0, -A2 * s2 - d4 * s23, -d4 * s23, c23],
            [0.0, A2 * c2 + d4 * c23, d4 * c23, s23],
            [1.0, 0.0, 0.0, 0.0],
        ]
    )


Q1 = np.array([1.0, -120 * DEG, 60 * DEG, 1.5])


@pytest.fixture(scope="module")
def ex1():
    plan = load_task(ROOT / "tasks/exercise1_prrp.yaml")
    return plan, run_task(plan)


def test_ex1_model_and_hand_jacobian(ex1) -> None:
    plan, _ = ex1
    robot = plan.robot.model
    np.testing.assert_allclose(plan.runs["min_norm"].q0, Q1, atol=1e-12)
    rng = np.random.default_rng(1)
    for q in [Q1, *(Q1 + rng.uniform(-0.5, 0.5, 4) for _ in range(3))]:
        robot.update(q)
        np.testing.assert_allclose(robot.frame_position("4"), _prrp_tip(q), atol=1e-12)
        np.testing.assert_allclose(robot.frame_jacobian("4")[:3], _prrp_jacobian(q), atol=1e-12)
        np.testing.assert_allclose(_prrp_jacobian(q), _fd_jacobian(_prrp_tip, q), atol=1e-8)


def test_ex1_singular_points_of_the_three_column_determinant(ex1) -> None:
    plan, _ = ex1
    robot = plan.robot.model
    for t3 in (-170, -90, -30, 30, 60, 120, 0, 180):
        q = np.array([0.4, -100 * DEG, t3 * DEG, 1.2])
        J3 = _prrp_jacobian(q)[:, :3]
        assert np.linalg.det(J3) == pytest.approx(A2 * 1.2 * np.sin(t3 * DEG), abs=1e-12)  # (d): a2 d4 sin θ3
        if t3 in (-170, -90, -30, 30, 60, 120):
            robot.update(q)
            assert np.linalg.matrix_rank(robot.frame_jacobian("4")[:3, :3], tol=1e-9) == 3
    robot.update(np.array([0.4, -100 * DEG, 0.0, 1.2]))
    assert np.linalg.matrix_rank(robot.frame_jacobian("4")[:3, :3], tol=1e-9) == 2


def test_ex1e_minimum_norm_velocity(ex1) -> None:
    _, res = ex1
    J = _prrp_jacobian(Q1)
    v = np.array([0.0, 1.0, 0.0])
    expected = J.T @ np.linalg.solve(J @ J.T, v)  # J⁺ = Jᵀ(JJᵀ)⁻¹ for a full-row-rank J
    qd = res["min_norm"].log.dq[0]
    np.testing.assert_allclose(qd, expected, atol=1e-10)
    np.testing.assert_allclose(ex.min_norm_velocity(J, v), expected, atol=1e-12)
    np.testing.assert_allclose(J @ qd, v, atol=1e-10)
    assert qd[0] == pytest.approx(0.0, abs=1e-12)  # the carriage does not move for a y0 velocity
    # minimum norm: every other solution qd + n (J n = 0) is longer
    n = np.linalg.svd(J)[2][-1]
    for s in (-0.3, 0.1, 0.5):
        assert np.linalg.norm(qd + s * n) > np.linalg.norm(qd)


def test_ex1f_general_solution_with_singularity_avoidance(ex1) -> None:
    _, res = ex1
    J = _prrp_jacobian(Q1)
    v = np.array([0.0, 1.0, 0.0])
    eta = np.array([0.0, 0.0, np.sin(2 * Q1[2]), 0.0])  # ∂ sin²θ3 / ∂q
    expected = np.linalg.pinv(J) @ v + (np.eye(4) - np.linalg.pinv(J) @ J) @ eta
    for run in ("sing_avoid", "hqp"):
        np.testing.assert_allclose(res[run].log.dq[0], expected, atol=1e-8, err_msg=run)
    np.testing.assert_allclose(ex.general_velocity(J, v, eta, 1.0), expected, atol=1e-12)
    # the subtask raises sin²θ3 faster than the rank solution at t = 0, and keeps θ3 away from 0 and 180°
    assert (expected[2] - res["min_norm"].log.dq[0][2]) * np.sin(2 * Q1[2]) > 0
    for r in res.values():
        assert r.log.potentials["sin2_q3"].min() >= 0.75 - 1e-9
        tips = np.array([_prrp_tip(q) for q in r.log.q])
        np.testing.assert_allclose(tips[:, 1] - tips[0, 1], r.log.t, atol=5e-3)  # ẏ = 1 m/s
        np.testing.assert_allclose(tips[:, [0, 2]], np.tile(tips[0, [0, 2]], (len(tips), 1)), atol=5e-3)
        assert r.summary["limit_violations"] == 0


# ---------------------------------------------------------------- exercise 2: RRP arm and the bowl
A1, LIP, LIP_R, ROD = 1.0, np.array([0.6, 0.4]), 0.03, 0.45


def _rrp_points(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elbow a1 u1 and wrist w = a1 u1 + d3 u12."""
    elbow = A1 * _u(q[0])
    return elbow, elbow + q[2] * _u(q[0] + q[1])


def _segment_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    s = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(a + s * (b - a) - p))


@pytest.fixture(scope="module")
def ex2():
    plan = load_task(ROOT / "tasks/exercise2_rrp_bowl.yaml")
    return plan, run_task(plan)


def test_ex2_model_matches_hand_formulas(ex2) -> None:
    plan, _ = ex2
    robot = plan.robot.model
    rng = np.random.default_rng(2)
    for q in [plan.runs["rank_only"].q0, *(rng.uniform([-3, -3, 0.1], [3, 3, 1.9]) for _ in range(3))]:
        robot.update(q)
        elbow, w = _rrp_points(q)
        np.testing.assert_allclose(robot.frame_position("1")[:2], elbow, atol=1e-12)
        np.testing.assert_allclose(robot.frame_position("3")[:2], w, atol=1e-12)
        np.testing.assert_allclose(ex.frame_axis(robot, "3", "z")[:2], _u(q[0] + q[1]), atol=1e-12)
        np.testing.assert_allclose(robot.frame_position("R")[:2], w - ROD * _u(q[0] + q[1]), atol=1e-12)
        J_fd = _fd_jacobian(lambda x: _rrp_points(x)[1], q)
        np.testing.assert_allclose(robot.frame_jacobian("3")[:2], J_fd, atol=1e-8)
        assert np.linalg.matrix_rank(robot.frame_jacobian("3")[:2]) == 2


def test_ex2b_singular_points(ex2) -> None:
    # columns a1 u1⊥ + d3 u12⊥, d3 u12⊥, u12: u12⊥ ⟂ u12, so rank 1 needs d3 = 0 and u1⊥ ∥ u12 (θ2 = ±90°)
    plan, _ = ex2
    robot = plan.robot.model
    for q, rank in [
        ((0.3, np.pi / 2, 0.0), 1),
        ((0.3, -np.pi / 2, 0.0), 1),
        ((0.3, 0.0, 0.0), 2),
        ((0.3, 0.0, 0.5), 2),
    ]:
        robot.update(np.array(q))
        assert np.linalg.matrix_rank(robot.frame_jacobian("3")[:2], tol=1e-9) == rank, q


def test_ex2c_torques_for_the_12N_pressing_force(ex2) -> None:
    plan, res = ex2
    robot = plan.robot.model
    for name in ("rank_only", "avoid_pinv", "avoid_hqp"):
        q = res[name].log.q[-1]
        _, w = _rrp_points(q)
        np.testing.assert_allclose(w, [0.8, 0.0], atol=1e-3)  # touching the wall at (0.8, 0)
        robot.update(q)
        tau = ex.static_torques(robot, "3", 12.0 * ex.frame_axis(robot, "3", "z")[:2])
        # virtual work: τ_i = F · ∂w/∂q_i, with ∂w/∂q by finite differences
        F = 12.0 * _u(q[0] + q[1])
        np.testing.assert_allclose(tau, _fd_jacobian(lambda x: _rrp_points(x)[1], q).T @ F, atol=1e-6)
        # the closed form from the statement: τ = (12 a1 sin θ2, 0, 12)
        np.testing.assert_allclose(tau, [12 * A1 * np.sin(q[1]), 0.0, 12.0], atol=1e-9)


def test_ex2d_linear_approach_avoids_the_rim(ex2) -> None:
    _, res = ex2
    t = res["rank_only"].log.t
    line = np.c_[1.0 - 0.1 * t, 1.0 - 0.5 * t]
    clear = {}
    for name, r in res.items():
        ws = np.array([_rrp_points(q)[1] for q in r.log.q])
        assert np.abs(ws - line).max() < 2e-3, name
        # the slider rod from the elbow through w, against the lip (disc of radius 0.03 at (0.6, 0.4))
        clear[name] = min(_segment_distance(*_rrp_points(q), LIP) - LIP_R for q in r.log.q)
        assert r.summary["limit_violations"] == 0, name
    assert clear["rank_only"] < 0.0  # the minimum-norm solution sweeps the rod over the lip
    assert clear["avoid_pinv"] > 0.03 and clear["avoid_hqp"] > 0.03
    assert res["avoid_hqp"].summary["min_clearance"] > 0.05 - 2e-3  # the hard bound on R


# ---------------------------------------------------------------- exercise 3: RPR arm and the lamp
A3, LAMP, LAMP_R, M = 1.0, np.array([0.4, 1.4]), 0.1, 2.0


def _rpr_points(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    elbow = q[1] * _u(q[0])
    return elbow, elbow + A3 * _u(q[0] + q[2])


def _rpr_jacobian(q: np.ndarray) -> np.ndarray:
    t1, d2, t3 = q
    return np.c_[d2 * _perp(t1) + A3 * _perp(t1 + t3), _u(t1), A3 * _perp(t1 + t3)]


@pytest.fixture(scope="module")
def ex3():
    plan = load_task(ROOT / "tasks/exercise3_rpr_lamp.yaml")
    return plan, run_task(plan)


def test_ex3ab_initial_joints_and_jacobian(ex3) -> None:
    plan, _ = ex3
    q0 = plan.runs["rank_only"].q0
    # (b): θ1 + θ3 = −90° → link 3 hangs straight down, elbow = tip + (0, a3) = (0.8, 1.4)
    np.testing.assert_allclose(q0, [np.arctan2(1.4, 0.8), np.hypot(0.8, 1.4), -np.pi / 2 - np.arctan2(1.4, 0.8)])
    elbow, tip = _rpr_points(q0)
    np.testing.assert_allclose(tip, [0.8, 0.4], atol=1e-12)
    robot = plan.robot.model
    robot.update(q0)
    np.testing.assert_allclose(robot.frame_position("3")[:2], tip, atol=1e-12)
    np.testing.assert_allclose(robot.frame_position("2")[:2], elbow, atol=1e-12)
    J = ex.task_jacobian(robot, "3", ("x", "y"))
    np.testing.assert_allclose(J, _rpr_jacobian(q0), atol=1e-12)
    np.testing.assert_allclose(J, _fd_jacobian(lambda x: _rpr_points(x)[1], q0), atol=1e-8)


def test_ex3c_elbow_does_not_touch_the_lamp(ex3) -> None:
    plan, res = ex3
    elbow, _ = _rpr_points(plan.runs["rank_only"].q0)
    assert np.linalg.norm(elbow - LAMP) == pytest.approx(0.4)  # (0.8, 1.4) vs (0.4, 1.4)
    assert res["rank_only"].log.potentials["lamp_clearance"][0] == pytest.approx(0.4 - LAMP_R)


def test_ex3d_given_velocity_is_a_null_solution_up_to_rounding(ex3) -> None:
    plan, _ = ex3
    q0 = plan.runs["rank_only"].q0
    J = _rpr_jacobian(q0)
    qd = np.array([-np.sqrt(3.0), 1.6, -1.5])
    residual, qn, angle = ex.null_check(J, qd)
    np.testing.assert_allclose(residual, J @ qd, atol=1e-12)
    # J q̇ = (−0.4·(−√3) + 0.8/√2.6·1.6 − 1.5, 0.8·(−√3) + 1.4/√2.6·1.6): small but not zero
    hand = np.array([0.4 * np.sqrt(3) + 0.8 / np.sqrt(2.6) * 1.6 - 1.5, -0.8 * np.sqrt(3) + 1.4 / np.sqrt(2.6) * 1.6])
    np.testing.assert_allclose(residual, hand, atol=1e-12)
    assert 1e-3 < np.linalg.norm(residual) < 0.02 * np.linalg.norm(qd)
    assert np.degrees(angle) < 0.5
    np.testing.assert_allclose(J @ qn, 0.0, atol=1e-12)
    # with the book's rounded joints (θ1 = 60°, d2 = 1.6) the y-row vanishes exactly (the x-row would need
    # q̇3 = −1.468, printed as −1.5)
    Jr = _rpr_jacobian(np.array([60 * DEG, 1.6, -150 * DEG]))
    assert abs((Jr @ qd)[1]) < 1e-12


def test_ex3e_torques_for_a_2kg_load(ex3) -> None:
    plan, res = ex3
    q0 = plan.runs["rank_only"].q0
    robot = plan.robot.model
    robot.update(q0)
    mg = M * 9.81
    tau = ex.static_torques(robot, "3", np.array([0.0, mg]))
    # moment arm of the load about joint 1 is the tip's x; the slider carries mg sin θ1; link 3 hangs straight down
    np.testing.assert_allclose(tau, [mg * 0.8, mg * 1.4 / np.sqrt(2.6), 0.0], atol=1e-9)
    mon = res["rank_only"].plan.torque_monitors[0]
    np.testing.assert_allclose(mon.torques(robot), tau, atol=1e-12)
    assert res["rank_only"].series["m.load.max"][0] == pytest.approx(mg * 1.4 / np.sqrt(2.6))


def test_ex3f_linear_move_keeps_the_elbow_off_the_lamp(ex3) -> None:
    _, res = ex3
    t = res["rank_only"].log.t
    line = np.c_[0.8 + 0.2 * t, 0.4 + 0.1 * t]
    clear = {}
    for name, r in res.items():
        pts = [_rpr_points(q) for q in r.log.q]
        tips = np.array([p[1] for p in pts])
        assert np.abs(tips - line).max() < 2e-3, name
        np.testing.assert_allclose(tips[-1], [1.4, 0.7], atol=2e-3)
        clear[name] = np.array([np.linalg.norm(p[0] - LAMP) - LAMP_R for p in pts])
        np.testing.assert_allclose(r.log.potentials["lamp_clearance"], clear[name], atol=1e-9)
        assert clear[name].min() >= 0.3 - 1e-9, name  # never closer than at t = 0
        assert r.summary["limit_violations"] == 0, name
    assert clear["avoid_pinv"][-1] > clear["rank_only"][-1] + 0.1
    # the bound c ≥ 0.45 as a velocity damper ċ ≥ 2 (0.45 − c): c(t) ≥ 0.45 − 0.15 e^(−2t) from c(0) = 0.3
    assert np.all(clear["avoid_hqp"] >= 0.45 - 0.15 * np.exp(-2.0 * t) - 2e-3)
    assert clear["avoid_hqp"][-1] > clear["rank_only"][-1]


def test_exercise_helpers_reject_bad_input() -> None:
    with pytest.raises(MechanismError):
        ex.min_norm_velocity(np.array([[1.0, 0.0], [2.0, 0.0]]), np.array([1.0, 0.0]))
    with pytest.raises(TaskError, match="expected"):
        ex.min_norm_velocity(np.eye(2), np.ones(3))
