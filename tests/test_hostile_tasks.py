"""Hostile arguments to tasks, targets, trajectories, potentials and stacks from Python: NaN, overflowing or absurd
values, booleans or strings where numbers belong, poses that are not poses; each refused where it is set, naming
what was wrong."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError, TaskError
from redundik.tasks.trajectory import Trajectory
from tests.hostile import _planar


@pytest.mark.parametrize("bad", [[math.nan, 0.0, 0.0], [0.0, math.inf, 0.0]])
def test_posture_target_with_nan_is_refused_where_it_is_set(bad: list[float]) -> None:
    """``PostureTask(target=[nan, ...])`` was accepted (``set_target`` refused the same vector)."""
    with pytest.raises(TaskError, match=r"posture task 'posture': target: contains NaN or infinite values"):
        rk.PostureTask(target=bad)
    posture = rk.PostureTask(target=[0.0, 1.0, 0.0])
    np.testing.assert_array_equal(posture.target, [0.0, 1.0, 0.0])


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.Circle(0.1, 1.0, phase=math.nan), "circle phase"),
        (lambda: rk.Circle(0.1, 1e308), "circle omega"),
        (lambda: rk.Circle(1e300, 1.0), "circle radius"),
        (lambda: rk.Circle(1e7, 1e7), "radius × omega"),
        (lambda: rk.Circle(True, 1.0), "circle radius must be a number, got bool"),  # type: ignore[arg-type]
        (lambda: rk.Line([1e300, 0.0]), "line velocity"),
        (lambda: rk.Line(["a", "b"]), "line velocity: expected 2 numbers, got list"),
        (lambda: rk.PoseInterpolation([0, 0, 0], True), "duration must be a number"),  # type: ignore[arg-type]
    ],
)
def test_trajectories_refuse_nan_and_overflowing_parameters(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(TaskError) as info:
        make()
    assert expected in str(info.value)


def test_pose_interpolation_too_fast_to_represent_is_refused_at_reset() -> None:
    robot, _, _ = _planar()
    task = rk.FrameTask("3", rk.PoseInterpolation([1.0, 0.0, 0.0], 1e-300), axes="planar")
    with pytest.raises(TaskError, match="longer duration"):
        task.reset(robot)


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.TaskStack(None), "stack.tasks: expected a list, got NoneType"),  # type: ignore[arg-type]
        (lambda: rk.TaskStack({"a": rk.PostureTask()}), "stack.tasks: expected a list, got dict"),  # type: ignore[arg-type]
        (lambda: rk.TaskStack(["x"]), "stack.tasks[0]: expected a Task, got str"),  # type: ignore[list-item]
        (
            lambda: rk.TaskStack([rk.GradientSubtask(rk.JointSine2("3"))]),  # type: ignore[list-item]
            "stack.tasks[0]: expected a Task, got GradientSubtask (a subtask belongs in the second list",
        ),
        (
            lambda: rk.TaskStack([], [rk.PostureTask()]),  # type: ignore[list-item]
            "stack.subtasks[0]: expected a Subtask, got PostureTask (a task belongs in the first list",
        ),
        (lambda: rk.TaskStack([rk.PostureTask(), rk.PostureTask()]), "repeated: ['posture']"),
    ],
)
def test_a_stack_refuses_what_it_cannot_hold_when_it_is_made(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(ResolverError) as info:
        make()
    assert expected in str(info.value)


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: rk.JointValue("3", True), "value must be a number, got bool"),
        (lambda: rk.JointValue("3", "x"), "value must be a number, got str"),  # type: ignore[arg-type]
        (lambda: rk.JointSine2(3), "JointSine2: joint must be a joint name (a string), got 3"),  # type: ignore[arg-type]
        (lambda: rk.JointSine2(None), "got None"),  # type: ignore[arg-type]
        (lambda: rk.VirtualPoint("3", ["a", "b", "c"]), "point: expected real numbers"),
        (lambda: rk.Clearance(None, [0, 0, 0]), "frame must be a frame name"),  # type: ignore[arg-type]
    ],
)
def test_potentials_refuse_values_that_are_not_numbers_or_names(make: Callable[[], object], expected: str) -> None:
    with pytest.raises(TaskError) as info:
        make()
    assert expected in str(info.value)


def test_hold_and_pose_interpolation_refuse_what_is_not_a_pose() -> None:
    import pinocchio as pin

    bad = pin.SE3.Identity()
    bad.translation = np.array([math.nan, 0.0, 0.0])
    with pytest.raises(TaskError, match="hold pose: contains NaN"):
        rk.Hold(bad)
    with pytest.raises(TaskError, match="hold pose: expected an SE3 or a 4×4"):
        rk.Hold("x")  # type: ignore[arg-type]
    with pytest.raises(TaskError, match="not a rigid transform"):
        rk.Hold(2.0 * np.eye(4))
    assert rk.Hold(np.eye(4)).pose == pin.SE3.Identity()  # a 4×4 matrix is a pose
    with pytest.raises(TaskError, match="goal rotation must be a 3×3 matrix of numbers"):
        rk.PoseInterpolation([0, 0, 0], 1.0, rotation="x")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("target", "expected"),
    [
        ([1e308, 0.0, 0.0], "coordinate beyond"),
        ([True, False, True], "got bool values"),
        ([1 + 2j, 0, 0], "got complex128 values"),
        ("abc", "of real numbers"),
    ],
)
def test_frame_target_that_is_absurd_or_not_numbers_is_refused(target: object, expected: str) -> None:
    task = rk.FrameTask("panda_hand")
    with pytest.raises(rk.TaskError, match=expected):
        task.set_target(target)
    far = np.eye(4)
    far[:3, 3] = (0.0, -2e6, 0.0)
    with pytest.raises(rk.TaskError, match="beyond"):
        task.set_target(far)


def test_posture_target_of_booleans_or_strings_is_refused() -> None:
    with pytest.raises(rk.TaskError, match=r"posture task 'posture': target: .*bool"):
        rk.PostureTask(target=[True] * 9)
    with pytest.raises(rk.TaskError, match=r"set_target: .*real numbers"):
        rk.PostureTask().set_target(["a"] * 9)


def test_posture_target_beyond_a_million_is_refused_where_it_is_set() -> None:
    """A posture 1e308 rad away asked wqp (no limits) for ~1e307 rad/s: now refused, naming the coordinate."""
    with pytest.raises(rk.TaskError, match=r"posture task 'posture': target: coordinate 1 = 1e\+308 is beyond"):
        rk.PostureTask(target=[0.0, 1e308, 0.0])
    posture = rk.PostureTask(target=[0.0, 1.0, 0.0])
    with pytest.raises(rk.TaskError, match=r"set_target: coordinate 0 = -2e\+06 is beyond"):
        posture.set_target([-2e6, 0.0, 0.0])
    np.testing.assert_array_equal(posture.target, [0.0, 1.0, 0.0])  # the refused target left the old one in place


class _UserRows(rk.Task):
    """A user's task whose ``evaluate`` returns what ``kind`` says (a frame's height row otherwise)."""

    def __init__(self, kind: str) -> None:
        self._init_task(f"user_{kind}", gain=1.0)
        self.kind, self.calls = kind, 0

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        self.calls += 1
        J = robot.frame_jacobian("panda_link4")[2:3].copy()
        e = np.array([0.3 - robot.frame_position("panda_link4")[2]])
        v: object = self.gain * e
        Jx: object = J
        kind = self.kind
        if kind == "none":
            return None  # type: ignore[return-value]
        if kind == "tuple":
            return (J, v, e)  # type: ignore[return-value]
        if kind == "zero" or (kind == "alternating" and self.calls % 2):
            Jx, v, e = J[:0], e[:0], e[:0]
        elif kind == "list":
            Jx, v = J.tolist(), [float(self.gain * e[0])]
        elif kind == "float32":
            Jx = J.astype(np.float32)
        elif kind == "bool":
            Jx = J != 0.0
        elif kind == "objects":
            Jx = J.astype(object)
        elif kind == "complex":
            Jx = J.astype(complex)
        elif kind == "strings":
            Jx = np.full(J.shape, "a")
        elif kind == "complex_objects":
            Jx = np.array([[1j] * J.shape[1]], dtype=object)
        return rk.TaskTerm(self.name, Jx, v, e, self.weight)  # type: ignore[arg-type]

    def __repr__(self) -> str:
        return f"_UserRows({self.kind!r})"


def _panda_stack(tasks: list[rk.Task]) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    """The Panda at a bent elbow with ``tasks`` and a posture, reset there: (robot, stack, q)."""
    robot = rk.load_example_robot("panda")
    q = robot.neutral()
    q[3] = -1.5
    robot.update(q)
    stack = rk.TaskStack([*tasks, rk.PostureTask(gain=1.0)])
    stack.reset(robot)
    return robot, stack, q


def _user_stack(kind: str) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    return _panda_stack([rk.FrameTask("panda_hand", gain=5.0), _UserRows(kind)])


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize(
    ("kind", "expected"),
    [
        ("none", r"task 'user_none': evaluate must return a TaskTerm"),
        ("tuple", r"task 'user_tuple': evaluate must return a TaskTerm"),
        ("complex", r"task 'user_complex': evaluate returned a J that is not real numbers \(dtype complex128\)"),
        ("strings", r"task 'user_strings': evaluate returned a J that is not real numbers"),
        ("complex_objects", r"task 'user_complex_objects': evaluate returned a J that is not real numbers"),
    ],
)
def test_a_user_term_that_is_not_real_rows_is_refused_naming_the_task(
    fuse: bool, method: str, kind: str, expected: str
) -> None:
    """A user's ``evaluate`` returning no ``TaskTerm``, or complex or non-numeric rows, gets a ``TaskError`` naming
    the task on the mixed and the per-task path alike. Complex rows were cast to real (a NumPy warning, the imaginary
    part dropped: a silent wrong answer), ``None`` an AttributeError."""
    robot, stack, q = _user_stack(kind)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    with pytest.raises(TaskError, match=expected):
        resolver.step(robot, stack, q, 0.0, 0.01)


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["zero", "alternating", "list", "float32", "bool", "objects"])
def test_a_user_term_numpy_reads_as_real_rows_is_solved_as_its_float_rows(method: str, kind: str) -> None:
    """Rows NumPy reads as real numbers (a list, float32, booleans, objects holding floats), or no rows at all this
    step, are solved as their float64 rows: the mixed step and the per-task path agree. Zero rows under ``hqp``'s
    mixed step raised IndexError, a list under ``wqp``'s per-task path numba's TypingError."""
    answers = []
    for fuse in (True, False):
        robot, stack, q = _user_stack(kind)
        resolver = rk.make_resolver(method)
        resolver.fuse = fuse  # type: ignore[attr-defined]
        dqs = []
        for k in range(4):
            res = resolver.step(robot, stack, q, 0.01 * k, 0.01)
            assert res.fallback is None and np.isfinite(res.dq).all()
            assert res.info["path"] == ("mixed" if fuse else "interpreted")
            dqs.append(res.dq.copy())
            q = robot.integrate(q, res.dq, 0.01)
        answers.append(np.array(dqs))
    np.testing.assert_allclose(answers[0], answers[1], rtol=0, atol=1e-12)


class _UserPotential(rk.Potential):
    """A user's potential that sets no ``name``: p = q₁², or what ``kind`` says."""

    def __init__(self, kind: str = "ok") -> None:
        self.kind = kind

    def value(self, robot: rk.RobotModel) -> float:
        values: dict[str, object] = {"value_nan": math.nan, "value_str": "x", "value_complex": 1j,
                                     "value_array": np.array([1.0, 2.0])}  # fmt: skip
        return values.get(self.kind, float(robot.q[1] ** 2))  # type: ignore[return-value]

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        g = np.zeros(robot.nv)
        g[1] = 2.0 * robot.q[1] + 0.1
        if self.kind == "gradient_nan":
            g[0] = math.nan
        elif self.kind == "gradient_complex":
            return g.astype(complex)
        elif self.kind == "gradient_list":
            return g.tolist()  # type: ignore[return-value]
        return g


