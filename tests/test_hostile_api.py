"""Hostile arguments to the public API outside the resolvers' step: ``RobotModel.limit_violation``, ``difference``,
``integrate``, ``frame_id`` and ``random_configuration``; trajectory times; ``blas_threads``; axes, frames and names
of tasks and potentials; the control loop's parts; ``solve_ik_batch``'s targets; integers beyond the float range;
``TaskStack.reset`` without a robot. Each is one of redundik's errors naming the argument and what was expected —
never a bare numpy / Python / Boost exception, a NaN returned, or a silently wrong meaning."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ModelError, ResolverError, TaskError

HUGE = 10**400  # an int beyond the float range: float(HUGE) raises OverflowError


@pytest.fixture(scope="module")
def panda() -> rk.RobotModel:
    return rk.load_example_robot("panda")


@pytest.fixture(scope="module")
def talos() -> rk.RobotModel:
    return rk.load_example_robot("talos")


def _zero_quaternion(robot: rk.RobotModel) -> np.ndarray:
    q = robot.neutral()
    q[3:7] = 0.0  # the free flyer's quaternion (x, y, z, w)
    return q


# ------------------------------------------------------------------------------------------------- A: limit_violation
@pytest.mark.parametrize(
    ("q", "tol", "match"),
    [
        (np.full(9, np.nan), 1e-9, r"limit_violation\(q\): contains NaN"),
        (np.zeros(12), 1e-9, r"limit_violation\(q\): expected 9 values .* got 12"),  # was truncated silently
        (np.zeros(3), 1e-9, r"limit_violation\(q\): expected 9 values .* got 3"),  # was an IndexError
        (["a"] * 9, 1e-9, r"limit_violation\(q\): expected 9 real numbers"),  # was a TypeError
        (None, 1e-9, r"limit_violation\(q\): expected 9"),
        (np.zeros(9), math.nan, r"limit_violation: tol must be a finite number ≥ 0"),
        (np.zeros(9), -1.0, r"limit_violation: tol must be a finite number ≥ 0"),
        (np.zeros(9), "1e-9", r"limit_violation: tol must be a real number"),
        (np.zeros(9), HUGE, r"limit_violation: tol must be a finite number ≥ 0 \(within the float range\)"),
    ],
)
def test_limit_violation_checks_q_and_tol(panda: rk.RobotModel, q: Any, tol: Any, match: str) -> None:
    with pytest.raises(ModelError, match=match):
        panda.limit_violation(q, tol)


def test_limit_violation_still_measures_a_list(panda: rk.RobotModel) -> None:
    q = 0.5 * (panda.lower_limits + panda.upper_limits)  # mid-range (the neutral q is outside panda_joint4's)
    q[0] = panda.upper_limits[0] + 0.5
    out = panda.limit_violation(q.tolist(), 0)
    assert out[0] == pytest.approx(0.5) and np.all(out[1:] == 0.0)


# ---------------------------------------------------------------------------------------------------- B: difference
@pytest.mark.parametrize(
    ("q1", "match"),
    [
        (np.full(9, np.nan), r"difference\(q1\): contains NaN"),  # was NaN returned
        ("x", r"difference\(q1\): expected 9 real numbers"),  # was Boost.Python.ArgumentError
        (np.zeros(3), r"difference\(q1\): expected 9 values .* got 3"),  # was a ValueError with a C++ path
        ([0.0] * 9 + [1.0], r"difference\(q1\): expected 9 values .* got 10"),
    ],
)
def test_difference_checks_both_configurations(panda: rk.RobotModel, q1: Any, match: str) -> None:
    with pytest.raises(ModelError, match=match):
        panda.difference(panda.neutral(), q1)
    with pytest.raises(ModelError, match=match.replace("q1", "q0")):
        panda.difference(q1, panda.neutral())


def test_difference_refuses_a_zero_quaternion_and_keeps_its_answer(talos: rk.RobotModel) -> None:
    q = talos.neutral()
    with pytest.raises(ModelError, match=r"difference\(q1\): joint 'root_joint': the quaternion .* has norm 0"):
        talos.difference(q, _zero_quaternion(talos))  # was NaN returned
    q1 = q.copy()
    q1[0] = 0.25
    np.testing.assert_allclose(talos.difference(q, q1)[:3], [0.25, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(talos.difference(q.tolist(), q1), talos.difference(q, q1))


# ---------------------------------------------------------------------------------------------------- C: integrate
def test_integrate_refuses_a_zero_quaternion_as_update_does(talos: rk.RobotModel) -> None:
    q = _zero_quaternion(talos)
    with pytest.raises(ModelError, match=r"integrate: q .*joint 'root_joint': the quaternion .* has norm 0"):
        talos.integrate(q, np.zeros(talos.nv), 0.01)  # was a zero quaternion returned
    with pytest.raises(ModelError, match="has norm 0"):
        talos.integrate(q.tolist(), np.zeros(talos.nv), 0.01)
    out = talos.integrate(talos.neutral(), np.ones(talos.nv), 0.01)
    assert np.isfinite(out).all() and abs(np.linalg.norm(out[3:7]) - 1.0) < 1e-12


@pytest.mark.parametrize(
    ("dq", "dt", "match"),
    [
        ("nope", 0.01, r"integrate: dq must be 9 real numbers"),  # was a ValueError
        (None, 0.01, r"integrate: dq must be 9 real numbers"),  # was a TypeError
        (np.zeros(9, dtype=bool), 0.01, r"integrate: dq must be 9 real numbers"),  # was cast to 0/1
        (np.zeros(9), HUGE, r"integrate: dt must be a finite number"),  # was an OverflowError
    ],
)
def test_integrate_refuses_a_dq_that_is_not_nv_real_numbers(panda: rk.RobotModel, dq: Any, dt: Any, match: str) -> None:
    with pytest.raises(ModelError, match=match):
        panda.integrate(panda.neutral(), dq, dt)


# ---------------------------------------------------------------------------------------------------- E: frame names
@pytest.mark.parametrize("name", [3, None, 2.5, ["panda_hand"], np.zeros(2)])
def test_frame_id_of_a_non_string_is_a_model_error(panda: rk.RobotModel, name: Any) -> None:
    with pytest.raises(ModelError, match=r"robot 'panda': a frame name \(str\) was expected, got"):
        panda.frame_id(name)  # was Boost.Python.ArgumentError


@pytest.mark.parametrize(("a", "b"), [(None, "panda_hand"), ("panda_hand", 7)])
def test_relative_pose_task_refuses_a_frame_that_is_not_a_name(a: Any, b: Any) -> None:
    with pytest.raises(TaskError, match=r"RelativePoseTask: frame_[ab] must be a frame name \(a str\)"):
        rk.RelativePoseTask(a, b)  # was Boost's multi-line signature at reset


# ---------------------------------------------------------------------------------------------------- K: rng
@pytest.mark.parametrize("rng", [-1, 2.5, "seed", True, np.random.RandomState(0)])
def test_random_configuration_refuses_what_is_not_a_generator_or_seed(panda: rk.RobotModel, rng: Any) -> None:
    with pytest.raises(ModelError, match=r"random_configuration\(rng\): expected a numpy Generator"):
        panda.random_configuration(rng)


def test_random_configuration_takes_an_int_seed(panda: rk.RobotModel) -> None:
    q = panda.random_configuration(5)  # was AttributeError: 'int' object has no attribute 'uniform'
    np.testing.assert_array_equal(q, panda.random_configuration(np.random.default_rng(5)))
    assert panda.limit_violation(q).max() == 0.0


# ---------------------------------------------------------------------------------------------------- D: time
def _started(trajectory: rk.Trajectory) -> rk.Trajectory:
    import pinocchio as pin

    trajectory.start(pin.SE3.Identity())
    return trajectory


TRAJECTORIES: list[Callable[[], rk.Trajectory]] = [
    lambda: rk.Hold(),
    lambda: rk.Line([0.1, 0.0, 0.0]),
    lambda: rk.Circle(0.1, 1.0),
    lambda: rk.PoseInterpolation([0.1, 0.0, 0.0], 1.0),
]


@pytest.mark.parametrize("make", TRAJECTORIES)
@pytest.mark.parametrize(
    ("t", "match"),
    [
        (math.nan, r"t must be a finite time \[s\]"),  # was NaN velocities and errors
        (math.inf, r"t must be a finite time \[s\]"),
        (HUGE, r"t must be a finite time \[s\]"),
        (None, r"t \[s\] must be a number, got NoneType"),  # was a TypeError
        ("x", r"t \[s\] must be a number, got str"),  # was a ValueError
        ([], r"t \[s\] must be a number, got list"),
    ],
)
def test_trajectory_reference_refuses_a_time_that_is_not_finite(
    make: Callable[[], rk.Trajectory], t: Any, match: str
) -> None:
    trajectory = _started(make())
    with pytest.raises(TaskError, match=rf"{type(trajectory).__name__}\.reference\(t\): " + match):
        trajectory.reference(t)
    p, _R, twist = trajectory.reference(np.float64(0.5))  # numpy floats and ints still go
    assert np.isfinite(p).all() and np.isfinite(twist).all()
    assert np.isfinite(trajectory.reference(1)[0]).all()


def test_frame_task_evaluate_at_a_nan_time_raises(panda: rk.RobotModel) -> None:
    task = rk.FrameTask("panda_hand", rk.Line([0.1, 0.0, 0.0]))
    panda.update(panda.neutral())
    task.reset(panda)
    with pytest.raises(TaskError, match=r"Line\.reference\(t\): t must be a finite time"):
        task.evaluate(panda, math.nan)
    assert np.isfinite(task.evaluate(panda, 0.1).v).all()


# ---------------------------------------------------------------------------------------------------- F: blas_threads
@pytest.mark.parametrize("value", ["nope", math.nan, math.inf, [1], 1e300, np.ones(2), -1, 0, 2.5, True, HUGE])
def test_blas_threads_is_checked_on_assignment(value: Any) -> None:
    resolver = rk.make_resolver("pinv")
    with pytest.raises(ResolverError, match=r"pinv: blas_threads must be None .*'auto' or an integer"):
        resolver.blas_threads = value
    assert resolver.blas_threads == "auto"  # (unchanged)


@pytest.mark.parametrize(("value", "kept"), [(None, None), ("auto", "auto"), (1, 1), (np.int64(4), 4)])
def test_blas_threads_accepts_none_auto_and_a_count(value: Any, kept: Any) -> None:
    resolver = rk.make_resolver("pinv")
    resolver.blas_threads = value
    assert resolver.blas_threads == kept and type(resolver.blas_threads) is type(kept)


# ---------------------------------------------------------------------------------------------------- G: axes
@pytest.mark.parametrize(
    ("axes", "match"),
    [
        (None, r"axes must be one of .* got NoneType"),
        (5, r"axes must be one of .* got int"),
        ([["x"]], r"expected distinct names among"),
        ({"x", "y"}, r"a set has no order"),  # was accepted, in a random row order
        ({"x": 1}, r"axes must be one of .* got dict"),
    ],
)
def test_axes_that_are_not_names_are_task_errors(axes: Any, match: str) -> None:
    with pytest.raises(TaskError, match=match):
        rk.FrameTask("panda_hand", axes=axes)
    with pytest.raises(TaskError, match=r"subtask 'manipulability_panda_hand': .*" + match):
        rk.Manipulability("panda_hand", axes=axes)
    potential = rk.Manipulability("panda_hand")
    with pytest.raises(TaskError, match=match):
        potential.axes = axes


def test_axes_keep_their_order() -> None:
    assert rk.FrameTask("panda_hand", axes=("z", "x")).axes == ("z", "x")
    assert rk.FrameTask("panda_hand", axes=np.array(["rz", "y"])).axes == ("rz", "y")


# ---------------------------------------------------------------------------------------------------- H: frames
@pytest.mark.parametrize("frames", [None, 5, {"panda_hand": 1}, {"panda_hand"}, [], ["panda_hand", 3]])
def test_best_posture_frames_must_be_names(frames: Any) -> None:
    with pytest.raises(TaskError, match=r"subtask 'best_posture': frames must be one frame name \(a str\) or a list"):
        rk.BestPosture(frames=frames)


# ---------------------------------------------------------------------------------------------------- I: names
NAMED: list[tuple[str, Callable[[Any], object]]] = [
    ("FrameTask", lambda name: rk.FrameTask("panda_hand", name=name)),
    ("GradientSubtask", lambda name: rk.GradientSubtask(rk.JointSine2("panda_joint4"), name=name)),
    ("TargetSubtask", lambda name: rk.TargetSubtask(rk.JointSine2("panda_joint4"), 0.5, name=name)),
    ("BoundSubtask", lambda name: rk.BoundSubtask(rk.JointSine2("panda_joint4"), lower=0.1, name=name)),
    ("JointSine2", lambda name: rk.JointSine2("panda_joint4", name=name)),
    ("Manipulability", lambda name: rk.Manipulability("panda_hand", name=name)),
    ("JointCoupling", lambda name: rk.JointCoupling("panda_joint2", "panda_joint4", name=name)),
    ("RelativePoseTask", lambda name: rk.RelativePoseTask("panda_hand", "panda_link4", name=name)),
]


@pytest.mark.parametrize(("owner", "make"), NAMED, ids=[n for n, _ in NAMED])
@pytest.mark.parametrize("name", [np.zeros(3), "", 0, ["a"]])
def test_a_name_must_be_a_non_empty_string(owner: str, make: Callable[[Any], object], name: Any) -> None:
    with pytest.raises(TaskError, match=rf"{owner}: name must be a non-empty string \(or None for the default"):
        make(name)
    assert getattr(make(None), "name", None)  # None: the default name


def test_control_loop_refuses_an_array_gc_slack(panda: rk.RobotModel) -> None:
    stack = rk.TaskStack([rk.FrameTask("panda_hand")])
    io: dict[str, Any] = {"read": panda.neutral, "write": lambda dq: None}
    with pytest.raises(ResolverError, match="control loop: gc_slack must be a number"):
        rk.ControlLoop(panda, stack, rk.make_resolver("pinv"), period=1e-3, gc_slack=np.zeros(3), **io)
    with pytest.raises(ResolverError, match="control loop: gc_slack must be a number"):
        rk.ControlLoop(panda, stack, rk.make_resolver("pinv"), period=1e-3, gc_slack="fast", **io)


# ---------------------------------------------------------------------------------------------------- J: coupling
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"offset": "nope"}, r"offset \[rad or m\] must be a number, got str"),  # was a TypeError from isfinite
        ({"offset": [1, 2]}, r"offset \[rad or m\] must be a number, got list"),  # was a ValueError
        ({"offset": math.nan}, r"offset \[rad or m\] must be a finite number"),
        ({"gain": "1"}, r"gain must be a number, got str"),
        ({"weight": [1.0]}, r"weight must be a number, got list"),
    ],
)
def test_joint_coupling_numbers_are_task_errors(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(TaskError, match=r"task 'coupling_panda_joint2_panda_joint4': " + match):
        rk.JointCoupling("panda_joint2", "panda_joint4", **kwargs)


@pytest.mark.parametrize("joint", [None, 3, ""])
def test_joint_coupling_joints_must_be_names(joint: Any) -> None:
    with pytest.raises(TaskError, match=r"JointCoupling: joint_j must be a joint name \(a str\)"):
        rk.JointCoupling("panda_joint2", joint)


@pytest.mark.parametrize("kwargs", [{"gain": "x"}, {"weight": None}, {"gain": HUGE}])
def test_relative_pose_task_numbers_are_task_errors(kwargs: dict[str, Any]) -> None:
    with pytest.raises(TaskError, match=r"task 'panda_hand_in_panda_link4': (gain|weight) must be a"):
        rk.RelativePoseTask("panda_hand", "panda_link4", **kwargs)


# ---------------------------------------------------------------------------------------------------- L: control loop
@pytest.mark.parametrize(
    ("part", "match"),
    [
        ("stack", r"stack must be a TaskStack, got list \(wrap the tasks"),  # was an AttributeError at the first tick
        ("robot", r"robot must be a RobotModel"),
        ("resolver", r"resolver must be a resolver"),
    ],
)
def test_control_loop_checks_its_parts_at_construction(panda: rk.RobotModel, part: str, match: str) -> None:
    parts: dict[str, Any] = {
        "robot": panda,
        "stack": rk.TaskStack([rk.FrameTask("panda_hand")]),
        "resolver": rk.make_resolver("pinv"),
    }
    parts[part] = [rk.FrameTask("panda_hand")] if part == "stack" else "pinv"
    with pytest.raises(ResolverError, match="control loop: " + match):
        rk.ControlLoop(
            parts["robot"], parts["stack"], parts["resolver"], period=1e-3, read=panda.neutral, write=lambda dq: None
        )


# ---------------------------------------------------------------------------------------------------- M: ik batch
@pytest.mark.parametrize("targets", [{"a": 1}, {0: np.eye(4)}, 5, {np.eye(4).tobytes()}])
def test_solve_ik_batch_refuses_targets_that_are_not_a_sequence(panda: rk.RobotModel, targets: Any) -> None:
    with pytest.raises(ResolverError, match=r"solve_ik_batch: targets must be a sequence .* or an array of N targets"):
        rk.solve_ik_batch(panda, "panda_hand", targets, panda.neutral())  # a dict was a KeyError 0


# ---------------------------------------------------------------------------------------------------- N: huge ints
@pytest.mark.parametrize(
    ("make", "error", "match"),
    [
        (lambda: rk.FrameTask("panda_hand", gain=HUGE), TaskError, r"gain must be a finite number, .*float range"),
        (lambda: rk.PostureTask(weight=HUGE), TaskError, r"weight must be a finite number, .*float range"),
        (lambda: rk.Circle(HUGE, 1.0), TaskError, r"circle radius must be a positive number"),
        (lambda: rk.PoseInterpolation([0, 0, 0], HUGE), TaskError, r"duration must be > 0 \[s\] and finite"),
        (lambda: rk.JointValue("panda_joint4", HUGE), TaskError, r"value must be finite \(within the float range\)"),
    ],
)
def test_ints_beyond_the_float_range_are_the_modules_errors(
    make: Callable[[], object], error: type, match: str
) -> None:
    with pytest.raises(error, match=match):
        make()


def test_ints_beyond_the_float_range_in_the_loop_ik_and_step(panda: rk.RobotModel) -> None:
    stack = rk.TaskStack([rk.FrameTask("panda_hand")])
    io: dict[str, Any] = {"read": panda.neutral, "write": lambda dq: None}
    with pytest.raises(ResolverError, match=r"control loop: period must be finite and > 0"):
        rk.ControlLoop(panda, stack, rk.make_resolver("pinv"), period=HUGE, **io)
    with pytest.raises(ResolverError, match=r"control loop: spin must be finite and ≥ 0"):
        rk.ControlLoop(panda, stack, rk.make_resolver("pinv"), period=1e-3, spin=HUGE, **io)
    with pytest.raises(ResolverError, match=r"solve_ik: timeout must be finite and > 0"):
        rk.solve_ik(panda, "panda_hand", np.array([0.3, 0.0, 0.5]), panda.neutral(), timeout=HUGE)
    resolver = rk.make_resolver("pinv")
    with pytest.raises(ResolverError, match=r"pinv: t must be finite \[s\]"):
        resolver.check_inputs(panda, panda.neutral(), HUGE, 0.01)
    with pytest.raises(ResolverError, match=r"pinv: dt must be finite \[s\]"):
        resolver.check_inputs(panda, panda.neutral(), 0.0, HUGE)


# ---------------------------------------------------------------------------------------------------- O: stack.reset
@pytest.mark.parametrize("robot", [None, "panda", object()])
def test_stack_reset_without_a_robot_says_a_robot_model_was_expected(robot: Any) -> None:
    stack = rk.TaskStack([rk.FrameTask("panda_hand")])
    with pytest.raises(TaskError, match=r"task stack: expected a RobotModel .* got"):
        stack.reset(robot)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize(
    ("levels", "match"),
    [
        ("", "expected a mapping"),  # a string was iterated as names: '1,2' gave {'1': 0, ',': 1, '2': 2}
        ("hand,posture", "expected a mapping"),
        ({"hand", "posture"}, "expected a mapping"),  # a set: no order of levels
        ([{"hand"}], "level 0 must be a name or a list of names"),
        ([["hand"], [None]], "level 1 has None"),
        ([[""]], "level 0 has ''"),
        ({"": 1}, "is not a task or subtask name"),
        ({None: 1}, "is not a task or subtask name"),
        ([["hand", True]], "level 0 has True"),
    ],
)
def test_levels_refuse_what_is_not_names_by_level(method: str, levels: Any, match: str) -> None:
    with pytest.raises(rk.RedundikError, match=match):
        rk.make_resolver(method, levels=levels)


def test_levels_take_integer_names_as_yaml_reads_them() -> None:
    """``levels: {3: 1}`` in YAML has an integer key: the task named '3' (a D-H frame's default name)."""
    assert rk.make_resolver("hqp", levels={3: 1}).levels == {"3": 1}  # type: ignore[attr-defined]
    assert rk.make_resolver("hqp", levels=[[3], "b"]).levels == {"3": 0, "b": 1}  # type: ignore[attr-defined]
