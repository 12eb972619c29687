"""Stewart platform forward kinematics: the chapter's three-circle grid search and an exact solver.

* :func:`grid_search_fk` reproduces the MATLAB listing of section 5.4.1 (eqs. (5.19)–(5.24)): each top joint
  of a 3-3 (or 6-3) platform moves on a circle about its two base joints, and a 201³ grid over the three circle
  angles θ_i is searched for a triangle whose sides match the top disc within 0.01. Deviation from the print:
  the prose says the search starts at 10°, the listing (and the printed θ) at 5° = π/36; we follow the listing.
  The grid answer's ``R06 = P0·P6⁻¹`` (5.24) is *not* an exact rotation (the triangle is only matched within
  the grid tolerance); its leg lengths are nevertheless exact because the joint points lie on the circles.
* :func:`forward_kinematics` solves the six leg-length equations ‖R p_6^i + p − p_0^i‖ = q_i exactly with
  :func:`scipy.optimize.least_squares` from many initial poses, parametrising R on SO(3) (always a proper
  rotation), and returns every distinct assembly it finds, best residual first. For a 3-3 / 6-3 platform each
  answer also carries the circle angles θ1–θ3 of its top joints (:func:`circle_angles`), as the listing prints
  them for its grid answer: :func:`circle_points` rebuilds the joints from them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_vector, left_jacobian_so3, rot_z
from redundik.parallel.stewart import StewartPlatform

#: Residual [length unit] (Euclidean norm over the six legs) below which an FK solution is accepted.
FK_TOL = 1e-9

HalfSpace = Literal["above", "below", "any"]


@dataclass(frozen=True)
class FKSolution:
    """One assembly of the platform.

    Attributes:
        p: p_0^6 [length unit], shape (3,).
        R: R_0^6 (a proper rotation for the exact solver; only approximately one for the grid search).
        residual: ‖q(p, R) − q_given‖ for the exact solver; for the grid search the norm of the top-triangle
            side errors [length unit] (the leg lengths of a grid answer are exact by construction).
        theta: the three circle angles θ1–θ3 [deg] of the top joints on their circles (5.19)–(5.21), for a
            platform with three top joints (3-3, 6-3): the grid point for the grid search, the exact angles for
            the exact solver (in (−180°, 180°]; a joint above the base plane has θ in (0°, 180°)); ``None`` for a
            6-6 platform.
    """

    p: FloatArray
    R: FloatArray
    residual: float
    theta: FloatArray | None = None


def _check_lengths(lengths: ArrayLike) -> FloatArray:
    q = as_vector(lengths, 6, "leg lengths")
    if np.any(q <= 0):
        raise MechanismError(f"leg lengths must be positive, got {q.tolist()}")
    return q


# ---------------------------------------------------------------------------------------------- grid search
def _circles(platform: StewartPlatform, q: FloatArray) -> list[tuple[FloatArray, FloatArray, FloatArray, float]]:
    """Circle (centre Q_j, in-plane unit u_j, base normal, radius h_j) of each top joint (5.19)–(5.21)."""
    if len(platform.top_points) != 3:
        raise MechanismError(
            f"the three-circle grid search needs 3 top joints (3-3 or 6-3 platform), got a {platform.kind}"
        )
    circles = []
    for j in range(3):
        legs = [i for i, (t, _) in enumerate(platform.legs) if t == j]
        if len(legs) != 2:
            raise MechanismError(f"top joint {j} must carry exactly two legs, carries {len(legs)}")
        i1, i2 = legs
        P, Q = platform.leg_base[i1], platform.leg_base[i2]
        base_len = float(np.linalg.norm(Q - P))
        l1, l2 = q[i1], q[i2]
        cos_a = (l1**2 + base_len**2 - l2**2) / (2.0 * l1 * base_len)  # law of cosines
        if abs(cos_a) >= 1.0:
            raise MechanismError(
                f"legs {i1 + 1} and {i2 + 1} ({l1:g}, {l2:g}) cannot meet above a base line of length "
                f"{base_len:g}: triangle inequality violated"
            )
        e = (Q - P) / base_len
        u = np.cross([0.0, 0.0, 1.0], e)
        if np.linalg.norm(u) < 1e-12:
            raise MechanismError("a base line is vertical; the grid search needs base lines in the x-y plane")
        u /= np.linalg.norm(u)
        circles.append((P + l1 * cos_a * e, u, np.array([0.0, 0.0, 1.0]), l1 * np.sqrt(1.0 - cos_a**2)))
    return circles


def circle_points(platform: StewartPlatform, lengths: ArrayLike, theta: ArrayLike) -> FloatArray:
    """The top joints at circle angles θ1–θ3 [deg]: row j is ``Q_j + h_j (cos θ_j u_j + sin θ_j z_0)`` (5.19)–(5.21).

    Args:
        platform: a platform with three top joints, each shared by two legs (3-3, 6-3).
        lengths: the six leg lengths q_i [length unit].
        theta: the three circle angles [deg].

    Returns:
        The three joint points in the base frame [length unit], shape (3, 3).

    Raises:
        MechanismError: wrong platform type, or a leg pair violating the triangle inequality.
    """
    angles = np.radians(as_vector(theta, 3, "circle angles"))
    circles = _circles(platform, _check_lengths(lengths))
    return np.stack([c + h * (np.cos(a) * u + np.sin(a) * z) for (c, u, z, h), a in zip(circles, angles, strict=True)])


def circle_angles(platform: StewartPlatform, lengths: ArrayLike, p: ArrayLike, R: ArrayLike) -> FloatArray:
    """The circle angles θ1–θ3 [deg] of the top joints of the pose (p, R): the inverse of :func:`circle_points`.

    θ_j = atan2((w_j − Q_j)·z_0, (w_j − Q_j)·u_j) for the joint w_j = R p_6^j + p, in (−180°, 180°]. Exact when the
    pose assembles the legs (then w_j lies on its circle); otherwise the angle of w_j's projection on the circle's
    plane.

    Raises:
        MechanismError: wrong platform type, or a leg pair violating the triangle inequality.
    """
    circles = _circles(platform, _check_lengths(lengths))
    world = platform.top_points @ np.asarray(R, dtype=float).T + as_vector(p, 3, "p")
    return np.degrees([np.arctan2((w - c) @ z, (w - c) @ u) for w, (c, u, z, _) in zip(world, circles, strict=True)])


def grid_search_fk(
    platform: StewartPlatform,
    lengths: ArrayLike,
    start: float = np.pi / 36.0,
    step: float = np.radians(0.8),
    samples: int = 201,
    tol: float = 0.01,
) -> FKSolution:
    """The chapter's three-circle grid search for a 3-3 / 6-3 platform (5.19)–(5.24).

    Top joint j lies on the circle ``Q_j + h_j (cos θ_j u_j + sin θ_j z_0)`` (u_j: horizontal, normal to its
    base line, as in (5.19)); the listing scans θ_j = start + k·step, k = 0 … 200 in the nested order
    (θ1, θ2, θ3), keeps the first triple whose three top-side lengths match within ``tol`` and returns
    ``p06 = (pa6 + pb6 + pc6)/3`` (5.23) (generalised to the top-point centroid) and ``R06 = P0 P6⁻¹`` (5.24).

    Args:
        platform: a platform with three top joints, each shared by two legs.
        lengths: the six leg lengths q_i [length unit].
        start: first angle [rad]; the listing uses π/36 = 5° (the prose's 10° is an erratum).
        step: grid step [rad] (0.8°).
        samples: grid points per angle (201: ``while i<=200``).
        tol: side-length tolerance [length unit] (0.01).

    Raises:
        MechanismError: wrong platform type, a leg pair violating the triangle inequality, or no grid point
            within tolerance.
    """
    q = _check_lengths(lengths)
    circles = _circles(platform, q)
    theta = start + step * np.arange(samples)
    pts = []
    for centre, u, z, h in circles:
        pts.append(centre + h * (np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * z))  # (N, 3)
    top = platform.top_points
    side = {(a, b): float(np.linalg.norm(top[a] - top[b])) for a in range(3) for b in range(3)}

    def ok(a: int, b: int) -> np.ndarray:
        d = np.linalg.norm(pts[a][:, None, :] - pts[b][None, :, :], axis=2)
        return np.abs(d - side[(a, b)]) < tol

    ab, ac, bc = ok(0, 1), ok(0, 2), ok(1, 2)  # indices (i, j), (i, k), (j, k)
    hit = ab[:, :, None] & ac[:, None, :] & bc[None, :, :]
    found = np.argwhere(hit)  # C order == the listing's loop order
    if len(found) == 0:
        raise MechanismError(f"grid search found no assembly for legs {q.tolist()} (tolerance {tol:g})")
    i, j, k = found[0]
    world = np.stack([pts[0][i], pts[1][j], pts[2][k]])
    centroid_w, centroid_t = world.mean(axis=0), top.mean(axis=0)
    a0, c0 = world[0] - centroid_w, world[2] - centroid_w
    a6, c6 = top[0] - centroid_t, top[2] - centroid_t
    P0 = np.column_stack([a0, c0, np.cross(a0, c0)])
    P6 = np.column_stack([a6, c6, np.cross(a6, c6)])
    R = P0 @ np.linalg.inv(P6)
    p = centroid_w - R @ centroid_t
    side_err = [np.linalg.norm(world[a] - world[b]) - side[(a, b)] for a, b in ((0, 1), (1, 2), (2, 0))]
    return FKSolution(p, R, float(np.linalg.norm(side_err)), np.degrees(theta[[i, j, k]]))


# ---------------------------------------------------------------------------------------------- exact solver
def _initial_guesses(platform: StewartPlatform, q: FloatArray, count: int, seed: int) -> list[FloatArray]:
    """Deterministic + seeded random starting poses x = (p, rotvec)."""
    height = float(np.mean(q))
    guesses = []
    for yaw in np.radians(np.arange(0.0, 360.0, 60.0)):
        for sign in (1.0, -1.0):
            guesses.append(np.r_[0.0, 0.0, sign * height, Rotation.from_matrix(rot_z(yaw)).as_rotvec()])
    rng = np.random.default_rng(seed)
    scale = float(np.max(np.abs(platform.base_points))) + height
    while len(guesses) < count:
        p = rng.normal(scale=0.5 * scale, size=3)
        guesses.append(np.r_[p, Rotation.random(random_state=rng).as_rotvec()])
    return guesses[:count]


def _solve_from(platform: StewartPlatform, q: FloatArray, x0: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Least squares on the leg lengths around the pose x0 = (p, rotvec); R = exp(φ) R_0 on SO(3)."""
    R0 = Rotation.from_rotvec(x0[3:]).as_matrix()
    top, base = platform.leg_top, platform.leg_base

    def fun(x: FloatArray) -> FloatArray:
        R = Rotation.from_rotvec(x[3:]).as_matrix() @ R0
        return np.linalg.norm(top @ R.T + x[:3] - base, axis=1) - q

    def jac(x: FloatArray) -> FloatArray:
        R = Rotation.from_rotvec(x[3:]).as_matrix() @ R0
        arm = top @ R.T
        vec = arm + x[:3] - base
        units = vec / np.maximum(np.linalg.norm(vec, axis=1), 1e-300)[:, None]
        # d‖l‖/dφ = rᵀ (−[R p6]×) J_l(φ) = (R p6 × r)ᵀ J_l(φ): the rows of J0ᵀ (5.28) times J_l
        return np.hstack([units, np.cross(arm, units) @ left_jacobian_so3(x[3:])])

    x = np.r_[x0[:3], 0.0, 0.0, 0.0]
    for _ in range(2):  # second pass re-centres the rotation parametrisation to polish to machine precision
        res = least_squares(fun, x, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=400)
        R0 = Rotation.from_rotvec(res.x[3:]).as_matrix() @ R0
        x = np.r_[res.x[:3], 0.0, 0.0, 0.0]
    return x[:3], R0


def forward_kinematics(
    platform: StewartPlatform,
    lengths: ArrayLike,
    starts: int = 48,
    seed: int = 0,
    half_space: HalfSpace = "above",
    initial: list[tuple[ArrayLike, ArrayLike]] | None = None,
    tol: float = FK_TOL,
) -> list[FKSolution]:
    """Exact forward kinematics of any 3-3 / 6-3 / 6-6 platform: every distinct assembly found.

    Solves ``‖R p_6^i + p − p_0^i‖ = q_i`` (the norms of (5.18)/(5.25)) by Levenberg–Marquardt
    (:func:`scipy.optimize.least_squares`) from ``starts`` initial poses (12 yaw/height seeds plus seeded
    random poses) and from any ``initial`` poses, with R = exp(φ)·R_start so every answer is a proper rotation.
    Converged answers (residual < ``tol``) are de-duplicated (‖Δp‖ + ‖ΔR‖_F < 1e-6) and sorted by residual,
    then by height. This is a multi-start search, not a certificate that all (up to 40) assemblies were found.

    Args:
        platform: the platform.
        lengths: leg lengths q_1 … q_6 [length unit].
        starts: number of generated initial poses.
        seed: random seed for the generated poses (results are deterministic).
        half_space: keep assemblies with the top origin above (p_z > 0), below, or on any side of the base
            plane (for planar base and top each assembly has a mirror image below the base).
        initial: extra initial poses ``(p, R)`` tried first (e.g. the previous sample of a trajectory).
        tol: acceptance threshold on the leg residual [length unit].

    Returns:
        The solutions, best first.

    Raises:
        MechanismError: non-positive / non-finite lengths, or no assembly (the message gives the smallest
            residual reached).
    """
    q = _check_lengths(lengths)
    guesses = [
        np.r_[as_vector(p, 3, "initial p"), Rotation.from_matrix(np.asarray(R, dtype=float)).as_rotvec()]
        for p, R in (initial or [])
    ]
    guesses += _initial_guesses(platform, q, starts, seed)
    found: list[FKSolution] = []
    best = np.inf
    three_circles = len(platform.top_points) == 3 and all(sum(t == j for t, _ in platform.legs) == 2 for j in range(3))
    for x0 in guesses:
        p, R = _solve_from(platform, q, x0)
        residual = float(np.linalg.norm(platform._legs(p, R).lengths - q)) if np.all(np.isfinite(p)) else np.inf
        best = min(best, residual)
        if residual > tol:
            continue
        if (half_space == "above" and p[2] <= 0) or (half_space == "below" and p[2] >= 0):
            continue
        if any(np.linalg.norm(s.p - p) + np.linalg.norm(s.R - R) < 1e-6 for s in found):
            continue
        theta = circle_angles(platform, q, p, R) if three_circles else None
        found.append(FKSolution(p, R, residual, theta))
    if not found:
        where = {"above": " above the base", "below": " below the base", "any": ""}[half_space]
        raise MechanismError(
            f"legs {q.tolist()} admit no assembly{where}: smallest leg residual reached {best:.3g} "
            f"{platform.unit} over {len(guesses)} starts"
        )
    found.sort(key=lambda s: (round(s.residual, 12), -abs(s.p[2])))
    return found


def nearest_solution(solutions: list[FKSolution], p: ArrayLike, R: ArrayLike) -> FKSolution:
    """The solution closest to a reference pose (‖Δp‖ + ‖ΔR‖_F)."""
    p, R = np.asarray(p, dtype=float), np.asarray(R, dtype=float)
    return min(solutions, key=lambda s: float(np.linalg.norm(s.p - p) + np.linalg.norm(s.R - R)))


__all__ = ["FKSolution", "circle_angles", "circle_points", "forward_kinematics", "grid_search_fk", "nearest_solution"]
