"""What a user of the control-loop API changes between steps reaches the step, or is refused: never silently missed.

Each case used to give a silent wrong answer or a bare traceback:

* ``JointCentering.center`` edited in place reached the per-task path (which read a view of it) but not the fused
  step's packed copy (0.32 rad/s apart on the Panda); an assigned centre or weights were ignored until the stack
  was checked again (0.5 rad/s off a fresh resolver).
* ``FrameTask.rows`` edited in place split the fused and per-task paths (0.31 rad/s); ``axes`` and ``frame``
  assigned were ignored (the task kept its rows and its frame id).
* A stack stepped on another robot model kept the first model's frame id (tracking another frame, silently), and
  a posture's captured target of the first robot's size raised Pinocchio's bare ValueError.
* ``Line.velocity`` edited in place or assigned, ``Circle.radius``, ``plane`` or ``center``, ``Hold.pose``, and a
  ``PoseInterpolation``'s goal or duration assigned, were ignored once started (``Circle.e1``/``e2`` could be
  assigned, to no effect).
* ``JointLimits.position_gain`` assigned was not validated (−1 drove every joint at its velocity limit), and
  ``acceleration`` (and the other options ``bind`` reads) assigned after the first step were ignored.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import ResolverError, TaskError
from redundik.kinematics.dh import DHRow, from_dh
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
METHODS = ["pinv", "wqp", "hqp"]


def _hand(traj: rk.Trajectory | None, qp: bool, frame: str = "panda_hand", axes: str = "position") -> rk.FrameTask:
    return rk.FrameTask(frame, traj, axes=axes, gain=1.0, priority=0 if qp else None)


def _steps(res: rk.Resolver, robot: rk.RobotModel, stack: rk.TaskStack, n: int) -> None:
    for k in range(n):
        res.step(robot, stack, Q0, 0.01 * k, 0.01)


def _per_task(method: str, **kw: object) -> rk.Resolver:
    res = make_resolver(method, **kw)
    res.fuse = False  # type: ignore[attr-defined]
    return res


@pytest.mark.parametrize("method", METHODS)
def test_a_joint_centering_centre_is_read_only_and_an_assigned_one_is_used(method: str) -> None:
    robot = rk.load_example_robot("panda")
    jc = rk.JointCentering(center=Q0 + 0.1)
    stack = rk.TaskStack([_hand(rk.Hold(), method != "pinv")], [rk.GradientSubtask(jc, gain=-1.0)])
    res = make_resolver(method)
    _steps(res, robot, stack, 3)
    assert jc.center is not None
    with pytest.raises(ValueError, match="read-only"):
        jc.center[0] += 0.5
    jc.center = Q0 + 0.6
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    ref = _per_task(method).step(robot, stack, Q0, 0.03, 0.01)
    sub = rk.GradientSubtask(rk.JointCentering(center=Q0 + 0.6), gain=-1.0)
    fresh = make_resolver(method).step(robot, rk.TaskStack([_hand(rk.Hold(), method != "pinv")], [sub]), Q0, 0.0, 0.01)
    np.testing.assert_allclose(got.dq, ref.dq, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.dq, fresh.dq, rtol=0, atol=1e-12)
    # the new centre moves the arm (0.6 rad away; under pinv q̇ is scaled to the fingers' 0.2 m/s velocity limit)
    assert float(np.abs(got.dq).max()) > (0.15 if method == "pinv" else 0.3)
    with pytest.raises(TaskError, match="weights must be ≥ 0"):
        jc.weights = -np.ones(9)


@pytest.mark.parametrize("method", METHODS)
def test_frame_task_rows_are_read_only_and_new_axes_or_frame_are_used(method: str) -> None:
    qp = method != "pinv"
    robot = rk.load_example_robot("panda")
    task = _hand(rk.Line([0.1, 0.0, 0.0]), qp)
    post = rk.PostureTask(Q0.copy(), gain=0.5)
    stack = rk.TaskStack([task, post], [])
    res = make_resolver(method)
    _steps(res, robot, stack, 3)
    with pytest.raises(ValueError, match="read-only"):
        task.rows[0] = 2
    task.axes = ("y", "z")  # type: ignore[assignment]
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    assert got.terms[0].v.shape == (2,)
    np.testing.assert_allclose(got.dq, _per_task(method).step(robot, stack, Q0, 0.03, 0.01).dq, rtol=0, atol=1e-12)
    task.frame = "panda_link5"  # reset there at the next step: anchored at that frame's pose
    got = res.step(robot, stack, Q0, 0.04, 0.01)
    line = rk.Line([0.1, 0.0, 0.0])
    fresh_task = rk.FrameTask("panda_link5", line, axes=["y", "z"], gain=1.0, priority=task.priority)
    own = rk.TaskStack([fresh_task, rk.PostureTask(Q0.copy(), gain=0.5)])
    fresh = make_resolver(method).step(robot, own, Q0, 0.04, 0.01)
    np.testing.assert_allclose(got.dq, fresh.dq, rtol=0, atol=1e-12)  # (the frame the step used is the new one)
    assert task._fid == robot.frame_id("panda_link5")


@pytest.mark.parametrize("method", METHODS)
def test_a_stack_stepped_on_another_model_tracks_its_frame_and_its_posture(method: str) -> None:
    qp = method != "pinv"
    a = from_dh([DHRow(n, a=1.0) for n in "abc"], name="A")
    b = from_dh([DHRow(n, a=1.0) for n in "xabc"], name="B")  # frame 'c' has another id here
    tip = rk.FrameTask("c", rk.Line([0.1, 0.1]), axes="planar", priority=0 if qp else None)
    post = rk.PostureTask(gain=0.5)  # the configuration at reset: of A's size first
    stack = rk.TaskStack([tip, post], [])
    res = make_resolver(method)
    res.step(a, stack, np.full(3, 0.3), 0.0, 0.01)
    got = res.step(b, stack, np.full(4, 0.3), 0.0, 0.01)  # used to raise Pinocchio's ValueError (posture)
    own = rk.TaskStack([rk.FrameTask("c", rk.Line([0.1, 0.1]), axes="planar", priority=tip.priority),
                        rk.PostureTask(gain=0.5)], [])  # fmt: skip
    fresh = make_resolver(method).step(b, own, np.full(4, 0.3), 0.0, 0.01)
    np.testing.assert_allclose(got.dq, fresh.dq, rtol=0, atol=1e-12)  # (open loop: the same twist of frame 'c')
    assert tip._fid == b.frame_id("c")
    with pytest.raises(rk.RedundikError):  # a given target of another size: a clear error, not Pinocchio's
        rk_post = rk.PostureTask(np.zeros(3))
        make_resolver(method).step(b, rk.TaskStack([own.tasks[0], rk_post]), np.full(4, 0.3), 0.0, 0.01)


@pytest.mark.parametrize("method", METHODS)
def test_a_started_line_or_circle_uses_new_parameters(method: str) -> None:
    qp = method != "pinv"
    robot = rk.load_example_robot("panda")
    line = rk.Line([0.1, 0.0, 0.0])
    stack = rk.TaskStack([_hand(line, qp), rk.PostureTask(Q0.copy(), gain=0.5)], [])
    res = make_resolver(method)
    _steps(res, robot, stack, 3)
    with pytest.raises(ValueError, match="read-only"):
        line.velocity[0] = 0.3
    line.velocity = [0.3, 0.0]  # type: ignore[assignment]
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    fresh = rk.TaskStack([_hand(rk.Line([0.3, 0.0, 0.0]), qp), rk.PostureTask(Q0.copy(), gain=0.5)], [])
    want = make_resolver(method).step(robot, fresh, Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, want.dq, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.terms[0].v[0], 0.3 + 1.0 * 0.3 * 0.03, atol=1e-12)  # v_d + K (v t)

    circle = rk.Circle(0.05, 1.0, plane=("y", "z"))
    stack = rk.TaskStack([_hand(circle, qp), rk.PostureTask(Q0.copy(), gain=0.5)], [])
    res = make_resolver(method)
    _steps(res, robot, stack, 3)
    center = circle._c.copy()
    circle.radius = 0.1
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, _per_task(method).step(robot, stack, Q0, 0.03, 0.01).dq, rtol=0, atol=1e-12)
    fresh_c = rk.Circle(0.1, 1.0, plane=("y", "z"), center=center)
    fresh = rk.TaskStack([_hand(fresh_c, qp), rk.PostureTask(Q0.copy(), gain=0.5)], [])
    np.testing.assert_allclose(got.dq, make_resolver(method).step(robot, fresh, Q0, 0.03, 0.01).dq, rtol=0, atol=1e-12)
    with pytest.raises(TaskError, match="circle radius"):
        circle.radius = -1.0


def _after_edit(
    method: str, make: Callable[[], Any], edit: Callable[[Any], None], fresh: rk.Trajectory, axes: str = "position"
) -> Any:
    """Three steps on ``make()``, ``edit`` it, then the next step equals a fresh run's on ``fresh`` (the edited
    trajectory as it would have been built), on the fused and on the per-task path, and differs from the unedited
    trajectory's step (the edit matters). Returns the edited trajectory."""
    qp = method != "pinv"
    robot = rk.load_example_robot("panda")

    def stack(t: rk.Trajectory) -> rk.TaskStack:
        return rk.TaskStack([_hand(t, qp, axes=axes), rk.PostureTask(Q0.copy(), gain=0.5)], [])

    traj, kept = make(), make()
    edited, unedited = stack(traj), stack(kept)
    res, same = make_resolver(method), make_resolver(method)
    _steps(res, robot, edited, 3)
    _steps(same, robot, unedited, 3)
    edit(traj)
    got = res.step(robot, edited, Q0, 0.03, 0.01)
    per_task = _per_task(method).step(robot, edited, Q0, 0.03, 0.01)
    before = same.step(robot, unedited, Q0, 0.03, 0.01)
    want = make_resolver(method).step(robot, stack(fresh), Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, want.dq, rtol=0, atol=1e-12)
    np.testing.assert_allclose(per_task.dq, want.dq, rtol=0, atol=1e-12)
    assert np.abs(got.dq - before.dq).max() > 1e-3
    return traj


