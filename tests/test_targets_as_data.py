"""Targets are data (issue 31): a frame target set every tick is written in place, the fused plan is kept, and the
answer is the per-task path's; a subclass of a frame task keeps the fused step unless it has rows of its own."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.resolvers.fused import plan_of

TOOL = "panda_hand_tcp"
Q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])


class MyFrameTask(rk.FrameTask):
    """A user's subclass that changes nothing about the rows."""


class ScaledFrameTask(rk.FrameTask):
    """A user's subclass with rows of its own (half the desired velocity)."""

    def evaluate(self, robot, t):  # type: ignore[no-untyped-def]
        term = super().evaluate(robot, t)
        term.v = 0.5 * term.v
        return term


def _target(home: pin.SE3, t: float) -> pin.SE3:
    offset = np.array([0.0, 0.05 * np.sin(2.0 * t), 0.03 * np.sin(4.0 * t)])
    if t >= 0.1:
        offset[0] += 0.02  # a jump
    return pin.SE3(home.rotation, home.translation + offset)


def _teleop(method: str, fuse: bool, form: str, steps: int = 150, task_class=rk.FrameTask):
    robot = rk.load_example_robot("panda")
    task = task_class(TOOL, gain=40.0)
    stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    q, dt = Q0.copy(), 2e-3
    robot.update(q)
    stack.reset(robot)
    home = robot.frame_pose(TOOL).copy()
    out, plans = [], []
    for k in range(steps):
        T = _target(home, k * dt)
        if form == "se3":
            task.set_target(T)
        elif form == "matrix":
            task.set_target(T.homogeneous)
        elif form == "position":
            task.set_target(T.translation.copy())
        else:
            task.set_target(list(T.translation))  # a list: the checked slow path, still in place
        if k == 80:
            stack.reset(robot)  # a restart keeps the target
        res = resolver.step(robot, stack, q, k * dt, dt)
        out.append(res.dq.copy())
        plans.append(plan_of(resolver))
        q = robot.integrate(q, res.dq, dt)
    return np.array(out), plans, task


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("form", ["se3", "matrix", "position", "list"])
def test_teleop_targets_keep_the_plan_and_equal_the_per_task_path(method: str, form: str) -> None:
    fused, plans, _ = _teleop(method, True, form)
    general, _, _ = _teleop(method, False, form)
    np.testing.assert_allclose(fused, general, rtol=0, atol=1e-12)
    # planned once, and again only after the reset at step 80 (the posture captures a new target there)
    for seg in (plans[5:80], plans[82:]):
        assert seg[0] is not None, "the teleop stack did not take the fused step"
        assert all(p is seg[0] for p in seg), "a set_target planned the stack again"
    assert np.abs(fused[100:]).max() > 1e-3  # it moved


def test_set_target_in_place_keeps_the_hold_and_validates() -> None:
    robot = rk.load_example_robot("panda")
    task = rk.FrameTask(TOOL, gain=10.0)
    stack = rk.TaskStack([task])
    robot.update(Q0)
    stack.reset(robot)
    hold = task.trajectory
    T = robot.frame_pose(TOOL)
    T.translation = T.translation + np.array([0.1, 0.0, 0.0])
    task.set_target(T)
    assert task.trajectory is hold
    np.testing.assert_allclose(task.target.translation, T.translation, atol=0)
    np.testing.assert_allclose(task.target.rotation, T.rotation, atol=0)
    task.set_target(np.array([0.3, 0.1, 0.5]))  # position: the orientation target is kept
    np.testing.assert_allclose(task.target.translation, [0.3, 0.1, 0.5], atol=0)
    np.testing.assert_allclose(task.target.rotation, T.rotation, atol=0)
    before = task.target
    bad_rotation = T.homogeneous.copy()
    bad_rotation[:3, :3] *= 1.01
    nan_pose = T.homogeneous.copy()
    nan_pose[0, 3] = np.nan
    flipped = T.homogeneous.copy()
    flipped[:3, 0] *= -1.0  # det −1
    far = np.array([2e6, 0.0, 0.0])
    bad_last_row = T.homogeneous.copy()
    bad_last_row[3, 0] = 0.5
    for bad in (bad_rotation, nan_pose, flipped, far, bad_last_row, np.zeros((2, 2)), "x", np.array([np.inf, 0, 0])):
        with pytest.raises(TaskError, match="set_target"):
            task.set_target(bad)
        assert task.trajectory is hold
        np.testing.assert_array_equal(task.target.homogeneous, before.homogeneous)  # nothing written
    stack.reset(robot)  # a reset keeps a target set in place
    np.testing.assert_array_equal(task.target.homogeneous, before.homogeneous)


