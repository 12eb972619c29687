"""``integrator: euler | rk4 | rk45``: the chapter's 3R cases integrated exactly match an independent solve_ivp of the
same law, and the (6+1) robot's held hand stays put."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from redundik.config import load_task
from redundik.config.runner import run_one
from redundik.errors import ConfigError
from redundik.simulation import simulate
from tests.conftest import PLANAR_TASK, TASKS

V_TIP = np.array([0.2, -0.4])  # [m/s]
Q0_DEG = np.array([110.0, -40.0, -30.0])


def _jacobian(q: np.ndarray) -> np.ndarray:
    """Tip Jacobian (x, y) of the 3R planar arm with a = 1 m, written out independently of redundik."""
    c = np.cumsum(q)
    J = np.zeros((2, 3))
    for i in range(3):
        J[0, i] = -np.sum(np.sin(c[i:]))
        J[1, i] = np.sum(np.cos(c[i:]))
    return J


def _law(null_gain: float) -> Callable[[float, np.ndarray], np.ndarray]:
    def f(_t: float, q: np.ndarray) -> np.ndarray:
        J = _jacobian(q)
        Jp = np.linalg.pinv(J)
        eta = np.array([0.0, 0.0, np.sin(2 * q[2])])  # ∂ sin²θ3 / ∂q
        return Jp @ V_TIP + null_gain * (np.eye(3) - Jp @ J) @ eta

    return f


@pytest.mark.parametrize(("run", "k"), [("rank_only", 0.0), ("rank_null", 1.0)])
def test_rk45_matches_an_independent_solve_ivp(run: str, k: float) -> None:
    plan = load_task(PLANAR_TASK)
    rp = plan.runs[run]
    rp.integrator = "rk45"
    log = run_one(plan, rp).log
    ref = solve_ivp(
        _law(k), (0.0, log.t[-1]), np.radians(Q0_DEG), method="DOP853", t_eval=log.t, rtol=1e-12, atol=1e-14
    )
    assert ref.success
    diff_deg = np.degrees(np.abs(log.q - ref.y.T)).max()
    assert diff_deg < 1e-6, diff_deg
    # and Euler is visibly different (the chapter's first-order drift)
    rp.integrator = "euler"
    euler = run_one(plan, rp).log
    assert np.degrees(np.abs(euler.q[-1] - ref.y[:, -1])).max() > 1e-2


def test_rk4_is_fourth_order_accurate_on_the_3r_line() -> None:
    plan = load_task(PLANAR_TASK)
    rp = plan.runs["rank_null"]
    rp.integrator = "rk4"
    log = run_one(plan, rp).log
    assert log.task_errors["tip"].max() < 1e-9  # tip stays on the line: Euler gives 3-4 mm


def test_held_hand_of_the_track7_robot_moves_less_than_1e_6_dm() -> None:
    plan = load_task(TASKS / "track7_posture.yaml")
    rp = plan.runs["best_posture"]
    rp.integrator = "rk45"
    log = run_one(plan, rp).log
    hand = log.frame_positions["7"]
    assert np.linalg.norm(hand - hand[0], axis=1).max() < 1e-6  # [dm]


def test_integrator_keys_in_the_file(write_yaml: Callable[..., Path], planar_task_data: dict) -> None:
    data = planar_task_data
    data["integrator"] = "rk4"
    data["runs"]["rank_null"]["integrator"] = "rk45"
    data["runs"]["rank_null"]["rtol"] = 1e-8
    plan = load_task(write_yaml(data))
    assert plan.runs["rank_only"].integrator == "rk4"
    assert (plan.runs["rank_null"].integrator, plan.runs["rank_null"].rtol) == ("rk45", 1e-8)
    data["runs"]["rank_null"]["integrator"] = "rk5"
    with pytest.raises(ConfigError, match=r"runs\.rank_null\.integrator: expected one of"):
        load_task(write_yaml(data))
    data["runs"]["rank_null"]["integrator"] = "rk45"
    data["atol"] = -1.0
    with pytest.raises(ConfigError, match="atol"):
        load_task(write_yaml(data))


def test_rk_refused_for_a_free_flyer_robot(write_yaml: Callable[..., Path], planar_task_data: dict) -> None:
    data = planar_task_data
    data["robot"] = {"urdf": "example-robot-data:ur5", "free_flyer": True}
    data["runs"]["rank_null"]["integrator"] = "rk45"
    with pytest.raises(ConfigError, match=r"runs\.rank_null\.integrator: rk45 needs .*nq = 13, nv = 12"):
        load_task(write_yaml(data))


def test_simulate_api_takes_the_integrator() -> None:
    from redundik.resolvers import make_resolver
    from redundik.tasks import FrameTask, Line, TaskStack
    from tests.helpers import planar3r

    robot = planar3r()
    q0 = np.radians(Q0_DEG)
    stack = TaskStack([FrameTask("3", axes="planar", trajectory=Line(V_TIP))], [])
    log = simulate(robot, stack, make_resolver("pinv"), q0, dt=0.01, steps=100, integrator="rk45")
    ref = solve_ivp(_law(0.0), (0.0, 1.0), q0, method="DOP853", t_eval=log.t, rtol=1e-12, atol=1e-14)
    assert np.degrees(np.abs(log.q - ref.y.T)).max() < 1e-6
    with pytest.raises(ValueError, match="integrator"):
        simulate(robot, stack, make_resolver("pinv"), q0, dt=0.01, steps=2, integrator="rk2")
