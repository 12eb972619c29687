"""The mixed step (issue 31's row protocol): members without a compiled form write their rows from Python (their
``evaluate``) into the compiled step's buffers; the rest of the stack stays compiled, and the answer is the per-task
path's. A floating-base ``PostureTask`` (Lie-group coordinates) is on the compiled path."""

from __future__ import annotations

import logging
import math

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import RedundikError, TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Task, TaskTerm

DT = 0.01


class Height(Task):
    """A user's task: a frame's height (one row), or its x and z (two rows) when ``rows`` is 2."""

    def __init__(self, frame: str, z: float, *, rows: int = 1, name: str = "height") -> None:
        self._init_task(name, gain=2.0, weight=0.5)
        self.frame, self.z, self.rows = frame, z, rows

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        sel = [2] if self.rows == 1 else [0, 2]
        p = robot.frame_pose(self.frame).translation
        J = robot.frame_jacobian(self.frame)[sel]
        target = np.array([0.3, self.z])[-len(sel) :]
        e = target - p[sel]
        return TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"Height({self.frame!r})"


def _panda_q0(robot: RobotModel) -> np.ndarray:
    q = pin.neutral(robot.model)
    q[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
    return q


def _run(
    make, robot_name: str, method: str, steps: int, edit=None, qp: list[int] | None = None, **options
) -> tuple[list[np.ndarray], list[str]]:
    """Step a fused copy and a per-task copy on the fused copy's trajectory; return the q̇ differences and paths."""
    copies = []
    for fuse in (True, False):
        robot = rk.load_example_robot(robot_name)
        q = _panda_q0(robot) if robot_name == "panda" else robot.neutral()
        robot.update(q)
        stack = make(robot)
        stack.reset(robot)
        res = rk.make_resolver(method, **options)
        res.fuse = fuse  # type: ignore[attr-defined]
        copies.append((robot, stack, res))
    q = copies[0][0].q.copy()
    diffs: list[np.ndarray] = []
    paths: list[str] = []
    for k in range(steps):
        for robot, stack, _ in copies:
            if edit is not None:
                edit(k, robot, stack)
        a, b = (res.step(robot, stack, q, k * DT, DT) for robot, stack, res in copies)
        assert b.info["path"] == "interpreted"
        paths.append(str(a.info["path"]))
        if qp is not None:
            qp.append(int(bool(a.info.get("qp"))))
        diffs.append(a.dq - b.dq)
        assert [t.name for t in a.terms] == [t.name for t in b.terms]
        for ta, tb in zip(a.terms, b.terms, strict=True):
            np.testing.assert_allclose(ta.J, tb.J, rtol=0, atol=1e-13)
            np.testing.assert_allclose(ta.v, tb.v, rtol=0, atol=1e-11)
        assert a.task_error == pytest.approx(b.task_error, rel=1e-12, abs=1e-15)
        q = copies[0][0].integrate(q, a.dq, DT)
    return diffs, paths


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_user_task_runs_mixed_with_the_per_task_answer(method: str, caplog: pytest.LogCaptureFixture) -> None:
    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0)
        return rk.TaskStack(
            [hand, Height("panda_link4", 0.45), rk.PostureTask(gain=1.0)],
            [rk.GradientSubtask(rk.JointCentering(), gain=-0.5)],
        )

    with caplog.at_level(logging.WARNING, logger="redundik"):
        diffs, paths = _run(make, "panda", method, 60)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert set(paths) == {"mixed"}
    assert any("runs mixed" in r.getMessage() and "height" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_user_task_whose_row_count_changes_is_packed_again(method: str) -> None:
    def edit(k: int, robot: RobotModel, stack: rk.TaskStack) -> None:
        if k == 15:
            stack.tasks[1].rows = 2  # type: ignore[attr-defined]
        if k == 30:
            stack.tasks[1].rows = 1  # type: ignore[attr-defined]

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
        return rk.TaskStack([hand, Height("panda_link4", 0.45), rk.PostureTask(gain=1.0)])

    diffs, paths = _run(make, "panda", method, 45, edit=edit)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert set(paths) == {"mixed"}


class Point(Task):
    """A user's task: a frame's position, all three coordinates or x and z only (``rows`` 3 or 2)."""

    def __init__(self, frame: str, target: tuple[float, float, float], *, priority: int | None = None) -> None:
        self._init_task("point", gain=2.0, weight=0.5, priority=priority)
        self.frame, self.target, self.rows = frame, np.array(target), 3

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        sel = [0, 1, 2] if self.rows == 3 else [0, 2]
        J = robot.frame_jacobian(self.frame)[sel]
        e = (self.target - robot.frame_pose(self.frame).translation)[sel]
        return TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"Point({self.frame!r})"


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_row_count_that_alternates_stays_mixed(method: str) -> None:
    """3 → 2 → 3 → 2 rows: each change lays the step's buffers out again (``hqp`` too, at a level of its own and
    below a frame task), the step stays mixed and gives the per-task answer."""

    def edit(k: int, robot: RobotModel, stack: rk.TaskStack) -> None:
        stack.tasks[1].rows = 3 if (k // 10) % 2 == 0 else 2  # type: ignore[attr-defined]

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
        user = Point("panda_link4", (0.05, 0.0, 0.5), priority=1 if method == "hqp" else None)
        return rk.TaskStack([hand, user, rk.PostureTask(gain=1.0)])

    diffs, paths = _run(make, "panda", method, 40, edit=edit)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert set(paths) == {"mixed"}


def test_mixed_wqp_with_binding_limits_agrees() -> None:
    """A tight joint limit binds: the mixed plan's P, g (its Python rows included) reach the backend."""
    from redundik.resolvers.qp.limits import JointLimits

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.08, 3.0, plane=("y", "z")), gain=5.0)
        return rk.TaskStack([hand, Height("panda_link4", 0.45), rk.PostureTask(gain=1.0)])

    tight = {"lower": {"panda_joint1": -0.01}, "upper": {"panda_joint1": 0.01}}
    try:
        diffs, paths = _run(make, "panda", "wqp", 80, limits=JointLimits(**tight))
    except TypeError:  # the limits option takes the mapping itself
        diffs, paths = _run(make, "panda", "wqp", 80, limits=tight)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-9
    assert set(paths) == {"mixed"}


