"""TALOS humanoid (example-robot-data, fixed pelvis): both hands on circles, posture subtask, pinv / wqp / hqp."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from redundik.config import load_task
from redundik.config.runner import run_task

ROOT = Path(__file__).resolve().parents[2]
RADIUS, OMEGA, STOP = 0.06, np.pi, 0.1


@pytest.fixture(scope="module")
def runs():
    plan = load_task(ROOT / "tasks/humanoid_reach.yaml")
    plan.steps = 120  # 1.2 s of the 4 s file: the torso-yaw stop is reached at 0.48 s by pinv
    return plan, run_task(plan)


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1.0, 1.0)))


def test_hands_draw_their_circles_with_orientation_held(runs) -> None:
    plan, res = runs
    robot = plan.robot.model
    for name, r in res.items():
        t = r.log.t
        for hand, plane_normal in (("left_hand", 0), ("right_hand", 1)):
            p = r.log.frame_positions[hand]
            # on a circle of radius R at angular rate ω the chord from the start is 2R sin(ωt/2)
            chord = np.linalg.norm(p - p[0], axis=1)
            np.testing.assert_allclose(chord, 2 * RADIUS * np.abs(np.sin(OMEGA * t / 2)), atol=3e-3, err_msg=name)
            # ... in the frontal y–z plane (left) or the sagittal x–z plane (right)
            assert np.abs(p[:, plane_normal] - p[0, plane_normal]).max() < 3e-3, (name, hand)
            robot.update(r.log.q[0])
            R0 = robot.frame_pose(hand).rotation.copy()
            for k in (40, 80, len(t) - 1):
                robot.update(r.log.q[k])
                assert _angle(R0, robot.frame_pose(hand).rotation) < 3e-3, (name, hand, k)
        assert r.summary["max_task_error"] < 3e-3, name


def test_fixed_pelvis_legs_stay_still(runs) -> None:
    plan, res = runs
    legs = [i for i, j in enumerate(plan.robot.model.joints) if j.name.startswith("leg_")]
    assert len(legs) == 12
    for name, r in res.items():
        assert np.abs(r.log.q[:, legs] - r.log.q[0, legs]).max() < 1e-9, name


def test_qp_runs_respect_limits_and_the_torso_stop(runs) -> None:
    plan, res = runs
    robot = plan.robot.model
    yaw = [j.name for j in robot.joints].index("torso_1_joint")
    lower, upper = robot.lower_limits, robot.upper_limits
    assert res["pinv"].log.q[:, yaw].min() < -STOP - 0.05  # the free motion turns the torso past the stop
    for name in ("wqp", "hqp"):
        q = res[name].log.q
        assert q[:, yaw].min() >= -STOP - 1e-6 and q[:, yaw].max() <= STOP + 1e-6, name
        assert np.all(q >= lower - 1e-6) and np.all(q <= upper + 1e-6), name
        assert res[name].summary["limit_violations"] == 0 and res[name].summary["fallbacks"] == 0, name
        assert q[:, yaw].min() == pytest.approx(-STOP, abs=1e-3)  # the stop is active, not merely respected
