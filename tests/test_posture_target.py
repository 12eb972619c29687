"""A posture's target is read-only where a fused step packs it: an edit in place is refused, not missed.

The fused steps of ``pinv``, ``wqp`` and ``hqp`` pack the posture's q_ref when they plan the stack and compare it by
identity afterwards. ``post.target[0] += 0.5`` used to change the array the per-task path reads while the fused step
kept the old value: a silent wrong answer (0.32 rad/s off on the Panda). Now the array is read-only, and a new target
(assigned, or through ``set_target``) is a new array, which the fused step sees.
"""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.resolvers.registry import make_resolver

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def _stack(post: rk.PostureTask, qp: bool) -> rk.TaskStack:
    if qp:
        post.priority = 1  # type: ignore[attr-defined]
    return rk.TaskStack([rk.FrameTask("panda_hand", rk.Hold(), axes="position", priority=0), post], [])


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_an_in_place_edit_of_the_target_is_refused(method: str) -> None:
    robot = rk.load_example_robot("panda")
    post = rk.PostureTask(Q0.copy())
    stack = _stack(post, method != "pinv")
    res = make_resolver(method)
    res.step(robot, stack, Q0, 0.0, 0.01)
    target = post.target
    assert target is not None and not target.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        target[0] += 0.5


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("how", ["assign", "set_target"])
def test_a_new_target_reaches_the_fused_step(method: str, how: str) -> None:
    """Set between steps, the new target gives the q̇ of a resolver that starts with it."""
    robot = rk.load_example_robot("panda")
    post = rk.PostureTask(Q0.copy())
    stack = _stack(post, method != "pinv")
    res = make_resolver(method)
    for k in range(3):
        res.step(robot, stack, Q0, k * 0.01, 0.01)
    new = Q0.copy()
    new[0] += 0.5
    if how == "assign":
        post.target = new
    else:
        post.set_target(new)
    got = res.step(robot, stack, Q0, 0.03, 0.01)
    fresh_post = rk.PostureTask(new)
    fresh = make_resolver(method).step(robot, _stack(fresh_post, method != "pinv"), Q0, 0.03, 0.01)
    np.testing.assert_allclose(got.dq, fresh.dq, rtol=0, atol=1e-12)
    assert np.abs(got.dq[0]) > 1e-3  # the new target moves the joint (the test could fail)


def test_the_callers_array_stays_writeable_and_a_bad_target_is_refused() -> None:
    given = Q0.copy()
    post = rk.PostureTask(given)
    given[0] = 1.0  # the caller's array is its own: not made read-only, and not the task's
    assert given.flags.writeable and post.target is not None and post.target[0] == 0.0
    with pytest.raises(TaskError, match="NaN or infinite"):
        post.target = np.full(9, np.nan)