class _UserBarrier(rk.Barrier):
    """A user's barrier that sets no ``name``: h = 0.5 − q₁ ≥ 0, or what ``kind`` says."""

    def __init__(self, kind: str = "ok") -> None:
        self.kind = kind

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        h, H = np.array([0.5 - robot.q[1]]), np.zeros((1, robot.nv))
        H[0, 1] = -1.0
        kind = self.kind
        if kind == "none":
            return None  # type: ignore[return-value]
        if kind == "lists":
            return rk.BarrierTerm(h.tolist(), H.tolist(), ["b"])  # type: ignore[arg-type]
        if kind == "complex":
            return rk.BarrierTerm(h.astype(complex), H, ["b"])
        if kind == "H_shape":
            return rk.BarrierTerm(h, H[:, :3], ["b"])
        if kind == "names":
            return rk.BarrierTerm(h, H, [])
        if kind in ("gamma_negative", "gamma_nan"):
            return rk.BarrierTerm(h, H, ["b"], np.array([-1.0 if kind == "gamma_negative" else math.nan]))
        if kind == "h_nan":
            return rk.BarrierTerm(np.array([math.nan]), H, ["b"])
        return rk.BarrierTerm(h, H, ["b"])


def _subtask_stack(sub: object) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    robot = rk.load_example_robot("panda")
    q = robot.neutral()
    q[1], q[3] = 0.2, -1.5
    robot.update(q)
    hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, plane=("y", "z")), gain=5.0, axes="position")
    stack = rk.TaskStack([hand, rk.PostureTask(gain=1.0)], [sub])  # type: ignore[list-item]
    stack.reset(robot)
    return robot, stack, q


