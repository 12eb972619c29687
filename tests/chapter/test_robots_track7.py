"""The (6+1) robot on a track (section 5.2): its completed D-H table against the printed (5.13)/(5.14), the exact
virtual-point gradient against the printed (wrong) one, and the two task files' behaviour.

Expected values come from the chapter's printed matrices (typed in below) and from finite differences, never from
the code under test.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from redundik.config import load_robot, load_task
from redundik.config.runner import RunResult, run_task
from redundik.tasks import VirtualPoint

ROOT = Path(__file__).resolve().parents[2]
A1, D2, A3 = 4.0, 3.0, 4.3  # the constants chosen in configs/track7.yaml [dm]
RNG = np.random.default_rng(7)


@pytest.fixture(scope="module")
def robot():
    return load_robot("configs/track7.yaml", ROOT).model


def _printed_a(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A_0^1, A_1^2, A_2^3 and A_0^3 as printed in (5.14) (d1 = q[0], θ2 = q[1], θ3 = q[2])."""
    d1, c2, s2, c3, s3 = q[0], np.cos(q[1]), np.sin(q[1]), np.cos(q[2]), np.sin(q[2])
    a01 = np.array([[1, 0, 0, A1], [0, 0, -1, 0], [0, 1, 0, d1], [0, 0, 0, 1.0]])
    a12 = np.array([[c2, 0, s2, 0], [s2, 0, -c2, 0], [0, 1, 0, D2], [0, 0, 0, 1.0]])
    a23 = np.array([[c3, -s3, 0, A3 * c3], [s3, c3, 0, A3 * s3], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    a03 = np.array(
        [
            [c2 * c3, -c2 * s3, s2, A1 + A3 * c2 * c3],
            [-s3, -c3, 0, -D2 - A3 * s3],
            [s2 * c3, -s2 * s3, -c2, d1 + A3 * s2 * c3],
            [0, 0, 0, 1.0],
        ]
    )
    return a01, a12, a23, a03


def _rel(robot, a: str, b: str) -> np.ndarray:
    return robot.frame_pose(a).actInv(robot.frame_pose(b)).homogeneous


def test_base_is_eq_5_13(robot) -> None:
    robot.update(robot.neutral())
    printed = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 7], [0, 0, 0, 1.0]])
    np.testing.assert_allclose(robot.frame_pose("0").homogeneous, printed, atol=1e-12)


@pytest.mark.parametrize("trial", range(5))
def test_first_three_a_matrices_are_the_printed_5_14(robot, trial: int) -> None:
    q = robot.random_configuration(RNG)
    robot.update(q)
    a01, a12, a23, a03 = _printed_a(q)
    np.testing.assert_allclose(_rel(robot, "0", "1"), a01, atol=1e-12)
    np.testing.assert_allclose(_rel(robot, "1", "2"), a12, atol=1e-12)
    np.testing.assert_allclose(_rel(robot, "2", "3"), a23, atol=1e-12)
    np.testing.assert_allclose(_rel(robot, "0", "3"), a03, atol=1e-12)
    # and the printed product is consistent with the printed factors
    np.testing.assert_allclose(a01 @ a12 @ a23, a03, atol=1e-12)


def _p_printed(q: np.ndarray) -> float:
    """p = ½(μx² + μz²) with μ from the printed A_0^3 (elbow in frame 0) and the virtual point (10, 20)."""
    a03 = _printed_a(q)[3]
    mux, muz = a03[0, 3] - 10.0, a03[2, 3] - 20.0
    return 0.5 * (mux**2 + muz**2)


def _eta_printed(q: np.ndarray) -> np.ndarray:
    """The chapter's printed 7×1 gradient, as the OCR reads it (a2 = 0 in this table)."""
    a03 = _printed_a(q)[3]
    mux, muz = a03[0, 3] - 10.0, a03[2, 3] - 20.0
    c2, s2, c3, s3 = np.cos(q[1]), np.sin(q[1]), np.cos(q[2]), np.sin(q[2])
    a2 = 0.0
    return np.array(
        [
            muz,
            -muz * A3 * s2 * s3 - mux * A3 * s2 * c3,
            -muz * a2 * s3 * s3 - mux * A3 * c2 * s3,
            0,
            0,
            0,
            0,
        ]
    )


