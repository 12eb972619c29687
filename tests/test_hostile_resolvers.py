"""Hostile arguments to the resolvers from Python: ``Resolver.step`` on q that is not real numbers or with the
wrong kind of robot or stack, ``make_resolver`` with a name that is not a string, batches with bad options, arrays
or frames fixed to the world; each a RedundikError naming what was wrong."""

from __future__ import annotations

import math

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ModelError, ResolverError
from tests.hostile import _planar


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
@pytest.mark.parametrize(
    ("q", "expected"),
    [
        (np.array([True, False, True]), "dtype bool"),
        (np.array([0.3 + 1j, 0.5, -0.4]), "dtype complex"),
        (np.array(["0.3", "0.5", "-0.4"]), "dtype <U"),
        (np.zeros((3, 2)), "shape (3, 2)"),
    ],
)
def test_step_refuses_q_that_is_not_real_numbers(name: str, q: np.ndarray, expected: str) -> None:
    robot, stack, _ = _planar()
    resolver = rk.make_resolver(name)
    with pytest.raises(ResolverError, match="q must be an array of 3 real numbers") as info:
        resolver.step(robot, stack, q, 0.0, 0.01)
    assert expected in str(info.value)
    res = resolver.step(robot, stack, np.array([0.3, 0.5, -0.4]).reshape(3, 1), 0.0, 0.01)  # a column: still q
    assert np.isfinite(res.dq).all()


def _batch(name: str = "pinv", **options: object) -> rk.resolvers.BatchResolver:  # type: ignore[name-defined]
    from redundik.resolvers import BatchResolver

    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1), rk.DHRow("3", a=1)])
    return BatchResolver(rk.make_resolver(name), robot, "3", axes="position", **options)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({"gain": math.nan}, "gain must be a finite number"),
        ({"gain": True}, "gain must be a number"),
        ({"posture_gain": -1.0}, "posture_gain must be a finite number ≥ 0"),
        ({"posture_target": np.array([math.nan, 0.0, 0.0])}, "batch: posture_target"),
    ],
)
def test_batch_refuses_bad_options(options: dict[str, object], expected: str) -> None:
    with pytest.raises((ResolverError, ModelError)) as info:
        _batch(**options)
    assert expected in str(info.value)


def test_batch_refuses_a_frame_fixed_to_the_world() -> None:
    from redundik.resolvers import BatchResolver

    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1)])
    with pytest.raises(ResolverError, match="frame '0' is fixed to the world"):
        BatchResolver(rk.make_resolver("pinv"), robot, "0")


@pytest.mark.parametrize("name", ["pinv", "wqp"])
def test_batch_refuses_bad_arrays_and_accepts_an_empty_batch(name: str) -> None:
    br = _batch(name)
    q = np.zeros((2, 3))
    targets = np.stack([np.eye(4)] * 2)
    targets[:, 0, 3] = 1.5
    cases: list[tuple[object, object, object, str]] = [
        (np.float64(1.0), targets, 0.01, "expected q (N, 3)"),
        (q.astype(bool), targets, 0.01, "q must be an array of real numbers, got dtype bool"),
        (q.astype(complex), targets, 0.01, "dtype complex"),
        (q, targets * 2.0, 0.01, "targets of problems [0, 1] are not rigid transforms"),
        (q, np.where(np.eye(4) > 0, np.nan, targets), 0.01, "targets of problems [0, 1] contain NaN"),
        (q, targets, True, "dt must be a number [s], got bool"),
        (q, targets, "0.01", "dt must be a number [s], got str"),
        (q, targets, 0.0, "dt must be finite and > 0"),
    ]
    for qq, tt, dt, expected in cases:
        with pytest.raises(ResolverError) as info:
            br.solve(qq, tt, dt)  # type: ignore[arg-type]
        assert expected in str(info.value), (expected, str(info.value))
    empty = br.solve(np.zeros((0, 3)), np.zeros((0, 4, 4)), 0.01)
    assert empty.dq.shape == (0, 3)
    assert np.isfinite(br.solve(q, targets, 0.01).dq).all()


