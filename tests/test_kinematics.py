"""Kinematics on Pinocchio: D-H construction, forward kinematics, Jacobians and their derivatives."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from redundik.errors import ModelError
from redundik.kinematics import DHRow, dh_matrix, from_dh, load_example_robot

from .helpers import fd_gradient, planar3r, random_dh_robot, random_dh_table


def test_3r_tip_matches_chapter() -> None:
    robot = planar3r()
    robot.update(np.deg2rad([110.0, -40.0, -30.0]))
    tip = robot.frame_position("3")
    # the chapter prints p_0^3(t=0) = (0.7660, 2.5222)
    assert tip[:2] == pytest.approx([0.7660, 2.5222], abs=5e-5)
    assert tip[2] == pytest.approx(0.0, abs=1e-15)


def test_3r_jacobian_matches_chapter_closed_form() -> None:
    robot = planar3r((1.0, 0.7, 0.4))
    q = np.array([0.3, -1.1, 0.8])
    robot.update(q)
    a1, a2, a3 = 1.0, 0.7, 0.4
    s1, s12, s123 = np.sin(q[0]), np.sin(q[0] + q[1]), np.sin(q.sum())
    c1, c12, c123 = np.cos(q[0]), np.cos(q[0] + q[1]), np.cos(q.sum())
    J_book = np.array(
        [
            [-a1 * s1 - a2 * s12 - a3 * s123, -a2 * s12 - a3 * s123, -a3 * s123],
            [a1 * c1 + a2 * c12 + a3 * c123, a2 * c12 + a3 * c123, a3 * c123],
        ]
    )
    np.testing.assert_allclose(robot.frame_jacobian("3")[:2], J_book, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_dh_fk_equals_product_of_a_matrices(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows, base = random_dh_table(rng)
    robot = from_dh(rows, base=base)
    q = robot.random_configuration(rng)
    robot.update(q)
    T = base
    for i, row in enumerate(rows):
        theta_i = row.theta + (q[i] if row.kind == "revolute" else 0.0)
        d_i = row.d + (q[i] if row.kind == "prismatic" else 0.0)
        T = T @ dh_matrix(theta_i, d_i, row.a, row.alpha)  # A_0^i = A_0^{i-1} A_{i-1}^i
        np.testing.assert_allclose(robot.frame_pose(row.name).homogeneous, T, atol=1e-12)


def test_dh_matrix_is_rz_tz_tx_rx() -> None:
    theta, d, a, alpha = 0.3, 0.2, 0.5, -0.7
    rz = pin.SE3(pin.rpy.rpyToMatrix(0, 0, theta), np.zeros(3)).homogeneous
    tz = pin.SE3(np.eye(3), np.array([0, 0, d])).homogeneous
    tx = pin.SE3(np.eye(3), np.array([a, 0, 0])).homogeneous
    rx = pin.SE3(pin.rpy.rpyToMatrix(alpha, 0, 0), np.zeros(3)).homogeneous
    np.testing.assert_allclose(dh_matrix(theta, d, a, alpha), rz @ tz @ tx @ rx, atol=1e-15)


@pytest.mark.parametrize("seed", range(4))
def test_frame_jacobian_matches_finite_differences(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    robot = random_dh_robot(rng)
    q = robot.random_configuration(rng)
    robot.update(q)
    J = robot.frame_jacobian(f"j{robot.nv}").copy()
    h = 1e-6
    for k in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[k] = h
        robot.update(q + dq)
        Mp = robot.frame_pose(f"j{robot.nv}").copy()
        robot.update(q - dq)
        Mm = robot.frame_pose(f"j{robot.nv}").copy()
        v = (Mp.translation - Mm.translation) / (2 * h)
        w = pin.log3(Mp.rotation @ Mm.rotation.T) / (2 * h)  # world angular velocity
        np.testing.assert_allclose(J[:3, k], v, atol=1e-6)
        np.testing.assert_allclose(J[3:, k], w, atol=1e-6)


@pytest.mark.parametrize("seed", range(3))
def test_jacobian_derivatives_match_finite_differences(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    robot = random_dh_robot(rng)
    frame = f"j{robot.nv - 1}"
    q = robot.random_configuration(rng)
    robot.update(q)
    H = robot.frame_jacobian_derivatives(frame)
    h = 1e-6
    for k in range(robot.nv):
        e = np.zeros(robot.nv)
        e[k] = h
        robot.update(q + e)
        Jp = robot.frame_jacobian(frame).copy()
        robot.update(q - e)
        Jm = robot.frame_jacobian(frame).copy()
        np.testing.assert_allclose(H[:, :, k], (Jp - Jm) / (2 * h), atol=1e-6)


def test_tree_with_coupled_branch_expresses_theta3r_equals_theta3l_plus_beta() -> None:
    beta = np.deg2rad(25.0)
    rows = [
        DHRow("t1", alpha=np.pi / 2, d=0.5),
        DHRow("t2", a=0.3),
        DHRow("3l", a=0.4, alpha=np.pi / 2),
        DHRow("4l", a=0.3),
        DHRow("3r", a=0.4, alpha=np.pi / 2, theta=beta, parent="t2", joint="3l"),
        DHRow("4r", a=0.3),
    ]
    robot = from_dh(rows, name="tree")
    assert robot.nv == 5  # t1, t2, 3l (shared by 3r), 4l, 4r
    rng = np.random.default_rng(7)
    q = robot.random_configuration(rng)
    robot.update(q)
    T2 = dh_matrix(q[0], 0.5, 0, np.pi / 2) @ dh_matrix(q[1], 0, 0.3, 0)
    np.testing.assert_allclose(robot.frame_pose("3l").homogeneous, T2 @ dh_matrix(q[2], 0, 0.4, np.pi / 2), atol=1e-12)
    np.testing.assert_allclose(
        robot.frame_pose("3r").homogeneous, T2 @ dh_matrix(q[2] + beta, 0, 0.4, np.pi / 2), atol=1e-12
    )
    T4r = T2 @ dh_matrix(q[2] + beta, 0, 0.4, np.pi / 2) @ dh_matrix(q[4], 0, 0.3, 0)
    np.testing.assert_allclose(robot.frame_pose("4r").homogeneous, T4r, atol=1e-12)


def test_base_transform_places_frame_zero() -> None:
    A_b0 = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 7], [0, 0, 0, 1]], dtype=float)  # (5.13)
    robot = from_dh([DHRow("1", kind="prismatic", alpha=np.pi / 2, a=0.5)], base=A_b0)
    robot.update(np.array([0.3]))
    np.testing.assert_allclose(robot.frame_pose("0").homogeneous, A_b0, atol=1e-15)
    np.testing.assert_allclose(robot.frame_pose("1").homogeneous, A_b0 @ dh_matrix(0, 0.3, 0.5, np.pi / 2), atol=1e-12)


def test_integrate_is_first_order_update_and_limits_are_reported() -> None:
    robot = from_dh([DHRow("1", lower=-1, upper=1), DHRow("2", kind="prismatic", lower=0, upper=0.5)])
    q = np.array([0.2, 0.1])
    np.testing.assert_allclose(robot.integrate(q, np.array([1.0, -2.0]), 0.01), [0.21, 0.08])
    np.testing.assert_allclose(robot.lower_limits, [-1, 0])
    np.testing.assert_allclose(robot.limit_violation(np.array([1.5, -0.1])), [0.5, 0.1])
    rng = np.random.default_rng(0)
    for _ in range(20):
        qr = robot.random_configuration(rng)
        assert np.all(robot.limit_violation(qr) == 0)


@pytest.mark.parametrize(
    ("rows", "kwargs", "match"),
    [
        ([DHRow("1"), DHRow("1")], {}, "duplicate frame name"),
        ([DHRow("1", kind="spherical")], {}, "kind must be revolute, prismatic or fixed"),
        ([DHRow("1", a=float("nan"))], {}, "must be finite"),
        ([DHRow("1", lower=1, upper=-1)], {}, "lower ≤ upper"),
        ([DHRow("1", parent="nowhere")], {}, "parent frame 'nowhere'"),
        ([DHRow("1"), DHRow("2", joint="zz")], {}, "coupled joint 'zz'"),
        ([DHRow("1")], {"base": np.diag([1.0, 1.0, -1.0, 1.0])}, "proper rotation"),
        ([], {}, "no rows"),
    ],
)
def test_bad_dh_tables_raise_clear_errors(rows, kwargs, match) -> None:
    with pytest.raises(ModelError, match=match):
        from_dh(rows, **kwargs)


def test_unknown_frame_and_joint_list_the_choices() -> None:
    robot = planar3r()
    with pytest.raises(ModelError, match=r"frame 'tipp' does not exist.*available: 0, 1, 2, 3"):
        robot.frame_id("tipp")
    with pytest.raises(ModelError, match=r"joint 'j9' does not exist.*\['1', '2', '3'\]"):
        robot.joint("j9")
    with pytest.raises(ModelError, match="expected 3 values"):
        robot.check_configuration([0.0, 1.0])
    with pytest.raises(ModelError, match="NaN"):
        robot.check_configuration([0.0, np.nan, 1.0])


def test_panda_loads_offline_with_limits_and_fd_jacobian() -> None:
    robot = load_example_robot("panda")
    assert robot.nv == 9 and "panda_hand" in robot.frame_names
    assert np.all(np.isfinite(robot.lower_limits[:7]))
    rng = np.random.default_rng(1)
    q = robot.random_configuration(rng)
    robot.update(q)
    J = robot.frame_jacobian("panda_hand")[:3].copy()

    def pos(qq: np.ndarray, k: int) -> float:
        robot.update(qq)
        return float(robot.frame_position("panda_hand")[k])

    for k in range(3):
        np.testing.assert_allclose(J[k], fd_gradient(lambda qq, k=k: pos(qq, k), q), atol=1e-6)


def test_unknown_example_robot_lists_known_ones() -> None:
    with pytest.raises(ModelError, match=r"unknown example robot .iiwa.; known: .*panda"):
        load_example_robot("iiwa")


def test_joint_kinds_are_recognised_for_dh_and_urdf_joints() -> None:
    robot = from_dh([DHRow("1"), DHRow("2", kind="prismatic"), DHRow("3", kind="fixed")])
    assert [j.kind for j in robot.joints] == ["revolute", "prismatic"]
    panda = load_example_robot("panda")
    assert [j.kind for j in panda.joints] == ["revolute"] * 7 + ["prismatic"] * 2
