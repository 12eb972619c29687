"""Grübler's mobility formula (5.16): m = D (l − n) + Σ f_i.

``D`` is the motion-space dimension (3 planar, 6 spatial), ``l`` the number of movable links (the fixed base
excluded), ``n`` the number of joints and ``f_i`` the axes (d.o.f.) of joint i; ``F = Σ f_i``.

Naming caution: the chapter calls a 2-axis ball joint (ball without spin) "spherical" (S) and the 3-axis one
"universal" (U) — the reverse of common usage, where a universal (Hooke) joint has 2 axes and a spherical
(ball) joint 3. :data:`JOINT_DOF` follows the chapter's letters so its examples read as printed (a UPS leg is
U = 3, P = 1, S = 2); the unambiguous names ``ball`` (3) and ``hooke`` (2) are also accepted. The totals of
the chapter's examples are the same under either naming.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from redundik.errors import MechanismError

#: Axes per joint type. R revolute, P prismatic, C cylindrical (slide + spin), S / U in the chapter's naming.
JOINT_DOF: dict[str, int] = {"R": 1, "P": 1, "C": 2, "S": 2, "U": 3, "hooke": 2, "ball": 3}

#: Motion-space dimension D per space name.
SPACE_DIM: dict[str, int] = {"planar": 3, "spatial": 6}


@dataclass(frozen=True)
class JointGroup:
    """``count`` joints of one kind.

    Attributes:
        type: a key of :data:`JOINT_DOF` (or any label when ``dof`` is given).
        count: number of such joints.
        dof: axes per joint; defaults to ``JOINT_DOF[type]``.
    """

    type: str
    count: int = 1
    dof: int | None = None

    @property
    def axes(self) -> int:
        """Axes per joint f_i."""
        if self.dof is not None:
            return self.dof
        if self.type not in JOINT_DOF:
            raise MechanismError(f"unknown joint type {self.type!r}; choose one of {sorted(JOINT_DOF)} or give dof")
        return JOINT_DOF[self.type]


@dataclass(frozen=True)
class Mobility:
    """Result of (5.16): ``m = D (l − n) + F``.

    Attributes:
        m: net degrees of freedom.
        F: total axes Σ f_i.
        D: motion-space dimension.
        links: movable links l.
        joints: joints n.
    """

    m: int
    F: int
    D: int
    links: int
    joints: int

    @property
    def passive(self) -> int:
        """F − m: axes that must stay passive (0 for an open serial chain)."""
        return self.F - self.m


def grubler(D: int, links: int, joints: Iterable[JointGroup | tuple[str, int] | int]) -> Mobility:
    """Grübler's formula (5.16).

    Args:
        D: 3 (planar) or 6 (spatial).
        links: movable links l (the fixed base excluded).
        joints: joint groups, ``(type, count)`` pairs, or plain per-joint axis counts f_i.

    Raises:
        MechanismError: D not 3 or 6, negative counts, joint axes outside 1 … D.
    """
    if D not in (3, 6):
        raise MechanismError(f"D must be 3 (planar) or 6 (spatial), got {D}")
    if links < 0:
        raise MechanismError(f"links must be >= 0, got {links}")
    n = F = 0
    for j in joints:
        group = j if isinstance(j, JointGroup) else JointGroup(*j) if isinstance(j, tuple) else JointGroup("?", 1, j)
        f = group.axes
        if group.count < 0 or not 1 <= f <= D:
            raise MechanismError(f"joint {group.type!r}: need count >= 0 and 1 <= dof <= {D}, got {group.count}, {f}")
        n += group.count
        F += group.count * f
    return Mobility(D * (links - n) + F, F, D, links, n)
