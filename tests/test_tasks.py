"""Trajectories and frame tasks: twists are the derivatives of the poses, errors and gains behave."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from redundik.errors import TaskError
from redundik.resolvers import PinvResolver
from redundik.simulation import simulate
from redundik.tasks import Circle, FrameTask, Hold, Line, PoseInterpolation, PostureTask, TaskStack

from .helpers import planar3r, random_dh_robot

START = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.4, -0.1, 0.7]))


def _trajectories():
    R1 = pin.rpy.rpyToMatrix(-0.4, 0.6, 1.2)
    return [
        Hold(),
        Line([0.2, -0.4, 0.1]),
        Circle(0.3, 0.5, ("y", "z")),
        Circle(0.1, -2.0, ("x", "y"), center=[0.0, 0.0, 0.7], phase=0.4),
        PoseInterpolation([1.0, 0.2, 0.3], 2.0, rotation=R1),
    ]


@pytest.mark.parametrize("traj", _trajectories(), ids=repr)
def test_twist_is_the_time_derivative_of_the_pose(traj) -> None:
    traj.start(START)
    h = 1e-6
    for t in (0.1, 0.7, 1.3):
        Mp, _ = traj.sample(t + h)
        Mm, _ = traj.sample(t - h)
        _, twist = traj.sample(t)
        np.testing.assert_allclose(twist[:3], (Mp.translation - Mm.translation) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(twist[3:], pin.log3(Mp.rotation @ Mm.rotation.T) / (2 * h), atol=1e-7)


def test_trajectories_start_at_the_start_pose_and_interpolation_ends_at_goal() -> None:
    for traj in _trajectories()[:3]:
        traj.start(START)
        M0, _ = traj.sample(0.0)
        np.testing.assert_allclose(M0.homogeneous, START.homogeneous, atol=1e-12)
    R1 = pin.rpy.rpyToMatrix(-0.4, 0.6, 1.2)
    interp = PoseInterpolation([1.0, 0.2, 0.3], 2.0, rotation=R1)
    interp.start(START)
    M, twist = interp.sample(2.5)
    np.testing.assert_allclose(M.translation, [1.0, 0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(M.rotation, R1, atol=1e-12)
    assert np.all(twist == 0)
    circle = Circle(0.3, 0.5, ("y", "z"))
    circle.start(START)
    for t in np.linspace(0, 10, 7):
        M, _ = circle.sample(t)
        assert np.linalg.norm(M.translation - circle.center) == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Line([0.1, float("nan"), 0.0]), "NaN"),
        (lambda: Line([0.1, 0.2, 0.3, 0.4]), "expected 3 numbers"),
        (lambda: Circle(-1.0, 1.0), "radius must be a positive number"),
        (lambda: Circle(1.0, 1.0, ("x", "x")), "two different axes"),
        (lambda: PoseInterpolation([0, 0, 0], 0.0), "duration must be > 0"),
        (lambda: PoseInterpolation([0, 0, 0], 1.0, rotation=np.diag([1.0, 1.0, -1.0])), "proper 3×3 rotation"),
        (lambda: FrameTask("tip", axes=["x", "q"]), "expected distinct names"),
        (lambda: FrameTask("tip", gain=-1.0), "gain must be ≥ 0, got -1"),
        (lambda: FrameTask("tip", gain=float("nan")), "gain must be a finite number"),
        (lambda: FrameTask("../x"), "not valid"),
    ],
)
def test_bad_task_parameters_raise(make, match) -> None:
    with pytest.raises(TaskError, match=match):
        make()


def test_sampling_before_start_is_a_clear_error() -> None:
    with pytest.raises(TaskError, match="start"):
        Line([0.1, 0, 0]).sample(0.0)


def test_frame_task_unknown_frame_is_reported_with_task_name() -> None:
    robot = planar3r()
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match="task 'tip': frame 'tipp' does not exist"):
        FrameTask("tipp", name="tip").reset(robot)


def test_frame_task_rows_error_and_feedback() -> None:
    rng = np.random.default_rng(4)
    robot = random_dh_robot(rng)
    q = robot.random_configuration(rng)
    robot.update(q)
    task = FrameTask("j7", Hold(), axes=["x", "z", "ry"], gain=3.0)
    task.reset(robot)
    term = task.evaluate(robot, 0.0)
    assert term.J.shape == (3, 7) and np.allclose(term.error, 0) and np.allclose(term.v, 0)
    np.testing.assert_allclose(term.J, robot.frame_jacobian("j7")[[0, 2, 4]])
    # move the robot: the error is desired − actual and v = K e
    robot.update(q + 0.01)
    term = task.evaluate(robot, 0.0)
    p0 = task.trajectory.start_pose.translation
    p = robot.frame_position("j7")
    np.testing.assert_allclose(term.error[:2], (p0 - p)[[0, 2]], atol=1e-12)
    np.testing.assert_allclose(term.v, 3.0 * term.error)


def test_closed_loop_gain_shrinks_tracking_error_20x() -> None:
    robot = planar3r()
    q0 = np.deg2rad([110.0, -40.0, -30.0])
    open_loop = TaskStack([FrameTask("3", Line([0.2, -0.4]), axes="planar")])
    closed = TaskStack([FrameTask("3", Line([0.2, -0.4]), axes="planar", gain=20.0)])
    e_open = simulate(robot, open_loop, PinvResolver(), q0, dt=0.01, steps=500).max_task_error
    e_closed = simulate(robot, closed, PinvResolver(), q0, dt=0.01, steps=500).max_task_error
    assert e_closed * 20 < e_open


def test_posture_task_drives_to_its_target() -> None:
    robot = planar3r()
    target = np.array([0.3, -0.5, 0.9])
    log = simulate(
        robot, TaskStack([PostureTask(target, gain=2.0)]), PinvResolver(), robot.neutral(), dt=0.01, steps=400
    )
    np.testing.assert_allclose(log.q[-1], target, atol=1e-3)
