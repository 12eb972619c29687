"""Stewart platform geometry, inverse kinematics (5.18, 5.25), Jacobian (5.28), velocities (5.29), statics (5.30).

One type, :class:`StewartPlatform`, covers the 3-3, 6-3 and 6-6 platforms of section 5.4.1: it holds the base
joint points ``p_0^i`` (base frame 0), the top joint points ``p_6^i`` (frame 6 of the top disc) and the leg
pairing ``(top index, base index)`` of the six pistons. Arbitrary points are allowed; the chapter's symmetric
layouts are class-method constructors.

Leg i (5.18)/(5.25)::

    l_0^i = R_0^6 p_6^{t(i)} + p_0^6 − p_0^{b(i)},   q_i = ‖l_0^i‖,   r_0^i = l_0^i / q_i.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_points, as_rotation, as_vector, rot_x, rot_z

#: Smallest admissible leg length [length unit]; below it the unit vector r_0^i is undefined.
MIN_LEG_LENGTH = 1e-9
#: Condition number of J0 above which statics / the inverse Jacobian equation refuse to solve.
MAX_CONDITION = 1e10


@dataclass(frozen=True)
class LegSolution:
    """Result of the Stewart inverse kinematics (5.18)/(5.25).

    Attributes:
        vectors: leg vectors l_0^i [length unit], shape (6, 3), base frame.
        lengths: joint values q_i = ‖l_0^i‖ [length unit], shape (6,).
        units: unit vectors r_0^i = l_0^i / q_i [-], shape (6, 3).
        top_world: top joint points R_0^6 p_6^i + p_0^6 [length unit], shape (6, 3) (one row per leg).
    """

    vectors: FloatArray
    lengths: FloatArray
    units: FloatArray
    top_world: FloatArray


@dataclass(frozen=True)
class StewartPlatform:
    """A six-leg Stewart platform (3-3, 6-3, 6-6 or any other pairing of joint points).

    Attributes:
        base_points: base joint points p_0^i [length unit], shape (nb, 3), base frame 0.
        top_points: top joint points p_6^i [length unit], shape (nt, 3), top frame 6.
        legs: six pairs ``(top index, base index)``; leg i runs from base point ``legs[i][1]`` to top point
            ``legs[i][0]``.
        name: free-text label.
        unit: length unit of every point and leg length (e.g. ``"m"``).

    Raises:
        MechanismError: not exactly six legs, an index out of range, a repeated leg, an unused joint point,
            collinear top or base points, non-finite coordinates.
    """

    base_points: FloatArray
    top_points: FloatArray
    legs: tuple[tuple[int, int], ...]
    name: str = "stewart"
    unit: str = "m"
    _top_idx: FloatArray = field(init=False, repr=False, compare=False)
    _base_idx: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        base = as_points(self.base_points, "base points")
        top = as_points(self.top_points, "top points")
        legs = tuple((int(t), int(b)) for t, b in self.legs)
        if len(legs) != 6:
            raise MechanismError(f"a Stewart platform needs exactly 6 legs, got {len(legs)}")
        for i, (t, b) in enumerate(legs):
            if not 0 <= t < len(top):
                raise MechanismError(f"leg {i + 1}: top index {t} out of range 0..{len(top) - 1}")
            if not 0 <= b < len(base):
                raise MechanismError(f"leg {i + 1}: base index {b} out of range 0..{len(base) - 1}")
        if len(set(legs)) != 6:
            raise MechanismError(f"legs must be six distinct (top, base) pairs, got {list(legs)}")
        for label, pts, used in (
            ("top", top, {t for t, _ in legs}),
            ("base", base, {b for _, b in legs}),
        ):
            unused = sorted(set(range(len(pts))) - used)
            if unused:
                raise MechanismError(f"{label} points {unused} are not connected to any leg")
            gaps = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2) + np.eye(len(pts))
            if gaps.min() < 1e-12:
                i, j = sorted(int(k) for k in np.unravel_index(int(np.argmin(gaps)), gaps.shape))
                raise MechanismError(f"{label} points {i} and {j} coincide")
            centred = pts - pts.mean(axis=0)
            if len(pts) < 3 or np.linalg.matrix_rank(centred, tol=1e-9 * max(1.0, np.abs(pts).max())) < 2:
                raise MechanismError(f"{label} points are collinear or coincident: {pts.tolist()}")
        object.__setattr__(self, "base_points", base)
        object.__setattr__(self, "top_points", top)
        object.__setattr__(self, "legs", legs)
        object.__setattr__(self, "_top_idx", np.array([t for t, _ in legs]))
        object.__setattr__(self, "_base_idx", np.array([b for _, b in legs]))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def symmetric_33(
        cls, base_side: float, top_side: float, top_offset: float = 2.0 * np.pi / 3.0, unit: str = "m"
    ) -> StewartPlatform:
        """The chapter's 3-3 platform (Fig. 5.20/5.21 and the F-K listing).

        Base joints A0, B0, C0 on an equilateral triangle of side ``base_side`` at angles 0°, 120°, 240°
        about z0 (so B0C0 ∥ y0 at x = −√3/6·L0, as the listing's ``xq`` assumes); top joints A6, B6, C6 on an
        equilateral triangle of side ``top_side`` at angles ``top_offset`` + 0°, 120°, 240° in frame 6.
        The default offset 120° reproduces the listing (``p6c = [x6; 0; 0]``, ``p6a`` at 120°).
        Legs (5.18): A6–A0, A6–B0, B6–B0, B6–C0, C6–C0, C6–A0.

        Args:
            base_side: L0 [length unit].
            top_side: L6 [length unit].
            top_offset: angle of A6 about z6 [rad].
            unit: length unit label.
        """
        if not (base_side > 0 and top_side > 0):
            raise MechanismError(f"sides must be positive, got L0={base_side}, L6={top_side}")
        ang = np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
        r0, r6 = base_side / np.sqrt(3.0), top_side / np.sqrt(3.0)
        base = np.stack([r0 * np.cos(ang), r0 * np.sin(ang), np.zeros(3)], axis=1)
        top = np.stack([r6 * np.cos(ang + top_offset), r6 * np.sin(ang + top_offset), np.zeros(3)], axis=1)
        legs = ((0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 0))
        return cls(base, top, legs, name="3-3", unit=unit)

    @classmethod
    def symmetric_63(
        cls,
        base_radius: float,
        top_radius: float,
        beta: float,
        top_offset: float = 2.0 * np.pi / 3.0,
        unit: str = "m",
    ) -> StewartPlatform:
        """A 6-3 platform: the 3-3 layout with each base joint split into two at ±``beta`` about z0.

        Base points a1, a2, b1, b2, c1, c2 at angles −β, β, 120°−β, 120°+β, 240°−β, 240°+β (radius
        ``base_radius``); top A6, B6, C6 as in :meth:`symmetric_33` (radius ``top_radius``). Legs: A6–a2, A6–b1,
        B6–b2, B6–c1, C6–c2, C6–a1 (each top joint keeps its two neighbouring base joints).

        Args:
            base_radius: radius of the base joint circle [length unit].
            top_radius: radius of the top joint circle [length unit].
            beta: half split angle of each base joint pair [rad], 0 < β < 60°.
            top_offset: angle of A6 about z6 [rad].
            unit: length unit label.
        """
        if not (base_radius > 0 and top_radius > 0 and 0 < beta < np.pi / 3):
            raise MechanismError(
                f"need positive radii and 0 < beta < 60 deg, got {base_radius}, {top_radius}, "
                f"{np.degrees(beta):.3f} deg"
            )
        centres = np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
        ang = np.ravel(np.stack([centres - beta, centres + beta], axis=1))
        base = np.stack([base_radius * np.cos(ang), base_radius * np.sin(ang), np.zeros(6)], axis=1)
        top = np.stack(
            [top_radius * np.cos(centres + top_offset), top_radius * np.sin(centres + top_offset), np.zeros(3)],
            axis=1,
        )
        legs = ((0, 1), (0, 2), (1, 3), (1, 4), (2, 5), (2, 0))
        return cls(base, top, legs, name="6-3", unit=unit)

    @classmethod
    def symmetric_66(
        cls,
        base_radius: float,
        top_radius: float,
        beta: float,
        gamma: float = 2.0 * np.pi / 3.0,
        unit: str = "m",
    ) -> StewartPlatform:
        """The chapter's 6-6 platform (Fig. 5.22 and the Jacobian listing of section 5.4.2).

        Points a1, a2, b1, b2, c1, c2 at angles −β, β, γ−β, γ+β, −γ−β, −γ+β on circles of radius
        ``base_radius`` (base) and ``top_radius`` (top). Legs (5.25): a1–a2, a2–b1, b1–b2, b2–c1, c1–c2,
        c2–a1 written as (top point, base point), e.g. l_0^1 = R p_6^{a1} + p − p_0^{a2}.

        Args:
            base_radius: base circle radius [length unit] (1.2 in the book).
            top_radius: top circle radius [length unit] (0.8 in the book).
            beta: split angle β [rad] (15° in the book).
            gamma: γ [rad] (120° in the book).
            unit: length unit label.
        """
        if not (base_radius > 0 and top_radius > 0):
            raise MechanismError(f"radii must be positive, got {base_radius}, {top_radius}")
        ang = np.array([-beta, beta, gamma - beta, gamma + beta, -gamma - beta, -gamma + beta])

        def ring(radius: float) -> FloatArray:
            return np.stack([radius * np.cos(ang), radius * np.sin(ang), np.zeros(6)], axis=1)

        legs = ((0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0))
        return cls(ring(base_radius), ring(top_radius), legs, name="6-6", unit=unit)

    # ------------------------------------------------------------------ properties
    @property
    def kind(self) -> str:
        """``"<base>-<top>"`` count of distinct joint points in the chapter's naming: 3-3, 6-3 or 6-6."""
        return f"{len(self.base_points)}-{len(self.top_points)}"

    @property
    def leg_base(self) -> FloatArray:
        """Base joint point of each leg p_0^{b(i)} [length unit], shape (6, 3)."""
        return self.base_points[self._base_idx]

    @property
    def leg_top(self) -> FloatArray:
        """Top joint point of each leg in frame 6, p_6^{t(i)} [length unit], shape (6, 3)."""
        return self.top_points[self._top_idx]

    # ------------------------------------------------------------------ kinematics
    def inverse_kinematics(self, p: ArrayLike, R: ArrayLike) -> LegSolution:
        """Leg vectors, lengths and unit vectors for a top pose (5.18), (5.25).

        Args:
            p: p_0^6, position of frame 6 in the base frame [length unit], shape (3,).
            R: R_0^6, orientation of frame 6 [-], a proper rotation.

        Raises:
            MechanismError: non-finite pose, a non-rotation ``R``, or a leg of zero length.
        """
        p = as_vector(p, 3, "p")
        R = as_rotation(R)
        return self._legs(p, R)

    def _legs(self, p: FloatArray, R: FloatArray) -> LegSolution:
        top_world = self.leg_top @ R.T + p  # (6, 3)
        vectors = top_world - self.leg_base
        lengths = np.linalg.norm(vectors, axis=1)
        if np.any(lengths < MIN_LEG_LENGTH):
            raise MechanismError(f"a leg has zero length at this pose: {lengths.tolist()}")
        return LegSolution(vectors, lengths, vectors / lengths[:, None], top_world)

    def jacobian(self, p: ArrayLike, R: ArrayLike) -> FloatArray:
        """Jacobian J_0 (5.28): column i is (r_0^i ; p_{6(0)}^i × r_0^i), shape (6, 6).

        ``p_{6(0)}^i = R_0^6 p_6^i`` is the top joint point seen from the origin of frame 6 in base
        coordinates. With it ``q̇ = J_0ᵀ V_0`` (5.29) for ``V_0 = (v_0^6; ω_0^6)`` [length unit/s; rad/s],
        both in the base frame, ``Ṙ_0^6 = (ω_0^6 ×) R_0^6``.

        Raises:
            MechanismError: as :meth:`inverse_kinematics`.
        """
        p = as_vector(p, 3, "p")
        R = as_rotation(R)
        return self._jacobian(p, R)

    def _jacobian(self, p: FloatArray, R: FloatArray) -> FloatArray:
        legs = self._legs(p, R)
        arm = self.leg_top @ R.T  # p_6(0)^i, (6, 3)
        return np.vstack([legs.units.T, np.cross(arm, legs.units).T])

    def leg_rates(self, p: ArrayLike, R: ArrayLike, V0: ArrayLike) -> FloatArray:
        """Joint velocities q̇ = J_0ᵀ V_0 (5.29) [length unit/s].

        Args:
            p: p_0^6 [length unit].
            R: R_0^6.
            V0: (v_0^6, ω_0^6) [length unit/s, rad/s], base frame, shape (6,).
        """
        return self.jacobian(p, R).T @ as_vector(V0, 6, "V0")

    def twist_from_rates(self, p: ArrayLike, R: ArrayLike, qdot: ArrayLike) -> FloatArray:
        """Top-disc velocity V_0 = J_0⁻ᵀ q̇ (inverse of (5.29)) [length unit/s, rad/s].

        Raises:
            MechanismError: J_0 singular (condition number above :data:`MAX_CONDITION`).
        """
        J0 = self.jacobian(p, R)
        _check_conditioning(J0)
        return np.linalg.solve(J0.T, as_vector(qdot, 6, "qdot"))

    def wrench(self, p: ArrayLike, R: ArrayLike, tau: ArrayLike) -> FloatArray:
        """Statics F_0 = J_0 τ (5.30): wrench (f_0; m_0) [N; N·length unit] on the top disc, base frame.

        Args:
            p: p_0^6 [length unit].
            R: R_0^6.
            tau: leg forces (f_1 … f_6) [N], positive when the leg pushes the top away from the base.
        """
        return self.jacobian(p, R) @ as_vector(tau, 6, "tau")

    def leg_forces(self, p: ArrayLike, R: ArrayLike, F0: ArrayLike) -> FloatArray:
        """Leg forces τ = J_0⁻¹ F_0 balancing a wrench on the top disc (inverse of (5.30)) [N].

        ``F_0 = (f_0; m_0)`` is the wrench [N; N·length unit] applied to the top disc, both parts in the base
        frame, the moment taken about the origin of frame 6. The chapter's example (250 kg load, 500 N·m
        twist about z6) uses ``f_0 = (0, 0, −Mg)`` and ``m_0 = R_0^6 (0, 0, m_z)``.

        Raises:
            MechanismError: J_0 singular (condition number above :data:`MAX_CONDITION`).
        """
        J0 = self.jacobian(p, R)
        _check_conditioning(J0)
        return np.asarray(np.linalg.solve(J0, as_vector(F0, 6, "F0")), dtype=float)


def _check_conditioning(J0: FloatArray) -> None:
    cond = float(np.linalg.cond(J0))
    if not np.isfinite(cond) or cond > MAX_CONDITION:
        raise MechanismError(f"J0 is singular at this pose (condition number {cond:.3g})")


def book_66_pose() -> tuple[FloatArray, FloatArray]:
    """The pose of the chapter's 6-6 example: p = (0, −0.2, 1), R = Rz(50°)·Rx(25°)."""
    return np.array([0.0, -0.2, 1.0]), rot_z(np.radians(50.0)) @ rot_x(np.radians(25.0))