@pytest.mark.parametrize("method", METHODS)
def test_a_started_circle_uses_a_new_plane_or_centre(method: str) -> None:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    p0 = robot.frame_position("panda_hand")
    centre = p0 - np.array([0.0, 0.05, 0.0])  # where the start pose puts it (phase 0: p0 = c + r e1)
    circle = _after_edit(method, lambda: rk.Circle(0.05, 1.0, plane=("y", "z")),
                         lambda c: setattr(c, "plane", ("x", "z")),
                         rk.Circle(0.05, 1.0, plane=("x", "z"), center=centre))  # fmt: skip
    assert circle.plane == ("x", "z") and circle.e1.tolist() == [1.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="read-only"):
        circle.e1[0] = 2.0
    with pytest.raises(AttributeError):
        circle.e2 = np.array([0.0, 1.0, 0.0])  # type: ignore[misc]
    for bad in (("x", "x"), ("x",), ("x", "w"), "xy", None, (1, 2)):
        with pytest.raises(TaskError, match="circle plane"):
            circle.plane = bad  # type: ignore[assignment]
    assert circle.plane == ("x", "z")  # a refused value changes nothing

    there = p0 + np.array([0.0, 0.0, 0.02])
    circle = _after_edit(method, lambda: rk.Circle(0.05, 1.0, plane=("y", "z")), lambda c: setattr(c, "center", there),
                rk.Circle(0.05, 1.0, plane=("y", "z"), center=there))  # fmt: skip
    np.testing.assert_array_equal(circle.center, there)
    with pytest.raises(TaskError, match="circle center"):
        circle.center = [0.0, float("nan"), 0.0]
    circle.center = None  # placed again from the start pose
    np.testing.assert_allclose(circle.center, centre, atol=1e-15)


