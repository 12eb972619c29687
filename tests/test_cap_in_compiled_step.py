"""The joint-speed cap on the compiled path: a compiled ``pinv`` or ``hqp`` step returns max_i |q̇_i| / c_i with q̇
(``fused_kernels.cap_ratio``), ``wqp``'s is tested after its step (``SpeedLimiter.binds``), and ``Resolver.step`` scales
q̇ exactly as it does on the interpreted path — same q̇, same ``capped``/``speed_scale``, on the steps where the cap
binds and on those where it does not."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.kinematics.model import RobotModel
from redundik.kinematics.urdf import load_example_robot
from redundik.resolvers.singularity import NO_CAPS

DT = 0.01
CAP = 1.9  # [rad/s]: the circle below asks 1.1–2.5 rad/s of its fastest joint: the cap binds on some steps only


def _stack(robot: RobotModel, method: str) -> rk.TaskStack:
    circle = rk.FrameTask("panda_hand", rk.Circle(0.12, 2.0 * np.pi, plane=("y", "z")), gain=50.0)
    q0 = pin.neutral(robot.model)
    if method == "pinv":
        return rk.TaskStack([circle], [rk.GradientSubtask(rk.JointCentering(center=q0), gain=-1.0)])
    return rk.TaskStack([circle, rk.PostureTask(gain=1.0, weight=1e-2, priority=2 if method == "hqp" else 1)])


def _run(method: str, fuse: bool, steps: int) -> list[tuple[np.ndarray, dict[str, object], str]]:
    robot = load_example_robot("panda")
    q = pin.neutral(robot.model)
    q[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
    robot.update(q)
    stack = _stack(robot, method)
    stack.reset(robot)
    resolver = rk.make_resolver(method, max_joint_speed=CAP)
    resolver.fuse = fuse  # type: ignore[attr-defined]
    rows = []
    for k in range(steps):
        res = resolver.step(robot, stack, q, k * DT, DT)
        rows.append((res.dq.copy(), dict(res.info), str(res.info["path"])))
        q = robot.integrate(q, res.dq, DT)
    return rows


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_the_compiled_cap_test_scales_as_the_interpreted_one(method: str) -> None:
    compiled, interpreted = _run(method, True, 150), _run(method, False, 150)
    capped = 0
    for k, ((dq_c, info_c, path_c), (dq_i, info_i, _)) in enumerate(zip(compiled, interpreted, strict=True)):
        assert path_c == "compiled", f"{method} step {k}: {path_c}"
        np.testing.assert_allclose(dq_c, dq_i, rtol=1e-9, atol=1e-11, err_msg=f"{method} step {k}")
        assert info_c.get("capped") == info_i.get("capped"), f"{method} step {k}"
        if info_i.get("capped"):
            capped += 1
            assert info_c["speed_scale"] == pytest.approx(info_i["speed_scale"], rel=1e-9)
        assert np.abs(dq_c).max() <= CAP * (1 + 1e-9), f"{method} step {k}: |q̇| over the cap"
    assert 10 <= capped <= 140, f"{method}: the cap bound on {capped} of 150 steps: the case does not probe both sides"


def test_folded_caps_only_without_a_guard_and_for_the_robot_built() -> None:
    robot, other = load_example_robot("panda"), load_example_robot("panda")
    resolver = rk.make_resolver("pinv", max_joint_speed=CAP)
    speed = resolver._limiter
    assert speed is not None
    assert speed.folded_caps(robot) is NO_CAPS  # (caps not built yet: the step's own test builds them)
    speed.caps(robot)
    np.testing.assert_allclose(speed.folded_caps(robot), 1.0 / CAP)
    assert speed.folded_caps(other) is NO_CAPS
    guarded = rk.make_resolver("pinv", max_joint_speed=CAP, singularity=True)
    assert guarded._limiter is not None
    guarded._limiter.caps(robot)
    assert guarded._limiter.folded_caps(robot) is NO_CAPS
