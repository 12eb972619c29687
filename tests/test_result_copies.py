"""A step's result pickles and copies as the plain record it reads as (``LazyStepResult.__reduce__``): every
resolver's result, compiled or interpreted, gives back the same q̇, terms and diagnostics — without the step's plan,
buffers or robot, which a lazy result holds to compute them on request (``hqp``'s held closures that do not pickle:
``pickle.dumps`` raised)."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.kinematics.urdf import load_example_robot
from redundik.resolvers.result import StepResult


def _last_result(method: str, fuse: bool) -> StepResult:
    robot = load_example_robot("panda")
    q = pin.neutral(robot.model)
    q[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
    robot.update(q)
    circle = rk.FrameTask("panda_hand", rk.Circle(0.12, 2.0 * np.pi, plane=("y", "z")), gain=50.0)
    posture = rk.PostureTask(gain=1.0, weight=1e-2, priority=2 if method == "hqp" else 1)
    stack = rk.TaskStack([circle] if method in ("pinv", "feedback") else [circle, posture])
    stack.reset(robot)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    for k in range(25):
        res = resolver.step(robot, stack, q, 0.01 * k, 0.01)
        q = robot.integrate(q, res.dq, 0.01)
    return res


@pytest.mark.parametrize("fuse", [True, False], ids=["compiled", "interpreted"])
@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
def test_a_result_pickles_and_copies_as_what_it_reads(method: str, fuse: bool) -> None:
    res = _last_result(method, fuse)
    blob = pickle.dumps(res)
    assert len(blob) < 20_000, f"{len(blob)} bytes: the step's plan or robot went with the result"
    for other in (pickle.loads(blob), copy.deepcopy(res)):
        assert isinstance(other, StepResult)
        np.testing.assert_array_equal(other.dq, res.dq)
        assert dict(other.info) == dict(res.info)
        assert other.sigma_min == res.sigma_min and other.damped == res.damped and other.damping == res.damping
        assert other.fallback == res.fallback and other.relaxed == res.relaxed and other.main == res.main
        assert [t.name for t in other.terms] == [t.name for t in res.terms]
        for a, b in zip(other.terms, res.terms, strict=True):
            np.testing.assert_array_equal(a.J, b.J)
            np.testing.assert_array_equal(a.v, b.v)
            np.testing.assert_array_equal(a.error, b.error)
        assert other.task_error == pytest.approx(res.task_error, rel=1e-12, abs=1e-15)
