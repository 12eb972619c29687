"""Differential-motion I-K and F-K updates of a Stewart platform (section 5.4.2, after (5.30)).

* I-K: ``q(j+1) = q(j) + J_0ᵀ V_0 dt`` (first-order use of (5.29)).
* F-K: ``V_0 = J_0⁻ᵀ q̇``, ``p(j+1) = p(j) + v_0^6 dt`` and the orientation increment ``Rδ`` from Rodrigues'
  formula with ``Δφ = ‖ω_0^6‖ dt``, ``k = ω_0^6/‖ω_0^6‖``.

Deviation from the print: the book updates ``R(j+1) = R(j)·Rδ``. Since ω_0^6 is expressed in the base frame
(``Ṙ = (ω×) R``), that right-multiplication treats it as a body-frame rate; the frame-consistent update is
``R(j+1) = Rδ·R(j)``. Both are offered (``update="book"`` reproduces the printed R06new and J0new,
``update="consistent"`` is the default) and :func:`follow_leg_profile` measures how far each drifts from the
exact forward kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_rotation, as_vector, rodrigues, rotation_angle_between
from redundik.parallel.stewart import StewartPlatform
from redundik.parallel.stewart_fk import forward_kinematics, nearest_solution

Update = Literal["book", "consistent"]
UPDATES: tuple[str, ...] = ("book", "consistent")


@dataclass(frozen=True)
class FKStep:
    """One differential F-K update.

    Attributes:
        p: updated p_0^6 [length unit].
        R: updated R_0^6.
        V0: the top-disc velocity (v; ω) = J_0⁻ᵀ q̇ used [length unit/s; rad/s].
        J0: the Jacobian (5.28) at the updated pose.
    """

    p: FloatArray
    R: FloatArray
    V0: FloatArray
    J0: FloatArray


def ik_update(
    platform: StewartPlatform, q: ArrayLike, p: ArrayLike, R: ArrayLike, V0: ArrayLike, dt: float
) -> FloatArray:
    """Differential I-K step ``q + J_0ᵀ V_0 dt`` [length unit] (first-order (5.29)).

    Args:
        platform: the platform.
        q: current leg lengths [length unit].
        p: current p_0^6 [length unit].
        R: current R_0^6.
        V0: (v_0^6; ω_0^6) [length unit/s; rad/s], base frame.
        dt: sampling interval [s].
    """
    return as_vector(q, 6, "q") + platform.leg_rates(p, R, V0) * float(dt)


def fk_update(
    platform: StewartPlatform, p: ArrayLike, R: ArrayLike, qdot: ArrayLike, dt: float, update: Update = "consistent"
) -> FKStep:
    """Differential F-K step from leg rates (inverse of (5.29) plus Rodrigues' formula).

    Args:
        platform: the platform.
        p: current p_0^6 [length unit].
        R: current R_0^6.
        qdot: leg rates q̇ [length unit/s].
        dt: sampling interval [s].
        update: ``"book"`` for the printed ``R·Rδ`` or ``"consistent"`` for ``Rδ·R`` (ω in the base frame).

    Raises:
        MechanismError: unknown ``update`` or a singular J_0.
    """
    if update not in UPDATES:
        raise MechanismError(f"unknown orientation update {update!r}; choose one of {list(UPDATES)}")
    p = as_vector(p, 3, "p")
    R = as_rotation(R)
    V0 = platform.twist_from_rates(p, R, qdot)
    Rd = rodrigues(V0[3:], float(dt))
    p_new = p + V0[:3] * float(dt)
    R_new = R @ Rd if update == "book" else Rd @ R
    return FKStep(p_new, R_new, V0, platform.jacobian(p_new, R_new))


@dataclass(frozen=True)
class Trajectory:
    """Result of :func:`follow_leg_profile`.

    Attributes:
        t: sample times [s], shape (N,).
        p: integrated positions [length unit], shape (N, 3).
        R: integrated orientations, shape (N, 3, 3).
        p_exact: exact F-K positions (the assembly nearest to the integrated pose), shape (N, 3).
        R_exact: exact F-K orientations, shape (N, 3, 3).
        position_drift: ‖p − p_exact‖ [length unit], shape (N,).
        angle_drift: rotation angle between R and R_exact [rad], shape (N,).
        leg_error: ‖q(p, R) − q_profile‖ [length unit], shape (N,).
    """

    t: FloatArray
    p: FloatArray
    R: FloatArray
    p_exact: FloatArray
    R_exact: FloatArray
    position_drift: FloatArray
    angle_drift: FloatArray
    leg_error: FloatArray


def follow_leg_profile(
    platform: StewartPlatform,
    q_profile: ArrayLike,
    p0: ArrayLike,
    R0: ArrayLike,
    dt: float,
    update: Update = "consistent",
) -> Trajectory:
    """Integrate the differential F-K along a sampled leg-length profile and compare with the exact F-K.

    The leg rate between samples j and j+1 is the finite difference ``(q_{j+1} − q_j)/dt``. At each sample the
    exact F-K is solved from the previous exact pose (the branch that the motion follows), so the drift
    is the integration error alone.

    Args:
        platform: the platform.
        q_profile: leg lengths per sample [length unit], shape (N, 6); row 0 must match the start pose.
        p0: start position [length unit].
        R0: start orientation.
        dt: sampling interval [s].
        update: orientation update, see :func:`fk_update`.

    Raises:
        MechanismError: bad shapes, a start pose not matching ``q_profile[0]`` (1e-6), or a singular J_0.
    """
    q = np.asarray(q_profile, dtype=float)
    if q.ndim != 2 or q.shape[1] != 6 or len(q) < 2 or not np.all(np.isfinite(q)):
        raise MechanismError(f"q_profile: expected a finite (N >= 2, 6) array, got shape {q.shape}")
    p, R = as_vector(p0, 3, "p0"), as_rotation(R0, "R0")
    mismatch = float(np.linalg.norm(platform.inverse_kinematics(p, R).lengths - q[0]))
    if mismatch > 1e-6:
        raise MechanismError(f"start pose does not match q_profile[0] (leg error {mismatch:.3g})")
    n = len(q)
    ps, Rs, pe, Re = np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3))
    ps[0], Rs[0], pe[0], Re[0] = p, R, p, R
    for j in range(n - 1):
        step = fk_update(platform, ps[j], Rs[j], (q[j + 1] - q[j]) / dt, dt, update)
        ps[j + 1], Rs[j + 1] = step.p, step.R
        sols = forward_kinematics(platform, q[j + 1], starts=0, half_space="any", initial=[(pe[j], Re[j])])
        best = nearest_solution(sols, pe[j], Re[j])
        pe[j + 1], Re[j + 1] = best.p, best.R
    leg_err = np.array([np.linalg.norm(platform._legs(ps[j], Rs[j]).lengths - q[j]) for j in range(n)])
    return Trajectory(
        t=np.arange(n, dtype=float) * dt,
        p=ps,
        R=Rs,
        p_exact=pe,
        R_exact=Re,
        position_drift=np.linalg.norm(ps - pe, axis=1),
        angle_drift=np.array([rotation_angle_between(a, b) for a, b in zip(Rs, Re, strict=True)]),
        leg_error=leg_err,
    )
