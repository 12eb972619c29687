"""One resolver stepping several robots in turn gives each the answer a resolver of its own gives.

A resolver keeps per-robot state between steps: its limits bound to the robot (the compiled kernels' arrays), the
previous q̇ of a rate window, warm starts, plans sized for the robot. When the robot changes it must start afresh:
``JointLimits.bind`` used to leave the previous robot's kernel arguments in place, so that a 4-joint robot after a
3-joint one got the first one's velocity limits and a box read past their end (0.7 rad/s off, values of 1e-310).
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

import redundik as rk
from redundik.kinematics.dh import DHRow, from_dh
from redundik.resolvers.registry import make_resolver


def _robot(i: int) -> rk.RobotModel:
    n = 3 + i % 3
    rows = [
        DHRow(str(j + 1), a=1.0, lower=-0.2 - 0.3 * (i % 3), upper=0.25 + 0.1 * (i % 3), velocity=0.5 + i % 3)
        for j in range(n)
    ]
    return from_dh(rows, name=f"arm{i}")


def _stack(robot: rk.RobotModel, qp: bool) -> rk.TaskStack:
    tip = rk.FrameTask(str(robot.nv), rk.Line([0.3, 0.1]), axes="planar", priority=0)
    post = rk.PostureTask(np.zeros(robot.nq), gain=0.5)
    subs: list[rk.Subtask] = [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)]
    return rk.TaskStack([tip, post], subs) if qp else rk.TaskStack([tip], subs)


@pytest.mark.parametrize(
    ("method", "rate"), [("pinv", False), ("feedback", False), ("wqp", False), ("wqp", True), ("hqp", False),
                         ("hqp", True)]
)  # fmt: skip
def test_a_resolver_handed_another_robot_starts_afresh(method: str, rate: bool) -> None:
    """(``rate``: a rate limit, whose window comes from the previous q̇.)"""
    kw: dict[str, object] = {}
    if method in ("wqp", "hqp"):
        kw["limits"] = rk.JointLimits(acceleration=5.0) if rate else rk.JointLimits()
    shared = make_resolver(method, **kw)
    worst = 0.0
    for i in range(12):
        robot = _robot(i)
        stack = _stack(robot, method in ("wqp", "hqp"))
        q = np.full(robot.nq, 0.1)
        own = make_resolver(method, **{k: rk.JointLimits(acceleration=5.0) if rate else rk.JointLimits() for k in kw})
        for k in range(3):  # a few steps each: the rate window of the robot's own previous q̇
            a = shared.step(robot, stack, q, 0.01 * k, 0.01)
            b = own.step(robot, stack, q, 0.01 * k, 0.01)
            assert np.isfinite(a.dq).all()
            worst = max(worst, float(np.abs(a.dq - b.dq).max()))
            q = robot.integrate(q, b.dq, 0.01)
        del robot, stack, own
        gc.collect()  # (a freed robot's address may be given to the next: it must not be taken for it)
    assert worst <= 1e-12, worst


def test_limits_bound_to_a_freed_robot_are_not_taken_for_one_made_at_its_address() -> None:
    lim = rk.JointLimits()
    for i in range(60):
        robot = _robot(i)
        box = lim.box(robot, np.full(robot.nq, 0.1), 0.01)
        assert box.ub.shape == (robot.nv,)
        np.testing.assert_array_equal(box.ub, np.minimum(0.5 + i % 3, box.ub))  # this robot's velocity limit
        assert float(box.ub.max()) == pytest.approx(0.5 + i % 3)
        del robot
        gc.collect()
