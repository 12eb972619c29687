"""The 17-joint dual arm of Table 5.1 (section 5.3): the augmented Jacobian (5.17) built from the A matrices
against the model, the coupled joint θ3r = θ3l + β, the relative-pose (coordination) task Jacobian against finite
differences, and the task runs (independent hands, carried object, r = 5 subtasks)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from redundik.config import load_robot, load_task
from redundik.config.dh_tables import read_dh_table
from redundik.config.runner import RunResult, run_task
from redundik.kinematics import augmented_jacobian, dh_matrix, joint_variables, numeric_rank
from redundik.tasks import RelativePoseTask

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs/dualarm17.yaml"
RNG = np.random.default_rng(17)


@pytest.fixture(scope="module")
def robot():
    return load_robot(str(CONFIG), ROOT).model


@pytest.fixture(scope="module")
def table():
    return read_dh_table(CONFIG)


def test_table_has_17_joints_in_the_chapter_order(robot, table) -> None:
    rows, _, _ = table
    names = [str(i) for i in range(1, 18)]
    names[2] = "3l"
    assert joint_variables(rows) == names
    assert robot.joint_names == names


@pytest.mark.parametrize("trial", range(4))
def test_augmented_jacobian_5_17_equals_the_model(robot, table, trial: int) -> None:
    rows, base, base_frame = table
    q = robot.random_configuration(RNG)
    values = dict(zip(joint_variables(rows), q, strict=True))
    j_end = augmented_jacobian(rows, values, ["10", "17"], base=base, base_frame=base_frame, projected="end")
    j_0 = augmented_jacobian(rows, values, ["10", "17"], base=base, base_frame=base_frame, projected="base")
    assert j_end.shape == (12, 17)
    # block structure of (5.17): torso columns 0-2 shared, each arm moves its own hand only
    assert np.all(j_end[:6, 10:] == 0) and np.all(j_end[6:, 3:10] == 0)
    assert np.abs(j_end[:6, :3]).max() > 0.1 and np.abs(j_end[6:, :3]).max() > 0.1
    robot.update(q)
    model_j = np.vstack([robot.frame_jacobian("10"), robot.frame_jacobian("17")])
    np.testing.assert_allclose(j_0, model_j, atol=1e-12)
    # J_0 = diag(R_0^10, R_0^10, R_0^17, R_0^17) J_end
    r10, r17 = robot.frame_pose("10").rotation, robot.frame_pose("17").rotation
    proj = np.zeros((12, 12))
    for i, rot in enumerate((r10, r10, r17, r17)):
        proj[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = rot
    np.testing.assert_allclose(proj @ j_end, j_0, atol=1e-12)
    assert 17 - numeric_rank(j_0) == 5  # r = 5


def test_coupled_torso_joint_theta3r_is_theta3l_plus_beta(robot) -> None:
    beta = np.pi
    for _ in range(3):
        q = robot.random_configuration(RNG)
        robot.update(q)
        f2 = robot.frame_pose("2")
        a23l = f2.actInv(robot.frame_pose("3l")).homogeneous
        a23r = f2.actInv(robot.frame_pose("3r")).homogeneous
        np.testing.assert_allclose(a23l, dh_matrix(q[2], 0.35, 0.25, 0.0), atol=1e-12)
        np.testing.assert_allclose(a23r, dh_matrix(q[2] + beta, 0.35, 0.25, 0.0), atol=1e-12)
    # one velocity for both: θ̇3l = θ̇3r, so the hands' Jacobian columns of joint 3 come from one variable
    robot.update(robot.random_configuration(RNG))
    assert robot.nv == 17


def _relative(robot, q: np.ndarray) -> pin.SE3:
    robot.update(q)
    return robot.frame_pose("10").actInv(robot.frame_pose("17"))


@pytest.mark.parametrize("trial", range(3))
def test_relative_pose_jacobian_matches_finite_differences(robot, trial: int) -> None:
    task = RelativePoseTask("17", "10")
    q = robot.random_configuration(RNG)
    robot.update(q)
    task.reset(robot)
    jac = task.jacobian(robot)
    rel0 = _relative(robot, q)
    h = 1e-6
    fd = np.zeros((6, robot.nv))
    for k in range(robot.nv):
        plus, minus = _relative(robot, q + h * np.eye(robot.nv)[k]), _relative(robot, q - h * np.eye(robot.nv)[k])
        fd[:3, k] = (plus.translation - minus.translation) / (2 * h)
        fd[3:, k] = (pin.log3(plus.rotation @ rel0.rotation.T) - pin.log3(minus.rotation @ rel0.rotation.T)) / (2 * h)
    np.testing.assert_allclose(jac, fd, atol=1e-7)
    # at the captured target the error is zero and so is the commanded velocity
    robot.update(q)
    term = task.evaluate(robot, 0.0)
    assert np.linalg.norm(term.error) < 1e-12 and np.linalg.norm(term.v) < 1e-12


def test_relative_pose_task_rejects_bad_input(robot) -> None:
    from redundik.errors import TaskError

    with pytest.raises(TaskError, match="must differ"):
        RelativePoseTask("10", "10")
    with pytest.raises(TaskError, match="homogeneous"):
        RelativePoseTask("17", "10", target=np.ones((4, 4)))
    task = RelativePoseTask("hand", "10")
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match="frame 'hand' does not exist"):
        task.reset(robot)


# ---------------------------------------------------------------------------------------------------- task runs
@pytest.fixture(scope="module")
def runs() -> dict[str, RunResult]:
    plan = load_task(ROOT / "tasks/dualarm17.yaml")
    plan.steps = 150  # 3 s of the 6 s file
    return run_task(plan, [n for n in plan.runs if n in ("independent_rank", "independent_r5", "carry_r5")])


def test_independent_paths_are_tracked_with_and_without_subtasks(runs) -> None:
    for name in ("independent_rank", "independent_r5"):
        s = runs[name].summary
        assert s["max_task_error"] < 2e-3, name
        assert s["limit_violations"] == 0
    # the five null-space subtasks act: the joints are more centred than with the rank solution alone
    cent_rank = runs["independent_rank"].log.potentials["centering"]
    cent_r5 = runs["independent_r5"].log.potentials["centering"]
    assert cent_r5[-1] < cent_rank[-1] - 0.1


def test_carried_object_keeps_the_relative_pose(runs) -> None:
    r = runs["carry_r5"]
    assert r.summary["task_errors"]["grasp"]["max"] < 1e-4  # held within 0.1 mm (the line stays in the workspace)
    assert r.summary["damped_steps"] == 0
    # independently: relative pose of the hands from the logged configurations
    robot = r.plan.stack.tasks[1]
    model = load_robot(str(CONFIG), ROOT).model
    rel0 = _relative(model, r.log.q[0])
    for k in (50, 100, 150):
        rel = _relative(model, r.log.q[k])
        assert np.linalg.norm(rel.translation - rel0.translation) < 1e-4
        assert np.linalg.norm(pin.log3(rel.rotation @ rel0.rotation.T)) < 1e-4
    # the object did move: the left hand travelled along its line
    left = r.log.frame_positions["10"]
    assert np.linalg.norm(left[150] - left[0]) == pytest.approx(np.linalg.norm([0, 0.015, 0.02]) * 3.0, rel=0.05)
    assert isinstance(robot, RelativePoseTask)
