"""Resolver settings set after construction: validated on assignment, and used from the next step.

Every numeric and on/off option of ``pinv``, ``feedback``, ``wqp`` and ``hqp`` is a ``Setting``
(:mod:`redundik.resolvers.settings`): a bad value is refused with the resolver, the option and what is expected;
a good one drops what the resolver built from the old value, so that the next step is the step of a resolver
constructed with it (before, ``wqp.level_ratio``, ``hqp.epsilon``/``rcond`` and ``hqp.fuse`` set after the first
step were silently ignored, and ``wqp.damping = -1`` or ``hqp.regularization = nan`` were taken as they were).
"""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError

BAD: dict[str, list[tuple[str, object]]] = {
    "pinv": [("epsilon", -1.0), ("max_damping", float("nan")), ("fuse", 1)],
    "feedback": [("epsilon", float("inf")), ("max_damping", -0.1), ("d_epsilon", "1e-3")],
    "wqp": [("damping", -1.0), ("damping", float("nan")), ("lm_damping", float("inf")), ("level_ratio", 5.0),
            ("level_ratio", 0.0), ("epsilon", -1.0), ("max_damping", True), ("fuse", "yes")],
    "hqp": [("regularization", 0.0), ("regularization", float("nan")), ("rcond", 2.0), ("epsilon", float("nan")),
            ("max_damping", float("inf")), ("slack_tolerance", -1e-7), ("level_shortcut", 0), ("identity_levels", None),
            ("complement_min_n", "x"), ("complement_min_n", -1), ("complement_min_n", 2.5),
            ("complement_fraction", -3.0), ("certified_qr", "no"), ("fuse", 1.0)],
}  # fmt: skip


@pytest.mark.parametrize(("method", "option", "value"), [(m, o, v) for m, bad in BAD.items() for o, v in bad])
def test_a_bad_setting_is_refused_on_assignment_and_the_old_value_kept(method: str, option: str, value: object) -> None:
    res = rk.make_resolver(method)
    before = getattr(res, option)
    with pytest.raises(ResolverError, match=rf"{method}: {option} must be"):
        setattr(res, option, value)
    assert getattr(res, option) == before


def _panda() -> tuple[rk.RobotModel, np.ndarray]:
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    return robot, q


def _stack(q: np.ndarray) -> rk.TaskStack:
    return rk.TaskStack(
        [rk.FrameTask("panda_hand", rk.Circle(radius=0.15, omega=3.0), axes="pose"),
         rk.PostureTask(q.copy(), priority=1)],
        [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)],
    )  # fmt: skip


CHANGES = [
    ("wqp", "level_ratio", 1e-2),
    ("wqp", "damping", 1e-3),
    ("wqp", "lm_damping", 0.5),
    ("wqp", "epsilon", 0.3),
    ("hqp", "epsilon", 0.3),
    ("hqp", "max_damping", 0.2),
    ("hqp", "rcond", 1e-3),
    ("hqp", "regularization", 1e-5),
    ("hqp", "fuse", False),
    ("hqp", "level_shortcut", False),
    ("hqp", "certified_qr", False),
    ("pinv", "epsilon", 0.3),
    ("pinv", "fuse", False),
    ("feedback", "d_epsilon", 0.2),
]


