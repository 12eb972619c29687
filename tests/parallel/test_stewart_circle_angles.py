"""The exact 3-3 forward kinematics returns the circle angles θ1–θ3 of each assembly (issue 32, item 16), as the
chapter's listing prints them for its grid answer."""

from __future__ import annotations

import numpy as np
import pytest
from tests.parallel.test_parallel_stewart_fk import BOOK_RUNS

from redundik.errors import MechanismError
from redundik.parallel import StewartPlatform, forward_kinematics, grid_search_fk
from redundik.parallel.stewart_fk import circle_angles, circle_points


@pytest.fixture(scope="module")
def book33() -> StewartPlatform:
    return StewartPlatform.symmetric_33(1.2, 1.0)


def _on_circle(platform: StewartPlatform, legs: np.ndarray, points: np.ndarray) -> None:
    """Each point is at its two legs' lengths from their base joints: the chapter's circle, built independently."""
    for i, (top, base) in enumerate(platform.legs):
        assert np.linalg.norm(points[top] - platform.base_points[base]) == pytest.approx(legs[i], abs=1e-10)


@pytest.mark.parametrize(("legs", "theta", "p", "R"), BOOK_RUNS)
def test_exact_fk_returns_the_circle_angles_of_its_pose(book33, legs, theta, p, R) -> None:
    legs = np.asarray(legs)
    sols = forward_kinematics(book33, legs, half_space="any")
    assert any(s.p[2] < 0 for s in sols)  # mirror images below the base too
    for s in sols:
        assert s.theta is not None and s.theta.shape == (3,)
        points = circle_points(book33, legs, s.theta)  # rebuilt from θ1–θ3 alone
        vertices = book33.top_points @ s.R.T + s.p  # the platform's top joints at the returned pose
        assert np.all(np.abs(s.theta) <= 180.0) and np.all((s.theta > 0) == (vertices[:, 2] > 0))
        np.testing.assert_allclose(points, vertices, atol=1e-9)
        _on_circle(book33, legs, points)
    # the assembly nearest the printed grid answer has angles near the printed ones: the grid accepts sides 0.01
    # off on circles of radius ~0.5-1 (about 1°) at a 0.8° step; measured: at most 1.45° apart
    nearest = min(sols, key=lambda s: np.linalg.norm(s.p - p))
    np.testing.assert_allclose(nearest.theta, theta, atol=2.0)
    assert np.linalg.norm(nearest.theta - theta) > 1e-6  # exact angles, not the grid's copy


@pytest.mark.parametrize(("legs", "theta", "p", "R"), BOOK_RUNS)
def test_grid_angles_rebuild_the_grid_joints(book33, legs, theta, p, R) -> None:
    sol = grid_search_fk(book33, legs)
    points = circle_points(book33, legs, sol.theta)
    np.testing.assert_allclose(sol.theta, theta, atol=1e-9)  # the chapter's printed θ
    _on_circle(book33, np.asarray(legs), points)
    # the grid's R is not a rotation: its pose puts the joints near, not on, the points (within the grid's ~1°)
    np.testing.assert_allclose(circle_angles(book33, legs, sol.p, sol.R), sol.theta, atol=2.0)


def test_a_66_platform_has_no_circle_angles() -> None:
    platform = StewartPlatform.symmetric_66(1.2, 1.0, np.radians(15.0))
    legs = platform.inverse_kinematics(np.array([0.0, 0.0, 1.0]), np.eye(3)).lengths
    assert all(s.theta is None for s in forward_kinematics(platform, legs))
    with pytest.raises(MechanismError, match="3 top joints"):
        circle_points(platform, legs, [90.0, 90.0, 90.0])