@pytest.mark.parametrize(
    ("method", "priority"), [("pinv", None), ("wqp", None), ("hqp", None), ("wqp", 0), ("hqp", 2), ("hqp", 0)]
)
def test_floating_base_posture_is_compiled(method: str, priority: int | None) -> None:
    """TALOS with the library's PostureTask (free-flyer coordinates: a Lie-group difference), in the null-space
    objective or at a level of its own: compiled, and the per-task path's answer, while a hand's target is set every
    few ticks."""

    def make(robot: RobotModel) -> rk.TaskStack:
        left = rk.FrameTask("gripper_left_joint", rk.Circle(0.05, np.pi, plane=("y", "z")), gain=20.0)
        right = rk.FrameTask("gripper_right_joint", None, gain=5.0)
        return rk.TaskStack([left, right, rk.PostureTask(gain=1.0, weight=0.01, priority=priority)])

    def edit(k: int, robot: RobotModel, stack: rk.TaskStack) -> None:
        if k % 3 == 0:
            right = stack.tasks[1]
            right.set_target(robot.frame_pose("gripper_right_joint").translation + np.array([0.0, 0.0, 0.001]))  # type: ignore[attr-defined]

    diffs, paths = _run(make, "talos", method, 30, edit=edit)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert paths.count("compiled") >= 28


def test_a_user_task_with_a_wrong_shape_gets_the_per_task_error() -> None:
    """A term whose Jacobian has the wrong width never reaches the compiled step: the per-task path says why."""

    class Wrong(Height):
        def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
            term = super().evaluate(robot, t)
            return TaskTerm(self.name, term.J[:, :3], term.v, term.error, term.weight)

    robot = rk.load_example_robot("panda")
    robot.update(_panda_q0(robot))
    stack = rk.TaskStack([rk.FrameTask("panda_hand", None, gain=5.0), Wrong("panda_link4", 0.45)])
    stack.reset(robot)
    for method in ("pinv", "wqp"):
        with pytest.raises(RedundikError):
            rk.make_resolver(method).step(robot, stack, robot.q.copy(), 0.0, DT)


