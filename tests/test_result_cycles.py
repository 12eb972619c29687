"""A step's result is freed when the loop drops it: no reference cycle for the cyclic garbage collector.

A lazy result and its lazy ``info`` share the pending diagnostics (``redundik.resolvers.base._Deferred``) rather
than point at each other: before, every step of a loop that read ``info`` left ~30 objects in cycles (a result,
its info, the closures holding its rows), and the collector's passes over them took ~100 µs every ~30 steps. The
diagnostics stay lazy and exact: read late, through the info alone, or after ``sigma_min``.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers.base import LazyInfo, LazyStepResult, StepResult


def _panda_case(tight: bool) -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray, dict[str, object]]:
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    stack = rk.TaskStack(
        [rk.FrameTask("panda_hand", rk.Circle(radius=0.15, omega=3.0), axes="pose"), rk.PostureTask(q.copy())],
        [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)],
    )
    limits = {"velocity_limits": dict.fromkeys(robot.joint_names, 0.3)} if tight else {}
    return robot, stack, q, limits


@pytest.mark.parametrize("tight", [False, True])
@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
def test_a_loop_that_reads_info_leaves_no_cycles(method: str, tight: bool) -> None:
    robot, stack, q, limits = _panda_case(tight)
    opts = {"limits": limits} if limits and method in ("wqp", "hqp") else {}
    res = rk.make_resolver(method, **opts)
    stack.reset(robot)
    dt, qp = 0.01, 0
    for k in range(20):  # (warm: plans, compiled calls, caches)
        q = robot.integrate(q, res.step(robot, stack, q, k * dt, dt).dq, dt)
    gc.collect()
    gc.set_debug(gc.DEBUG_SAVEALL)
    try:
        for k in range(20, 80):
            step = res.step(robot, stack, q, k * dt, dt)
            qp += int(step.info.get("qp", 0))  # an eager key: the diagnostics stay pending
            q = robot.integrate(q, step.dq, dt)
        del step
        gc.collect()
        ours = [o for o in gc.garbage if isinstance(o, (StepResult, LazyInfo))]
        count = len(gc.garbage)
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
    assert not ours and count < 10, (count, ours[:3])
    if tight and method in ("wqp", "hqp"):
        assert qp > 0  # (the QP path was in the loop)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_lazy_diagnostics_read_through_the_info_alone_or_late(method: str) -> None:
    """The info read after its result is dropped, or after later steps, has the entries an eager read gives; a
    result whose info was read has nothing pending; ``sigma_min`` read first fills the same entries."""
    robot, stack, q, limits = _panda_case(True)
    opts = {"limits": limits} if method != "pinv" else {}
    res, ref = rk.make_resolver(method, **opts), rk.make_resolver(method, **opts)
    stack.reset(robot)
    dt = 0.01
    infos = []
    for k in range(12):
        a = res.step(robot, stack, q, k * dt, dt)
        b = ref.step(robot, stack, q, k * dt, dt)
        np.testing.assert_array_equal(a.dq, b.dq)
        eager = dict(b.info)  # read at once
        if k % 3 == 0:
            infos.append((a.info, eager))  # the info kept, its result dropped below
        elif k % 3 == 1:
            assert a.sigma_min == b.sigma_min and a.damped == b.damped
            assert dict(a.info) == eager
        else:
            assert isinstance(a, LazyStepResult)
            assert dict(a.info) == eager and a.pending is None
        q = robot.integrate(q, b.dq, dt)
        del a
    for info, eager in infos:
        assert dict(info) == eager
