"""The subtask potentials' defining properties (their gradients against finite differences: test_fd_every_class)."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.errors import TaskError
from redundik.kinematics import DHRow, from_dh
from redundik.tasks import (
    BestPosture,
    Clearance,
    JointCentering,
    JointSine2,
    JointValue,
    Manipulability,
    VirtualPoint,
)

from .helpers import random_dh_robot


def test_sin2_gradient_is_the_chapter_sin_2theta() -> None:
    robot = from_dh([DHRow("1", a=1), DHRow("2", a=1), DHRow("3", a=1)])
    q = np.array([0.4, -0.2, np.deg2rad(-30)])
    robot.update(q)
    p = JointSine2("3")
    p.check(robot)
    assert p.value(robot) == pytest.approx(np.sin(q[2]) ** 2)
    np.testing.assert_allclose(p.gradient(robot), [0, 0, np.sin(2 * q[2])])  # η = (0 0 sin 2θ3)ᵀ


def test_joint_centering_default_center_is_mid_range() -> None:
    robot = from_dh([DHRow("1", lower=-1, upper=3), DHRow("2", kind="prismatic", lower=0.2, upper=0.6)])
    robot.update(np.array([1.0, 0.4]))
    p = JointCentering()
    p.check(robot)
    assert p.value(robot) == pytest.approx(0.0)
    robot.update(np.array([2.0, 0.5]))
    assert p.value(robot) == pytest.approx(0.5 * (1.0**2 + 0.1**2))  # ½‖q − q_c‖², (5.9)
    np.testing.assert_allclose(p.gradient(robot), [1.0, 0.1])  # η = q − q_c, (5.10)


def test_best_posture_is_sum_of_eigenvalues_and_torques_are_jt_f() -> None:
    rng = np.random.default_rng(5)
    robot = random_dh_robot(rng)
    robot.update(robot.random_configuration(rng))
    w = np.linspace(0.5, 2.0, 7)
    p = BestPosture("j7", weights=w)
    p.check(robot)
    J = robot.frame_jacobian("j7")
    assert p.value(robot) == pytest.approx(np.sum(np.linalg.eigvalsh(J @ np.diag(w) @ J.T)))
    F = np.array([-1.0, 2.0, 0, 0, 0, 0])
    np.testing.assert_allclose(p.torques(robot, F), J.T @ F)
    # Rayleigh bound: λ_min ≤ FᵀJWJᵀF/FᵀF ≤ λ_max, whose sum is tr(JWJᵀ)
    tau = p.torques(robot, F)
    assert tau @ (w * tau) / (F @ F) <= p.value(robot) + 1e-12


def test_manipulability_is_sqrt_det_and_zero_at_singularity() -> None:
    robot = from_dh([DHRow("1", a=1), DHRow("2", a=1)])
    p = Manipulability("2", axes="planar")
    robot.update(np.array([0.3, 0.0]))  # stretched: singular
    assert p.value(robot) == pytest.approx(0.0, abs=1e-12)
    g = p.gradient(robot)  # one-sided: bending the elbow raises p at rate a1 a2 |cos θ2| = 1
    assert np.all(np.isfinite(g)) and abs(g[1]) == pytest.approx(1.0)
    robot.update(np.array([0.3, 1.0]))
    assert p.value(robot) == pytest.approx(abs(np.sin(1.0)))  # 2R arm: √det(JJᵀ) = a1 a2 |sin θ2|


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: JointValue("j1", float("nan")), "must be finite"),
        (lambda: VirtualPoint("j1", [0, 0]), "expected 3 numbers"),
        (lambda: VirtualPoint("j1", [0, 0, 0], axes=["x", "rz"]), "axes must be among x, y, z"),
        (lambda: Clearance("j1", [0, 0, 0], radius=-1), "radius must be ≥ 0"),
        (lambda: BestPosture("j1", weights=[1, -1, 1, 1, 1, 1, 1]), "weights must be > 0"),
        (lambda: Manipulability("j1", axes="diagonal"), "unknown axes 'diagonal'"),
    ],
)
def test_bad_parameters_raise(make, match) -> None:
    with pytest.raises(TaskError, match=match):
        make()


def test_unknown_frame_or_joint_is_reported_at_check() -> None:
    robot = random_dh_robot(np.random.default_rng(0))
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match="subtask 'sin2_j99': joint 'j99' does not exist"):
        JointSine2("j99").check(robot)
    with pytest.raises(TaskError, match="frame 'elbow' does not exist"):
        VirtualPoint("elbow", [0, 0, 0]).check(robot)
    with pytest.raises(TaskError, match="weights: expected 7 numbers"):
        BestPosture("j7", weights=[1.0] * 6).check(robot)  # the chapter's W has 6 entries for 7 joints
