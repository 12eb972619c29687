"""The 3-leg UPR platform of section 5.4.3: passive orientation (5.31)–(5.38), legs (5.42), forward kinematics.

Each leg runs from a base joint p_0^i (the chapter's "universal", 3-axis joint) through a piston to a revolute
joint at p_3^i on the mobile disc (frame 3) whose axis u_i = p_3^{α,β,γ} lies in the x3-y3 plane, is
perpendicular to p_3^i and is kept perpendicular to the leg. The "Top" point sits at height d4 above the
origin of frame 3: ``p_0^t = o_3 + d_4 z_0^3``. Then η_0^i = p_0^t − p_0^i (5.34) satisfies
``η_0^{iT} R_0^3 u_i = 0`` (5.31), three equations for the passive orientation R_0^3.

Deviations from the print, each pinned by a test:

* (5.42) reads ``l_0^i = p_0^t − p_0^a − d_4 z_0^3 − R_0^3 p_3^i`` for every leg. Each leg uses its own base
  point and, with the convention of (5.18) (``l = R p + o − p_0``), the platform term enters with a plus sign:
  ``l_0^i = p_0^t − d_4 z_0^3 + R_0^3 p_3^i − p_0^i``.
* (5.38): γ11 and γ13 contain b_3^β where b_3^γ belongs; :meth:`UPRPlatform.book_orientation` derives the coefficients
  from the axis table, which gives the corrected form.
* The book's closed form assumes ``R_0^3 = R(y, ψ) R(x, φ)`` (no spin) and uses only two of the three rows
  of (5.32) for the right isosceles and rectangle layouts, so the third row is in general violated; for the
  equilateral layout the 2×2 system (5.38) returns (sin φ, cos φ) off the unit circle. It is exact for the
  exercise's rectangle arm (the two parallel axes along x3 with base joints b, c on the y0-axis give the same
  ψ from both rows). :meth:`UPRPlatform.exact_orientation` solves all three equations of (5.31) on SO(3) (least squares,
  seeded by the closed form) and is what the exact I-K uses.
* The closed form needs one leg whose axis is ∥ x3 (row with a_i2 = 0, giving ψ by (5.36)); the exercise's
  rectangle arm has its joint a on the x3-axis, so its axis is ∥ y3 and legs b, c carry the x3-axes. We pick
  the ψ-row and the φ-row from the axis table instead of by leg name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_points, as_rotation, as_vector, rot_x, rot_y

Layout = Literal["equilateral", "right_isosceles", "rectangle"]

#: Revolute-axis table of Fig. 5.25 in frame 3: rows (a_i1, a_i2) for α, β, γ.
AXIS_TABLE: dict[str, FloatArray] = {
    "equilateral": np.array([[1.0, 0.0], [-0.5, np.sqrt(3) / 2], [-0.5, -np.sqrt(3) / 2]]),
    "right_isosceles": np.array([[1.0, 0.0], [0.0, 1.0], [-np.sqrt(2) / 2, -np.sqrt(2) / 2]]),
    "rectangle": np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]),
}

#: Constraint residual [-] below which an orientation counts as an exact solution of (5.31).
ORIENTATION_TOL = 1e-10


@dataclass(frozen=True)
class Orientation:
    """A passive orientation of the mobile disc.

    Attributes:
        R: R_0^3.
        residual: max_i |η̂_i^T R u_i| (unit η̂), the violation of (5.31) [-].
        psi: ψ [rad] of the book's R(y, ψ) R(x, φ) (None for the exact solver).
        phi: φ [rad] (None for the exact solver).
    """

    R: FloatArray
    residual: float
    psi: float | None = None
    phi: float | None = None


@dataclass(frozen=True)
class PlatformPose:
    """Pose of the mobile disc with its legs.

    Attributes:
        o3: origin of frame 3 [length unit].
        R03: orientation of frame 3.
        top: the Top point p_0^t = o3 + d4 z_0^3 [length unit].
        vectors: leg vectors l_0^i (5.42 corrected) [length unit], shape (3, 3).
        lengths: leg lengths [length unit], shape (3,).
        residual: constraint residual (orientation for the I-K, all six equations for the F-K).
    """

    o3: FloatArray
    R03: FloatArray
    top: FloatArray
    vectors: FloatArray
    lengths: FloatArray
    residual: float


@dataclass(frozen=True)
class UPRPlatform:
    """A 3-UPR platform (Fig. 5.24).

    Attributes:
        base_points: p_0^a, p_0^b, p_0^c [length unit], shape (3, 3), base frame.
        top_points: p_3^a, p_3^b, p_3^c [length unit], shape (3, 3), frame 3 (z = 0).
        axes: revolute-axis unit vectors p_3^α, p_3^β, p_3^γ in frame 3, shape (3, 3); default: tangential,
            ``z3 × p_3^i / ‖p_3^i‖``, the only direction that is ⟂ z3 and ⟂ p_3^i as (5.31) requires.
        d4: height of the Top point above the origin of frame 3 [length unit].
        unit: length unit label.

    Raises:
        MechanismError: non-finite or collinear points, top points off the x3-y3 plane, an axis not a unit
            vector ⟂ z3 and ⟂ its joint point, negative d4.
    """

    base_points: FloatArray
    top_points: FloatArray
    axes: FloatArray | None = None
    d4: float = 0.0
    unit: str = "m"

    def __post_init__(self) -> None:
        base = as_points(self.base_points, "base points")
        top = as_points(self.top_points, "top points")
        if base.shape != (3, 3) or top.shape != (3, 3):
            raise MechanismError("a 3-leg platform needs exactly 3 base and 3 top points")
        for label, pts in (("base", base), ("top", top)):
            if np.linalg.matrix_rank(pts - pts.mean(axis=0), tol=1e-9) < 2:
                raise MechanismError(f"{label} points are collinear or coincident: {pts.tolist()}")
        if np.any(np.abs(top[:, 2]) > 1e-12):
            raise MechanismError("top points must lie in the x3-y3 plane (z = 0)")
        if np.any(np.linalg.norm(top, axis=1) < 1e-12):
            raise MechanismError("a top joint at the origin of frame 3 has no defined revolute axis")
        if self.axes is None:
            axes = np.cross([0.0, 0.0, 1.0], top)
            axes /= np.linalg.norm(axes, axis=1)[:, None]
        else:
            axes = as_points(self.axes, "axes")
            if axes.shape != (3, 3):
                raise MechanismError("axes: expected three axis vectors")
            bad = (
                (np.abs(np.linalg.norm(axes, axis=1) - 1.0) > 1e-9)
                | (np.abs(axes[:, 2]) > 1e-9)
                | (np.abs(np.sum(axes * top, axis=1)) > 1e-9)
            )
            if np.any(bad):
                raise MechanismError(
                    f"axes {np.flatnonzero(bad).tolist()} must be unit vectors perpendicular to z3 and to "
                    "their joint points (5.31)"
                )
        if not (np.isfinite(self.d4) and self.d4 >= 0):
            raise MechanismError(f"d4 must be a non-negative number, got {self.d4}")
        object.__setattr__(self, "base_points", base)
        object.__setattr__(self, "top_points", top)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "d4", float(self.d4))

    @property
    def joint_axes(self) -> FloatArray:
        """The revolute axes of the top joints, shape (3, 3) (always set once constructed)."""
        if self.axes is None:  # unreachable after __post_init__
            raise MechanismError("the platform's joint axes are not set")
        return self.axes

    @classmethod
    def book_layout(
        cls, layout: Layout, base_radius: float, top_radius: float, d4: float = 0.0, unit: str = "m"
    ) -> UPRPlatform:
        """One of the three revolute-joint layouts of Fig. 5.25 with the axes of the book's table.

        The axes u_i are the table's (a_i1, a_i2); the joints sit at the feet of the perpendiculars from the
        disc centre onto the axis lines, ``p_3^i = r (u_i × z3)`` (the incircle of the axis triangle), and the
        base joints in the same directions at ``base_radius``.

        Args:
            layout: ``"equilateral"``, ``"right_isosceles"`` or ``"rectangle"``.
            base_radius: distance of the base joints from the base origin [length unit].
            top_radius: distance of the top joints from the origin of frame 3 [length unit].
            d4: Top-point height [length unit].
            unit: length unit label.
        """
        if layout not in AXIS_TABLE:
            raise MechanismError(f"unknown layout {layout!r}; choose one of {sorted(AXIS_TABLE)}")
        if not (base_radius > 0 and top_radius > 0):
            raise MechanismError("radii must be positive")
        axes = np.column_stack([AXIS_TABLE[layout], np.zeros(3)])
        radial = np.cross(axes, [0.0, 0.0, 1.0])
        return cls(base_radius * radial, top_radius * radial, axes, d4, unit)

    # ------------------------------------------------------------------ orientation
    def _eta(self, top: FloatArray) -> FloatArray:
        return top - self.base_points  # (5.34), rows η^α, η^β, η^γ

    def orientation_residual(self, top: ArrayLike, R03: ArrayLike) -> float:
        """max_i |η̂_iᵀ R_0^3 u_i| — the violation of (5.31) [-] (η̂ = η/‖η‖)."""
        eta = self._eta(np.asarray(top, dtype=float))
        eta = eta / np.linalg.norm(eta, axis=1)[:, None]
        return float(np.max(np.abs(np.sum(eta * (self.axes @ np.asarray(R03).T), axis=1))))

    def book_orientation(self, top: ArrayLike) -> Orientation:
        """The chapter's closed form: R_0^3 = R(y, ψ) R(x, φ) from (5.32)–(5.38).

        ψ = arctan(b_1/b_3) (5.36) from the leg whose axis is ∥ x3; φ from a leg whose axis is ∥ y3 by (5.37),
        otherwise from the 2×2 system (5.38) of the remaining two legs (with γ11, γ13 corrected) as
        φ = atan2(sin φ, cos φ). See the module docstring for where this is only approximate.

        Args:
            top: p_0^t [length unit].

        Raises:
            MechanismError: no leg has its axis along x3 (the closed form does not apply), b_3 = 0, or a
                singular 2×2 system.
        """
        top = as_vector(top, 3, "top point")
        a = self.joint_axes[:, :2]
        eta = self._eta(top)
        rows_x = [i for i in range(3) if abs(a[i, 1]) < 1e-12]
        if not rows_x:
            raise MechanismError("the book's closed form needs a leg whose revolute axis is along x3")
        i = rows_x[0]
        b1, _, b3 = eta[i]
        if abs(b3) < 1e-12:
            raise MechanismError("ψ undefined: the Top point is level with a base joint (b3 = 0 in (5.36))")
        psi = float(np.arctan(b1 / b3))  # (5.36), ψ in (−90°, 90°)
        cps, sps = np.cos(psi), np.sin(psi)
        others = [j for j in range(3) if j != i]
        # Row j: a_j1 (b1 cψ − b3 sψ) + a_j2 [(b1 sψ + b3 cψ) sφ + b2 cφ] = 0.
        coef = np.array([[a[j, 1] * (eta[j, 0] * sps + eta[j, 2] * cps), a[j, 1] * eta[j, 1]] for j in others])
        rhs = np.array([-a[j, 0] * (eta[j, 0] * cps - eta[j, 2] * sps) for j in others])
        pure_y = [k for k, j in enumerate(others) if abs(a[j, 0]) < 1e-12 and abs(a[j, 1]) > 1e-12]
        if pure_y:
            k = pure_y[0]  # (5.37): φ = arctan(−b2 / (b1 sψ + b3 cψ))
            den = eta[others[k], 0] * sps + eta[others[k], 2] * cps
            if abs(den) < 1e-12:
                raise MechanismError("φ undefined in (5.37): zero denominator")
            phi = float(np.arctan(-eta[others[k], 1] / den))
        else:
            if abs(np.linalg.det(coef)) < 1e-12:
                raise MechanismError("the 2x2 matrix of (5.38) is singular at this Top point")
            s, c = np.linalg.solve(coef, rhs)  # (5.38)
            phi = float(np.arctan2(s, c))
        R = rot_y(psi) @ rot_x(phi)  # (5.35)
        return Orientation(R, self.orientation_residual(top, R), psi, phi)

    def exact_orientation(self, top: ArrayLike, guess: ArrayLike | None = None) -> Orientation:
        """Solve the three equations (5.31) η_iᵀ R_0^3 u_i = 0 exactly on SO(3) (spin allowed).

        Starts from ``guess`` if given, else from the closed form when it applies (exact for the rectangle),
        else from the identity; the answer is the branch nearest the start.

        Raises:
            MechanismError: no solution reached (residual above :data:`ORIENTATION_TOL`).
        """
        top = as_vector(top, 3, "top point")
        eta = self._eta(top)
        eta = eta / np.linalg.norm(eta, axis=1)[:, None]
        if guess is not None:
            R0 = as_rotation(guess, "guess")
        else:
            try:
                book = self.book_orientation(top)
            except MechanismError:
                R0 = np.eye(3)
            else:
                if book.residual < 1e-14:
                    return Orientation(book.R, book.residual)
                R0 = book.R

        def fun(phi: FloatArray) -> FloatArray:
            R = Rotation.from_rotvec(phi).as_matrix() @ R0
            return np.sum(eta * (self.axes @ R.T), axis=1)

        res = least_squares(fun, np.zeros(3), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        R = Rotation.from_rotvec(res.x).as_matrix() @ R0
        residual = self.orientation_residual(top, R)
        if residual > ORIENTATION_TOL:
            raise MechanismError(f"no passive orientation satisfies (5.31) at this Top point (residual {residual:.3g})")
        return Orientation(R, residual)

    # ------------------------------------------------------------------ legs and F-K
    def legs(self, top: ArrayLike, R03: ArrayLike) -> PlatformPose:
        """Leg vectors by the corrected (5.42): l_0^i = p_0^t − d4 z_0^3 + R_0^3 p_3^i − p_0^i.

        Args:
            top: p_0^t [length unit].
            R03: R_0^3 (e.g. from :meth:`exact_orientation`).
        """
        top = as_vector(top, 3, "top point")
        R03 = as_rotation(R03, "R03")
        o3 = top - self.d4 * R03[:, 2]
        vectors = o3 + self.top_points @ R03.T - self.base_points
        lengths = np.linalg.norm(vectors, axis=1)
        if np.any(lengths < 1e-9):
            raise MechanismError("a leg has zero length at this Top point")
        return PlatformPose(o3, R03, top, vectors, lengths, self.orientation_residual(top, R03))

    def inverse_kinematics(
        self, top: ArrayLike, method: Literal["exact", "book"] = "exact", guess: ArrayLike | None = None
    ) -> PlatformPose:
        """Passive orientation and legs for a Top point (steps 2–4 of the chapter's procedure).

        Args:
            top: p_0^t [length unit].
            method: ``"exact"`` (all of (5.31)) or ``"book"`` (closed form (5.35)–(5.38)).
            guess: branch hint for the exact solver.
        """
        orient = self.exact_orientation(top, guess) if method == "exact" else self.book_orientation(top)
        return self.legs(top, orient.R)

    def constraint_residuals(self, o3: FloatArray, R03: FloatArray, lengths: FloatArray) -> FloatArray:
        """Six F-K equations: ‖l_i‖ − q_i and l_iᵀ R u_i (leg ⟂ revolute axis), [length unit]."""
        vec = o3 + self.top_points @ R03.T - self.base_points
        return np.r_[np.linalg.norm(vec, axis=1) - lengths, np.sum(vec * (self.axes @ R03.T), axis=1)]

    def forward_kinematics(
        self,
        lengths: ArrayLike,
        starts: int = 24,
        seed: int = 0,
        initial: list[tuple[ArrayLike, ArrayLike]] | None = None,
        tol: float = 1e-10,
    ) -> list[PlatformPose]:
        """Mobile-disc poses for three leg lengths — every distinct assembly above the base found.

        This is the chapter's "upside-down Stewart" problem (each base joint lies on a circle of radius q_i
        about A_3 in the plane ⟂ u_i); it is solved here directly by least squares on the six equations of
        :meth:`constraint_residuals` from ``initial`` poses and ``starts`` generated ones.

        Args:
            lengths: q_1, q_2, q_3 [length unit].
            starts: number of generated initial poses.
            seed: random seed of the generated poses.
            initial: extra initial poses (o3, R03), tried first.
            tol: acceptance threshold on the residual norm [length unit].

        Returns:
            Solutions with o3_z > 0, best residual first.

        Raises:
            MechanismError: bad lengths or no assembly.
        """
        q = as_vector(lengths, 3, "leg lengths")
        if np.any(q <= 0):
            raise MechanismError(f"leg lengths must be positive, got {q.tolist()}")
        guesses = [(as_vector(p, 3, "initial o3"), as_rotation(R, "initial R03")) for p, R in (initial or [])]
        rng = np.random.default_rng(seed)
        for k in range(starts):
            h = float(np.mean(q)) * (1.0 if k % 2 == 0 else 0.6)
            tilt = Rotation.from_rotvec(0.3 * rng.normal(size=3)).as_matrix() if k >= 2 else np.eye(3)
            guesses.append((np.r_[0.2 * rng.normal(size=2), h], tilt))
        found: list[PlatformPose] = []
        best = np.inf
        for p0, R0 in guesses:

            def fun(x: FloatArray, R0: FloatArray = R0) -> FloatArray:
                return self.constraint_residuals(x[:3], Rotation.from_rotvec(x[3:]).as_matrix() @ R0, q)

            res = least_squares(fun, np.r_[p0, 0.0, 0.0, 0.0], method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
            o3, R = res.x[:3], Rotation.from_rotvec(res.x[3:]).as_matrix() @ R0
            residual = float(np.linalg.norm(self.constraint_residuals(o3, R, q)))
            best = min(best, residual)
            if residual > tol or o3[2] <= 0:
                continue
            if any(np.linalg.norm(s.o3 - o3) + np.linalg.norm(s.R03 - R) < 1e-6 for s in found):
                continue
            vec = o3 + self.top_points @ R.T - self.base_points
            found.append(PlatformPose(o3, R, o3 + self.d4 * R[:, 2], vec, np.linalg.norm(vec, axis=1), residual))
        if not found:
            raise MechanismError(
                f"legs {q.tolist()} admit no assembly of the 3-leg platform: smallest residual {best:.3g}"
            )
        found.sort(key=lambda s: round(s.residual, 12))
        return found