def test_a_users_potential_or_barrier_without_a_name_gets_one_from_its_class() -> None:
    """``GradientSubtask(MyPotential())`` raised AttributeError ('no attribute name') on a potential that sets none,
    even with ``name=`` given; the subtask now takes the class's name in snake case."""
    assert rk.GradientSubtask(_UserPotential(), gain=-1.0).name == "user_potential"
    assert rk.TargetSubtask(_UserPotential(), target=0.1).name == "user_potential"
    assert rk.GradientSubtask(_UserPotential(), name="mine").name == "mine"
    assert rk.BoundSubtask(_UserBarrier()).name == "user_barrier"
    assert "_UserBarrier" in repr(_UserBarrier())


_REFUSED: list[tuple[Callable[[], object], str]] = [
    (lambda: rk.TargetSubtask(_UserPotential("value_str"), target=0.1), "the value of potential .* is not one"),
    (lambda: rk.TargetSubtask(_UserPotential("value_complex"), target=0.1), "is not one real number"),
    (lambda: rk.TargetSubtask(_UserPotential("value_array"), target=0.1), r"is not one real number \(2 values"),
    (lambda: rk.GradientSubtask(_UserPotential("gradient_complex"), gain=-1.0), "is not a vector of numbers"),
    (lambda: rk.TargetSubtask(_UserPotential("gradient_complex"), target=0.1), "is not a vector of numbers"),
    (lambda: rk.BoundSubtask(_UserBarrier("none")), "must return a BarrierTerm"),
    (lambda: rk.BoundSubtask(_UserBarrier("complex")), "are not real numbers"),
    (lambda: rk.BoundSubtask(_UserBarrier("H_shape")), r"H of shape \(1, 3\)"),
    (lambda: rk.BoundSubtask(_UserBarrier("names")), "one name per row"),
    (lambda: rk.BoundSubtask(_UserBarrier("gamma_negative")), "gamma must be finite and ≥ 0"),
    (lambda: rk.BoundSubtask(_UserBarrier("gamma_nan")), "gamma must be finite and ≥ 0"),
]
#: (``feedback`` takes the first five, gradient and target subtasks; the bound subtasks are wqp's and hqp's.)


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize(
    ("method", "k"),
    [(m, k) for m in ("feedback", "wqp", "hqp") for k in range(len(_REFUSED)) if m != "feedback" or k < 5],
)
def test_a_users_potential_or_barrier_giving_no_real_rows_is_refused_naming_it(fuse: bool, method: str, k: int) -> None:
    """Complex or non-numeric values, misshapen rows, names or γ from a user's potential or barrier: a ``TaskError``
    naming the subtask. They raised numba's or NumPy's errors, or were cast to real with a mere warning."""
    make, expected = _REFUSED[k]
    sub = make()
    robot, stack, q = _subtask_stack(sub)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    with pytest.raises(TaskError, match=expected):
        resolver.step(robot, stack, q, 0.0, 0.01)


