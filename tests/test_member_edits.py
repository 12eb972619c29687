"""Edits of a stack's members between steps reach the compiled and the per-task path alike, and are honoured: after
the edit, both give the q̇ a fresh resolver gives on the edited stack (a compiled step packs a member's data once:
an edit it did not see was a silently wrong q̇). Arrays a member hands out are read-only, so that an edit is an
assignment, which the member sees.

Found by a differential fuzz of the two paths under random public edits (CoM target and axes, a relative pose's
axes and frames, a subtask's potential or source, BestPosture's weights edited in place)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.tasks.balance import CoMTask, SupportPolygon

Q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
DT = 0.01
HAND = "panda_hand_tcp"


def _hand() -> rk.FrameTask:
    return rk.FrameTask(HAND, rk.Circle(0.05, 3.0, plane=("y", "z")), gain=20.0)


def _com() -> rk.TaskStack:
    return rk.TaskStack([_hand(), CoMTask(gain=5.0, weight=0.5)], [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)])


def _relative() -> rk.TaskStack:
    return rk.TaskStack(
        [_hand(), rk.RelativePoseTask("panda_link4", "panda_link2", axes="position", gain=3.0, weight=0.5)],
        [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)],
    )


def _subtasks() -> rk.TaskStack:
    return rk.TaskStack(
        [rk.FrameTask(HAND, rk.Circle(0.05, 3.0, plane=("y", "z")), axes="position", gain=20.0)],
        [
            rk.GradientSubtask(rk.JointCentering(), gain=-1.0),
            rk.TargetSubtask(rk.JointValue("panda_joint1", 0.3), 0.0, rate=2.0),
        ],
    )


def _bounded() -> rk.TaskStack:
    return rk.TaskStack(
        [rk.FrameTask(HAND, rk.Circle(0.05, 3.0, plane=("y", "z")), axes="position", gain=20.0)],
        [rk.BoundSubtask(rk.Clearance("panda_link4", [0.45, 0.0, 0.6], 0.05), lower=0.08, rate=5.0)],
    )


def _best_posture() -> rk.TaskStack:
    return rk.TaskStack(
        [rk.FrameTask(HAND, rk.Circle(0.05, 3.0, plane=("y", "z")), axes="position", gain=20.0)],
        [rk.GradientSubtask(rk.BestPosture(HAND, axes="position", weights=np.ones(9)), gain=-1.0)],
    )


Edit = Callable[[rk.TaskStack], None]


def _swap(attr: str, index: int, make: Callable[[], object]) -> Callable[[], Edit]:
    """An edit that gives subtask ``index`` another ``attr``, made before the run (making a potential moves
    ``Edits``, which a compiled step reads: made at the edit, it would hide a stale plan)."""

    def made() -> Edit:
        new = make()
        return lambda st: setattr(st.subtasks[index], attr, new)

    return made


def _set(path: Callable[[rk.TaskStack], object], attr: str, value: object) -> Callable[[], Edit]:
    def made() -> Edit:
        return lambda st: setattr(path(st), attr, value)

    return made


#: name: (the stack, the edit (made before the run), the resolvers)
CASES: dict[str, tuple[Callable[[], rk.TaskStack], Callable[[], Edit], tuple[str, ...]]] = {
    "com target None": (_com, _set(lambda st: st.tasks[1], "target", None), ("pinv", "wqp", "hqp")),
    "com target": (_com, _set(lambda st: st.tasks[1], "target", [0.1, 0.0, 0.5]), ("pinv", "wqp", "hqp")),
    "com axes": (_com, _set(lambda st: st.tasks[1], "axes", ("x", "y")), ("pinv", "wqp", "hqp")),
    "relative axes": (_relative, _set(lambda st: st.tasks[1], "axes", ("x", "z")), ("pinv", "wqp", "hqp")),
    "relative frame": (_relative, _set(lambda st: st.tasks[1], "frame_b", "panda_link1"), ("pinv", "wqp", "hqp")),
    "gradient potential": (
        _subtasks,
        _swap("potential", 0, lambda: rk.VirtualPoint("panda_link4", [0.3, 0.2, 0.5])),
        ("wqp", "hqp"),
    ),
    "gradient potential, linear": (
        _subtasks,
        _swap("potential", 0, lambda: rk.JointValue("panda_joint2", 0.2)),
        ("wqp", "hqp"),
    ),
    "target potential": (_subtasks, _swap("potential", 1, lambda: rk.JointValue("panda_joint3", 0.4)), ("wqp", "hqp")),
    "bound source": (
        _bounded,
        _swap("source", 0, lambda: rk.Clearance("panda_link4", [-0.165, 0.1, 0.62], 0.05)),  # (0.05 off: binds)
        ("wqp", "hqp"),
    ),
    "best posture weights": (
        _best_posture,
        _set(lambda st: st.subtasks[0].potential, "weights", np.linspace(0.5, 3.0, 9)),
        ("pinv", "wqp", "hqp"),
    ),
}


def _steps(
    method: str, fuse: bool, build: Callable[[], rk.TaskStack], make_edit: Callable[[], Edit]
) -> tuple[list[np.ndarray], ...]:
    """q̇ of the steps after the edit, and those a fresh resolver gives at the same states."""
    robot = rk.load_example_robot("panda")
    stack = build()
    edit = make_edit()
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    robot.update(Q0)
    stack.reset(robot)
    q = Q0.copy()
    for k in range(4):
        q = robot.integrate(q, resolver.step(robot, stack, q, k * DT, DT).dq, DT)
    edit(stack)
    got, fresh = [], []
    for k in range(4, 8):
        res = resolver.step(robot, stack, q, k * DT, DT)
        got.append(res.dq.copy())
        other = rk.make_resolver(method)
        other.fuse = fuse
        fresh.append(other.step(robot, stack, q, k * DT, DT).dq.copy())
        q = robot.integrate(q, res.dq, DT)
    return got, fresh


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_edit_between_steps_reaches_both_paths_as_a_fresh_resolver_sees_it(case: str) -> None:
    build, edit, methods = CASES[case]
    for method in methods:
        fused, fused_fresh = _steps(method, True, build, edit)
        plain, plain_fresh = _steps(method, False, build, edit)
        for k, (a, b, c, d) in enumerate(zip(fused, plain, fused_fresh, plain_fresh, strict=True)):
            scale = max(1.0, float(np.max(np.abs(b))))
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * scale, err_msg=f"{method}, step {k}: fused")
            np.testing.assert_allclose(a, c, rtol=0, atol=1e-12 * scale, err_msg=f"{method}, step {k}: fresh")
            np.testing.assert_allclose(b, d, rtol=0, atol=1e-12 * scale, err_msg=f"{method}, step {k}: fresh")


def test_the_arrays_members_hand_out_are_read_only_copies() -> None:
    weights = np.ones(9)
    best = rk.BestPosture(HAND, axes="position", weights=weights)
    weights[2] = 5.0  # (the caller's own array, edited after: not the potential's)
    assert best.weights is not None and best.weights[2] == 1.0
    com = CoMTask(target=[0.1, 0.0, 0.5], axes=("x", "z"))
    relative = rk.RelativePoseTask("panda_link4", "panda_link2", axes=("x", "z"))
    for arr in (best.weights, best.rows, com.target, com.rows, relative.rows):
        assert arr is not None
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 2.0


def test_an_edit_is_checked_where_it_is_made() -> None:
    bound = rk.BoundSubtask(rk.Clearance("panda_link4", [0.45, 0.0, 0.6], 0.05), lower=0.08, name="keep_out")
    with pytest.raises(TaskError, match=r"keep_out.*barrier"):  # (a barrier takes no bounds)
        bound.source = SupportPolygon(["leg_left_sole_fix_joint"])
    with pytest.raises(TaskError, match=r"keep_out.*Potential"):
        bound.source = "a clearance"  # type: ignore[assignment]
    target = rk.TargetSubtask(rk.JointValue("panda_joint1", 0.3), 0.0, name="j1")
    with pytest.raises(TaskError, match=r"j1.*Potential"):
        target.potential = 3.0  # type: ignore[assignment]
    relative = rk.RelativePoseTask("panda_link4", "panda_link2")
    with pytest.raises(TaskError, match="differ"):
        relative.frame_b = "panda_link4"
    with pytest.raises(TaskError, match="axes"):
        CoMTask().axes = ("x", "w")


def test_a_relative_pose_task_edited_gives_the_rows_of_a_task_made_so() -> None:
    """A relative pose task's axes or frames assigned after it ran: its rows are those of a task made with them (its
    frames looked up again; the target kept for new axes, taken anew for new frames)."""
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    task = rk.RelativePoseTask("panda_link4", "panda_link2", axes="position", gain=3.0)
    task.reset(robot)
    q = Q0 + 0.05
    robot.update(q)
    held = task.target
    task.axes = ("x", "rz")
    made = rk.RelativePoseTask("panda_link4", "panda_link2", axes=("x", "rz"), gain=3.0, target=held)
    made.reset(robot)
    a, b = task.evaluate(robot, 0.0), made.evaluate(robot, 0.0)
    assert a.J.shape == (2, robot.nv) and np.abs(a.error).max() > 1e-4
    np.testing.assert_allclose(a.J, b.J, rtol=0, atol=1e-14)
    np.testing.assert_allclose(a.error, b.error, rtol=0, atol=1e-14)
    task.frame_b = "panda_link1"
    made = rk.RelativePoseTask("panda_link4", "panda_link1", axes=("x", "rz"), gain=3.0)
    made.reset(robot)
    a, b = task.evaluate(robot, 0.0), made.evaluate(robot, 0.0)
    np.testing.assert_allclose(a.J, b.J, rtol=0, atol=1e-14)
    np.testing.assert_allclose(a.error, b.error, rtol=0, atol=1e-14)


def test_a_com_task_given_new_axes_controls_them() -> None:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    com = CoMTask(axes=("x", "y", "z"))
    com.reset(robot)
    com.axes = ("x", "z")
    assert com.rows.tolist() == [0, 2]
    term = com.evaluate(robot, 0.0)
    made = CoMTask(target=com.target, axes=("x", "z"))
    np.testing.assert_array_equal(term.J, made.evaluate(robot, 0.0).J)
