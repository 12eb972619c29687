"""The 3+3 hybrid arm (UPR platform + RRR wrist) of section 5.4.3 and computer project 2 of section 5.5.

Wrist D-H (the one-step matrices before (5.39)): A_3^4 (θ4, d4, α = −90°), A_4^5 (θ5, d5, α = +90°),
A_5^6 (θ6, d6, α = 0), so that (5.39)

    R_3^6 = [[c4c5c6 − s4s6, −c4c5s6 − s4c6, c4s5], [s4c5c6 + c4s6, −s4c5s6 + c4c6, s4s5], [−s5c6, s5s6, c5]]
    p_3^6 = (d6c4s5 − d5s4, d6s4s5 + d5c4, d6c5 + d4).

The chapter's six-step I-K (after (5.42)) needs the Top point p_0^t = p_0^6 − d6 z_0^6 − d5 y_0^5 (5.41),
and y_0^5 = R_0^6 (sin θ6, cos θ6, 0) depends on θ6, which is only known at the end (step 6). The book
therefore uses the previous sample's θ6 ("lagged" scheme, :meth:`Hybrid33Arm.ik_book`), so its joints reproduce
the commanded pose only up to d5·|Δθ6|.

Self-consistent reading (documented deviation): the home pose of project 2 gives p_0^6, R_0^6 = I *and*
θ6(h) = 0, which is over-specified — step 6 does not return θ6 = 0 there. We read (p_0^6, R_0^6) as the pose
(six numbers for six joints) and θ6(h) = 0 only as the book's initial value of its lag. The exact I-K
(:meth:`Hybrid33Arm.ik_exact`) solves the scalar fixed point θ6 = step6(step1…5(θ6)) by a scan plus
:func:`scipy.optimize.brentq`, one root per wrist branch (sin θ5 > 0: ``branch=+1``, the book's formulas;
sin θ5 < 0: ``branch=−1``); there is no lag and the F-K round trip is exact.

Step 6 is evaluated as θ4 = atan2(b R23, b R13), θ5 = atan2(b·√(R13² + R23²), R33), θ6 = atan2(b R32, −b R31)
(b = ±1); for b = +1 this equals the printed θ5 = atan2(R13/cos θ4, R33) without dividing by cos θ4.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_rotation, as_vector, rotation_angle_between, wrap_angle
from redundik.parallel.upr import UPRPlatform

Branch = Literal[1, -1]


@dataclass(frozen=True)
class HybridIK:
    """Joint solution of the 3+3 arm.

    Attributes:
        lengths: l_1, l_2, l_3 [length unit].
        vectors: leg vectors l_0^i [length unit], shape (3, 3).
        theta: θ4, θ5, θ6 [rad].
        R03: passive orientation of the mobile disc.
        o3: origin of frame 3 [length unit].
        top: the Top point p_0^t used (5.41) [length unit].
        theta6_used: the θ6 that fixed the Top point [rad] (the previous θ6 for the book scheme).
        lag: wrap(θ6 − θ6_used) [rad]; 0 for a self-consistent solution.
        orientation_residual: violation of (5.31) by R03 [-].
    """

    lengths: FloatArray
    vectors: FloatArray
    theta: FloatArray
    R03: FloatArray
    o3: FloatArray
    top: FloatArray
    theta6_used: float
    lag: float
    orientation_residual: float

    @property
    def joints(self) -> FloatArray:
        """(l1, l2, l3, θ4, θ5, θ6) [length unit ×3, rad ×3]."""
        return np.r_[self.lengths, self.theta]


@dataclass(frozen=True)
class ArmPose:
    """A forward-kinematics answer: tool frame 6 and the mobile disc."""

    p: FloatArray
    R: FloatArray
    o3: FloatArray
    R03: FloatArray
    residual: float


def wrist_angles(R36: ArrayLike, branch: Branch = 1) -> FloatArray:
    """θ4, θ5, θ6 [rad] from R_3^6 by comparison with (5.39) (step 6).

    Args:
        R36: the wrist rotation R_3^6.
        branch: +1 for sin θ5 > 0 (the book's formulas), −1 for the other wrist branch.

    Raises:
        MechanismError: bad branch, or the wrist singularity θ5 = π (θ5 = 0 sets θ4 = 0).
    """
    if branch not in (1, -1):
        raise MechanismError(f"branch must be +1 or -1, got {branch!r}")
    R = np.asarray(R36, dtype=float)
    s5 = branch * float(np.hypot(R[0, 2], R[1, 2]))
    if abs(s5) < 1e-12:
        if R[2, 2] < 0:
            raise MechanismError("wrist singular at θ5 = 180°")
        return np.array([0.0, 0.0, float(np.arctan2(R[1, 0], R[0, 0]))])
    return np.array(
        [
            np.arctan2(branch * R[1, 2], branch * R[0, 2]),
            np.arctan2(s5, R[2, 2]),
            np.arctan2(branch * R[2, 1], -branch * R[2, 0]),
        ]
    )


@dataclass(frozen=True)
class Hybrid33Arm:
    """UPR 3-leg platform carrying an RRR wrist (Fig. 5.26, 5.29).

    Attributes:
        platform: the 3-leg platform; its ``d4`` is the wrist's first offset.
        d5: wrist offset d5 [length unit].
        d6: tool offset d6 [length unit].
    """

    platform: UPRPlatform
    d5: float
    d6: float

    def __post_init__(self) -> None:
        for name in ("d5", "d6"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise MechanismError(f"{name} must be a non-negative number, got {value}")

    @classmethod
    def project2(cls) -> Hybrid33Arm:
        """The rectangle-configuration arm of computer project 2 (section 5.5.1), lengths in m."""
        platform = UPRPlatform(
            base_points=np.array([[1.2, 0.0, 0.0], [0.0, 0.8, 0.0], [0.0, -0.8, 0.0]]),
            top_points=np.array([[0.6, 0.0, 0.0], [0.0, 0.4, 0.0], [0.0, -0.4, 0.0]]),
            d4=0.6,
        )
        return cls(platform, d5=0.2, d6=0.4)

    # ------------------------------------------------------------------ wrist and Top point
    def wrist(self, theta: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """R_3^6 and p_3^6 [length unit] of (5.39) for θ4, θ5, θ6 [rad]."""
        t4, t5, t6 = as_vector(theta, 3, "theta")
        c4, s4, c5, s5, c6, s6 = np.cos(t4), np.sin(t4), np.cos(t5), np.sin(t5), np.cos(t6), np.sin(t6)
        R = np.array(
            [
                [c4 * c5 * c6 - s4 * s6, -c4 * c5 * s6 - s4 * c6, c4 * s5],
                [s4 * c5 * c6 + c4 * s6, -s4 * c5 * s6 + c4 * c6, s4 * s5],
                [-s5 * c6, s5 * s6, c5],
            ]
        )
        d4, d5, d6 = self.platform.d4, self.d5, self.d6
        p = np.array([d6 * c4 * s5 - d5 * s4, d6 * s4 * s5 + d5 * c4, d6 * c5 + d4])
        return R, p

    def top_point(self, p06: ArrayLike, R06: ArrayLike, theta6: float) -> FloatArray:
        """p_0^t = p_0^6 − d6 z_0^6 − d5 y_0^5 with y_0^5 = R_0^6 (sin θ6, cos θ6, 0) (5.41) [length unit]."""
        p06, R06 = np.asarray(p06, dtype=float), np.asarray(R06, dtype=float)
        y05 = R06 @ np.array([np.sin(theta6), np.cos(theta6), 0.0])
        return p06 - self.d6 * R06[:, 2] - self.d5 * y05

    # ------------------------------------------------------------------ inverse kinematics
    def _solve(
        self, p06: FloatArray, R06: FloatArray, theta6: float, branch: Branch, orientation: Literal["book", "exact"]
    ) -> HybridIK:
        top = self.top_point(p06, R06, theta6)  # step 1 (5.41)
        pose = self.platform.inverse_kinematics(top, method=orientation)  # steps 2-4 (5.32)-(5.42)
        theta = wrist_angles(pose.R03.T @ R06, branch)  # steps 5-6
        return HybridIK(
            pose.lengths,
            pose.vectors,
            theta,
            pose.R03,
            pose.o3,
            top,
            float(theta6),
            float(wrap_angle(theta[2] - theta6)),
            pose.residual,
        )

    def ik_book(
        self,
        p06: ArrayLike,
        R06: ArrayLike,
        theta6_prev: float,
        branch: Branch = 1,
        orientation: Literal["book", "exact"] = "book",
    ) -> HybridIK:
        """The chapter's six-step I-K with the Top point fixed by the previous θ6 (lagged scheme).

        Args:
            p06: p_0^6 [length unit].
            R06: R_0^6.
            theta6_prev: θ6 of the previous sample [rad] (θ6(0) at t = 0).
            branch: wrist branch of step 6.
            orientation: passive orientation by the book's closed form or the exact (5.31) solver.
        """
        p06 = as_vector(p06, 3, "p06")
        R06 = as_rotation(R06, "R06")
        return self._solve(p06, R06, float(theta6_prev), branch, orientation)

    def _residual(self, p06: FloatArray, R06: FloatArray, branch: Branch) -> Callable[[float], float]:
        def g(theta6: float) -> float:
            return float(self._solve(p06, R06, theta6, branch, "exact").lag)

        return g

    def ik_all(self, p06: ArrayLike, R06: ArrayLike, branch: Branch | None = None, samples: int = 72) -> list[HybridIK]:
        """Every self-consistent I-K solution found (fixed points of θ6 ↦ step6(θ6)) on one or both branches.

        Args:
            p06: p_0^6 [length unit].
            R06: R_0^6.
            branch: restrict to one wrist branch (None: both).
            samples: scan resolution over θ6 ∈ [−π, π).

        Raises:
            MechanismError: no self-consistent solution (unreachable pose).
        """
        p06 = as_vector(p06, 3, "p06")
        R06 = as_rotation(R06, "R06")
        out: list[HybridIK] = []
        grid = np.linspace(-np.pi, np.pi, samples + 1)
        for b in (1, -1) if branch is None else (branch,):
            g = self._residual(p06, R06, b)
            try:
                vals = [g(t) for t in grid]
            except MechanismError:
                continue
            for lo, hi, g_lo, g_hi in zip(grid[:-1], grid[1:], vals[:-1], vals[1:], strict=True):
                if g_lo * g_hi <= 0 and abs(g_hi - g_lo) < np.pi:  # a genuine root, not a wrap jump
                    root = brentq(g, lo, hi, xtol=1e-15, rtol=1e-15) if g_lo != g_hi else lo
                    sol = self._solve(p06, R06, root, b, "exact")
                    if abs(sol.lag) < 1e-10 and not any(
                        abs(float(wrap_angle(s.theta6_used - root))) < 1e-8
                        and np.sign(s.theta[1]) == np.sign(sol.theta[1])
                        for s in out
                    ):
                        out.append(sol)
        if not out:
            raise MechanismError("no self-consistent 3+3 I-K solution for this pose (unreachable?)")
        return out

    def ik_exact(
        self, p06: ArrayLike, R06: ArrayLike, branch: Branch = 1, theta6_hint: float | None = None
    ) -> HybridIK:
        """Self-consistent I-K (no lag in θ6) on wrist ``branch``, the root nearest ``theta6_hint``.

        With a hint (e.g. the previous sample of a path) a bracket of ±0.3 rad about it is tried first; the
        full scan of :meth:`ik_all` is the fallback and the default (then the root with the smallest |θ6|).

        Raises:
            MechanismError: no self-consistent solution on that branch.
        """
        p06 = as_vector(p06, 3, "p06")
        R06 = as_rotation(R06, "R06")
        if theta6_hint is not None:
            g = self._residual(p06, R06, branch)
            for half in (0.05, 0.3):
                lo, hi = theta6_hint - half, theta6_hint + half
                g_lo, g_hi = g(lo), g(hi)
                if g_lo * g_hi < 0 and abs(g_hi - g_lo) < np.pi:
                    root = brentq(g, lo, hi, xtol=1e-15, rtol=1e-15)
                    return self._solve(p06, R06, float(wrap_angle(root)), branch, "exact")
        sols = self.ik_all(p06, R06, branch)
        ref = 0.0 if theta6_hint is None else theta6_hint
        return min(sols, key=lambda s: abs(float(wrap_angle(s.theta6_used - ref))))

    # ------------------------------------------------------------------ forward kinematics
    def forward_kinematics(
        self, lengths: ArrayLike, theta: ArrayLike, hint: tuple[ArrayLike, ArrayLike] | None = None, starts: int = 24
    ) -> list[ArmPose]:
        """Tool poses for leg lengths and wrist angles: platform F-K, then the wrist (5.39).

        Args:
            lengths: l_1, l_2, l_3 [length unit].
            theta: θ4, θ5, θ6 [rad].
            hint: a platform pose (o3, R03) tried first; with a hint the answers are sorted nearest first.
            starts: generated initial poses of the platform F-K.

        Raises:
            MechanismError: the legs admit no assembly.
        """
        R36, p36 = self.wrist(theta)
        plats = self.platform.forward_kinematics(lengths, starts=starts, initial=[hint] if hint else None)
        poses = [ArmPose(s.o3 + s.R03 @ p36, s.R03 @ R36, s.o3, s.R03, s.residual) for s in plats]
        if hint is not None:
            o3, R03 = np.asarray(hint[0], dtype=float), np.asarray(hint[1], dtype=float)
            poses.sort(key=lambda a: float(np.linalg.norm(a.o3 - o3) + np.linalg.norm(a.R03 - R03)))
        return poses


@dataclass(frozen=True)
class PathResult:
    """Computer project 2: joint profiles of the lagged (book) and exact schemes, and their round trips.

    Attributes:
        t: sample times [s], shape (N,).
        p: commanded p_0^6 [length unit], shape (N, 3).
        R: commanded R_0^6, shape (N, 3, 3).
        joints_book: (l1, l2, l3, θ4, θ5, θ6) of the lagged scheme [length unit, rad], shape (N, 6); the
            angles are unwrapped along the path.
        joints_exact: the same for the self-consistent I-K, shape (N, 6).
        lag_book: θ6 − θ6_used of the book scheme [rad], shape (N,).
        roundtrip_book: F-K position error ‖p_FK − p‖ of the book joints [length unit], shape (N,).
        roundtrip_book_angle: F-K orientation error of the book joints [rad], shape (N,).
        roundtrip_exact: F-K position error of the exact joints [length unit], shape (N,).
        roundtrip_exact_angle: F-K orientation error of the exact joints [rad], shape (N,).
        home_book: the book's home solution (θ6 = θ6(h)), answering project 2 (a)–(c).
        home_exact: the self-consistent home solution.
    """

    t: FloatArray
    p: FloatArray
    R: FloatArray
    joints_book: FloatArray
    joints_exact: FloatArray
    lag_book: FloatArray
    roundtrip_book: FloatArray
    roundtrip_book_angle: FloatArray
    roundtrip_exact: FloatArray
    roundtrip_exact_angle: FloatArray
    home_book: HybridIK
    home_exact: HybridIK

    def summary(self) -> dict[str, float]:
        """Maximum round-trip errors and lag [length unit / rad] as a JSON-ready dict."""
        return {
            "roundtrip_position_max_book": float(self.roundtrip_book.max()),
            "roundtrip_angle_max_book": float(self.roundtrip_book_angle.max()),
            "roundtrip_position_max_exact": float(self.roundtrip_exact.max()),
            "roundtrip_angle_max_exact": float(self.roundtrip_exact_angle.max()),
            "theta6_lag_max_book": float(np.abs(self.lag_book).max()),
        }


def linear_path(
    p_home: ArrayLike, R_home: ArrayLike, p_dest: ArrayLike, R_dest: ArrayLike, n: int
) -> tuple[FloatArray, FloatArray]:
    """Straight-line position and constant-axis (slerp) orientation from home to destination, n samples."""
    p_home, p_dest = as_vector(p_home, 3, "p_home"), as_vector(p_dest, 3, "p_dest")
    R_home, R_dest = as_rotation(R_home, "R_home"), as_rotation(R_dest, "R_dest")
    if n < 2:
        raise MechanismError(f"a path needs at least 2 samples, got {n}")
    s = np.linspace(0.0, 1.0, n)
    rel = Rotation.from_matrix(R_home.T @ R_dest).as_rotvec()
    Rs = np.array([R_home @ Rotation.from_rotvec(k * rel).as_matrix() for k in s])
    return (1.0 - s)[:, None] * p_home + s[:, None] * p_dest, Rs


def run_path(
    arm: Hybrid33Arm,
    p_home: ArrayLike,
    R_home: ArrayLike,
    p_dest: ArrayLike,
    R_dest: ArrayLike,
    n: int = 100,
    dt: float = 0.01,
    theta6_home: float = 0.0,
    branch: Branch = 1,
) -> PathResult:
    """Computer project 2: home → destination in ``n`` samples, book (lagged) and exact I-K, F-K round trips.

    Sample j is at t = j·dt and path parameter s = j/(n − 1), so the last sample is the destination.

    Args:
        arm: the 3+3 arm.
        p_home: home p_0^6 [length unit].
        R_home: home R_0^6.
        p_dest: destination p_0^6 [length unit].
        R_dest: destination R_0^6.
        n: number of samples (N = 100).
        dt: sampling interval [s] (0.01).
        theta6_home: the book's θ6(h) that starts its lag [rad].
        branch: wrist branch.
    """
    ps, Rs = linear_path(p_home, R_home, p_dest, R_dest, n)
    jb, je = np.zeros((n, 6)), np.zeros((n, 6))
    lag, rb, rba, re, rea = (np.zeros(n) for _ in range(5))
    theta6 = float(theta6_home)
    hint: float | None = None
    home_book = home_exact = None
    for j in range(n):
        book = arm.ik_book(ps[j], Rs[j], theta6, branch)
        exact = arm.ik_exact(ps[j], Rs[j], branch, theta6_hint=hint if hint is not None else theta6_home)
        if j == 0:
            home_book, home_exact = book, exact
        theta6, hint = float(book.theta[2]), float(exact.theta[2])
        jb[j], je[j], lag[j] = book.joints, exact.joints, book.lag
        for sol, pos, ang in ((book, rb, rba), (exact, re, rea)):
            fk = arm.forward_kinematics(sol.lengths, sol.theta, hint=(sol.o3, sol.R03), starts=0)[0]
            pos[j] = np.linalg.norm(fk.p - ps[j])
            ang[j] = rotation_angle_between(fk.R, Rs[j])
    jb[:, 3:] = np.unwrap(jb[:, 3:], axis=0)  # continuous profiles (angles may leave (−π, π])
    je[:, 3:] = np.unwrap(je[:, 3:], axis=0)
    if home_book is None or home_exact is None:  # n >= 2 guarantees both; keeps the types exact
        raise MechanismError("empty path")
    return PathResult(np.arange(n, dtype=float) * dt, ps, Rs, jb, je, lag, rb, rba, re, rea, home_book, home_exact)
