"""A posture on some joints (``PostureTask(joints=...)``): J = S, the rows of the identity it covers; in the null-space
objective z += Sᵀ K S(q_ref ⊖ q) — so ``joints="actuated"`` leaves a floating base to the other tasks, as pink's and
mink's postures do — and at a level of its own, rows S q̇ = K S(q_ref ⊖ q). Checked against the closed form written
out here with NumPy, across the compiled and per-task paths, and for YAML and bad input."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.config import load_task
from redundik.errors import ConfigError, TaskError
from redundik.tasks.base import TaskTerm

DT = 0.01
GRIPPER = "gripper_left_joint"


@pytest.fixture(scope="module")
def talos() -> rk.RobotModel:
    return rk.load_example_robot("talos")


def _talos_q(robot: rk.RobotModel, seed: int) -> np.ndarray:
    """TALOS away from its neutral configuration: the base moved and turned, every joint off its reference."""
    rng = np.random.default_rng(seed)
    q = robot.neutral()
    q[:3] = rng.uniform(-0.1, 0.1, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.2, 0.2, 3))).coeffs()
    q[7:] += rng.uniform(-0.1, 0.1, robot.nq - 7)
    return q


def test_actuated_leaves_a_free_flyer_out_and_names_select_their_coordinates(talos: rk.RobotModel) -> None:
    robot = talos
    robot.update(robot.neutral())
    actuated = rk.PostureTask(joints="actuated")
    actuated.reset(robot)
    sel, _ = actuated.joint_form(robot)  # type: ignore[misc]
    np.testing.assert_array_equal(sel, np.arange(6, robot.nv))
    named = rk.PostureTask(joints=["arm_left_4_joint", "root_joint.2", "leg_left_1_joint"])
    named.reset(robot)
    sel, _ = named.joint_form(robot)  # type: ignore[misc]
    expected = sorted([2, robot.joint("arm_left_4_joint").idx_v, robot.joint("leg_left_1_joint").idx_v])
    np.testing.assert_array_equal(sel, expected)
    whole_base = rk.PostureTask(joints=["root_joint"])
    whole_base.reset(robot)
    np.testing.assert_array_equal(whole_base.joint_form(robot)[0], np.arange(6))  # type: ignore[index]
    panda = rk.load_example_robot("panda")  # a fixed base: "actuated" is every coordinate
    panda.update(panda.neutral())
    fixed = rk.PostureTask(joints="actuated")
    fixed.reset(panda)
    np.testing.assert_array_equal(fixed.joint_form(panda)[0], np.arange(panda.nv))  # type: ignore[index]


def test_its_term_is_the_selected_rows_of_the_full_posture(talos: rk.RobotModel) -> None:
    robot = talos
    ref = _talos_q(robot, 1)
    q = _talos_q(robot, 2)
    robot.update(q)
    full, part = rk.PostureTask(ref, gain=3.0), rk.PostureTask(ref, joints="actuated", gain=3.0)
    a, b = full.evaluate(robot, 0.0), part.evaluate(robot, 0.0)
    np.testing.assert_array_equal(b.J, np.eye(robot.nv)[6:])
    np.testing.assert_allclose(b.error, a.error[6:], rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.v, 3.0 * a.error[6:], rtol=0, atol=1e-15)
    assert full.identity_jacobian and not part.identity_jacobian and part.regularization


def _closed_form(J: np.ndarray, V: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The chapter's J⁺V + (I − J⁺J) z (5.8), with NumPy's pseudo-inverse."""
    Jp = np.linalg.pinv(J)
    return Jp @ V + (np.eye(J.shape[1]) - Jp @ J) @ z


@pytest.mark.parametrize("method", ["pinv", "feedback", "hqp"])
@pytest.mark.parametrize("fuse", [True, False])
def test_in_the_null_space_it_adds_St_v_to_z_so_the_base_gets_no_posture_term(
    talos: rk.RobotModel, method: str, fuse: bool
) -> None:
    robot = talos
    ref, q = _talos_q(robot, 3), _talos_q(robot, 4)
    robot.update(q)
    hand = rk.FrameTask(GRIPPER, gain=5.0)
    posture = rk.PostureTask(ref, joints="actuated", gain=2.0)
    stack = rk.TaskStack([hand, posture])
    stack.reset(robot)
    goal = robot.frame_pose(GRIPPER).copy()
    goal.translation += np.array([0.02, -0.01, 0.03])
    hand.set_target(goal)
    resolver = rk.make_resolver(method, max_joint_speed=None)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    if method == "hqp":
        resolver.limits = rk.JointLimits(position=False, velocity=False)  # type: ignore[attr-defined]
    res = resolver.step(robot, stack, q, 0.0, DT)
    assert res.fallback is None, res.fallback
    assert res.info["path"] == ("compiled" if fuse else "interpreted")
    terms = {t.name: t for t in res.terms}
    z = np.zeros(robot.nv)
    z[6:] = 2.0 * robot.difference(q, ref)[6:]  # Sᵀ K S (q_ref ⊖ q): nothing on the base
    expected = _closed_form(terms[hand.name].J, terms[hand.name].v, z)
    assert np.abs(res.dq - expected).max() <= 1e-9 * max(1.0, np.abs(expected).max())


