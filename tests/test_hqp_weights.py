"""``hqp`` counts a level's weights relative to each other only: scaling every row of a level leaves its optimum, and
so the step, unchanged — the damping rule's ε, λ_max and the regulariser are relative to the level's largest weight
(``Level.scale``). Before, a main task of weight 1e-4 alone at the top level was damped away (0.17 m off a 10 cm
circle on the Panda, every step "damped")."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from tests.helpers import random_dh_robot

SCALES = (1e-6, 1e-4, 1e-2, 1e2, 1e6)


def _tip(robot: rk.RobotModel) -> str:
    return robot.joint_names[-1]


def _stack(robot: rk.RobotModel, c: float, posture_level: bool) -> rk.TaskStack:
    """Tip position (level 0, weight c) with the tip orientation (level 0, weight 0.5 c: relative weights), a bound
    on a joint (level 1) and a posture (level 2, weight c) or the centering gradient in the null space."""
    names = robot.joint_names
    tasks: list[rk.Task] = [
        rk.FrameTask(_tip(robot), rk.Line([0.3, -0.2, 0.1]), axes="position", gain=2.0, weight=c),
        rk.FrameTask(_tip(robot), rk.Hold(), axes="orientation", gain=1.0, weight=0.5 * c, name="ori"),
    ]
    subs: list[rk.Subtask] = [
        rk.BoundSubtask(rk.JointValue(names[2], 0.0, name="b3"), upper=0.4, rate=10.0, priority=1),
    ]
    if posture_level:
        tasks.append(rk.PostureTask(gain=1.0, weight=c, priority=2))
    else:
        subs.append(rk.GradientSubtask(rk.JointCentering(), gain=-1.0))
    return rk.TaskStack(tasks, subs)


def _steps(robot: rk.RobotModel, stack: rk.TaskStack, q0: np.ndarray, fuse: bool, limits: object) -> np.ndarray:
    res = rk.HierarchicalQPResolver(limits=limits)  # type: ignore[arg-type]
    res.fuse = fuse
    robot.update(q0)
    stack.reset(robot)
    q, out = q0.copy(), []
    for k in range(4):
        r = res.step(robot, stack, q, 0.01 * k, 0.01)
        out.append(r.dq)
        q = robot.integrate(q, r.dq, 0.01)
    return np.array(out)


@pytest.mark.parametrize("posture_level", [False, True])
@pytest.mark.parametrize("tight", [False, True])
def test_scaling_every_weight_of_a_level_leaves_the_step_unchanged(posture_level: bool, tight: bool) -> None:
    rng = np.random.default_rng(5)
    qp_steps = 0
    for trial in range(3):
        robot = random_dh_robot(rng, 7, with_prismatic=False)
        q0 = robot.random_configuration(np.random.default_rng(trial))
        limits = rk.JointLimits(velocity_limits=dict.fromkeys(robot.joint_names, 0.2)) if tight else None
        for fuse in (True, False):
            ref = _steps(robot, _stack(robot, 1.0, posture_level), q0, fuse, limits)
            for c in SCALES:
                got = _steps(robot, _stack(robot, c, posture_level), q0, fuse, limits)
                np.testing.assert_allclose(got, ref, rtol=0, atol=1e-8 * max(1.0, float(np.abs(ref).max())))
        if tight:
            res = rk.HierarchicalQPResolver(limits=limits)  # type: ignore[arg-type]
            stack = _stack(robot, 1e-4, posture_level)
            robot.update(q0)
            stack.reset(robot)
            qp_steps += int(res.step(robot, stack, q0, 0.0, 0.01).info["qp"] > 0)
    if tight:
        assert qp_steps  # the constrained cascade was exercised, not only the closed form


def test_a_small_weight_top_task_tracks_on_the_panda() -> None:
    """The README's loop with the frame task at weight 1e-4: tracked as at weight 1, nothing damped."""
    robot = rk.load_example_robot("panda")
    q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    errs = {}
    for w in (1.0, 1e-4):
        task = rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, np.pi, plane=("y", "z")), gain=50.0, weight=w)
        stack = rk.TaskStack([task], [rk.GradientSubtask(rk.JointCentering(), gain=-2.0)])
        res, dt, q = rk.make_resolver("hqp"), 1e-3, q0.copy()
        robot.update(q)
        stack.reset(robot)
        worst, damped = 0.0, 0
        for tick in range(300):
            r = res.step(robot, stack, q, tick * dt, dt)
            q = robot.integrate(q, r.dq, dt)
            damped += bool(r.damped)
            if tick >= 100:
                worst = max(worst, r.task_error)
        errs[w] = worst
        assert damped == 0
    assert errs[1e-4] < 1e-4
    assert abs(errs[1e-4] - errs[1.0]) < 1e-9
