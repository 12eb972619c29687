"""A copy of a running control loop — ``copy.deepcopy`` or ``pickle`` of (resolver, stack, robot) together, the way a
worker process or a "what if" branch is started — steps exactly as the original from then on, new targets included.

Objects that keep live views of a robot's Pinocchio data (a frame task's pose, a fused plan's Jacobians, a collision
world's placements, a trajectory's parameter row) recognise it by identity; copied together, a view became a frozen
array that passed that test: a copied frame task followed a pose that no longer moved, and a copied hold ignored a new
target on the per-task path. Checked on every run of every shipped task file."""

from __future__ import annotations

import copy
import pickle
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.config.loader import load_task

TASKS = Path(__file__).resolve().parents[1] / "tasks"
DT = 0.01


def _lockstep(original: tuple, clone: tuple, q: np.ndarray, t0: float, steps: int, edit=None) -> None:
    """Step the original and its clone from the same q; each integrates its own q̇, which must be the same."""
    qa, qb = q.copy(), q.copy()
    for k in range(steps):
        t = t0 + k * DT
        out = []
        for (res, stack, robot), qk in ((original, qa), (clone, qb)):
            if edit is not None:
                edit(k, stack, robot)
            out.append(res.step(robot, stack, qk, t, DT))
        a, b = out
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12, err_msg=f"step {k}")
        if k >= 2:  # (the copy plans its compiled step again on its own data: its first step may be per-task)
            assert a.info.get("path") == b.info.get("path"), f"step {k}"
        qa = original[2].integrate(qa, a.dq, DT)
        qb = clone[2].integrate(qb, b.dq, DT)


def _runs() -> list[tuple[Path, str]]:
    out = []
    for path in sorted(TASKS.glob("*.yaml")):
        plan = load_task(path)
        out += [(path, name) for name in plan.runs]
    return out


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize(("path", "run"), _runs(), ids=lambda x: x.stem if isinstance(x, Path) else x)
def test_a_copied_loop_steps_as_the_original(path: Path, run: str, how: str) -> None:
    plan = load_task(path)
    spec = plan.runs[run]
    robot, stack, res = plan.robot.model, spec.stack, spec.resolver
    q = spec.q0.copy()
    stack.reset(robot)
    for k in range(5):
        q = robot.integrate(q, res.step(robot, stack, q, k * DT, DT).dq, DT)
    original = (res, stack, robot)
    clone = copy.deepcopy(original) if how == "deepcopy" else pickle.loads(pickle.dumps(original))
    _lockstep(original, clone, q, 5 * DT, 15)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp", "feedback"])
@pytest.mark.parametrize("fuse", [True, False])
def test_a_copied_teleop_loop_follows_new_targets(method: str, fuse: bool) -> None:
    """A teleoperated hand (``set_target`` every tick) copied mid-run: the copy follows the targets given to it as the
    original follows the same targets, compiled or not (``fuse``)."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    hand = rk.FrameTask("panda_hand_tcp", gain=20.0)
    stack = rk.TaskStack([hand, rk.PostureTask(gain=1.0)])
    stack.reset(robot)
    res = rk.make_resolver(method)
    if hasattr(res, "fuse"):
        res.fuse = fuse
    home = robot.frame_pose("panda_hand_tcp")

    def edit(k: int, stack: rk.TaskStack, robot: rk.RobotModel) -> None:
        offset = np.array([0.0, 0.002 * k, 0.001 * k])
        stack.tasks[0].set_target(pin.SE3(home.rotation, home.translation + offset))

    for k in range(5):
        edit(k, stack, robot)
        q = robot.integrate(q, res.step(robot, stack, q, k * DT, DT).dq, DT)
    original = (res, stack, robot)
    _lockstep(original, copy.deepcopy(original), q, 5 * DT, 40, edit)
    robot.update(q)
