"""Joint limits as bounds on q̇ for one step of length dt: position (through dt), velocity and rate limits.

For a 1-dof joint i at q_i with limits [q_lo, q_hi], velocity limit v_max and (optional) rate limit a_max:

    position:  g·(q_lo − q_i)/dt ≤ q̇_i ≤ g·(q_hi − q_i)/dt        (g = ``position_gain`` ∈ (0, 1])
    velocity:  −v_max ≤ q̇_i ≤ v_max
    rate:      q̇_prev,i − a_max·dt ≤ q̇_i ≤ q̇_prev,i + a_max·dt     (acceleration-like, between steps)
    braking:   −B(q_i − q_lo) ≤ q̇_i ≤ B(q_hi − q_i),  B(δ) = −a_max·dt + √((a_max·dt)² + 2·a_max·δ)  (with a_max)

so that q_i + q̇_i·dt stays in [q_lo, q_hi] whenever it starts there; with a rate limit the braking bound keeps the
joint slow enough near a limit to stop in time, so the rate window never has to be broken to respect a limit. From a
start *outside* a limit (q_i > q_hi) the upper bound is negative: the joint may only move back inside, as fast as
the velocity limit allows (−v_max when g·(q_hi − q_i)/dt < −v_max), and it is back inside after ⌈(q_i −
q_hi)/(v_max·dt)⌉ steps. Position and velocity bounds are hard; a rate window that does not meet them is moved onto
the nearest feasible velocity (the rate limit is the one relaxed), so the box is never empty and the QP over it is
always feasible. Only 1-dof joints (``JointInfo.idx_q ≥ 0``) carry position limits; free-flyer and unbounded (cos,
sin) joints have none. Defaults come from the model (D-H rows' ``lower``/``upper``/``velocity``, URDF ``<limit>``);
a limit with magnitude ≥ 1e10 or infinite means "no limit"; a URDF velocity of 0 (missing) means none too.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel

#: Codes of what sets a bound, in :attr:`LimitBox.lower_src` / :attr:`LimitBox.upper_src`.
NONE, POSITION, VELOCITY, RATE = 0, 1, 2, 3
SOURCE_NAMES = {POSITION: "position", VELOCITY: "velocity", RATE: "rate"}

_BIG = 1e10


@dataclass
class LimitBox:
    """Bounds lb ≤ q̇ ≤ ub for one step, and which limit sets each bound.

    Attributes:
        lb: Lower bound on q̇ (nv,), ``-inf`` where free.
        ub: Upper bound on q̇ (nv,), ``+inf`` where free.
        lower_src: Code of the limit setting each lower bound (``POSITION``, ``VELOCITY``, ``RATE`` or ``NONE``).
        upper_src: Same for the upper bounds.
    """

    lb: np.ndarray
    ub: np.ndarray
    lower_src: np.ndarray
    upper_src: np.ndarray

    @property
    def bounded(self) -> bool:
        """True when at least one bound is finite."""
        return bool(np.isfinite(self.lb).any() or np.isfinite(self.ub).any())

    def clip(self, dq: np.ndarray) -> np.ndarray:
        """q̇ projected onto the box."""
        return np.minimum(np.maximum(dq, self.lb), self.ub)

    def contains(self, dq: np.ndarray, tol: float = 0.0) -> bool:
        """True when lb − tol ≤ q̇ ≤ ub + tol."""
        return bool(np.all(dq >= self.lb - tol) and np.all(dq <= self.ub + tol))

    def active(self, dq: np.ndarray, names: list[str], tol: float = 1e-7) -> list[str]:
        """``"joint:upper_position"``-style labels of the bounds q̇ sits on (within ``tol`` [unit/s])."""
        out = []
        scale_u = tol * np.maximum(1.0, np.abs(self.ub))
        scale_l = tol * np.maximum(1.0, np.abs(self.lb))
        for i in np.flatnonzero((self.ub - dq <= scale_u) & (self.upper_src > 0)):
            out.append(f"{names[i]}:upper_{SOURCE_NAMES[int(self.upper_src[i])]}")
        for i in np.flatnonzero((dq - self.lb <= scale_l) & (self.lower_src > 0)):
            out.append(f"{names[i]}:lower_{SOURCE_NAMES[int(self.lower_src[i])]}")
        return out


class JointLimits:
    """Per-joint limit settings; :meth:`box` turns them into bounds on q̇ for one step.

    Args:
        position: Enforce position limits.
        velocity: Enforce velocity limits.
        lower: Overrides of lower position limits by joint name [rad or m].
        upper: Overrides of upper position limits by joint name.
        velocity_limits: Overrides of velocity limits by joint name [rad/s or m/s]; ``inf`` removes one.
        acceleration: Rate limit a_max [rad/s²]: one number for every joint, or by joint name; ``None`` = off.
        position_gain: g ∈ (0, 1]: fraction of the remaining range a single step may use (1 = may reach the limit).

    Raises:
        ResolverError: bad numbers; unknown joint names are reported by :meth:`bind` (they need the robot).
    """

    def __init__(
        self,
        *,
        position: bool = True,
        velocity: bool = True,
        lower: Mapping[str, float] | None = None,
        upper: Mapping[str, float] | None = None,
        velocity_limits: Mapping[str, float] | None = None,
        acceleration: float | Mapping[str, float] | None = None,
        position_gain: float = 1.0,
    ) -> None:
        if not (np.isfinite(position_gain) and 0.0 < position_gain <= 1.0):
            raise ResolverError(f"limits: position_gain must be in (0, 1], got {position_gain}")
        self.position, self.velocity = bool(position), bool(velocity)
        self.lower = dict(lower or {})
        self.upper = dict(upper or {})
        self.velocity_limits = dict(velocity_limits or {})
        self.acceleration = acceleration
        self.position_gain = float(position_gain)
        for key, table in (("lower", self.lower), ("upper", self.upper)):
            for jn, val in table.items():
                if np.isnan(val):
                    raise ResolverError(f"limits: {key}['{jn}'] is NaN")
        for jn, val in self.velocity_limits.items():
            if not val > 0:
                raise ResolverError(f"limits: velocity_limits['{jn}'] must be > 0, got {val}")
        if isinstance(acceleration, Mapping):
            for jn, val in acceleration.items():
                if not val > 0:
                    raise ResolverError(f"limits: acceleration['{jn}'] must be > 0, got {val}")
        elif acceleration is not None and not acceleration > 0:
            raise ResolverError(f"limits: acceleration must be > 0 or None, got {acceleration}")
        self._robot_id: int | None = None

    def bind(self, robot: RobotModel) -> None:
        """Resolve names and defaults against ``robot`` (done once per robot).

        Raises:
            ResolverError: an override names a joint the robot lacks (the message lists the valid names), or gives a
                position limit to a joint without a 1-dof position coordinate, or lower > upper.
        """
        names = robot.joint_names
        index = {n: k for k, n in enumerate(names)}
        acc = self.acceleration if isinstance(self.acceleration, Mapping) else {}
        for key, table in (
            ("lower", self.lower),
            ("upper", self.upper),
            ("velocity_limits", self.velocity_limits),
            ("acceleration", acc),
        ):
            bad = [jn for jn in table if jn not in index]
            if bad:
                raise ResolverError(
                    f"limits: {key}: unknown joint(s) {bad} in robot '{robot.name}'; available: {names}"
                )
        nv = robot.nv
        iq = np.array([j.idx_q for j in robot.joints], dtype=int)
        lo = np.array([j.lower for j in robot.joints], dtype=float)
        hi = np.array([j.upper for j in robot.joints], dtype=float)
        vmax = np.array([j.velocity for j in robot.joints], dtype=float)
        for jn, val in self.lower.items():
            lo[index[jn]] = val
        for jn, val in self.upper.items():
            hi[index[jn]] = val
        for jn, val in self.velocity_limits.items():
            vmax[index[jn]] = val
        for k in range(nv):
            if iq[k] < 0 and ((np.isfinite(lo[k]) and abs(lo[k]) < _BIG) or (np.isfinite(hi[k]) and abs(hi[k]) < _BIG)):
                if names[k] in self.lower or names[k] in self.upper:
                    raise ResolverError(
                        f"limits: joint '{names[k]}' has no 1-dof position coordinate; "
                        "position limits apply to revolute and prismatic joints only"
                    )
        lo[(np.abs(lo) >= _BIG) | (iq < 0)] = -np.inf
        hi[(np.abs(hi) >= _BIG) | (iq < 0)] = np.inf
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            k = int(bad[0])
            raise ResolverError(f"limits: joint '{names[k]}': lower {lo[k]} > upper {hi[k]}")
        vmax[~(vmax > 0) | (vmax >= _BIG)] = np.inf
        if isinstance(self.acceleration, Mapping):
            amax = np.full(nv, np.inf)
            for jn, val in self.acceleration.items():
                amax[index[jn]] = val
        else:
            amax = np.full(nv, np.inf if self.acceleration is None else float(self.acceleration))
        self._has_pos = self.position and bool(np.isfinite(lo).any() or np.isfinite(hi).any())
        self._pos_k = np.flatnonzero(np.isfinite(lo) | np.isfinite(hi))
        self._pos_iq = iq[self._pos_k]
        self._lo, self._hi = lo[self._pos_k], hi[self._pos_k]
        self._vmax = vmax if self.velocity else np.full(nv, np.inf)
        self._amax = amax
        self._has_rate = bool(np.isfinite(amax).any())
        self._names = names
        self._robot_id = id(robot)
        # preallocated box arrays (filled in place by box())
        self._lb, self._ub = np.empty(nv), np.empty(nv)
        self._ls, self._us = np.empty(nv, dtype=np.int8), np.empty(nv, dtype=np.int8)
        self._vsrc = np.where(np.isfinite(self._vmax), VELOCITY, NONE).astype(np.int8)

    @property
    def joint_names(self) -> list[str]:
        """Joint names in q̇ order (after :meth:`bind`)."""
        return self._names

    @property
    def lower_position(self) -> np.ndarray:
        """Effective lower position limits by q̇ coordinate (after :meth:`bind`; ``-inf`` where none)."""
        out = np.full(len(self._names), -np.inf)
        out[self._pos_k] = self._lo
        return out

    @property
    def upper_position(self) -> np.ndarray:
        """Effective upper position limits by q̇ coordinate (after :meth:`bind`; ``+inf`` where none)."""
        out = np.full(len(self._names), np.inf)
        out[self._pos_k] = self._hi
        return out

    def box(self, robot: RobotModel, q: np.ndarray, dt: float, dq_prev: np.ndarray | None = None) -> LimitBox:
        """Bounds on q̇ for a step dt [s] from q (see the module docstring).

        The returned arrays are reused by the next call (no allocation per step): copy them to keep them.
        """
        if self._robot_id != id(robot):
            self.bind(robot)
        lb, ub, ls, us = self._lb, self._ub, self._ls, self._us
        vmax = self._vmax
        np.negative(vmax, out=lb)
        np.copyto(ub, vmax)
        ls[:] = self._vsrc
        us[:] = self._vsrc
        if self.position and self._pos_k.size:
            k = self._pos_k
            qk = q[self._pos_iq]
            g = self.position_gain / dt
            pl = g * (self._lo - qk)  # ≤ 0 inside the range
            pu = g * (self._hi - qk)  # ≥ 0 inside the range
            if self._has_rate:
                # braking distance: with |Δq̇| ≤ a·dt per step, a joint at distance δ from its limit must keep
                # q̇ ≤ B(δ) = −a·dt + √((a·dt)² + 2aδ) (covers v²/2a + v·dt ≥ the discrete stopping distance), so
                # the next step's rate window always meets the position window and neither limit is ever broken
                ak = self._amax[k]
                adt = ak * dt
                with np.errstate(invalid="ignore"):
                    bu = -adt + np.sqrt(adt * adt + 2.0 * ak * np.maximum(self._hi - qk, 0.0))
                    bl = adt - np.sqrt(adt * adt + 2.0 * ak * np.maximum(qk - self._lo, 0.0))
                fin = np.isfinite(ak)
                pu = np.where(fin & (self._hi >= qk), np.minimum(pu, bu), pu)
                pl = np.where(fin & (self._lo <= qk), np.maximum(pl, bl), pl)
            vk = vmax[k]
            # outside a limit: move back at most as fast as the velocity limit allows
            pl = np.minimum(pl, vk)
            pu = np.maximum(pu, -vk)
            m = pl > lb[k]
            lb[k[m]] = pl[m]
            ls[k[m]] = POSITION
            m = pu < ub[k]
            ub[k[m]] = pu[m]
            us[k[m]] = POSITION
        if self._has_rate and dq_prev is not None:
            step = self._amax * dt
            rl = np.clip(dq_prev - step, lb, ub)
            ru = np.clip(dq_prev + step, lb, ub)
            m = rl > lb
            ls[m] = RATE
            m2 = ru < ub
            us[m2] = RATE
            np.copyto(lb, rl)
            np.copyto(ub, ru)
        return LimitBox(lb, ub, ls, us)

    def __repr__(self) -> str:
        return (
            f"JointLimits(position={self.position}, velocity={self.velocity}, acceleration={self.acceleration}, "
            f"position_gain={self.position_gain})"
        )