_NON_FINITE: list[Callable[[], object]] = [
    lambda: rk.TargetSubtask(_UserPotential("value_nan"), target=0.1),
    lambda: rk.TargetSubtask(_UserPotential("gradient_nan"), target=0.1),
    lambda: rk.BoundSubtask(_UserBarrier("h_nan")),
]


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize(
    ("method", "k"), [(m, k) for m in ("feedback", "wqp", "hqp") for k in range(3) if m != "feedback" or k < 2]
)
def test_non_finite_subtask_rows_stop_the_step_and_name_the_subtask(fuse: bool, method: str, k: int) -> None:
    """A NaN value or gradient of a target subtask's potential, or a NaN barrier value: the step stops (q̇ = 0,
    inside the limits) and its fallback names the subtask, on both paths. A NaN barrier row was dropped without a
    word (q̇ as if the barrier were not there), and ``wqp``'s mixed step ignored a NaN target value."""
    sub = _NON_FINITE[k]()
    robot, stack, q = _subtask_stack(sub)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    for k in range(2):
        res = resolver.step(robot, stack, q, 0.01 * k, 0.01)
        assert np.isfinite(res.dq).all() and not res.dq.any()
        assert res.fallback is not None and f"subtask '{sub.name}'" in res.fallback  # type: ignore[attr-defined]


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_users_barrier_given_as_lists_is_solved_as_its_float_rows(method: str) -> None:
    answers = []
    for kind in ("ok", "lists"):
        robot, stack, q = _subtask_stack(rk.BoundSubtask(_UserBarrier(kind)))
        res = rk.make_resolver(method).step(robot, stack, q, 0.0, 0.01)
        assert res.fallback is None
        answers.append(res.dq)
    np.testing.assert_allclose(answers[0], answers[1], rtol=0, atol=1e-12)