@pytest.mark.parametrize("method", METHODS)
def test_a_started_hold_or_interpolation_uses_new_values(method: str) -> None:
    robot = rk.load_example_robot("panda")
    robot.update(Q0)
    pose = robot.frame_pose("panda_hand").copy()
    pose.translation = pose.translation + np.array([0.05, -0.02, 0.03])
    hold = _after_edit(method, rk.Hold, lambda h: setattr(h, "pose", pose), rk.Hold(pose), axes="pose")
    assert hold.pose is not None and np.allclose(hold.pose.homogeneous, pose.homogeneous)
    with pytest.raises(TaskError, match="hold pose"):
        hold.pose = np.eye(3)  # type: ignore[assignment]

    goal = pose.translation
    _after_edit(method, lambda: rk.PoseInterpolation(goal - 0.1, 2.0), lambda i: setattr(i, "goal_position", goal),
                rk.PoseInterpolation(goal, 2.0))  # fmt: skip
    _after_edit(method, lambda: rk.PoseInterpolation(goal, 2.0), lambda i: setattr(i, "duration", 0.5),
                rk.PoseInterpolation(goal, 0.5))  # fmt: skip
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3) @ pose.rotation
    interp = _after_edit(method, lambda: rk.PoseInterpolation(goal, 1.0), lambda i: setattr(i, "goal_rotation", R),
                         rk.PoseInterpolation(goal, 1.0, R), axes="pose")  # fmt: skip
    for key, bad in (("duration", 0.0), ("duration", True), ("goal_position", [0.0, 1.0]),
                     ("goal_rotation", 2 * np.eye(3)), ("goal_rotation", np.full((3, 3), np.nan))):  # fmt: skip
        with pytest.raises(TaskError):
            setattr(interp, key, bad)
    with pytest.raises(ValueError, match="read-only"):
        interp.goal_position[0] = 1.0


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_joint_limit_options_set_between_steps_are_validated_and_used(method: str) -> None:
    robot = rk.load_example_robot("panda")
    stack = rk.TaskStack([_hand(rk.Line([0.3, 0.0, 0.0]), True), rk.PostureTask(Q0.copy(), gain=0.5)], [])
    lim = rk.JointLimits()
    res = make_resolver(method, limits=lim)
    own = make_resolver(method, limits=rk.JointLimits(acceleration=0.5))
    res.step(robot, stack, Q0, 0.0, 0.01)
    own.step(robot, stack, Q0, 0.0, 0.01)  # (the same first q̇: no previous one, no rate window)
    for bad in (0.0, -1.0, float("nan"), 5.0, True):
        with pytest.raises(ResolverError, match="position_gain"):
            lim.position_gain = bad  # type: ignore[assignment]
    with pytest.raises(TypeError):
        lim.lower["panda_joint1"] = 0.0  # type: ignore[index]
    lim.acceleration = 0.5  # used to be ignored until another robot came
    got = res.step(robot, stack, Q0, 0.01, 0.01)
    want = own.step(robot, stack, Q0, 0.01, 0.01)
    np.testing.assert_allclose(got.dq, want.dq, rtol=0, atol=1e-12)
    lim.velocity_limits = {"panda_joint2": 0.01}
    assert abs(res.step(robot, stack, Q0, 0.02, 0.01).dq[1]) <= 0.01 + 1e-12