@pytest.mark.parametrize(
    ("method", "option", "value", "tight"),
    [(*c, False) for c in CHANGES] + [(*c, True) for c in CHANGES if c[0] in ("wqp", "hqp")],  # (QP: limits)
)
def test_a_setting_assigned_after_steps_is_used_from_the_next_step(
    method: str, option: str, value: object, tight: bool
) -> None:
    """Ten steps, the option assigned, ten more: each of those the step of a resolver constructed (or set up)
    with the value from the start, from the same configuration and time, on a stack set up alike (to 1e-12; the QP
    resolvers under tight velocity limits too)."""
    robot, q0 = _panda()
    opts = {"limits": {"velocity_limits": dict.fromkeys(robot.joint_names, 0.3)}} if tight else {}
    moved, fresh = rk.make_resolver(method, **opts), rk.make_resolver(method, **opts)
    setattr(fresh, option, value)
    stack_m, stack_f = _stack(q0), _stack(q0)
    stack_m.reset(robot)
    stack_f.reset(robot)
    dt, q = 0.01, q0.copy()
    for k in range(10):
        q = robot.integrate(q, moved.step(robot, stack_m, q, k * dt, dt).dq, dt)
    setattr(moved, option, value)
    assert getattr(moved, option) == value
    for k in range(10, 20):
        a = moved.step(robot, stack_m, q, k * dt, dt)
        b = fresh.step(robot, stack_f, q, k * dt, dt)
        scale = max(1.0, float(np.abs(b.dq).max()))
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12 * scale)
        q = robot.integrate(q, b.dq, dt)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("backend", "quadprog"),
        ("limits", {"velocity_limits": {"panda_joint2": 0.2, "panda_joint4": 0.2}}),
        ("limits", False),
        ("levels", {"posture": 0}),
    ],
)
def test_backend_limits_and_levels_assigned_after_steps_are_the_constructors(
    method: str, option: str, value: object
) -> None:
    """``backend``, ``limits`` and ``levels`` take what the constructor takes (a name, a mapping, True/False) and
    are used from the next step: the steps of a resolver constructed with them (before, a mapping or a name was
    stored as given and failed later, and new levels were ignored: the layout was cached)."""
    robot, q0 = _panda()
    moved, fresh = rk.make_resolver(method), rk.make_resolver(method, **{option: value})
    stack_m, stack_f = _stack(q0), _stack(q0)
    for stack in (stack_m, stack_f):
        stack.reset(robot)
    dt, q = 0.01, q0.copy()
    for k in range(10):
        q = robot.integrate(q, moved.step(robot, stack_m, q, k * dt, dt).dq, dt)
    setattr(moved, option, value)
    for k in range(10, 20):
        a = moved.step(robot, stack_m, q, k * dt, dt)
        b = fresh.step(robot, stack_f, q, k * dt, dt)
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12 * max(1.0, float(np.abs(b.dq).max())))
        assert a.info["backend"] == b.info["backend"]
        q = robot.integrate(q, b.dq, dt)


def test_a_bad_backend_limits_or_levels_assignment_says_what_is_wrong() -> None:
    robot, q0 = _panda()
    res = rk.make_resolver("hqp")
    with pytest.raises(rk.SolverError, match="unknown QP backend 'nosuch'"):
        res.backend = "nosuch"
    with pytest.raises(ResolverError, match=r"limits: unknown option\(s\) \['speed'\]"):
        res.limits = {"speed": 1.0}
    with pytest.raises(ResolverError, match="levels: 'posture' must be an integer level"):
        res.levels = {"posture": -1}
    assert res.backend.name == "daqp" and res.levels == {}
    res.levels = {"nosuch": 0}  # (a name is checked against the stack it is used with, at the next step)
    stack = _stack(q0)
    stack.reset(robot)
    with pytest.raises(ResolverError, match=r"levels: 'nosuch': no such task or subtask.*'posture'"):
        res.step(robot, stack, q0, 0.0, 0.01)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize(
    "limits", [{"acceleration": 20.0}, {"velocity": False}, None, True], ids=["accel", "no-velocity", "none", "default"]
)
def test_limits_assigned_between_steps_are_bound_and_used_as_a_fresh_resolvers(
    method: str, fuse: bool, limits: object
) -> None:
    """``resolver.limits = …`` between steps: the next step binds the new limits to the robot (the per-task path
    raised AttributeError on unbound limits) and steps as a fresh resolver made with them."""
    robot = rk.load_example_robot("panda")
    q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    stack = rk.TaskStack([rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, 3.0, plane=("y", "z")), gain=20.0)])
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse
    robot.update(q0)
    stack.reset(robot)
    for k in range(3):
        resolver.step(robot, stack, q0, k * 0.01, 0.01)
    resolver.limits = limits  # type: ignore[assignment]
    got = resolver.step(robot, stack, q0, 0.03, 0.01).dq
    fresh = rk.make_resolver(method, limits=limits)
    fresh.fuse = fuse
    np.testing.assert_allclose(got, fresh.step(robot, stack, q0, 0.03, 0.01).dq, rtol=0, atol=1e-12)
