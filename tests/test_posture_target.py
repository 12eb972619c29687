"""A posture's target is read-only where a fused step packs it: an edit in place is refused, not missed.

The fused steps of ``pinv``, ``wqp`` and ``hqp`` pack the posture's q_ref when they plan the stack and compare it by
identity afterwards. ``post.target[0] += 0.5`` used to change the array the per-task path reads while the fused step
kept the old value: a silent wrong answer (0.32 rad/s off on the Panda). Now the array is read-only, and a new target
(assigned, or through ``set_target``) is a new array, which the fused step sees.
"""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def _stack(post: rk.PostureTask, qp: bool) -> rk.TaskStack:
    if qp:
        post.priority = 1  # type: ignore[attr-defined]
    return rk.TaskStack([rk.FrameTask("panda_hand", rk.Hold(), axes="position", priority=0), post], [])


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_an_in_place_edit_of_the_target_is_refused(method: str) -> None:
    robot = rk.load_example_robot("panda")
    post = rk.PostureTask(Q0.copy())
    stack = _stack(post, method != "pinv")
    res = make_resolver(method)
    res.step(robot, stack, Q0, 0.0, 0.01)
    target = post.target
    assert target is not None and not target.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        target[0] += 0.5


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("how", ["assign", "set_target"])
def test_a_new_target_reaches_the_fused_step(method: str, how: str) -> None:
    """Set between steps, the new target gives the q̇ of a resolver that starts with it."""
    robot = rk.load_example_robot("panda")
    post = rk.PostureTask(Q0.copy())
    stack = _stack(post, method != "pinv")
    res = make_resolver(method)
    for k in range(3):
        res.step(robot, stack, Q0, k * 0.01, 0.01)
    new = Q0.copy()
    new[0] += 0.5
    if how == "assign":
        post.target = new
    else:
        post.set_target(new)
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    fresh_post = rk.PostureTask(new)
    fresh = make_resolver(method).step(robot, _stack(fresh_post, method != "pinv"), Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, fresh.dq, rtol=0, atol=1e-12)
    assert np.abs(got.dq[0]) > 1e-3  # the new target moves the joint (the test could fail)


def test_the_callers_array_stays_writeable_and_a_bad_target_is_refused() -> None:
    given = Q0.copy()
    post = rk.PostureTask(given)
    given[0] = 1.0  # the caller's array is its own: not made read-only, and not the task's
    assert given.flags.writeable and post.target is not None and post.target[0] == 0.0
    with pytest.raises(TaskError, match="NaN or infinite"):
        post.target = np.full(9, np.nan)


class _BaseAndArm(rk.Task):
    """A user's joint-space task on some base and arm coordinates of a free-flyer robot (a selection that is not
    every coordinate): J = I[sel], e = (q_ref ⊖ q)[sel] — its ``joint_form`` lets a fused step take it."""

    def __init__(self, sel: list[int], target: np.ndarray) -> None:
        self._init_task("base_and_arm", gain=2.0)
        self.sel, self.target = np.array(sel), target

    def joint_form(self, robot: rk.RobotModel) -> tuple[np.ndarray, np.ndarray]:
        return self.sel, self.target

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        e = robot.difference(robot.q, self.target)[self.sel]
        return rk.TaskTerm(self.name, np.eye(robot.nv)[self.sel], self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"_BaseAndArm({self.sel.tolist()})"


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize("which", ["posture", "selection"])
def test_a_free_flyer_joint_task_is_compiled_and_agrees(method: str, which: str) -> None:
    """On a free-flyer robot a joint-space task's error (q_ref ⊖ q)[sel] is Pinocchio's difference (the base's 6
    coordinates are not subtractions), written before the compiled call: the library's ``PostureTask`` (every
    coordinate) and a user's selection (base and arm coordinates, out of order) give the per-task path's q̇ and
    terms, the base tilted and displaced from the target."""
    robot = rk.load_example_robot("talos")
    q_ref = robot.neutral()
    q0 = q_ref.copy()
    q0[:3] += [0.05, -0.02, 0.01]
    q0[3:7] = [0.05, -0.03, 0.02, 1.0]
    q0[3:7] /= np.linalg.norm(q0[3:7])
    arm = robot.joint("arm_left_4_joint").idx_v
    results = []
    for fuse in (True, False):
        joint = rk.PostureTask(q_ref, gain=1.0) if which == "posture" else _BaseAndArm([arm, 5, 0, 3, arm + 1], q_ref)
        if method == "hqp":
            joint.priority = 1  # type: ignore[attr-defined]
        hand = rk.FrameTask("gripper_left_joint", rk.Circle(0.05, 2.0, plane=("y", "z")), gain=5.0)
        stack = rk.TaskStack([hand, joint])
        robot.update(q0)
        stack.reset(robot)
        res = make_resolver(method)
        res.fuse = fuse  # type: ignore[attr-defined]
        q, steps = q0.copy(), []
        for k in range(40):
            step = res.step(robot, stack, q, k * 0.01, 0.01)
            steps.append((step.dq.copy(), [(t.J.copy(), t.v.copy()) for t in step.terms], step.info["path"]))
            q = robot.integrate(q, step.dq, 0.01)
        results.append(steps)
    compiled, plain = results
    assert {path for _, _, path in compiled} == {"compiled"}
    assert {path for _, _, path in plain} == {"interpreted"}
    for k, ((dq_a, terms_a, _), (dq_b, terms_b, _)) in enumerate(zip(compiled, plain, strict=True)):
        np.testing.assert_allclose(dq_a, dq_b, rtol=0, atol=1e-11, err_msg=f"step {k}")
        for (Ja, va), (Jb, vb) in zip(terms_a, terms_b, strict=True):
            np.testing.assert_allclose(Ja, Jb, rtol=0, atol=1e-13)
            np.testing.assert_allclose(va, vb, rtol=0, atol=1e-11)
    assert np.abs(compiled[0][1][1][1][:6] if which == "posture" else compiled[0][1][1][1]).max() > 1e-3