def test_a_given_hold_is_not_written_through() -> None:
    robot = rk.load_example_robot("panda")
    shared = rk.Hold()
    a, b = rk.FrameTask(TOOL, shared, gain=5.0), rk.FrameTask(TOOL, shared, gain=5.0, name="b")
    robot.update(Q0)
    rk.TaskStack([a]).reset(robot)
    rk.TaskStack([b]).reset(robot)
    T = robot.frame_pose(TOOL)
    T.translation = T.translation + 0.05
    a.set_target(T)
    assert a.trajectory is not shared and b.trajectory is shared
    assert shared.pose is None  # the caller's hold keeps holding its start pose


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_subclass_keeps_the_fused_step_and_one_with_its_own_rows_runs_mixed(method: str) -> None:
    def run(task_class):
        robot = rk.load_example_robot("panda")
        task = task_class(TOOL, rk.Circle(0.1, np.pi, plane=("y", "z")), gain=50.0)
        stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)])
        resolver = rk.make_resolver(method)
        q, dt = Q0.copy(), 1e-3
        robot.update(q)
        stack.reset(robot)
        out = []
        for k in range(40):
            res = resolver.step(robot, stack, q, k * dt, dt)
            out.append(res.dq.copy())
            q = robot.integrate(q, res.dq, dt)
        return np.array(out), plan_of(resolver), res

    base, base_plan, _ = run(rk.FrameTask)
    sub, sub_plan, sub_res = run(MyFrameTask)
    own, own_plan, own_res = run(ScaledFrameTask)
    np.testing.assert_array_equal(sub, base)
    assert base_plan is not None and sub_plan is not None
    assert sub_res.info["path"] == "compiled"
    # a subclass with its own evaluate: its rows are written from Python, the rest of the step stays compiled
    assert own_plan is not None and own_res.info["path"] == "mixed"
    assert own_res.info["interpreted"] == ("panda_hand_tcp",)
    assert np.abs(own - base).max() > 1e-6  # its own rows are used


def test_the_frame_tasks_ok_status_is_the_writers() -> None:
    """``FrameTask.set_target`` reads the writers' ``OK`` as a constant of its own (no numba import): the same code."""
    from redundik.tasks import frame, target_kernels

    assert frame._STATUS_OK == target_kernels.OK
    assert len({target_kernels.OK, target_kernels.NOT_FINITE, target_kernels.TOO_FAR, target_kernels.NOT_RIGID}) == 4


def _posture_run(robot_name: str, method: str, fuse: bool, priority: int | None, steps: int = 60):
    """A hand task on a circle and a posture whose q_ref moves every tick (``set_target``, a new float64 array)."""
    robot = rk.load_example_robot(robot_name)
    q = Q0.copy() if robot_name == "panda" else robot.neutral()
    frame = TOOL if robot_name == "panda" else "gripper_left_joint"
    post = rk.PostureTask(gain=2.0, priority=priority)
    hand = rk.FrameTask(frame, rk.Circle(0.05, np.pi, plane=("y", "z")), axes="position", gain=20.0, priority=0)
    stack = rk.TaskStack([hand, post])
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    robot.update(q)
    stack.reset(robot)
    base = q.copy()
    arm = [robot.model.joints[robot.model.getJointId(n)].idx_q for n in robot.joint_names[-7:]]
    out, plans, paths = [], [], []
    dt = 1e-3
    for k in range(steps):
        ref = base.copy()
        ref[arm] += 0.2 * np.sin(0.05 * k + np.arange(len(arm)))  # a moving posture reference (revolute joints)
        post.set_target(ref)
        res = resolver.step(robot, stack, q, k * dt, dt)
        out.append(res.dq.copy())
        plans.append(plan_of(resolver))
        paths.append(res.info["path"])
        q = robot.integrate(q, res.dq, dt)
    return np.array(out), plans, paths


@pytest.mark.parametrize(
    ("robot_name", "method", "priority"),
    [
        ("panda", "pinv", None),
        ("panda", "wqp", None),
        ("panda", "wqp", 1),
        ("panda", "hqp", None),
        ("panda", "hqp", 1),
        ("talos", "wqp", 1),  # a free flyer: the level's error on Lie-group coordinates, written from Python
        ("talos", "hqp", None),
    ],
)
def test_a_posture_target_moved_every_tick_is_data(robot_name: str, method: str, priority: int | None) -> None:
    """``PostureTask.set_target`` every tick: the fused plan is kept (the new q_ref written into its row of the
    plan), the step stays compiled, and q̇ is the per-task path's to 1e-12 — not the previous target's."""
    fused, plans, paths = _posture_run(robot_name, method, True, priority)
    general, _, _ = _posture_run(robot_name, method, False, priority)
    np.testing.assert_allclose(fused, general, rtol=0, atol=1e-12)
    assert plans[2] is not None and all(p is plans[2] for p in plans[2:]), "a posture target planned the stack again"
    if robot_name == "panda":
        assert set(paths[2:]) == {"compiled"}, paths
    assert np.abs(np.diff(fused, axis=0)).max() > 1e-4  # the posture's moving target moves q̇


