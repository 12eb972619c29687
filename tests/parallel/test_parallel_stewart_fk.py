"""Stewart forward kinematics: the chapter's grid search (5.19)–(5.24) and the exact multi-start solver."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.errors import MechanismError
from redundik.parallel import StewartPlatform, book_66_pose, forward_kinematics, grid_search_fk
from redundik.parallel._linalg import rot_x, rot_y, rot_z

ATOL4 = 0.5e-4 + 1e-9

# The two printed runs of the F-K listing. The printed R06(3,1) of the second run reads ".0934": the minus
# sign is OCR damage (the grid answer is -0.0934, and |R06(3,1)| = 0.0934 either way).
BOOK_RUNS = [
    (
        [1.0, 0.8, 1.2, 1.1, 0.9, 1.0],
        [99.4, 109.8, 106.6],
        [-0.1236, -0.0495, 0.7586],
        [[0.5769, 0.7749, 0.2724], [-0.8170, 0.5644, 0.0801], [-0.0956, -0.2673, 0.9587]],
    ),
    (
        [0.8, 0.6, 1.0, 1.2, 0.7, 0.9],
        [121.0, 104.2, 101.0],
        [-0.0994, 0.0825, 0.5661],
        [[0.3584, 0.7331, 0.5657], [-0.9272, 0.3336, 0.1382], [-0.0934, -0.5765, 0.7993]],
    ),
]


@pytest.fixture(scope="module")
def book33() -> StewartPlatform:
    return StewartPlatform.symmetric_33(1.2, 1.0)


def _assert_exact(platform: StewartPlatform, sols: list, q: np.ndarray) -> None:
    assert sols
    for s in sols:
        np.testing.assert_allclose(platform.inverse_kinematics(s.p, s.R).lengths, q, atol=1e-10)
        np.testing.assert_allclose(s.R.T @ s.R, np.eye(3), atol=1e-12)
        assert np.linalg.det(s.R) == pytest.approx(1.0, abs=1e-12)
        assert s.residual < 1e-10
    residuals = [s.residual for s in sols]
    assert residuals == sorted(residuals) or max(residuals) < 1e-12


@pytest.mark.parametrize(("legs", "theta", "p", "R"), BOOK_RUNS)
def test_grid_search_reproduces_the_printed_answers(book33, legs, theta, p, R) -> None:
    sol = grid_search_fk(book33, legs)
    np.testing.assert_allclose(sol.theta, theta, atol=1e-9)
    np.testing.assert_allclose(sol.p, p, atol=ATOL4)
    np.testing.assert_allclose(sol.R, R, atol=ATOL4)
    # Pinned erratum: R06 = P0 P6^-1 is not an exact rotation ...
    assert np.linalg.norm(sol.R.T @ sol.R - np.eye(3)) > 1e-3
    assert 0 < sol.residual < 0.03
    # ... yet the leg check of the book comes out exact: the joints lie on the circles.
    top_world = book33.leg_top @ sol.R.T + sol.p
    np.testing.assert_allclose(np.linalg.norm(top_world - book33.leg_base, axis=1), legs, atol=1e-12)


def test_grid_search_from_the_prose_start_angle_misses_the_printed_theta(book33) -> None:
    legs, theta, _, _ = BOOK_RUNS[0]
    sol = grid_search_fk(book33, legs, start=np.radians(10.0))
    assert not np.allclose(sol.theta, theta, atol=0.05)


@pytest.mark.parametrize(("legs", "theta", "p", "R"), BOOK_RUNS)
def test_exact_fk_refines_the_grid_answer(book33, legs, theta, p, R) -> None:
    sols = forward_kinematics(book33, legs)
    _assert_exact(book33, sols, np.asarray(legs))
    assert all(s.p[2] > 0 for s in sols)
    nearest = min(sols, key=lambda s: np.linalg.norm(s.p - p))
    assert np.linalg.norm(nearest.p - p) < 0.01
    assert np.linalg.norm(nearest.R - np.asarray(R)) < 0.03
    # every grid-tolerance answer is an approximation of a distinct exact assembly
    assert len(sols) >= 2


def test_exact_fk_below_base_mirrors_above(book33) -> None:
    legs = BOOK_RUNS[0][0]
    above = forward_kinematics(book33, legs)
    below = forward_kinematics(book33, legs, half_space="below")
    assert len(above) == len(below)
    mirror = np.diag([1.0, 1.0, -1.0])
    for s in above:
        assert min(np.linalg.norm(b.p - mirror @ s.p) for b in below) < 1e-8


@pytest.mark.parametrize(
    "platform",
    [
        StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0)),
        StewartPlatform.symmetric_63(0.8, 0.5, np.radians(20.0)),
        StewartPlatform(
            base_points=[
                [1.0, 0.1, 0.0],
                [0.2, 1.1, 0.05],
                [-0.9, 0.4, 0.0],
                [-0.5, -0.8, 0.1],
                [0.4, -1.0, 0.0],
                [1.1, -0.5, 0.0],
            ],
            top_points=[
                [0.5, 0.2, 0.0],
                [0.0, 0.6, 0.0],
                [-0.5, 0.1, 0.0],
                [-0.2, -0.5, 0.05],
                [0.3, -0.4, 0.0],
                [0.6, -0.1, 0.0],
            ],
            legs=((0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0)),
        ),
    ],
    ids=["6-6", "6-3", "arbitrary"],
)
def test_exact_fk_round_trip(platform: StewartPlatform) -> None:
    p, R = np.array([0.05, -0.1, 0.9]), rot_z(0.4) @ rot_y(0.15) @ rot_x(-0.1)
    q = platform.inverse_kinematics(p, R).lengths
    sols = forward_kinematics(platform, q)
    _assert_exact(platform, sols, q)
    assert min(np.linalg.norm(s.p - p) + np.linalg.norm(s.R - R) for s in sols) < 1e-9


def test_exact_fk_finds_the_book66_pose() -> None:
    platform = StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0))
    p, R = book_66_pose()
    q = platform.inverse_kinematics(p, R).lengths
    sols = forward_kinematics(platform, q)
    _assert_exact(platform, sols, q)
    assert any(np.linalg.norm(s.p - p) < 1e-9 and np.linalg.norm(s.R - R) < 1e-9 for s in sols)


def test_unreachable_legs_raise(book33) -> None:
    with pytest.raises(MechanismError, match="triangle inequality"):
        grid_search_fk(book33, [0.1] * 6)
    with pytest.raises(MechanismError, match=r"admit no assembly above the base: smallest leg residual"):
        forward_kinematics(book33, [0.1] * 6, starts=8)
    six = StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0))
    with pytest.raises(MechanismError, match="admit no assembly"):
        forward_kinematics(six, [0.05, 0.05, 0.05, 0.05, 0.05, 3.0], starts=8)


def test_bad_lengths_raise(book33) -> None:
    with pytest.raises(MechanismError, match="non-finite"):
        forward_kinematics(book33, [1.0, np.nan, 1.0, 1.0, 1.0, 1.0])
    with pytest.raises(MechanismError, match="positive"):
        forward_kinematics(book33, [1.0, -1.0, 1.0, 1.0, 1.0, 1.0])
    with pytest.raises(MechanismError, match="expected 6 numbers"):
        forward_kinematics(book33, [1.0, 1.0])


def test_grid_search_needs_three_top_joints() -> None:
    with pytest.raises(MechanismError, match="needs 3 top joints"):
        grid_search_fk(StewartPlatform.symmetric_66(1.2, 0.8, 0.2), [1.0] * 6)