# --------------------------------------------------------------------------- target and bound subtasks' numbers
_Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def _subtask_stack(sub: rk.Subtask) -> rk.TaskStack:
    return rk.TaskStack([rk.FrameTask("panda_hand", rk.Hold(), axes="position", priority=0)], [sub])


@pytest.mark.parametrize(
    ("kind", "attr", "value"),
    [("target", "rate", float("nan")), ("target", "rate", -1.0), ("target", "weight", float("nan")),
     ("target", "weight", -1.0), ("target", "target", float("nan")), ("target", "target_rate", float("inf")),
     ("bound", "lower", float("nan")), ("bound", "upper", -np.inf), ("bound", "rate", float("nan")),
     ("bound", "rate", -3.0), ("bound", "upper", None), ("bound", "lower", 1.0)],
)  # fmt: skip
def test_a_subtask_number_assigned_between_ticks_is_checked_as_the_constructor_checks_it(
    kind: str, attr: str, value: object
) -> None:
    """A NaN or negative rate or weight used to reach the resolvers: hqp raised a bare LinAlgError (weight NaN or
    −1), a negative rate pushed the potential away from its target, a NaN bound rate was silently ignored."""
    potential = rk.JointValue("panda_joint4", -1.2)
    sub: rk.Subtask = (
        rk.TargetSubtask(potential, target=0.0, rate=5.0, priority=1)
        if kind == "target"
        else rk.BoundSubtask(potential, upper=0.0, rate=5.0, priority=1)
    )
    with pytest.raises(TaskError, match="subtask 'value_panda_joint4'"):
        setattr(sub, attr, value)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize(("kind", "attr", "value"), [("target", "rate", 2.0), ("target", "weight", 0.25),
                                                     ("target", "target", -0.4), ("bound", "upper", -0.8),
                                                     ("bound", "rate", 1.0)])  # fmt: skip
