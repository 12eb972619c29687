"""Target subtasks on the compiled step (issue 31, items 1 and 3): under ``wqp`` and ``hqp`` a target subtask's one
row ηᵀq̇ = ṗ_d + K (p_d − p) is written into the step's rows from Python — by its potential's compiled writer when it
has one — instead of sending the whole stack down the per-task path. Its answer is the per-task path's (1e-12, the
lockstep of ``tests/test_fused.py``), its data (target, rate, weight, the potential's own) are read every step, and a
potential without a compiled form runs mixed, named."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.frame import PostureTask
from redundik.tasks.potentials import JointSine2, JointValue
from redundik.tasks.stack import TaskStack
from redundik.tasks.subtasks import TargetSubtask
from redundik.tasks.trajectory import Circle

from .test_fused import _chapter_potentials, _compare, _hand, _q0

#: p_d per chapter potential of ``_chapter_potentials`` (sin²θ, (q − c)², a virtual point, a clearance)
TARGETS = (0.5, 0.0, 0.0, 0.2)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize("which", range(4))
def test_a_target_subtask_runs_compiled(method: str, which: int) -> None:
    """Hand circle + posture + a target subtask on each chapter potential: every step compiled, q̇ and the terms the
    per-task path's; a new target, rate and weight, and the potential's data moved, at step 20 (no new plan)."""

    def stack(robot: RobotModel) -> TaskStack:
        sub = TargetSubtask(_chapter_potentials()[which], TARGETS[which], rate=2.0)
        return TaskStack([_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)], [sub])

    def edit(k: int, robot: RobotModel, stack: TaskStack) -> None:
        sub = stack.subtasks[0]
        if k == 20:
            sub.set_target(0.8 * TARGETS[which] + 0.01, target_rate=0.05)
            sub.rate, sub.weight = 4.0, 3.0
            pot = sub.potential
            if hasattr(pot, "c"):
                pot.c = -0.2
            if hasattr(pot, "center"):
                pot.center = [0.45, 0.2, 0.5]

    paths: list[str] = []
    took = _compare(stack, method, steps=40, edit=edit, paths=paths)
    assert sum(took) >= 36
    assert set(paths[2:]) == {"compiled"}


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_target_subtasks_at_two_levels_and_a_binding_limit(method: str) -> None:
    """Two target subtasks at levels 1 and 2 (hqp: their rows placed after their level's tasks; wqp: weighted
    ρ^k), one pulling a joint fast enough that its velocity limit binds: the QP steps agree too."""

    def stack(robot: RobotModel) -> TaskStack:
        subs = [
            TargetSubtask(JointValue("panda_joint2", 0.4, name="pull"), 0.0, rate=8.0, priority=1),
            TargetSubtask(JointSine2("panda_joint4", name="sine"), 0.6, rate=1.0, weight=2.0, priority=2),
        ]
        return TaskStack([_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)], subs)

    qp: list[int] = []
    paths: list[str] = []
    took = _compare(stack, method, steps=60, qp_steps=qp, paths=paths)
    assert sum(took) >= 52
    assert set(paths[2:]) == {"compiled"}
    assert qp, "the velocity limit never bound: the constrained steps were not compared"


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_target_on_a_potential_without_a_compiled_form_runs_mixed(method: str) -> None:
    """A user's potential with only ``value`` and ``gradient``: its row from ``TargetSubtask.row``, the rest compiled
    (``path == "mixed"``, the subtask named), the per-task path's answer."""

    class Height(rk.Potential):
        name = "link4_height"  # (not test_mixed_plan's "height": each mixed warning is given once per process)

        def value(self, robot: RobotModel) -> float:
            return float(robot.frame_position("panda_link4")[2])

        def gradient(self, robot: RobotModel) -> np.ndarray:
            return np.array(robot.frame_jacobian("panda_link4")[2])

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack(
            [_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)], [TargetSubtask(Height(), 0.5)]
        )

    paths: list[str] = []
    took = _compare(stack, method, steps=30, paths=paths)
    assert sum(took) >= 24
    assert set(paths[2:]) == {"mixed"}
    robot = rk.load_example_robot("panda")
    q = _q0(robot)
    robot.update(q)
    s = stack(robot)
    s.reset(robot)
    resolver = rk.make_resolver(method)
    for _ in range(2):
        res = resolver.step(robot, s, q, 0.0, 0.01)
    assert res.info["path"] == "mixed" and res.info["interpreted"] == ("link4_height",)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp", "feedback"])
