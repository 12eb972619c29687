"""The 3+3 hybrid arm: six-step I-K (5.31)-(5.42) with its errata, the exact I-K, F-K and project 2."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError
from redundik.parallel import Hybrid33Arm, UPRPlatform, run_path, wrist_angles
from redundik.parallel._linalg import rot_x, rot_y

HOME_P, HOME_R = np.array([0.8, 0.4, 2.2]), np.eye(3)
DEST_P, DEST_R = np.array([-1.0, -1.0, 2.0]), np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


@pytest.fixture(scope="module")
def arm() -> Hybrid33Arm:
    return Hybrid33Arm.project2()


@pytest.fixture(scope="module")
def path(arm: Hybrid33Arm):
    return run_path(arm, HOME_P, HOME_R, DEST_P, DEST_R, n=100, dt=0.01, theta6_home=0.0)


def _dh_steps(t4: float, t5: float, t6: float, d4: float, d5: float, d6: float) -> np.ndarray:
    """A_3^4 A_4^5 A_5^6 exactly as printed before (5.39)."""
    c4, s4, c5, s5, c6, s6 = np.cos(t4), np.sin(t4), np.cos(t5), np.sin(t5), np.cos(t6), np.sin(t6)
    A34 = np.array([[c4, 0, -s4, 0], [s4, 0, c4, 0], [0, -1, 0, d4], [0, 0, 0, 1.0]])
    A45 = np.array([[c5, 0, s5, 0], [s5, 0, -c5, 0], [0, 1, 0, d5], [0, 0, 0, 1.0]])
    A56 = np.array([[c6, -s6, 0, 0], [s6, c6, 0, 0], [0, 0, 1, d6], [0, 0, 0, 1.0]])
    return A34 @ A45 @ A56


def test_wrist_matches_the_dh_product(arm: Hybrid33Arm) -> None:
    rng = np.random.default_rng(3)
    for _ in range(5):
        theta = rng.uniform(-np.pi, np.pi, 3)
        R, p = arm.wrist(theta)
        A = _dh_steps(*theta, arm.platform.d4, arm.d5, arm.d6)
        np.testing.assert_allclose(R, A[:3, :3], atol=1e-14)
        np.testing.assert_allclose(p, A[:3, 3], atol=1e-14)


@pytest.mark.parametrize("branch", [1, -1])
def test_wrist_angles_round_trip(arm: Hybrid33Arm, branch: int) -> None:
    rng = np.random.default_rng(4)
    for _ in range(10):
        theta = rng.uniform(-np.pi, np.pi, 3)
        theta[1] = branch * rng.uniform(0.1, 3.0)
        got = wrist_angles(arm.wrist(theta)[0], branch)
        np.testing.assert_allclose(np.angle(np.exp(1j * (got - theta))), 0.0, atol=1e-12)
    with pytest.raises(MechanismError, match="branch must be"):
        wrist_angles(np.eye(3), 0)  # type: ignore[arg-type]


def test_corrected_542_legs_and_the_literal_print(arm: Hybrid33Arm) -> None:
    plat = arm.platform
    top = np.array([0.8, 0.2, 1.8])
    pose = plat.inverse_kinematics(top, method="book")
    R, d4 = pose.R03, plat.d4
    for i in range(3):
        # corrected: the leg joins p_0^i to the revolute joint o3 + R p_3^i and is perpendicular to its axis
        np.testing.assert_allclose(plat.base_points[i] + pose.vectors[i], pose.o3 + R @ plat.top_points[i])
        assert pose.vectors[i] @ (R @ plat.axes[i]) == pytest.approx(0.0, abs=1e-14)
    # the printed (5.42) (own base point replaced by p0a, minus sign on R p3) breaks both properties
    literal = [top - plat.base_points[0] - d4 * R[:, 2] - R @ plat.top_points[i] for i in range(3)]
    assert abs(literal[1] @ (R @ plat.axes[1])) > 0.1
    assert np.linalg.norm(literal[0] - pose.vectors[0]) > 0.5


def test_project_layout_reads_the_rectangle_with_axes_from_the_joints(arm: Hybrid33Arm) -> None:
    # joint a on x3 => its axis is y3; b, c on ±y3 => axes along x3 (tangential); (5.31) needs axis ⟂ p_3^i
    np.testing.assert_allclose(np.abs(arm.platform.axes), [[0, 1, 0], [1, 0, 0], [1, 0, 0]], atol=1e-15)
    with pytest.raises(MechanismError, match="perpendicular"):
        # the book's rectangle table (α = x3) applied literally to the exercise's joints
        UPRPlatform(arm.platform.base_points, arm.platform.top_points, axes=[[1, 0, 0], [0, 1, 0], [0, -1, 0]])


def _equilateral_rows(top: np.ndarray, plat: UPRPlatform, psi: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows 2 and 3 of (5.32) with A, B of the printed equilateral table, as M (sin φ, cos φ) = rhs."""
    eta = top - plat.base_points
    A = np.array([eta[0], -0.5 * eta[1], -0.5 * eta[2]])
    B = np.array([np.zeros(3), np.sqrt(3) / 2 * eta[1], -np.sqrt(3) / 2 * eta[2]])
    rx = np.array([np.cos(psi), 0.0, -np.sin(psi)])  # R(y,ψ)R(x,φ) x3
    ry_s, ry_c = np.array([np.sin(psi), 0.0, np.cos(psi)]), np.array([0.0, 1.0, 0.0])  # R y3 = s·ry_s + c·ry_c
    M = np.column_stack([B[1:] @ ry_s, B[1:] @ ry_c])
    return M, -(A[1:] @ rx)