@pytest.mark.parametrize(
    ("method", "priority"), [("pinv", None), ("feedback", None), ("wqp", None), ("hqp", None), ("wqp", 0), ("hqp", 1)]
)
def test_compiled_and_per_task_paths_agree_over_a_run(talos: rk.RobotModel, method: str, priority: int | None) -> None:
    """In the null-space objective, and at a level of its own (``wqp``: beside the gripper; ``hqp``: below it)."""
    runs = {}
    for fuse in (True, False):
        robot = talos
        q = _talos_q(robot, 5)
        robot.update(q)
        hand = rk.FrameTask(GRIPPER, gain=20.0)
        joints = ["arm_left_1_joint", "arm_left_2_joint", "torso_1_joint"]
        posture = rk.PostureTask(joints=joints, gain=4.0, priority=priority, weight=0.1)
        stack = rk.TaskStack([hand, posture])
        stack.reset(robot)
        goal = robot.frame_pose(GRIPPER).copy()
        goal.translation += np.array([0.05, 0.0, 0.02])
        hand.set_target(goal)
        resolver = rk.make_resolver(method)
        resolver.fuse = fuse  # type: ignore[attr-defined]
        dqs, paths = [], set()
        for k in range(15):
            res = resolver.step(robot, stack, q, k * DT, DT)
            dqs.append(res.dq.copy())
            paths.add(res.info["path"])
            q = robot.integrate(q, res.dq, DT)
        runs[fuse] = (np.array(dqs), paths)
    assert runs[True][1] == {"compiled"} and runs[False][1] == {"interpreted"}
    np.testing.assert_allclose(runs[True][0], runs[False][0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("fuse", [True, False])
def test_at_a_level_of_its_own_its_rows_are_weighted_as_any_tasks(talos: rk.RobotModel, fuse: bool) -> None:
    """``wqp``, hand (weight 1) and posture on the actuated joints (weight w) in one level: q̇ minimises
    ‖J q̇ − v‖² + w‖S q̇ − K S e‖² + λ‖q̇‖² — the normal equations, solved here."""
    robot = talos
    ref, q = _talos_q(robot, 6), _talos_q(robot, 7)
    robot.update(q)
    hand = rk.FrameTask(GRIPPER, gain=10.0)
    posture = rk.PostureTask(ref, joints="actuated", gain=3.0, priority=0, weight=1e-3)
    stack = rk.TaskStack([hand, posture])
    stack.reset(robot)
    resolver = rk.make_resolver(
        "wqp", damping=1e-6, lm_damping=0.0, max_joint_speed=None, limits=rk.JointLimits(position=False, velocity=False)
    )
    resolver.fuse = fuse  # type: ignore[attr-defined]
    res = resolver.step(robot, stack, q, 0.0, DT)
    assert res.fallback is None, res.fallback
    h = {t.name: t for t in res.terms}[hand.name]
    S = np.eye(robot.nv)[6:]
    e = robot.difference(q, ref)[6:]
    H = h.J.T @ h.J + 1e-3 * S.T @ S + 1e-6 * np.eye(robot.nv)
    g = h.J.T @ h.v + 1e-3 * S.T @ (3.0 * e)
    expected = np.linalg.solve(H, g)
    assert np.abs(res.dq - expected).max() <= 1e-7 * np.abs(expected).max()


class _DoubledRow(rk.Task):
    """A user's regulariser whose Jacobian is not rows of the identity: 2 q̇_k = K (c − q_k)."""

    regularization = True

    def __init__(self, k: int, c: float, gain: float) -> None:
        self._init_task("doubled", gain=gain)
        self.k, self.c = k, c

    def evaluate(self, robot: rk.RobotModel, t: float) -> TaskTerm:
        J = np.zeros((1, robot.nv))
        J[0, self.k] = 2.0
        e = np.array([self.c - robot.q[self.k]])
        return TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return "_DoubledRow()"


def test_a_users_regulariser_joins_the_null_objective_as_its_least_norm_velocity() -> None:
    """It used to be laid out below the null-space objective, where ``pinv`` left it out of q̇ without a word."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.1, -0.6, 0.2, -2.2, 0.1, 1.4, 0.6, 0.02, 0.02])
    robot.update(q)
    hand = rk.FrameTask("panda_hand_tcp", gain=5.0, axes="position")
    reg = _DoubledRow(2, 0.7, gain=4.0)
    stack = rk.TaskStack([hand, reg])
    stack.reset(robot)
    res = rk.make_resolver("pinv", max_joint_speed=None).step(robot, stack, q, 0.0, DT)
    z = np.zeros(robot.nv)
    z[2] = 4.0 * (0.7 - q[2]) / 2.0  # J⁺v of the row 2 q̇_2 = v
    h = {t.name: t for t in res.terms}[hand.name]
    expected = _closed_form(h.J, h.v, z)
    assert abs(z[2]) > 0.1 and np.abs(res.dq - expected).max() <= 1e-9


@pytest.mark.parametrize(
    ("joints", "words"),
    [
        ("arm_left_4_joint", ["a list of joint names", "joints=['arm_left_4_joint']"]),
        ([], ["empty"]),
        (["arm_left_4_joint", "arm_left_4_joint"], ["more than once"]),
        ([3], ["joint names (str)"]),
        (7, ["int"]),
    ],
)
def test_a_malformed_selection_is_refused_where_it_is_given(joints: Any, words: list[str]) -> None:
    with pytest.raises(TaskError) as info:
        rk.PostureTask(joints=joints, name="pose")
    for word in words:
        assert word in str(info.value) and "posture task 'pose'" in str(info.value), str(info.value)


def test_a_joint_the_robot_does_not_have_is_named_at_reset(talos: rk.RobotModel) -> None:
    task = rk.PostureTask(joints=["arm_left_4_jiont"], name="pose")
    talos.update(talos.neutral())
    with pytest.raises(TaskError, match=r"joint 'arm_left_4_jiont' does not exist.*did you mean 'arm_left_4_joint'"):
        task.reset(talos)


def test_yaml_posture_joints(write_yaml: Callable[..., Path], planar_task_data: dict[str, Any]) -> None:
    d = planar_task_data
    d["runs"] = {"p": {"main": [{"type": "posture", "joints": ["2", "3"], "gain": 2}], "q0": [110, -40, -30]}}
    plan = load_task(write_yaml(d))
    task = plan.runs["p"].stack.tasks[0]
    assert task.joints == ("2", "3")  # type: ignore[attr-defined]
    d["runs"]["p"]["main"][0]["joints"] = ["2", "4"]
    with pytest.raises(ConfigError) as info:
        load_task(write_yaml(d))
    assert info.value.path == "runs.p.main[0].joints" and "joint '4' does not exist" in str(info.value), str(info.value)


def test_actuated_leaves_a_planar_root_out_and_nothing_else() -> None:
    """A mobile base as a planar root joint (x, y, θ) carrying an arm joint, then a free flyer further down (a
    floating object on the arm): only the root's coordinates are left out. A robot that is only a free flyer has
    no actuated coordinate: said at reset."""
    model = pin.Model()
    base = model.addJoint(0, pin.JointModelPlanar(), pin.SE3.Identity(), "base")
    arm = model.addJoint(base, pin.JointModelRZ(), pin.SE3.Identity(), "arm")
    model.addJoint(arm, pin.JointModelFreeFlyer(), pin.SE3(np.eye(3), np.array([0.5, 0.0, 0.0])), "floating")
    model.addFrame(pin.Frame("tip", 3, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    robot = rk.RobotModel(model, name="mobile")
    robot.update(robot.neutral())
    task = rk.PostureTask(joints="actuated")
    task.reset(robot)
    sel, _ = task.joint_form(robot)  # type: ignore[misc]
    np.testing.assert_array_equal(sel, np.arange(3, robot.nv))  # the arm joint and the free flyer below it
    floating_only = pin.Model()
    floating_only.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    alone = rk.RobotModel(floating_only, name="alone")
    alone.update(alone.neutral())
    with pytest.raises(TaskError, match="covers no velocity coordinate"):
        rk.PostureTask(joints="actuated").reset(alone)
