"""The public forms through which a resolver reads a task without testing its class (issue 31):
``Potential.clearance_form`` / ``BoundSubtask.clearance_form`` (``hqp``'s packed damper rows),
``BoundSubtask.fixed_rows`` for a subclass, and ``Task.reference_sampled`` (a fused step's sampled orientation,
kept by a frame task)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import redundik as rk
from redundik.tasks.subtasks import BoundSubtask

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


class PlainClearance(rk.Clearance):
    """A user's subclass that changes nothing of the formula."""


class OffsetClearance(rk.Clearance):
    """A subclass with a formula of its own: p shifted by 5 cm."""

    def value_and_gradient_into(self, robot: rk.RobotModel, out: np.ndarray, scale: float = 1.0) -> float:
        return super().value_and_gradient_into(robot, out, scale) + 0.05


class OwnRows(BoundSubtask):
    """A bound subtask whose rows are its own (the damper rows, tightened)."""

    def rows(self, robot: rk.RobotModel, dt: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
        C, d, names = super().rows(robot, dt)
        return C, d - 0.01, names


def _stack(robot: rk.RobotModel, clearance: type[rk.Clearance], bound: type[BoundSubtask]) -> rk.TaskStack:
    robot.update(Q0)
    centre = robot.frame_position("panda_hand") + np.array([0.08, 0.0, 0.0])  # clearance 6 cm, the bound 5
    clear = clearance("panda_hand", centre, radius=0.02, name="c")
    hand = rk.FrameTask("panda_hand", rk.Line([0.2, 0.0, 0.0]), gain=1.0, priority=1)
    return rk.TaskStack([hand, rk.PostureTask(Q0.copy(), gain=0.5, priority=2)], [bound(clear, lower=0.05, priority=0)])


def _run(clearance: type[rk.Clearance], bound: type[BoundSubtask]) -> tuple[np.ndarray, bool]:
    """Twenty hqp steps; the last q and whether the bounds were packed for the compiled step."""
    robot = rk.load_example_robot("panda")
    stack = _stack(robot, clearance, bound)
    res, q = rk.make_resolver("hqp"), Q0.copy()
    for k in range(20):
        out = res.step(robot, stack, q, 0.01 * k, 0.01)
        q = robot.integrate(q, out.dq, 0.01)
    plan = res._plan  # the test reads the resolver's plan, as test_hqp_buffers does
    robot.update(q)
    assert stack.subtasks[0].source.value(robot) < 0.051 or clearance is OffsetClearance  # the bound was reached
    return q, plan is not None and plan._packed is not None


def test_a_clearance_subclass_that_keeps_the_formula_is_packed_and_moves_the_same() -> None:
    q_builtin, packed_builtin = _run(rk.Clearance, BoundSubtask)
    q_plain, packed_plain = _run(PlainClearance, BoundSubtask)
    assert packed_builtin and packed_plain  # (a type test used to keep a subclass off the packed rows)
    np.testing.assert_array_equal(q_plain, q_builtin)


def test_a_formula_of_its_own_is_not_packed_and_is_followed() -> None:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    own = OffsetClearance("panda_hand", [0.5, 0.0, 0.5], radius=0.0)
    assert own.clearance_form(robot) is None
    assert PlainClearance("panda_hand", [0.5, 0.0, 0.5]).clearance_form(robot) is not None
    q_own, packed = _run(OffsetClearance, BoundSubtask)
    q_builtin, _ = _run(rk.Clearance, BoundSubtask)
    assert not packed
    assert not np.allclose(q_own, q_builtin)  # the 5 cm it adds changes the damper rows


def test_a_bound_subtask_with_rows_of_its_own_keeps_them() -> None:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    sub = OwnRows(rk.Clearance("panda_hand", [0.5, 0.0, 0.5]), lower=0.05)
    assert sub.fixed_rows is None and sub.clearance_form(robot) is None
    _, d, _ = sub.rows(robot, 0.01)
    plain = BoundSubtask(rk.Clearance("panda_hand", [0.5, 0.0, 0.5]), lower=0.05)
    assert plain.fixed_rows == 1
    np.testing.assert_allclose(d, plain.rows(robot, 0.01)[1] - 0.01)
    _, packed = _run(rk.Clearance, OwnRows)
    assert not packed


def test_a_fused_step_tells_a_frame_task_the_orientation_it_sampled() -> None:
    """A trajectory without a compiled form is sampled by the fused step in Python; a position-only target set after
    such steps keeps that step's orientation (``Task.reference_sampled``), as after the task's own evaluation."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    start = robot.frame_pose("panda_hand")
    goal = start.rotation @ pin.exp3(np.array([0.0, 0.0, 0.4]))
    task = rk.FrameTask("panda_hand", rk.PoseInterpolation(start.translation, 0.05, rotation=goal), gain=5.0)
    stack = rk.TaskStack([task, rk.PostureTask(Q0.copy(), gain=0.1)])
    res, q = rk.make_resolver("pinv"), Q0.copy()
    for k in range(10):
        out = res.step(robot, stack, q, 0.01 * k, 0.01)
        q = robot.integrate(q, out.dq, 0.01)
    assert out.info["path"] == "compiled"
    task.set_target(np.array([0.4, 0.0, 0.5]))
    robot.update(q)
    task.evaluate(robot, 0.2)
    target = task.target
    assert target is not None
    np.testing.assert_allclose(target.rotation, goal, atol=1e-12)
    np.testing.assert_allclose(target.translation, [0.4, 0.0, 0.5])


def test_a_task_says_whether_its_gain_is_tracked() -> None:
    """``Task.gain_tracked`` (a resolver re-reads the gains only when ``Edits`` moved): True for the validated
    property, False for a subclass with a gain of its own (read every step)."""

    class Scheduled(rk.FrameTask):
        @property
        def gain(self) -> float:
            return 2.0

        @gain.setter
        def gain(self, value: float) -> None:
            pass

    class Plain(rk.FrameTask):
        pass

    assert rk.FrameTask("panda_hand").gain_tracked and Plain("panda_hand").gain_tracked
    assert rk.PostureTask().gain_tracked
    assert not Scheduled("panda_hand").gain_tracked