def test_538_equilateral_uses_b3_gamma(arm: Hybrid33Arm) -> None:
    sym = UPRPlatform.book_layout("equilateral", 1.0, 0.4, d4=0.3)
    # with all base joints at z = 0, b3^β = b3^γ and the misprint is harmless: lift the base joints apart
    lift = np.array([[0, 0, 0.0], [0, 0, 0.2], [0, 0, -0.1]])
    plat = UPRPlatform(sym.base_points + lift, sym.top_points, sym.axes, 0.3)
    top = np.array([0.15, -0.1, 1.5])
    book = plat.book_orientation(top)
    M, rhs = _equilateral_rows(top, plat, book.psi)
    s, c = np.linalg.solve(M, rhs)
    assert book.phi == pytest.approx(np.arctan2(s, c), abs=1e-12)
    # the printed γ11, γ13 (with b3^β) give a different system and a different φ
    eta = top - plat.base_points
    cps, sps = np.cos(book.psi), np.sin(book.psi)
    beta = [
        np.sqrt(3) / 2 * (eta[1, 0] * sps + eta[1, 2] * cps),
        np.sqrt(3) / 2 * eta[1, 1],
        0.5 * (eta[1, 0] * cps - eta[1, 2] * sps),
    ]
    gamma_lit = [
        -np.sqrt(3) / 2 * (eta[2, 0] * sps + eta[1, 2] * cps),
        -np.sqrt(3) / 2 * eta[2, 1],
        0.5 * (eta[2, 0] * cps - eta[1, 2] * sps),
    ]
    s_l, c_l = np.linalg.solve([beta[:2], gamma_lit[:2]], [beta[2], gamma_lit[2]])
    assert np.hypot(s_l - s, c_l - c) > 1e-3


@pytest.mark.parametrize("layout", ["equilateral", "right_isosceles", "rectangle"])
def test_three_layouts_book_vs_exact_orientation(layout: str) -> None:
    plat = UPRPlatform.book_layout(layout, 1.0, 0.4, d4=0.3)
    top = np.array([0.15, -0.1, 1.5])
    book, exact = plat.book_orientation(top), plat.exact_orientation(top)
    assert exact.residual < 1e-12
    np.testing.assert_allclose(exact.R.T @ exact.R, np.eye(3), atol=1e-12)
    assert np.linalg.det(exact.R) == pytest.approx(1.0, abs=1e-12)
    assert book.residual > 1e-3  # the no-spin closed form misses one row of (5.31) here
    np.testing.assert_allclose(book.R, rot_y(book.psi) @ rot_x(book.phi), atol=1e-15)
    # at a centred Top point, by symmetry, the closed form is exact for the right isosceles and rectangle
    if layout != "equilateral":
        assert plat.book_orientation([0.0, 0.0, 1.5]).residual < 1e-12


@pytest.mark.parametrize("layout", ["equilateral", "right_isosceles", "rectangle"])
def test_platform_fk_round_trip(layout: str) -> None:
    plat = UPRPlatform.book_layout(layout, 1.0, 0.4, d4=0.3)
    pose = plat.inverse_kinematics([0.15, -0.1, 1.5])
    sols = plat.forward_kinematics(pose.lengths)
    assert min(np.linalg.norm(s.o3 - pose.o3) + np.linalg.norm(s.R03 - pose.R03) for s in sols) < 1e-9
    for s in sols:
        assert s.residual < 1e-10
        np.testing.assert_allclose(s.R03.T @ s.R03, np.eye(3), atol=1e-12)
        again = plat.legs(s.top, s.R03)
        np.testing.assert_allclose(again.lengths, pose.lengths, atol=1e-10)
        assert again.residual < 1e-10