class _UserTrajectory(Trajectory):
    """A user's trajectory: a 5 cm sway along y from the start pose, or what ``mode`` says."""

    def __init__(self, kind: str = "ok") -> None:
        self.mode = kind

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        start = self.start_pose
        p = np.array(start.translation) + np.array([0.0, 0.05 * math.sin(t), 0.0])
        R = np.array(start.rotation)
        twist = np.array([0.0, 0.05 * math.cos(t), 0.0, 0.0, 0.0, 0.0])
        kind = self.mode
        out: dict[str, object] = {
            "none": None,
            "two": (p, R),
            "lists": (p.tolist(), R.tolist(), twist.tolist()),
            "float32": (p.astype(np.float32), R, twist),
            "complex": (p.astype(complex), R, twist),
            "twist_shape": (p, R, twist[:3]),
            "p_shape": (p[:2], R, twist),
            "not_rigid": (p, 2.0 * R, twist),
            "p_nan": (p + math.nan, R, twist),
        }
        return out.get(kind, (p, R, twist))  # type: ignore[return-value]


def _trajectory_stack(kind: str) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    return _panda_stack([rk.FrameTask("panda_hand", _UserTrajectory(kind), gain=5.0)])


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize(
    ("kind", "expected"),
    [
        ("none", r"reference\(t\) must return \(p \(3,\), R \(3, 3\), twist \(6,\)\), got None"),
        ("two", r"reference\(t\) must return"),
        ("complex", r"reference is not real numbers \(dtype complex128\)"),
        ("twist_shape", r"twist of shape \(3,\); expected \(3,\), \(3, 3\) and \(6,\)"),
        ("p_shape", r"p of shape \(2,\)"),
        ("not_rigid", "reference rotation is not a rotation"),
    ],
)
def test_a_users_trajectory_giving_no_reference_is_refused_naming_the_task(
    fuse: bool, method: str, kind: str, expected: str
) -> None:
    """A user's ``Trajectory.reference`` that gives no (p, R, twist) of real numbers and the right shapes, or a
    matrix that is not a rotation: a ``TaskError`` naming the task, on both paths. Before: a
    twist of 3 entries or a position of 2 was taken without a word on the per-task path (NumPy broadcast them) and
    refused by a broadcast error on the compiled one; a non-rotation R was used as it was; lists and complex
    numbers raised numba's TypingError on the per-task path and were cast to real on the compiled one."""
    robot, stack, q = _trajectory_stack(kind)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    with pytest.raises(TaskError, match=f"task 'panda_hand': .*{expected}"):
        resolver.step(robot, stack, q, 0.0, 0.01)


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["lists", "float32", "p_nan"])
def test_a_users_trajectory_read_as_real_numbers_gives_the_same_step_on_both_paths(method: str, kind: str) -> None:
    """Lists or float32 are solved as their float64 values; a NaN position falls back (q̇ = 0) naming the task;
    the compiled step and the per-task path agree."""
    answers = []
    for fuse in (True, False):
        robot, stack, q = _trajectory_stack(kind)
        resolver = rk.make_resolver(method)
        resolver.fuse = fuse  # type: ignore[attr-defined]
        res = resolver.step(robot, stack, q, 0.3, 0.01)
        assert np.isfinite(res.dq).all()
        assert (res.fallback is not None and "panda_hand" in res.fallback) == (kind == "p_nan")
        answers.append(res.dq)
    np.testing.assert_allclose(answers[0], answers[1], rtol=0, atol=1e-12)