@pytest.mark.parametrize("bound", ["clearance", "joint"])
def test_wqp_with_bound_subtasks_takes_the_compiled_step(bound: str) -> None:
    """Bound subtasks under wqp: the compiled step writes the task rows, the bound rows come from Python as the QP's
    inequalities; the free optimum is tested against them, the backend called when one binds — the per-task answer."""

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.08, 2.0, plane=("y", "z")), gain=5.0)
        if bound == "clearance":
            p4 = robot.frame_pose("panda_link4").translation
            source: object = rk.Clearance("panda_link4", p4 + np.array([0.12, 0.0, 0.0]), 0.05, axes=("x", "y"))
            sub = rk.BoundSubtask(source, lower=0.06)
        else:
            sub = rk.BoundSubtask(rk.JointValue("panda_joint1", 0.0, name="j1"), lower=0.05, upper=0.3, rate=5.0)
        return rk.TaskStack([hand, rk.PostureTask(gain=1.0)], [sub])

    qp: list[int] = []
    diffs, paths = _run(make, "panda", "wqp", 80, qp=qp)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-9
    assert paths.count("compiled") >= 75
    assert sum(qp) > 0, "the bound rows bind (the backend is called with them)"


class _Height(rk.Potential):
    """A user's Python potential (no compiled form): the height of a frame [m]."""

    def __init__(self, frame: str) -> None:
        self.frame = frame
        self.name = f"height_{frame}"

    def value(self, robot: RobotModel) -> float:
        return float(robot.frame_position(self.frame)[2])

    def gradient(self, robot: RobotModel) -> np.ndarray:
        return np.array(robot.frame_jacobian(self.frame)[2])


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_bound_rows_written_from_python_make_a_mixed_step_that_names_them(
    method: str, caplog: pytest.LogCaptureFixture
) -> None:
    """A bound subtask whose source has no compiled form (a user's Python potential) has its rows written from
    Python before the compiled solve: the step is mixed and names it, with a one-time warning; a bound on a
    potential with a compiled form (a joint value) leaves the step compiled."""
    robot = rk.load_example_robot("panda")
    q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    hand = rk.FrameTask("panda_hand", rk.Circle(0.08, 2.0, plane=("y", "z")), gain=5.0)
    user = rk.BoundSubtask(_Height("panda_link4"), lower=0.2, name="elbow_up")
    joint = rk.BoundSubtask(rk.JointValue("panda_joint1", 0.0, name="j1"), lower=-0.3, upper=0.3, rate=5.0)
    for subs, path, named in (([joint], "compiled", ()), ([joint, user], "mixed", ("elbow_up",))):
        stack = rk.TaskStack([hand, rk.PostureTask(gain=1.0)], subs)
        resolver = rk.make_resolver(method)
        robot.update(q0)
        stack.reset(robot)
        with caplog.at_level("WARNING"):
            for k in range(3):
                res = resolver.step(robot, stack, q0, k * 0.01, 0.01)
        assert res.info["path"] == path, res.info["path"]
        assert tuple(res.info["interpreted"]) == named
    assert any("runs mixed" in r.getMessage() and "elbow_up" in r.getMessage() for r in caplog.records)


class OddArrays(Task):
    """A user's task whose arrays are valid but not C-ordered float64: J Fortran-ordered or read-only, e strided,
    v of integers (a frame's height, one row)."""

    def __init__(self, kind: str) -> None:
        self._init_task(f"odd_{kind}", gain=2.0, weight=0.5)
        self.kind = kind

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        J = robot.frame_jacobian("panda_link4")[[2]]
        e = np.array([0.45 - robot.frame_position("panda_link4")[2]])
        v = self.gain * e
        if self.kind == "fortran":
            J = np.asfortranarray(np.vstack([J, J]))[:1]  # (a strided row of a Fortran array: neither C nor F)
        elif self.kind == "readonly":
            J.flags.writeable = False
        elif self.kind == "strided":
            e = np.repeat(e, 2)[::2]
            v = np.repeat(v, 2)[::2]
        elif self.kind == "integer":
            v = np.array([1])
        return TaskTerm(self.name, J, v, e, self.weight)

    def __repr__(self) -> str:
        return f"OddArrays({self.kind!r})"


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["plain", "fortran", "readonly", "strided", "integer"])
def test_a_user_tasks_arrays_of_any_layout_are_written_as_numpy_reads_them(method: str, kind: str) -> None:
    """A mixed step writes a user's rows straight into its buffers (one compiled call for C-ordered float64 arrays,
    NumPy for any other layout or type): the per-task path's answer either way, and no kernel compiled for the
    odd layouts on the hot path."""
    from redundik.resolvers.linalg import FK

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
        return rk.TaskStack([hand, OddArrays(kind), rk.PostureTask(gain=1.0)])

    diffs, paths = _run(make, "panda", method, 8)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert set(paths) == {"mixed"}
    for kernel in (FK.put_rows, FK.put_level_rows):
        signatures = getattr(kernel, "signatures", None)
        if signatures is not None:  # (compiled: at most one specialisation, C-ordered float64 arrays)
            assert len(signatures) <= 1