def test_project2_home_is_over_specified(arm: Hybrid33Arm) -> None:
    book = arm.ik_book(HOME_P, HOME_R, theta6_prev=0.0)
    # (a) the passive orientation is exact for this layout ...
    assert book.orientation_residual < 1e-14
    assert book.R03[1, 0] == pytest.approx(0.0, abs=1e-15)  # R(y,ψ)R(x,φ) has no (2,1) entry
    # ... but step 6 does not return θ6 = 0: the home data are over-specified
    assert abs(book.theta[2]) > 1.0 and abs(book.lag) > 1.0
    exact = arm.ik_exact(HOME_P, HOME_R)
    assert abs(exact.lag) < 1e-12


def test_exact_ik_both_branches_round_trip(arm: Hybrid33Arm) -> None:
    sols = arm.ik_all(HOME_P, HOME_R)
    assert {int(np.sign(s.theta[1])) for s in sols} == {1, -1}
    for s in sols:
        assert abs(s.lag) < 1e-10
        fk = arm.forward_kinematics(s.lengths, s.theta, hint=(s.o3, s.R03))[0]
        np.testing.assert_allclose(fk.p, HOME_P, atol=1e-10)
        np.testing.assert_allclose(fk.R, HOME_R, atol=1e-10)
    down = arm.ik_exact(HOME_P, HOME_R, branch=-1)
    assert down.theta[1] < 0


def test_book_roundtrip_error_is_the_lag_on_the_d5_circle(arm: Hybrid33Arm) -> None:
    book = arm.ik_book(HOME_P, HOME_R, theta6_prev=0.0)
    fk = arm.forward_kinematics(book.lengths, book.theta, hint=(book.o3, book.R03), starts=0)[0]
    assert np.linalg.norm(fk.p - HOME_P) == pytest.approx(2 * arm.d5 * abs(np.sin(book.lag / 2)), abs=1e-10)
    np.testing.assert_allclose(fk.R, HOME_R, atol=1e-10)  # orientation is met; position misses


def test_project2_path(path) -> None:
    assert path.t.shape == (100,) and path.t[-1] == pytest.approx(0.99)
    np.testing.assert_allclose(path.p[0], HOME_P)
    np.testing.assert_allclose(path.p[-1], DEST_P)
    np.testing.assert_allclose(path.R[-1], DEST_R, atol=1e-12)
    assert path.roundtrip_exact.max() < 1e-9 and path.roundtrip_exact_angle.max() < 1e-9
    assert path.roundtrip_book[0] > 0.3  # the θ6(h) = 0 start
    assert path.roundtrip_book[1] > 0.05  # still catching up
    assert 1e-5 < path.roundtrip_book[2:].max() < 0.01  # afterwards one sample of lag
    assert path.roundtrip_book_angle.max() < 1e-9
    np.testing.assert_allclose(path.joints_book[2:], path.joints_exact[2:], atol=0.05)
    assert np.abs(np.diff(path.joints_exact, axis=0)).max() < 0.1  # continuous branch
    summary = path.summary()
    assert summary["roundtrip_position_max_exact"] < 1e-9 < summary["roundtrip_position_max_book"]


def test_bad_inputs(arm: Hybrid33Arm) -> None:
    with pytest.raises(MechanismError, match="non-finite"):
        arm.ik_exact([np.nan, 0.0, 2.0], HOME_R)
    with pytest.raises(MechanismError, match="not a proper rotation"):
        arm.ik_book(HOME_P, 2 * HOME_R, 0.0)
    with pytest.raises(MechanismError, match="admit no assembly"):
        arm.platform.forward_kinematics([0.01, 0.01, 0.01], starts=4)
    with pytest.raises(MechanismError, match="d5 must be"):
        Hybrid33Arm(arm.platform, d5=-1.0, d6=0.4)
    with pytest.raises(MechanismError, match="choose one of"):
        UPRPlatform.book_layout("square", 1.0, 0.5)  # type: ignore[arg-type]
    with pytest.raises(MechanismError, match="along x3"):
        UPRPlatform(arm.platform.base_points, [[0.5, 0.3, 0], [-0.4, 0.4, 0], [-0.3, -0.5, 0]]).book_orientation(
            [0.0, 0.0, 1.5]
        )


def test_random_rotation_round_trip(arm: Hybrid33Arm) -> None:
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    p = np.array([0.4, 0.1, 2.0])
    s = arm.ik_exact(p, R)
    fk = arm.forward_kinematics(s.lengths, s.theta)
    assert min(np.linalg.norm(a.p - p) + np.linalg.norm(a.R - R) for a in fk) < 1e-9
