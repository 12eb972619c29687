"""Delta (URR) legs from the equivalent UPR leg length (end of section 5.4.3, Fig. 5.27).

A URR leg with lower link a1 and upper link a2 replaces a UPR piston of length l: the two-link planar arm lives
in the leg frame ``H_0^a = [[R_0^a, p_0^a], [0, 1]]`` with ``R_0^a = (l̂, u × l̂, u)`` (l̂ = l_0^a/l, u = R_0^3 p_3^α
the revolute axis), and its tip must reach ``p_a^2 = (l, 0, 0)``:

    a1 c1 + a2 c12 = l,  a1 s1 + a2 s12 = 0  ⇒  c2 = (l² − a1² − a2²)/(2 a1 a2),
    θ2 = −arccos(c2) ∈ (−180°, 0) (knee outward),  θ1 = atan2(−a2 s2, a1 + a2 c2).

The knee angle of the law of cosines is ∠A_a = θ2 + 180°.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from redundik.errors import MechanismError
from redundik.parallel._linalg import FloatArray, as_vector
from redundik.parallel.upr import UPRPlatform


def urr_angles(length: float, a1: float, a2: float) -> tuple[float, float]:
    """θ1^a, θ2^a [rad] of a URR leg equivalent to a UPR leg of ``length`` (knee outward, θ2 < 0).

    Args:
        length: UPR leg length l [length unit].
        a1: lower link length [length unit].
        a2: upper link length [length unit].

    Raises:
        MechanismError: non-positive links, or a length the two links cannot span (|a1 − a2| < l < a1 + a2).
    """
    if not (a1 > 0 and a2 > 0):
        raise MechanismError(f"link lengths must be positive, got a1={a1}, a2={a2}")
    if not (np.isfinite(length) and abs(a1 - a2) < length < a1 + a2):
        raise MechanismError(
            f"leg length {length} out of reach of links a1={a1}, a2={a2} (needs {abs(a1 - a2)} < l < {a1 + a2})"
        )
    c2 = (length**2 - a1**2 - a2**2) / (2.0 * a1 * a2)
    s2 = -np.sqrt(1.0 - c2**2)
    return float(np.arctan2(-a2 * s2, a1 + a2 * c2)), float(np.arctan2(s2, c2))


def leg_frame(leg_vector: ArrayLike, axis: ArrayLike, base_point: ArrayLike) -> FloatArray:
    """H_0^a (4×4): x along the leg, z along the revolute axis u = R_0^3 p_3^α, origin at the base joint.

    Raises:
        MechanismError: the axis is not perpendicular to the leg (the UPR orthogonality of (5.31)).
    """
    leg = as_vector(leg_vector, 3, "leg vector")
    u = as_vector(axis, 3, "axis")
    x = leg / np.linalg.norm(leg)
    z = u / np.linalg.norm(u)
    if abs(x @ z) > 1e-8:
        raise MechanismError(f"revolute axis is not perpendicular to the leg (cos = {x @ z:.3g})")
    H = np.eye(4)
    H[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    H[:3, 3] = as_vector(base_point, 3, "base point")
    return H


def planar_link(theta: float, a: float) -> FloatArray:
    """One-step D-H transform of a planar link (θ, d = 0, α = 0, a) — the A_a^1, A_1^2 of Fig. 5.27."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0, a * c], [s, c, 0.0, a * s], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class DeltaLegs:
    """Whole-Delta I-K result.

    Attributes:
        theta: (θ1^i, θ2^i) per leg [rad], shape (3, 2).
        lengths: equivalent UPR leg lengths [length unit], shape (3,).
        frames: H_0^i per leg, shape (3, 4, 4).
        knees: knee points H_0^i A_i^1 origin [length unit], shape (3, 3).
        tips: upper-link tips H_0^i A_i^2 origin (= the top joints) [length unit], shape (3, 3).
        R03: passive orientation of the top disc.
        o3: origin of frame 3 [length unit].
    """

    theta: FloatArray
    lengths: FloatArray
    frames: FloatArray
    knees: FloatArray
    tips: FloatArray
    R03: FloatArray
    o3: FloatArray


@dataclass(frozen=True)
class DeltaRobot:
    """A 3-URR Delta: the UPR platform geometry with each piston replaced by links a1, a2.

    Attributes:
        platform: the equivalent UPR platform (its d4 sets where the Top point is).
        a1: lower link length [length unit].
        a2: upper link length [length unit].
    """

    platform: UPRPlatform
    a1: float
    a2: float

    def inverse_kinematics(self, top: ArrayLike) -> DeltaLegs:
        """Leg angles, frames and knee points for a Top point p_0^t [length unit].

        Raises:
            MechanismError: no passive orientation, or a leg out of the links' reach.
        """
        pose = self.platform.inverse_kinematics(top, method="exact")
        thetas, frames, knees, tips = [], [], [], []
        for i in range(3):
            t1, t2 = urr_angles(float(pose.lengths[i]), self.a1, self.a2)
            H = leg_frame(pose.vectors[i], pose.R03 @ self.platform.joint_axes[i], self.platform.base_points[i])
            A1 = planar_link(t1, self.a1)
            thetas.append((t1, t2))
            frames.append(H)
            knees.append((H @ A1)[:3, 3])
            tips.append((H @ A1 @ planar_link(t2, self.a2))[:3, 3])
        return DeltaLegs(
            np.array(thetas), pose.lengths, np.array(frames), np.array(knees), np.array(tips), pose.R03, pose.o3
        )
