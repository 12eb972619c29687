"""The joint-speed cap on the compiled path: a compiled ``pinv``, ``wqp`` or ``hqp`` step returns max_i |q̇_i| / c_i
with q̇ (``fused_kernels.cap_ratio``; ``wqp`` reads the caps from its QP record's row ``QP_CAPS``), and
``Resolver.step`` scales q̇ exactly as it does on the interpreted path — same q̇, same ``capped``/``speed_scale``, on
the steps where the cap binds and on those where it does not, and after the cap is changed between steps."""

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


def _run(
    method: str, fuse: bool, steps: int, ratios: list[float] | None = None, change_at: int = -1
) -> list[tuple[np.ndarray, dict[str, object], str]]:
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
        if k == change_at:
            resolver.max_joint_speed = 1.5 * CAP  # type: ignore[attr-defined]
        res = resolver.step(robot, stack, q, k * DT, DT)
        if ratios is not None:
            ratios.append(float(res.__dict__.get("_cap_ratio", -1.0)))
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


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_the_compiled_step_tests_the_cap_itself_and_follows_a_new_cap(method: str) -> None:
    """The ratio the compiled call returns is max_i |q̇_i| / c_i of the q̇ it gives (on the steps the cap leaves as
    they are), and a cap changed between steps is the one tested from the next step: the interpreted path's q̇."""
    ratios: list[float] = []
    compiled = _run(method, True, 120, ratios, change_at=60)
    interpreted = _run(method, False, 120, change_at=60)
    tested = 0
    for k, ((dq_c, info_c, _), (dq_i, _, _)) in enumerate(zip(compiled, interpreted, strict=True)):
        np.testing.assert_allclose(dq_c, dq_i, rtol=1e-9, atol=1e-11, err_msg=f"{method} step {k}")
        if ratios[k] >= 0.0 and not info_c.get("capped"):
            tested += 1
            cap = CAP if k < 60 else 1.5 * CAP
            assert ratios[k] == pytest.approx(float(np.abs(dq_c).max()) / cap, rel=1e-12), f"{method} step {k}"
    assert tested >= 40, f"{method}: the compiled call tested the cap on {tested} of 120 steps"