class _LinearPotential(rk.Potential):
    """A user's potential declaring η = w ⊙ (q ⊖ q_c) (``linear_gradient``), its answer what ``mode`` says."""

    name = "linear"

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.answer: object = None

    def value(self, robot: rk.RobotModel) -> float:
        return 0.0

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        return np.zeros(robot.nv)

    def linear_gradient(self, robot: rk.RobotModel) -> tuple[np.ndarray, np.ndarray] | None:
        if self.answer is None:  # (the same objects at every call, as the protocol asks)
            w, c = np.ones(robot.nv), np.zeros(robot.nq)
            self.answer = {
                "w_shape": (w[:3], c),
                "c_shape": (w, c[:2]),
                "complex": (w.astype(complex), c),
                "lists": (w.tolist(), c.tolist()),
                "three": (w, c, 1),
                "scalar": 5,
            }[self.mode]
        return self.answer  # type: ignore[return-value]


@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize("mode", ["w_shape", "c_shape", "complex", "lists", "three", "scalar"])
def test_a_users_linear_gradient_that_does_not_fit_is_refused_naming_the_subtask(method: str, mode: str) -> None:
    """A compiled step packs a potential's ``linear_gradient`` (w, q_c) into its data: one of other sizes was packed
    as it was and read past its end (a silent wrong answer); lists, complex numbers or another shape of answer
    raised raw errors or were cast. Now a ``TaskError`` names the subtask."""
    robot = rk.load_example_robot("panda")
    q = robot.neutral()
    q[3] = -1.5
    robot.update(q)
    hand = rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, plane=("y", "z")), gain=5.0, axes="position")
    stack = rk.TaskStack([hand], [rk.GradientSubtask(_LinearPotential(mode), gain=-0.5)])
    stack.reset(robot)
    with pytest.raises(TaskError, match="subtask 'linear': its potential's linear_gradient must return"):
        rk.make_resolver(method).step(robot, stack, q, 0.0, 0.01)