class CountedTerm(TaskTerm):
    """A user's TaskTerm subclass (the mixed step's quick checks leave it to the general walk)."""


class Counted(OddArrays):
    """:class:`OddArrays` that counts its evaluations, switching to two rows from the 5th (``kind`` "rows") or
    returning a :class:`CountedTerm` (``kind`` "subclass")."""

    def __init__(self, kind: str) -> None:
        super().__init__("plain" if kind in ("rows", "subclass") else kind)
        self.calls, self.mode = 0, kind

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        self.calls += 1
        term = super().evaluate(robot, t)
        if self.mode == "rows" and self.calls >= 5:
            J = robot.frame_jacobian("panda_link4")[[0, 2]]
            e = np.array([0.3, 0.45]) - robot.frame_position("panda_link4")[[0, 2]]
            return TaskTerm(self.name, J, self.gain * e, e, self.weight)
        if self.mode == "subclass":
            return CountedTerm(term.name, term.J, term.v, term.error, term.weight)
        return term


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["plain", "fortran", "integer", "rows", "subclass"])
def test_a_user_task_is_evaluated_once_per_step_on_every_walk(method: str, kind: str) -> None:
    """The mixed step's quick walk hands a term it cannot put (another row count, a subclass, odd arrays) to the
    general walk with the terms already evaluated: each member's ``evaluate`` runs once a step, whichever walk
    writes its rows, and the answer is the per-task path's."""
    tasks: list[Counted] = []

    def make(robot: RobotModel) -> rk.TaskStack:
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
        tasks.append(Counted(kind))
        return rk.TaskStack([hand, tasks[-1], rk.PostureTask(gain=1.0)])

    diffs, paths = _run(make, "panda", method, 10)
    assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
    assert set(paths) == {"mixed"}
    fused, per_task = tasks
    assert fused.calls == per_task.calls == 10, (fused.calls, per_task.calls)


class Weighted(Task):
    """A user's task (a frame's height) whose term carries the weight ``w`` it was given."""

    def __init__(self, w: object) -> None:
        self._init_task("weighted", gain=2.0)
        self.w = w

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        J = robot.frame_jacobian("panda_link4")[[2]]
        e = np.array([0.45 - robot.frame_position("panda_link4")[2]])
        return TaskTerm(self.name, J, self.gain * e, e, self.w)  # type: ignore[arg-type]

    def __repr__(self) -> str:
        return f"Weighted({self.w!r})"


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("weight", [math.nan, math.inf, 0.0, -1.0, "1", 10**400, None])
def test_a_term_weight_that_is_not_a_finite_positive_number_is_refused_naming_the_task(
    method: str, weight: object
) -> None:
    """A NaN, infinite, zero, negative, text or overflowing weight in a term a user's ``evaluate`` returns was used
    as it was (``wqp`` then failed its QP and fell back without saying why; ``pinv`` ignored it): every path now
    refuses it as ``Task.weight`` refuses it, naming the task."""
    for fuse in (True, False):
        robot = rk.load_example_robot("panda")
        q = _panda_q0(robot)
        robot.update(q)
        hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
        stack = rk.TaskStack([hand, Weighted(weight), rk.PostureTask(gain=1.0)])
        stack.reset(robot)
        resolver = rk.make_resolver(method)
        resolver.fuse = fuse  # type: ignore[attr-defined]
        with pytest.raises(TaskError, match=r"task 'weighted': evaluate returned the weight .*expected a finite"):
            resolver.step(robot, stack, q, 0.0, DT)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_an_integer_or_boolean_term_weight_is_read_as_its_float(method: str) -> None:
    """A weight of 2 (or True) is the weight 2.0 (1.0): the per-task path's answer, on the mixed step."""

    for weight in (2, True):

        def make(robot: RobotModel, weight: object = weight) -> rk.TaskStack:
            hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 1.5, plane=("y", "z")), gain=5.0, axes="position")
            return rk.TaskStack([hand, Weighted(weight), rk.PostureTask(gain=1.0)])

        diffs, paths = _run(make, "panda", method, 6)
        assert max(float(np.abs(d).max()) for d in diffs) <= 1e-12
        assert set(paths) == {"mixed"}
