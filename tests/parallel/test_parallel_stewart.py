"""Stewart platform: the chapter's printed numbers (section 5.4.2) and kinematic invariants."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError
from redundik.parallel import StewartPlatform, book_66_pose, fk_update, follow_leg_profile, ik_update
from redundik.parallel._linalg import rot_x, rot_z, skew

# Printed values are rounded to 4 decimals: agree within half of the last printed digit (+ float slack).
ATOL4 = 0.5e-4 + 1e-9

Q_PRINT = [1.0503, 1.4286, 1.5378, 1.3567, 0.8561, 1.1282]
J0_PRINT = [
    [-0.4938, 0.4645, 0.1164, 0.0679, 0.3968, -0.6698],
    [-0.0374, -0.4526, -0.4922, 0.4015, 0.2292, -0.4416],
    [0.8688, 0.7612, 0.8626, 0.9133, 0.8888, 0.5969],
    [0.4062, 0.5820, 0.4123, -0.1908, -0.6233, -0.5076],
    [-0.5132, -0.2280, 0.6156, 0.7070, -0.1207, -0.0220],
    [0.2088, -0.4907, 0.2957, -0.2966, 0.3094, -0.5859],
]
QNEW_PRINT = [1.0471, 1.4283, 1.5338, 1.3598, 0.8579, 1.1316]
P06NEW_PRINT = [-0.0099, -0.1929, 1.0010]
R06NEW_PRINT = [[0.6441, -0.6915, 0.3271], [0.7650, 0.5846, -0.2704], [-0.0043, 0.4244, 0.9055]]
J0NEW_PRINT = [
    [-0.5018, 0.4613, 0.1113, 0.0609, 0.3830, -0.6771],
    [-0.0317, -0.4505, -0.4872, 0.4060, 0.2372, -0.4341],
    [0.8644, 0.7644, 0.8662, 0.9119, 0.8928, 0.5942],
    [0.4035, 0.5824, 0.4143, -0.1915, -0.6252, -0.5045],
    [-0.5082, -0.2320, -0.6149, -0.7037, -0.1150, -0.0168],
    [0.2156, -0.4882, 0.2927, -0.3005, 0.2988, -0.5872],
]
TAU1_PRINT = [-550.8253, -549.3252, -42.1803, -842.5501, -571.0821, -405.9182]
TAU2_PRINT = [-795.0905, -358.6778, -256.8914, -593.4673, -695.3522, -179.3081]
V0 = np.array([0.1, 0.2, 0.0, -0.4, 0.0, -0.5])
QDOT = np.array([0.4, -0.5, -0.2, 0.6, -0.4, 0.5])


@pytest.fixture(scope="module")
def book66() -> StewartPlatform:
    return StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0), np.radians(120.0))


def test_book_pose_is_the_printed_rotation() -> None:
    _, R = book_66_pose()
    printed = [[0.6428, -0.6943, 0.3237], [0.7660, 0.5826, -0.2717], [0.0, 0.4226, 0.9063]]
    np.testing.assert_allclose(R, printed, atol=ATOL4)


def test_book66_leg_lengths_and_jacobian(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    assert book66.kind == "6-6"
    np.testing.assert_allclose(book66.inverse_kinematics(p, R).lengths, Q_PRINT, atol=ATOL4)
    np.testing.assert_allclose(book66.jacobian(p, R), J0_PRINT, atol=ATOL4)


def test_book66_differential_ik(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    q = book66.inverse_kinematics(p, R).lengths
    np.testing.assert_allclose(ik_update(book66, q, p, R, V0, 0.01), QNEW_PRINT, atol=ATOL4)


def test_book66_differential_fk_book_update(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    step = fk_update(book66, p, R, QDOT, 0.01, update="book")
    np.testing.assert_allclose(step.p, P06NEW_PRINT, atol=ATOL4)
    np.testing.assert_allclose(step.R, R06NEW_PRINT, atol=ATOL4)
    misprinted = np.zeros((6, 6), dtype=bool)
    misprinted[4, 2] = misprinted[4, 3] = True  # entries (5,3), (5,4) in the book's 1-based numbering
    np.testing.assert_allclose(step.J0[~misprinted], np.asarray(J0NEW_PRINT)[~misprinted], atol=ATOL4)
    # Pin the erratum: the two entries agree in magnitude but have the opposite sign of the print.
    np.testing.assert_allclose(step.J0[misprinted], -np.asarray(J0NEW_PRINT)[misprinted], atol=ATOL4)


def test_consistent_update_differs_from_book_and_matches_base_frame_rate(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    book = fk_update(book66, p, R, QDOT, 0.01, update="book")
    good = fk_update(book66, p, R, QDOT, 0.01, update="consistent")
    np.testing.assert_allclose(good.p, book.p)
    assert np.linalg.norm(good.R - book.R) > 1e-3
    # Ṙ = (ω×)R with ω in the base frame: the consistent update has this first-order term, the book's not.
    dt = 1e-6
    tiny = fk_update(book66, p, R, QDOT, dt, update="consistent")
    np.testing.assert_allclose((tiny.R - R) / dt, skew(tiny.V0[3:]) @ R, atol=1e-5)
    tiny_book = fk_update(book66, p, R, QDOT, dt, update="book")
    assert np.linalg.norm((tiny_book.R - R) / dt - skew(tiny.V0[3:]) @ R) > 0.1
    # And q̇ = J0ᵀ V0 holds for the V0 the F-K step used.
    np.testing.assert_allclose(book66.jacobian(p, R).T @ good.V0, QDOT, atol=1e-12)


def test_unknown_update_is_rejected(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    with pytest.raises(MechanismError, match=r"choose one of \['book', 'consistent'\]"):
        fk_update(book66, p, R, QDOT, 0.01, update="left")  # type: ignore[arg-type]


def test_book66_statics(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    M, g, mz = 250.0, 9.81, 500.0
    f0 = np.array([0.0, 0.0, -M * g])
    tau1 = book66.leg_forces(p, R, np.r_[f0, R @ [0.0, 0.0, mz]])
    tau2 = book66.leg_forces(p, R, np.r_[f0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(tau1, TAU1_PRINT, atol=ATOL4)
    np.testing.assert_allclose(tau2, TAU2_PRINT, atol=ATOL4)
    assert tau2.sum() == pytest.approx(-2878.8, abs=0.05)
    np.testing.assert_allclose(book66.wrench(p, R, tau2), np.r_[f0, 0.0, 0.0, 0.0], atol=1e-9)


def _platforms() -> list[StewartPlatform]:
    return [
        StewartPlatform.symmetric_33(1.2, 1.0),
        StewartPlatform.symmetric_63(0.8, 0.5, np.radians(20.0)),
        StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0)),
    ]


@pytest.mark.parametrize("platform", _platforms(), ids=lambda s: s.kind)
def test_jacobian_matches_finite_differences_of_ik(platform: StewartPlatform) -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        p = np.array([0.0, 0.0, 1.0]) + 0.2 * rng.normal(size=3)
        R = Rotation.from_rotvec(0.3 * rng.normal(size=3)).as_matrix()
        V = rng.normal(size=6)
        h = 1e-6

        def q_at(s: float, p: np.ndarray = p, R: np.ndarray = R, V: np.ndarray = V) -> np.ndarray:
            Rs = Rotation.from_rotvec(V[3:] * s).as_matrix() @ R  # base-frame angular velocity
            return platform.inverse_kinematics(p + V[:3] * s, Rs).lengths

        fd = (q_at(h) - q_at(-h)) / (2 * h)
        np.testing.assert_allclose(platform.leg_rates(p, R, V), fd, atol=1e-8)


@pytest.mark.parametrize("platform", _platforms(), ids=lambda s: s.kind)
def test_duality_power_balance(platform: StewartPlatform) -> None:
    rng = np.random.default_rng(2)
    p, R = np.array([0.05, -0.1, 0.9]), rot_z(0.3) @ rot_x(0.2)
    for _ in range(5):
        tau, V = rng.normal(size=6), rng.normal(size=6)
        qdot, F0 = platform.leg_rates(p, R, V), platform.wrench(p, R, tau)
        assert tau @ qdot == pytest.approx(F0 @ V, abs=1e-12)
        np.testing.assert_allclose(platform.leg_forces(p, R, F0), tau, atol=1e-10)


def test_ik_outputs_are_consistent() -> None:
    platform = StewartPlatform.symmetric_33(1.2, 1.0)
    p, R = np.array([0.1, 0.0, 0.8]), rot_x(0.2)
    legs = platform.inverse_kinematics(p, R)
    np.testing.assert_allclose(np.linalg.norm(legs.units, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(legs.units * legs.lengths[:, None], legs.vectors, atol=1e-15)
    # (5.18): leg 2 runs from B0 to A6.
    np.testing.assert_allclose(legs.vectors[1], R @ platform.top_points[0] + p - platform.base_points[1])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"legs": ((0, 0), (0, 1), (1, 1), (1, 2), (2, 2))}, "exactly 6 legs"),
        ({"legs": ((0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 7))}, "base index 7 out of range"),
        ({"legs": ((0, 0), (0, 0), (1, 1), (1, 2), (2, 2), (2, 0))}, "six distinct"),
        ({"base_points": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]}, "base points are collinear"),
        ({"top_points": [[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]}, "non-finite"),
        ({"top_points": [[0, 0], [1, 0], [0, 1]]}, r"expected a \(k, 3\) array"),
    ],
)
def test_bad_geometry_is_rejected(kwargs: dict, message: str) -> None:
    good = StewartPlatform.symmetric_33(1.2, 1.0)
    args = {"base_points": good.base_points, "top_points": good.top_points, "legs": good.legs} | kwargs
    with pytest.raises(MechanismError, match=message):
        StewartPlatform(**args)


def test_bad_poses_are_rejected(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    with pytest.raises(MechanismError, match="non-finite"):
        book66.inverse_kinematics([0.0, np.nan, 1.0], R)
    with pytest.raises(MechanismError, match="not a proper rotation"):
        book66.inverse_kinematics(p, -R)
    with pytest.raises(MechanismError, match="singular"):
        # top disc in the base plane, same radius, no rotation: legs are all horizontal -> J0 rank deficient
        flat = StewartPlatform.symmetric_66(1.0, 1.0, np.radians(15.0))
        flat.leg_forces([0.0, 0.0, 0.0], rot_z(0.4), np.ones(6))


def test_trajectory_consistent_update_drifts_less_than_book(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    t = np.arange(41) * 0.01
    q = np.array(
        [
            book66.inverse_kinematics(
                p + np.array([0.1 * np.sin(2 * s), 0.05 * s, 0.1 * s]), rot_z(0.5 * s) @ R @ rot_x(0.4 * s)
            ).lengths
            for s in t
        ]
    )
    book = follow_leg_profile(book66, q, p, R, 0.01, update="book")
    good = follow_leg_profile(book66, q, p, R, 0.01, update="consistent")
    assert good.position_drift[0] == 0.0
    assert good.angle_drift.max() < 1e-3 < 0.05 < book.angle_drift.max()
    assert good.leg_error.max() < 2e-3 < book.leg_error.max()
    # the exact poses along the way are exact
    for pe, Re, qj in zip(good.p_exact, good.R_exact, q, strict=True):
        np.testing.assert_allclose(book66.inverse_kinematics(pe, Re).lengths, qj, atol=1e-10)


def test_trajectory_rejects_mismatched_start(book66: StewartPlatform) -> None:
    p, R = book_66_pose()
    with pytest.raises(MechanismError, match="does not match"):
        follow_leg_profile(book66, np.ones((3, 6)), p, R, 0.01)
