"""A member's level edited between steps: a task's or a subtask's ``priority``, or a name a resolver's level
override refers to, takes effect at the next step, on the compiled and the per-task path alike — as a fresh resolver
would step the edited stack. (A resolver kept the layout of the stack's first step while its membership was the
same: such an edit was silently ignored.)"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError, TaskError

Q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
DT = 0.01


def _stack() -> rk.TaskStack:
    return rk.TaskStack(
        [
            rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, 3.0, plane=("y", "z")), gain=20.0),
            rk.FrameTask("panda_link4", axes="position", gain=5.0, name="elbow"),
        ],
        [
            rk.TargetSubtask(rk.JointValue("panda_joint1", 0.5), 0.0, rate=2.0),
            rk.BoundSubtask(rk.JointValue("panda_joint4", 1.0), upper=-1.0, rate=5.0, name="j4"),
        ],
    )


EDITS: dict[str, Callable[[rk.TaskStack], None]] = {
    "task priority": lambda st: setattr(st.tasks[1], "priority", 1),
    "task priority back": lambda st: setattr(st.tasks[0], "priority", 0),
    "target subtask priority": lambda st: setattr(st.subtasks[0], "priority", 0),
    "bound subtask priority": lambda st: setattr(st.subtasks[1], "priority", 0),
}


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize("edit", sorted(EDITS))
@pytest.mark.parametrize("fuse", [True, False])
def test_a_priority_edited_between_steps_is_the_fresh_resolvers_layout(method: str, edit: str, fuse: bool) -> None:
    robot = rk.load_example_robot("panda")
    stack = _stack()
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    robot.update(Q0)
    stack.reset(robot)
    q = Q0.copy()
    for k in range(3):
        q = robot.integrate(q, resolver.step(robot, stack, q, k * DT, DT).dq, DT)
    before = resolver.step(robot, stack, q, 3 * DT, DT).dq.copy()
    EDITS[edit](stack)
    got = resolver.step(robot, stack, q, 3 * DT, DT).dq
    fresh = rk.make_resolver(method)
    fresh.fuse = fuse
    want = fresh.step(robot, stack, q, 3 * DT, DT).dq
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    if edit in ("task priority", "target subtask priority"):  # (these move q̇: the test could fail)
        assert np.max(np.abs(before - want)) > 1e-6


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_renaming_a_member_a_level_override_names_is_refused_at_the_next_step(method: str) -> None:
    robot = rk.load_example_robot("panda")
    stack = _stack()
    resolver = rk.make_resolver(method, levels={"elbow": 1})
    robot.update(Q0)
    stack.reset(robot)
    resolver.step(robot, stack, Q0, 0.0, DT)
    stack.tasks[1].name = "forearm"
    with pytest.raises(ResolverError, match="elbow"):
        resolver.step(robot, stack, Q0, DT, DT)
    stack.tasks[1].name = "elbow"  # (back: the override applies again)
    got = resolver.step(robot, stack, Q0, DT, DT).dq
    want = rk.make_resolver(method, levels={"elbow": 1}).step(robot, stack, Q0, DT, DT).dq
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("bad", [-1, 1.5, "0", True])
def test_a_subtask_priority_is_checked_where_it_is_assigned(bad: object) -> None:
    stack = _stack()
    for sub in stack.subtasks:
        with pytest.raises(TaskError, match=sub.name):
            sub.priority = bad  # type: ignore[assignment]
        assert sub.priority is None


def test_an_unchanged_assignment_keeps_the_layout(monkeypatch: pytest.MonkeyPatch) -> None:
    """Assigning the level a member already has, or constructing tasks elsewhere, lays nothing out again; a change
    does."""
    made = [0]
    layout = rk.TaskStack.layout

    def counted(self: rk.TaskStack, overrides: object = None) -> object:
        made[0] += 1
        return layout(self, overrides)  # type: ignore[arg-type]

    monkeypatch.setattr(rk.TaskStack, "layout", counted)
    robot = rk.load_example_robot("panda")
    stack = _stack()
    resolver = rk.make_resolver("hqp")
    robot.update(Q0)
    stack.reset(robot)
    resolver.step(robot, stack, Q0, 0.0, DT)
    before = made[0]
    stack.tasks[1].priority = stack.tasks[1].priority
    stack.subtasks[0].priority = None
    stack.tasks[1].name = "elbow"
    rk.FrameTask("panda_link4", priority=2, name="unrelated")
    rk.TargetSubtask(rk.JointValue("panda_joint1", 0.5), 0.0, priority=3)
    resolver.step(robot, stack, Q0, DT, DT)
    assert made[0] == before
    stack.tasks[1].priority = 2
    resolver.step(robot, stack, Q0, DT, DT)
    assert made[0] > before