def test_virtual_point_gradient_is_exact_and_the_print_is_not(robot) -> None:
    pot = VirtualPoint("3", [10.0, 20.0, 0.0], axes=("x", "y"))  # x_0, z_0 of frame 0 are x_b, y_b
    pot.check(robot)
    worst_print = 0.0
    for _ in range(5):
        q = robot.random_configuration(RNG)
        robot.update(q)
        assert pot.value(robot) == pytest.approx(_p_printed(q), rel=1e-12)
        h = 1e-6
        fd = np.array([(_p_printed(q + h * e) - _p_printed(q - h * e)) / (2 * h) for e in np.eye(7)])
        np.testing.assert_allclose(pot.gradient(robot), fd, rtol=1e-6, atol=1e-6)
        worst_print = max(worst_print, float(np.max(np.abs(_eta_printed(q) - fd))))
    assert worst_print > 1.0  # the printed η is not the gradient of the printed p


# ---------------------------------------------------------------------------------------------------- task runs
@pytest.fixture(scope="module")
def posture() -> dict[str, RunResult]:
    return run_task(load_task(ROOT / "tasks/track7_posture.yaml"))


@pytest.fixture(scope="module")
def post() -> dict[str, RunResult]:
    plan = load_task(ROOT / "tasks/track7_post.yaml")
    return run_task(plan)


def test_round_trip_holds_the_hand_and_slides_to_c_and_back(posture) -> None:
    r = posture["round_trip"]
    d1 = r.log.q[:, 0]
    assert r.summary["max_task_error"] < 0.02  # [dm] the hand stays put
    assert abs(d1.max() - 9.0) < 0.25  # reaches c = 9 dm (switch tolerance 0.2)
    assert abs(d1[-1] - 5.0) < 0.05  # and comes back home
    assert int(np.argmax(d1)) < 0.6 * d1.size
    wp = r.summary["subtasks"]["track_round_trip"]["waypoints"]
    assert wp == {"values": [9.0, 5.0], "tolerance": 0.2, "reached": 2}


def test_a_round_trip_that_stalls_short_of_a_waypoint_says_so() -> None:
    """The arm's reach stops d1 at 8.799 under rk4 (Euler's overshoot passes 8.8): 0 of 2 waypoints, in the
    summary and flagged in the terminal table."""
    from redundik.config.runner import task_summary
    from redundik.reporting.terminal import summary_table

    plan = load_task(ROOT / "tasks/track7_posture.yaml")
    plan.runs = {"round_trip": plan.runs["round_trip"]}
    plan.runs["round_trip"].integrator = "rk4"
    results = run_task(plan)
    wp = results["round_trip"].summary["subtasks"]["track_round_trip"]["waypoints"]
    assert wp["reached"] == 0
    assert float(np.max(results["round_trip"].log.q[:, 0])) < 9.0 - 0.2
    from rich.console import Console

    console = Console(record=True, width=200)
    console.print(summary_table(task_summary(plan, results)))
    assert "track_round_trip: 0/2 waypoints reached" in console.export_text()


def test_waypoints_reached_follows_the_switching_rule(robot) -> None:
    from redundik.tasks.waypoints import JointWaypoints

    wp = JointWaypoints("1", [9.0, 5.0], tolerance=0.2)
    wp.check(robot)
    series = np.zeros((5, robot.nq))
    series[:, 0] = [5.0, 8.9, 7.0, 5.1, 5.0]
    assert wp.reached(series) == 2
    assert wp.reached(series[:2]) == 1
    series[:, 0] = [5.0, 8.7, 5.0, 5.0, 5.0]  # 5.0 first: the order counts, c = 9 never reached
    assert wp.reached(series) == 0


def test_trace_and_torque_monitors_are_the_statics_of_the_model(posture, robot) -> None:
    r = posture["round_trip"]
    w = np.array([1, 0.5, 0.05, 1, 1, 1, 1])
    f0 = np.array([-1.0, 2.0, 0.0])  # F in frame 0 (the chapter's F), rotated into b by eq. (5.13)
    rb0 = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0.0]])
    for k in (0, 120, 300):
        q = r.log.q[k]
        # finite-difference Jacobian of the hand position and orientation (world b)
        h = 1e-6
        jac = np.zeros((6, 7))
        for i in range(7):
            robot.update(q + h * np.eye(7)[i])
            pp, rp = robot.frame_position("7"), np.array(robot.frame_pose("7").rotation)
            robot.update(q - h * np.eye(7)[i])
            pm, rm = robot.frame_position("7"), np.array(robot.frame_pose("7").rotation)
            jac[:3, i] = (pp - pm) / (2 * h)
            dr = (rp - rm) / (2 * h) @ rp.T
            jac[3:, i] = [dr[2, 1], dr[0, 2], dr[1, 0]]
        assert r.log.potentials["trace_JWJT"][k] == pytest.approx(float(np.sum(jac**2 * w)), rel=1e-6)
        tau = np.abs(jac.T @ np.concatenate([rb0 @ f0, np.zeros(3)]))
        assert r.series["m.tau.max"][k] == pytest.approx(tau.max(), rel=1e-6, abs=1e-9)
        assert r.series["m.tau.min"][k] == pytest.approx(tau.min(), rel=1e-6, abs=1e-9)
        assert r.series["m.tau.mean"][k] == pytest.approx(tau.mean(), rel=1e-6, abs=1e-9)