def test_a_gradient_of_the_wrong_size_is_named(method: str) -> None:
    """A user's potential whose gradient is not one entry per velocity coordinate: a TaskError naming the subtask,
    the potential and both sizes (it used to be numpy's broadcast error), on the compiled and per-task paths."""

    class Short(rk.Potential):
        name = "short"

        def value(self, robot: RobotModel) -> float:
            return float(robot.q[3])

        def gradient(self, robot: RobotModel) -> np.ndarray:
            return np.ones(3)

    robot = rk.load_example_robot("panda")
    robot.update(_q0(robot))
    sub = rk.GradientSubtask(Short()) if method == "pinv" else TargetSubtask(Short(), 0.0)
    for fuse in (True, False):
        stack = TaskStack([_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)], [sub])
        stack.reset(robot)
        res = rk.make_resolver(method)
        if hasattr(res, "fuse"):
            res.fuse = fuse
        with pytest.raises(TaskError, match=r"subtask 'short'.*potential 'short'.*shape \(3,\), expected \(9,\)"):
            res.step(robot, stack, robot.q.copy(), 0.0, 0.01)


@pytest.mark.parametrize(
    ("method", "options", "why"),
    [
        ("wqp", {"limits": {"acceleration": 20.0, "jerk": 5000.0}}, "jerk limit"),
        ("hqp", {"limits": {"acceleration": 20.0, "jerk": 5000.0}}, "jerk limit"),
        ("wqp", {"lm_damping": 0.1}, "lm_damping"),
        ("hqp", {"scaling": "direction"}, "scaling='direction'"),
    ],
)
def test_options_without_a_compiled_step_name_every_member(
    method: str, options: dict[str, object], why: str, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A resolver option that has no compiled step (a jerk limit, ``lm_damping``, direction scaling): every step is
    interpreted, ``info["interpreted"]`` names every member (not an empty tuple), and a one-time warning says why."""
    from redundik.resolvers import base

    monkeypatch.setattr(base, "_WARNED_INTERPRETED", set())  # (one warning per process: earlier tests may have had it)
    robot = rk.load_example_robot("panda")
    q = _q0(robot)
    robot.update(q)
    stack = TaskStack(
        [_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)],
        [TargetSubtask(JointSine2("panda_joint4", name="sine"), 0.5)],
    )
    stack.reset(robot)
    resolver = rk.make_resolver(method, **options)
    with caplog.at_level("WARNING", logger="redundik"):
        for k in range(3):
            res = resolver.step(robot, stack, q, k * 0.01, 0.01)
            q = robot.integrate(q, res.dq, 0.01)
    assert res.info["path"] == "interpreted"
    assert set(res.info["interpreted"]) == {stack.tasks[0].name, stack.tasks[1].name, "sine"}
    assert any(why in r.getMessage() and "every step runs interpreted" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("method", ["wqp", "hqp"])
@pytest.mark.parametrize("fuse", [True, False])
def test_a_nan_target_row_degrades_and_is_named(method: str, fuse: bool) -> None:
    """A user's potential whose value and gradient turn NaN: the step does not raise (hqp's compiled cascade raised
    numpy's LinAlgError), q̇ is finite and within the limits, and the fallback names the subtask."""

    class Broken(rk.Potential):
        name = "broken"

        def value(self, robot: RobotModel) -> float:
            return float("nan")

        def gradient(self, robot: RobotModel) -> np.ndarray:
            return np.full(robot.nv, np.nan)

    robot = rk.load_example_robot("panda")
    q = _q0(robot)
    robot.update(q)
    stack = TaskStack(
        [_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)], [TargetSubtask(Broken(), 0.0)]
    )
    stack.reset(robot)
    resolver = rk.make_resolver(method)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    for k in range(3):
        res = resolver.step(robot, stack, q, k * 0.01, 0.01)
        assert np.isfinite(res.dq).all()
        assert res.fallback is not None and "subtask 'broken'" in res.fallback