def test_a_valid_subtask_number_assigned_between_ticks_takes_effect(
    method: str, kind: str, attr: str, value: float
) -> None:
    robot = rk.load_example_robot("panda")

    def make(**kw: float) -> rk.Subtask:
        potential = rk.JointValue("panda_joint4", -1.2)
        if kind == "target":
            args = {"target": 0.0, "rate": 5.0, "weight": 1.0} | kw
            return rk.TargetSubtask(potential, priority=1, **args)
        args = {"upper": 0.0, "rate": 5.0} | kw
        return rk.BoundSubtask(potential, priority=1, **args)

    sub = make()
    stack = _subtask_stack(sub)
    res = make_resolver(method)
    res.step(robot, stack, _Q0, 0.0, 0.01)
    setattr(sub, attr, value)
    got = res.step(robot, stack, _Q0, 0.01, 0.01)
    fresh = make_resolver(method)
    fresh_stack = _subtask_stack(make(**{attr: value}))
    fresh.step(robot, fresh_stack, _Q0, 0.0, 0.01)
    want = fresh.step(robot, fresh_stack, _Q0, 0.01, 0.01)
    np.testing.assert_allclose(got.dq, want.dq, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- frame potentials' members
_PANDA_LINKS = ("panda_link4", "panda_link6")


def _frame_potentials() -> list[tuple[str, Callable[[], Any], str, object, Callable[[], Any]]]:
    """(label, the potential as built, the member assigned, the value, the potential built with that value)."""
    C, P = rk.Clearance, rk.VirtualPoint
    return [
        ("clearance.frame", lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.05), "frame", "panda_link6",
         lambda: C("panda_link6", [0.3, 0.2, 0.4], 0.05)),
        ("clearance.axes", lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.05), "axes", ("x", "z"),
         lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.05, axes=("x", "z"))),
        ("clearance.center", lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.05), "center", [0.1, -0.2, 0.5],
         lambda: C("panda_link4", [0.1, -0.2, 0.5], 0.05)),
        ("clearance.radius", lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.05), "radius", 0.2,
         lambda: C("panda_link4", [0.3, 0.2, 0.4], 0.2)),
        ("virtual_point.frame", lambda: P("panda_link4", [0.3, 0.2, 0.4]), "frame", "panda_link6",
         lambda: P("panda_link6", [0.3, 0.2, 0.4])),
        ("virtual_point.point", lambda: P("panda_link4", [0.3, 0.2, 0.4]), "point", [0.0, 0.1, 0.2],
         lambda: P("panda_link4", [0.0, 0.1, 0.2])),
        ("manipulability.frame", lambda: rk.Manipulability("panda_link4"), "frame", "panda_hand",
         lambda: rk.Manipulability("panda_hand")),
        ("manipulability.axes", lambda: rk.Manipulability("panda_hand"), "axes", "position",
         lambda: rk.Manipulability("panda_hand", axes="position")),
        ("best_posture.frames", lambda: rk.BestPosture("panda_link4", axes="position"), "frames",
         ["panda_hand", "panda_link6"], lambda: rk.BestPosture(["panda_hand", "panda_link6"], axes="position")),
    ]  # fmt: skip