def test_make_resolver_with_a_name_that_is_not_a_string() -> None:
    with pytest.raises(ResolverError, match=r"unknown resolver \['pinv'\]; available"):
        rk.make_resolver(["pinv"])  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_step_with_the_wrong_kind_of_robot_or_stack_says_so(name: str) -> None:
    robot, stack, q = _planar()
    resolver = rk.make_resolver(name)
    for bad in (list(stack.tasks), None, stack.tasks[0]):
        with pytest.raises(ResolverError, match=f"{name}: stack must be a TaskStack .*, got {type(bad).__name__}"):
            resolver.step(robot, bad, q, 0.0, 0.01)  # type: ignore[arg-type]
    for bad_robot in (None, robot.model):
        with pytest.raises(ResolverError, match=f"robot must be a RobotModel, got {type(bad_robot).__name__}"):
            resolver.step(bad_robot, stack, q, 0.0, 0.01)  # type: ignore[arg-type]
    assert np.isfinite(resolver.step(robot, stack, q, 0.0, 0.01).dq).all()  # and the loop goes on


class _NonFiniteRowTask(rk.Task):
    """A user's task whose row has one NaN or infinite entry, in J or in v."""

    def __init__(self, where: str, value: float) -> None:
        self._init_task("bad_row", gain=1.0)
        self.where, self.value = where, value

    def __repr__(self) -> str:
        return f"_NonFiniteRowTask({self.where!r})"

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        J = np.array(robot.frame_jacobian("4")[:1])
        e = np.array([0.1])
        v = e.copy()
        if self.where == "J":
            J[0, 2] = self.value
        else:
            v[0] = self.value
        return rk.TaskTerm(self.name, J, v, e, 1.0)


class _NonFiniteGradient(rk.Potential):
    """A user's potential whose gradient has one NaN or infinite entry."""

    name = "bad_gradient"

    def __init__(self, value: float) -> None:
        self.bad = value

    def value(self, robot: rk.RobotModel) -> float:
        return 0.3

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        g = np.ones(robot.nv)
        g[3] = self.bad
        return g


@pytest.mark.parametrize("value", [math.nan, math.inf])
@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize(
    ("method", "where"),
    [
        (method, where)
        for method in ("pinv", "feedback", "wqp", "hqp")
        for where in ("task J", "task v", "gradient", "target")
        if not (method == "pinv" and where == "target")  # (pinv takes no target subtask: it refuses them)
    ],
)
def test_a_non_finite_row_falls_back_and_names_its_member(method: str, fuse: bool, where: str, value: float) -> None:
    """A NaN or infinite entry in a task's J or v, a gradient or a target subtask's gradient: the step falls back
    (a finite q̇) and names the member, and reading its diagnostics raises nothing. A NaN row used to reach the
    SVD of ``pinv``, ``feedback`` and ``wqp`` (numba's LinAlgError out of ``step``), and ``hqp``'s rank test on read."""
    robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    tasks: list[rk.Task] = [rk.FrameTask("7", None, gain=5.0)]
    subtasks: list[rk.Subtask] = []
    if where.startswith("task"):
        tasks.append(_NonFiniteRowTask(where[-1], value))
    elif where == "gradient":
        subtasks.append(rk.GradientSubtask(_NonFiniteGradient(value), gain=1.0))
    else:
        subtasks.append(rk.TargetSubtask(_NonFiniteGradient(value), target=0.5))
    stack = rk.TaskStack(tasks, subtasks)
    stack.reset(robot)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    with np.errstate(invalid="ignore"):  # (the diagnostics' residual of a NaN row is NaN)
        res = resolver.step(robot, stack, q, 0.0, 0.01)
        assert np.isfinite(res.dq).all()
        assert res.fallback is not None and ("bad_row" in res.fallback or "bad_gradient" in res.fallback)
        dict(res.info)
        _ = (res.sigma_min, res.damped, res.task_error, res.terms, res.dq_rank, res.dq_null)
