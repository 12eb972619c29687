"""Values the public API returns are the caller's to keep: a pose stored as "home" does not move with the robot."""

from __future__ import annotations

import numpy as np

import redundik as rk


def _arm() -> rk.RobotModel:
    return rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])


def test_a_stored_frame_pose_does_not_follow_the_robot() -> None:
    robot = _arm()
    robot.update(np.array([0.1, 0.2, 0.3]))
    home = robot.frame_pose("3")  # no .copy(): the teleop habit
    kept = home.homogeneous.copy()
    robot.update(np.array([1.0, -0.5, 0.7]))
    np.testing.assert_array_equal(home.homogeneous, kept)
    assert not np.allclose(robot.frame_pose("3").homogeneous, kept)  # the robot did move


def test_editing_a_returned_pose_or_jacobian_leaves_the_model_alone() -> None:
    robot = _arm()
    q = np.array([0.1, 0.2, 0.3])
    robot.update(q)
    pose, J, p = robot.frame_pose("3"), robot.frame_jacobian("3"), robot.frame_position("3")
    before = (pose.homogeneous.copy(), J.copy(), p.copy())
    pose.translation = np.array([9.0, 9.0, 9.0])
    J[:] = 7.0
    p[:] = 5.0
    np.testing.assert_array_equal(robot.frame_pose("3").homogeneous, before[0])
    np.testing.assert_array_equal(robot.frame_jacobian("3"), before[1])
    np.testing.assert_array_equal(robot.frame_position("3"), before[2])


def test_a_frame_task_still_tracks_after_the_user_edits_a_returned_pose() -> None:
    """The task's own view (frame_pose_view) follows the robot; a user's copy cannot disturb it."""
    robot = _arm()
    q = np.array([0.6, -0.4, -0.3])
    robot.update(q)
    task = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar", gain=10.0)
    stack = rk.TaskStack([task])
    stack.reset(robot)
    start = robot.frame_position("3")
    res = rk.make_resolver("pinv")
    for k in range(20):
        robot.frame_pose("3").translation = np.zeros(3)  # a careless user between ticks
        q = robot.integrate(q, res.step(robot, stack, q, 0.01 * k, 0.01).dq, 0.01)
    robot.update(q)
    np.testing.assert_allclose(robot.frame_position("3")[:2] - start[:2], [0.04, -0.08], atol=2e-3)