@pytest.mark.parametrize("case", _frame_potentials(), ids=lambda c: c[0])
def test_a_frame_potential_member_assigned_after_use_is_used(case: tuple[Any, ...]) -> None:
    """An assigned frame used to keep the first frame's id (the potential measured the old frame, silently); an
    assigned axes kept the old rows; a NaN centre or a negative radius reached the rows."""
    _, make, attr, value, fresh = case
    robot = rk.load_example_robot("panda")
    robot.update(_Q0)
    pot = make()
    pot.check(robot)
    before = pot.value(robot), pot.gradient(robot)
    setattr(pot, attr, value)
    want = fresh()
    want.check(robot)
    assert pot.value(robot) == pytest.approx(want.value(robot), abs=1e-14)
    np.testing.assert_allclose(pot.gradient(robot), want.gradient(robot), rtol=0, atol=1e-14)
    assert abs(pot.value(robot) - before[0]) > 1e-6  # (the assignment changed something)


@pytest.mark.parametrize(
    ("make", "attr", "bad"),
    [(lambda: rk.Clearance("panda_link4", [0, 0, 0]), "center", [0.0, float("nan"), 0.0]),
     (lambda: rk.Clearance("panda_link4", [0, 0, 0]), "center", [0.0, 1.0]),
     (lambda: rk.Clearance("panda_link4", [0, 0, 0]), "radius", -0.1),
     (lambda: rk.Clearance("panda_link4", [0, 0, 0]), "radius", float("inf")),
     (lambda: rk.Clearance("panda_link4", [0, 0, 0]), "axes", ("x", "rz")),
     (lambda: rk.Clearance("panda_link4", [0, 0, 0]), "frame", ""),
     (lambda: rk.VirtualPoint("panda_link4", [0, 0, 0]), "point", "abc"),
     (lambda: rk.Manipulability("panda_link4"), "axes", ("x", "w")),
     (lambda: rk.BestPosture("panda_link4"), "frames", [])],
)  # fmt: skip
def test_a_frame_potential_member_assigned_a_bad_value_is_refused(make: Any, attr: str, bad: object) -> None:
    pot = make()
    with pytest.raises(TaskError, match=f"subtask '{pot.name}'"):
        setattr(pot, attr, bad)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_bound_clearance_moved_between_steps_is_used(method: str) -> None:
    """A moving obstacle: the clearance's assigned centre and radius reach the next step, fused or not (its centre
    is read-only: a fused step packs it)."""
    robot = rk.load_example_robot("panda")
    robot.update(_Q0)
    p = robot.frame_position("panda_link4")

    def stack(center: np.ndarray, radius: float) -> rk.TaskStack:
        bound = rk.BoundSubtask(rk.Clearance("panda_link4", center, radius, axes=("x", "y")), lower=0.05,
                                rate=10.0, priority=1)  # fmt: skip
        return rk.TaskStack([_hand(rk.Circle(0.05, 2.0, ("y", "z")), True), rk.PostureTask(_Q0.copy(), gain=0.5,
                            priority=2)], [bound])  # fmt: skip

    far = p + np.array([0.0, 0.5, 0.0])
    near = p + np.array([0.0, 0.10, 0.0])  # 10 cm − r 6 cm = 4 cm, under the 5 cm margin: the link must move off
    moving = stack(far, 0.05)
    res = make_resolver(method)
    _steps(res, robot, moving, 3)
    clear = moving.subtasks[0].source
    with pytest.raises(ValueError, match="read-only"):
        clear.center[1] = near[1]
    clear.center, clear.radius = near, 0.06
    got = res.step(robot, moving, _Q0, 0.03, 0.01)
    want = make_resolver(method).step(robot, stack(near, 0.06), _Q0, 0.03, 0.01)
    per_task = _per_task(method).step(robot, moving, _Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, want.dq, rtol=0, atol=1e-9)
    np.testing.assert_allclose(per_task.dq, want.dq, rtol=0, atol=1e-9)
    unmoved = make_resolver(method).step(robot, stack(far, 0.05), _Q0, 0.03, 0.01)
    assert np.abs(got.dq - unmoved.dq).max() > 1e-4