def test_a_posture_target_is_still_checked_where_it_is_set_and_against_the_robot() -> None:
    robot = rk.load_example_robot("panda")
    post = rk.PostureTask(gain=1.0)
    stack = rk.TaskStack([rk.FrameTask(TOOL, rk.Hold(), axes="position"), post])
    resolver = rk.make_resolver("wqp")
    robot.update(Q0)
    stack.reset(robot)
    resolver.step(robot, stack, Q0, 0.0, 1e-3)
    for bad, words in (
        (np.full(9, np.nan), "NaN or infinite"),
        (np.full(9, 1e7), "beyond"),
        (np.array([1.0, np.inf] + [0.0] * 7), "NaN or infinite"),
    ):
        with pytest.raises(TaskError, match=words):
            post.set_target(bad)
    post.set_target(np.zeros(4))  # a configuration of another robot: refused at the next step, naming the task
    with pytest.raises(Exception, match="posture") as info:
        resolver.step(robot, stack, Q0, 1e-3, 1e-3)
    assert "9" in str(info.value) and "4" in str(info.value)
    target = post.target
    assert target is not None and not target.flags.writeable


def _relative_run(method: str, fuse: bool, steps: int = 200):
    """The Panda's hand held relative to its link 4, the relative target moved every tick (``set_target``)."""
    robot = rk.load_example_robot("panda")
    rel = rk.RelativePoseTask("panda_hand", "panda_link1", axes="position", gain=20.0)
    stack = rk.TaskStack([rel, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    q, dt = Q0.copy(), 2e-3
    robot.update(q)
    stack.reset(robot)
    start = rel.target
    assert start is not None
    out, plans, paths = [], [], []
    for k in range(steps):
        offset = np.array([0.02 * np.sin(0.04 * min(k, 40)), 0.02, 0.0])  # moving, then held from step 40
        rel.set_target(pin.SE3(start.rotation, start.translation + offset) if k % 2 else
                       (pin.SE3(start.rotation, start.translation + offset)).homogeneous)  # fmt: skip
        res = resolver.step(robot, stack, q, k * dt, dt)
        out.append(res.dq.copy())
        plans.append(plan_of(resolver))
        paths.append(res.info["path"])
        q = robot.integrate(q, res.dq, dt)
    robot.update(q)
    return np.array(out), plans, paths, rel.relative_pose(robot).translation - (start.translation + offset)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_relative_target_moved_every_tick_is_data(method: str) -> None:
    fused, plans, paths, miss = _relative_run(method, True)
    general, _, _, _ = _relative_run(method, False)
    np.testing.assert_allclose(fused, general, rtol=0, atol=1e-12)
    assert plans[2] is not None and all(p is plans[2] for p in plans[2:]), "a relative target planned the stack again"
    assert set(paths[2:]) == {"compiled"}, paths
    assert np.linalg.norm(miss) < 1e-3  # it reached the last target (held for 0.32 s at 20 /s)
    with pytest.raises(TaskError, match="homogeneous"):
        rk.RelativePoseTask("panda_hand", "panda_link4").set_target(np.eye(3))
    with pytest.raises(TaskError, match="homogeneous"):
        rk.RelativePoseTask("panda_hand", "panda_link4").set_target(np.full((4, 4), np.nan))


@pytest.mark.parametrize(
    "bad",
    [
        np.eye(4, dtype=bool),
        np.eye(4) + 0j,
        "T",
        None,
        np.eye(3),
        np.full((4, 4), np.inf),
        np.vstack([np.eye(4)[:3], [0.0, 0.0, 1.0, 1.0]]),  # not a homogeneous matrix's last row
        np.diag([2.0, 1.0, 1.0, 1.0]),  # not a rotation
    ],
)
def test_a_relative_target_is_checked_where_it_is_set(bad: object) -> None:
    task = rk.RelativePoseTask("panda_hand", "panda_link1")
    with pytest.raises(TaskError, match="homogeneous transform"):
        task.set_target(bad)  # type: ignore[arg-type]
    assert task.target is None  # nothing was taken


def test_a_teleop_stack_stepped_by_two_resolvers_in_turn() -> None:
    """One teleoperated stack stepped by a pinv and a wqp resolver in turn: each fused plan takes the hold's parameter
    row for its own packed data when it packs, so the other must copy every new target it reads. Each resolver's q̇
    is that of the same resolver on a stack of its own with the same targets (1e-12)."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)

    def make() -> tuple[rk.TaskStack, pin.SE3]:
        stack = rk.TaskStack([rk.FrameTask(TOOL, gain=40.0), rk.PostureTask(gain=1.0)])
        stack.reset(robot)
        return stack, robot.frame_pose(TOOL)

    shared, home = make()
    own = {m: make()[0] for m in ("pinv", "wqp")}
    both = {m: rk.make_resolver(m) for m in ("pinv", "wqp")}
    alone = {m: rk.make_resolver(m) for m in ("pinv", "wqp")}
    for k in range(80):
        t = 0.01 * k
        for m in ("pinv", "wqp") if k % 3 else ("wqp", "pinv"):
            shared.tasks[0].set_target(_target(home, t))
            own[m].tasks[0].set_target(_target(home, t))
            a = both[m].step(robot, shared, Q0, t, 0.01)
            b = alone[m].step(robot, own[m], Q0, t, 0.01)
            np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12, err_msg=f"{m}, step {k}")
            assert a.info["path"] == "compiled" or k < 2
