"""Small rotation and validation helpers shared by the parallel-mechanism modules.

Everything here is a thin wrapper around numpy / :class:`scipy.spatial.transform.Rotation`; the point of the
module is to give the chapter's notation (``R(x, φ)``, ``K = k×``, Rodrigues' formula (2.8)) one home and to
turn bad inputs into :class:`~redundik.errors.MechanismError` at the boundary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError

FloatArray = NDArray[np.float64]

#: Tolerance [-] on ‖RᵀR − I‖ and |det R − 1| for a matrix to be accepted as a rotation.
ROTATION_TOL = 1e-6


def as_vector(value: ArrayLike, size: int, name: str) -> FloatArray:
    """Return ``value`` as a finite float vector of length ``size``.

    Raises:
        MechanismError: wrong shape or a non-finite entry (NaN, inf).
    """
    arr = np.asarray(value, dtype=float)
    if arr.shape != (size,):
        raise MechanismError(f"{name}: expected {size} numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MechanismError(f"{name}: contains a non-finite value {arr.tolist()}")
    return arr


def as_points(value: ArrayLike, name: str) -> FloatArray:
    """Return ``value`` as a finite ``(k, 3)`` float array of points [length unit].

    Raises:
        MechanismError: wrong shape or a non-finite entry.
    """
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise MechanismError(f"{name}: expected a (k, 3) array of points, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MechanismError(f"{name}: contains a non-finite value")
    return arr


def as_rotation(value: ArrayLike, name: str = "R", tol: float = ROTATION_TOL) -> FloatArray:
    """Validate a 3×3 proper rotation matrix (orthonormal, det = +1) and return it as a float array.

    Raises:
        MechanismError: wrong shape, non-finite entries, not orthonormal or a reflection.
    """
    arr = np.asarray(value, dtype=float)
    if arr.shape != (3, 3):
        raise MechanismError(f"{name}: expected a 3x3 rotation matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MechanismError(f"{name}: contains a non-finite value")
    ortho = float(np.linalg.norm(arr.T @ arr - np.eye(3)))
    det = float(np.linalg.det(arr))
    if ortho > tol or abs(det - 1.0) > tol:
        raise MechanismError(
            f"{name}: not a proper rotation (‖RᵀR − I‖ = {ortho:.2e}, det = {det:.6f}; tolerance {tol:g})"
        )
    return arr


def rot_x(angle: float) -> FloatArray:
    """Elementary rotation R(x, angle) [rad] about the x-axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> FloatArray:
    """Elementary rotation R(y, angle) [rad] about the y-axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> FloatArray:
    """Elementary rotation R(z, angle) [rad] about the z-axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(roll: float, pitch: float, yaw: float, degrees: bool = True) -> FloatArray:
    """Orientation ``R = Rz(yaw)·Ry(pitch)·Rx(roll)`` (the CLI's ``--rpy R P Y`` convention).

    Args:
        roll: rotation about x [deg] (or [rad] if ``degrees`` is False).
        pitch: rotation about y [deg].
        yaw: rotation about z [deg].
        degrees: whether the angles are in degrees.
    """
    k = np.pi / 180.0 if degrees else 1.0
    return rot_z(yaw * k) @ rot_y(pitch * k) @ rot_x(roll * k)


def skew(v: ArrayLike) -> FloatArray:
    """Skew-symmetric matrix ``v×`` so that ``skew(v) @ w == cross(v, w)``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rodrigues(omega: ArrayLike, dt: float) -> FloatArray:
    """Orientation increment ``Rδ = I + sin Δφ K + (1 − cos Δφ) K²`` (chapter eq. (2.8)).

    ``Δφ = ‖ω‖ dt`` and ``K = k×`` with ``k = ω/‖ω‖``; evaluated through
    :meth:`scipy.spatial.transform.Rotation.from_rotvec`, which is the same formula and is well defined for
    ω = 0 (the book's listing divides by ‖ω‖).

    Args:
        omega: angular velocity [rad/s], shape (3,).
        dt: time step [s].
    """
    return Rotation.from_rotvec(np.asarray(omega, dtype=float) * dt).as_matrix()


def left_jacobian_so3(phi: ArrayLike) -> FloatArray:
    """Left Jacobian J_l(φ) of SO(3): d/dφ [exp(φ)·x] = −[exp(φ)x]× J_l(φ) for a fixed vector x."""
    phi = np.asarray(phi, dtype=float)
    theta = float(np.linalg.norm(phi))
    k = skew(phi)
    if theta < 1e-8:
        return np.eye(3) + 0.5 * k + k @ k / 6.0
    return np.eye(3) + (1.0 - np.cos(theta)) / theta**2 * k + (theta - np.sin(theta)) / theta**3 * (k @ k)


def rotation_angle_between(r_a: ArrayLike, r_b: ArrayLike) -> float:
    """Angle [rad] of the relative rotation ``R_aᵀ R_b`` (0 when equal)."""
    rel = np.asarray(r_a, dtype=float).T @ np.asarray(r_b, dtype=float)
    # log map instead of arccos((tr − 1)/2), which loses half the digits near 0
    return float(Rotation.from_matrix(rel).magnitude())


def wrap_angle(angle: float | FloatArray) -> float | FloatArray:
    """Wrap an angle [rad] to (−π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(angle), 2.0 * np.pi)