def test_best_posture_run_lowers_the_trace_to_a_constrained_minimum(posture, robot) -> None:
    r = posture["best_posture"]
    tr = r.log.potentials["trace_JWJT"]
    assert r.summary["max_task_error"] < 0.02
    assert tr[-1] < tr[0] - 3.0
    assert np.all(np.diff(tr) < 1e-6)  # k < 0 in the null space: p never increases (to first order)
    # at the end the trace is stationary along the self-motion: its gradient has no null-space component
    q = r.log.q[-1]
    robot.update(q)
    jac = robot.frame_jacobian("7")
    null = np.eye(7) - np.linalg.pinv(jac) @ jac
    h = 1e-6

    def trace(x: np.ndarray) -> float:
        robot.update(x)
        return float(np.sum(robot.frame_jacobian("7") ** 2 * np.array([1, 0.5, 0.05, 1, 1, 1, 1])))

    grad = np.array([(trace(q + h * e) - trace(q - h * e)) / (2 * h) for e in np.eye(7)])
    assert np.linalg.norm(null @ grad) < 0.02 * np.linalg.norm(grad)


def test_rank_only_hits_the_post_and_the_virtual_point_avoids_it(post) -> None:
    assert post["rank_only"].summary["min_clearance"] < -0.1
    assert post["virtual_point"].summary["min_clearance"] > 0.0
    for r in post.values():
        assert r.summary["max_task_error"] < 0.02  # both draw the circle
        assert r.summary["limit_violations"] == 0
    # the clearance monitor is the elbow's distance to the post axis minus 0.3 dm (frame 3 in x_b, y_b)
    r = post["rank_only"]
    elbow = r.log.frame_positions["3"]
    dist = np.hypot(elbow[:, 0] - 7.0, elbow[:, 1] - 7.5) - 0.3
    np.testing.assert_allclose(r.log.potentials["post_clearance"], dist, atol=1e-12)


def _deviation_from_rank(plan, result: RunResult) -> tuple[np.ndarray, np.ndarray]:
    """Per step: ‖q̇ − q̇_rank‖ and ‖J(q̇ − q̇_rank)‖, with q̇_rank the rank-only solution at the same state."""
    rank = plan.runs["rank_only"]
    robot = plan.robot.model
    robot.update(rank.q0)
    rank.stack.reset(robot)
    dev, task_dev = [], []
    for k in range(result.log.q.shape[0] - 1):
        robot.update(result.log.q[k])
        ref = rank.resolver.solve(robot, rank.stack, float(result.log.t[k]), plan.dt)
        d = result.log.dq[k] - ref.dq
        dev.append(np.linalg.norm(d))
        task_dev.append(np.linalg.norm(robot.frame_jacobian("7") @ d))
    return np.array(dev), np.array(task_dev)


@pytest.mark.parametrize("run", ["qp_clearance", "hqp_clearance"])
def test_qp_clearance_is_a_hard_inequality_with_the_least_deviation(run: str) -> None:
    plan = load_task(ROOT / "tasks/track7_post.yaml")
    res = run_task(plan, ["virtual_point", run])
    r = res[run]
    assert r.summary["min_clearance"] > 0.04  # held at ≥ 0.05 dm up to the Euler step
    assert r.summary["max_task_error"] < 0.02
    dev, task_dev = _deviation_from_rank(plan, r)
    clearance = r.log.potentials["post_clearance"][:-1]
    tol = {"qp_clearance": 1e-4, "hqp_clearance": 1e-8}[run]  # wqp: weighted sum with damping; hqp: exact levels
    assert np.all(task_dev < tol)  # the correction lies in the null space of J
    assert np.all(dev[clearance > 1.0] < 10 * tol)  # far from the post it is the rank solution itself
    assert dev.max() > 1e-2  # near the post it is not
    dev_vp, _ = _deviation_from_rank(plan, res["virtual_point"])
    assert dev.sum() < 0.2 * dev_vp.sum()
