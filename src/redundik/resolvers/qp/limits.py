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
q_hi)/(v_max·dt)⌉ steps. Position and velocity bounds are hard; a rate window that does not meet them is moved
onto the nearest feasible velocity (the rate limit is the one relaxed), and from outside a limit a braking bound of
the other limit that would cut off the way back yields to it, so the box is never empty (lb ≤ ub on every joint,
from any finite start, with or without rate limits) and the QP over it is always feasible. Only 1-dof joints
(``JointInfo.idx_q ≥ 0``) carry position limits; free-flyer and unbounded (cos, sin) joints have none.
Defaults come from the model (D-H rows' ``lower``/``upper``/``velocity``, URDF ``<limit>``);
a limit with magnitude ≥ 1e10 or infinite means "no limit"; a URDF velocity of 0 (missing) means none too.

Jerk limits (``jerk`` j_max [rad/s³], one number or by joint name) bound the change of the step's acceleration:
with the last two q̇ (q̇₁ the previous, q̇₂ the one before; d₁ = q̇₁ − q̇₂, α = a_max·dt, β = j_max·dt²)

    jerk:      q̇₁ + max(d₁ − β, −α) ≤ q̇_i ≤ q̇₁ + min(d₁ + β, α)       (|q̈| ≤ a_max and |Δq̈| ≤ j_max·dt)
    viability: the hardest braking d ← max(d − β, −α) from the state q̇_i leads to keeps q̇·dt ≤ g·(q_hi − q) and
               q̇ ≤ v_max at every later step (and the mirror image for the lower limits)

The viability bound replaces the acceleration-only braking bound B above: a joint near a limit moves only as fast
as it can still stop in time with bounded acceleration *and* jerk; the braking roll-out is exact in discrete time,
monotone in q̇_i, and its first step from a viable state is again in the box, so the box stays non-empty
(recursive feasibility; :mod:`redundik.resolvers.jerk_kernels` gives the argument and its references — Del Prete
2018 for the discrete-time viability of position/velocity bounds, Berscheid & Kröger 2021, Ruckig, for
jerk-limited stops). A jerk limit assumes the robot at rest before the resolver's first step and after
:meth:`~redundik.resolvers.base.Resolver.reset` (q̇₁ = q̇₂ = 0: the acceleration window then applies from the first
step on), and an unknown q̇₂ (the resolver stepped without the jerk limit) as q̇₂ = q̇₁ (zero acceleration).

When no candidate meets jerk, acceleration and viability together (a start outside a limit, a measured q that is
not where the last q̇ led, limits tightened mid-run, the state left by a step without the jerk limit) the limits
are relaxed in a fixed order and the step says so in ``result.relaxed``: first the jerk limit (``"jerk_limit"``:
the box is the acceleration-limited box above, and within it the q̇ closest to the jerk window), then the
acceleration limit (``"acceleration_limit"``: the rate window moved onto the position/velocity box, as above);
position and velocity limits are never relaxed (from outside, the way back of the rule above).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from redundik.errors import ResolverError, short_repr
from redundik.kinematics.model import RobotModel
from redundik.resolvers.layouts import (
    JERK_BRAKE_HI,
    JERK_BRAKE_LO,
    JERK_LB,
    JERK_ROWS,
    JERK_UB,
    JERK_WINDOW_HI,
    JERK_WINDOW_LO,
    LIM_AMAX,
    LIM_HI,
    LIM_JERK_ROWS,
    LIM_JMAX,
    LIM_LO,
    LIM_VMAX,
    OUT_BOX,
    OUT_LB,
    OUT_UB,
)
from redundik.resolvers.linalg import K, _Kernels

#: The jerk kernels (:mod:`redundik.resolvers.jerk_kernels`), loaded on first use.
JK = _Kernels("jerk_kernels")

#: Codes of what sets a bound, in :attr:`LimitBox.lower_src` / :attr:`LimitBox.upper_src`.
NONE, POSITION, VELOCITY, RATE, JERK = 0, 1, 2, 3, 4
SOURCE_NAMES = {POSITION: "position", VELOCITY: "velocity", RATE: "rate", JERK: "jerk"}
#: Names of the relaxations a box may report (``LimitBox.relaxed``, then ``StepResult.relaxed``).
JERK_RELAXED, ACCELERATION_RELAXED = "jerk_limit", "acceleration_limit"

_BIG = 1e10


@dataclass
class LimitBox:
    """Bounds lb ≤ q̇ ≤ ub for one step, with the candidate bounds they came from (to say which limit is active).

    Attributes:
        lb: Lower bound on q̇ (nv,), ``-inf`` where free.
        ub: Upper bound on q̇ (nv,), ``+inf`` where free.
        pos_lo: Lower bound from the position limit (−inf where none), after the outside-start rule.
        pos_hi: Upper bound from the position limit (+inf where none).
        vmax: Velocity limits (inf where none).
        rate_lo: Lower end of the rate window, or ``None`` without a rate limit.
        rate_hi: Upper end of the rate window, or ``None``.
        jerk_lo: With jerk limits: the lower end of the jerk window q̇₁ + d₁ − β (``None`` without).
        jerk_hi: Its upper end.
        relaxed: The limits this box had to relax (``JERK_RELAXED``, ``ACCELERATION_RELAXED``), in order.
    """

    lb: np.ndarray
    ub: np.ndarray
    pos_lo: np.ndarray
    pos_hi: np.ndarray
    vmax: np.ndarray
    rate_lo: np.ndarray | None = None
    rate_hi: np.ndarray | None = None
    jerk_lo: np.ndarray | None = None
    jerk_hi: np.ndarray | None = None
    relaxed: tuple[str, ...] = ()

    def pinned(self) -> np.ndarray:
        """Mask of the joints whose box is a single value, ub − lb ≤ 1e-12·max(1, |ub|) (q̇_j is fixed)."""
        both = np.isfinite(self.lb) & np.isfinite(self.ub)
        width = np.where(both, self.ub - self.lb, np.inf)
        return both & (width <= 1e-12 * np.maximum(1.0, np.abs(np.where(both, self.ub, 0.0))))

    @property
    def bounded(self) -> bool:
        """True when at least one bound is finite."""
        return bool(np.isfinite(self.lb).any() or np.isfinite(self.ub).any())

    def _source(
        self, bound: np.ndarray, pos: np.ndarray, vel: np.ndarray, rate: np.ndarray | None, jerk: np.ndarray | None
    ) -> np.ndarray:
        src = np.full(bound.shape[0], NONE, dtype=np.int8)
        src[np.isfinite(bound) & (bound == vel)] = VELOCITY
        src[np.isfinite(bound) & (bound == pos)] = POSITION
        if rate is not None:
            src[(bound == rate) & (bound != pos) & (bound != vel)] = RATE
        if jerk is not None:
            src[(bound == jerk) & (bound != pos) & (bound != vel)] = JERK
        return src

    @property
    def lower_src(self) -> np.ndarray:
        """Code of the limit setting each lower bound (``POSITION``, ``VELOCITY``, ``RATE``, ``JERK`` or ``NONE``)."""
        return self._source(self.lb, self.pos_lo, -self.vmax, self.rate_lo, self.jerk_lo)

    @property
    def upper_src(self) -> np.ndarray:
        """Same for the upper bounds."""
        return self._source(self.ub, self.pos_hi, self.vmax, self.rate_hi, self.jerk_hi)

    def clip(self, dq: np.ndarray) -> np.ndarray:
        """q̇ projected onto the box."""
        return np.minimum(np.maximum(dq, self.lb), self.ub)

    def contains(self, dq: np.ndarray, tol: float = 0.0) -> bool:
        """True when lb − tol ≤ q̇ ≤ ub + tol."""
        if dq.ndim == 1 and self.lb.ndim == 1:
            return bool(K.in_box(dq, self.lb, self.ub, float(tol)))  # one compiled call
        if tol:
            return not ((dq < self.lb - tol).any() or (dq > self.ub + tol).any())
        return not ((dq < self.lb).any() or (dq > self.ub).any())

    def active(self, dq: np.ndarray, names: list[str], tol: float = 1e-7) -> list[str]:
        """``"joint:upper_position"``-style labels of the bounds q̇ sits on (within ``tol`` [rad/s or m/s])."""
        near_u = self.ub - dq <= tol
        near_l = dq - self.lb <= tol
        if not (near_u.any() or near_l.any()):
            return []
        out = []
        us, ls = self.upper_src, self.lower_src
        for i in np.flatnonzero(near_u & (us > 0)):
            out.append(f"{names[i]}:upper_{SOURCE_NAMES[int(us[i])]}")
        for i in np.flatnonzero(near_l & (ls > 0)):
            out.append(f"{names[i]}:lower_{SOURCE_NAMES[int(ls[i])]}")
        return out


def _is_number(val: object) -> bool:
    return isinstance(val, (int, float, np.integer, np.floating)) and not isinstance(val, (bool, np.bool_))


def _per_joint_limit(key: str, value: object, unit: str) -> float | dict[str, float] | None:
    """A validated rate-type limit (``acceleration``, ``jerk``): a number > 0, a mapping joint name → number > 0
    (``inf``: none for that joint), or ``None``.

    Raises:
        ResolverError: names the key, the joint and what was expected.
    """
    if value is None:
        return None
    if isinstance(value, Mapping):
        for jn, val in value.items():
            if not _is_number(val) or not val > 0:
                raise ResolverError(f"limits: {key}['{jn}'] must be a number > 0 [{unit}], got {short_repr(val)}")
        return {str(jn): float(val) for jn, val in value.items()}
    number = float(value) if _is_number(value) else math.nan  # type: ignore[arg-type]
    if not number > 0:
        raise ResolverError(f"limits: {key} must be a number > 0 [{unit}] or None, got {short_repr(value)}")
    return number


class JointLimits:
    """Per-joint limit settings; :meth:`box` turns them into bounds on q̇ for one step.

    Args:
        position: Enforce position limits.
        velocity: Enforce velocity limits.
        lower: Overrides of lower position limits by joint name [rad or m].
        upper: Overrides of upper position limits by joint name.
        velocity_limits: Overrides of velocity limits by joint name [rad/s or m/s]; ``inf`` removes one.
        acceleration: Rate limit a_max [rad/s²]: one number for every joint, or by joint name; ``None`` = off.
        jerk: Jerk limit j_max [rad/s³]: one number for every joint, or by joint name; ``None`` = off (module
            docstring: the window, the braking bound, the relaxation order).
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
        jerk: float | Mapping[str, float] | None = None,
    ) -> None:
        #: The robot bound (weakly: a robot freed and another made at its address is not taken for it).
        self._robot: weakref.ref[RobotModel] | None = None
        self._args: tuple[Any, ...] | None = None  # kernel_args of the bound robot, kept while the options stay
        self.position_gain = position_gain
        self.position = position
        self.velocity = velocity
        self.lower = lower or {}
        self.upper = upper or {}
        self.velocity_limits = velocity_limits or {}
        self.acceleration = acceleration
        self.jerk = jerk

    # Every option is a validated property. Those that ``bind`` turns into arrays (velocity, the overrides, the
    # acceleration) bind the robot again at once when one is bound: set between steps, they used to be ignored
    # until another robot came (a rate limit set after the first step was never applied). The override tables are
    # read-only mappings for the same reason (an entry added in place would be missed); assign a new table.
    def _rebind(self) -> None:
        """Bind the bound robot again (the options changed); nothing to do before the first bind."""
        robot = self._robot() if self._robot is not None else None
        if robot is not None:
            self.bind(robot)

    @property
    def position_gain(self) -> float:
        """g ∈ (0, 1]: the fraction of the remaining range a single step may use."""
        return self._position_gain

    @position_gain.setter
    def position_gain(self, value: float) -> None:
        if not _is_number(value) or not (np.isfinite(value) and 0.0 < value <= 1.0):
            raise ResolverError(f"limits: position_gain must be in (0, 1], got {short_repr(value)}")
        self._position_gain = float(value)

    @property
    def position(self) -> bool:
        """Enforce the position limits."""
        return self._position

    @position.setter
    def position(self, flag: bool) -> None:
        self._position = self._switch("position", flag)

    @property
    def velocity(self) -> bool:
        """Enforce the velocity limits."""
        return self._velocity

    @velocity.setter
    def velocity(self, flag: bool) -> None:
        self._velocity = self._switch("velocity", flag)
        self._rebind()

    @staticmethod
    def _switch(key: str, flag: object) -> bool:
        if not isinstance(flag, (bool, np.bool_)):
            hint = (
                f"; a velocity limit for every joint is velocity_limits={{joint name: {short_repr(flag)}, ...}}"
                if key == "velocity" and _is_number(flag)
                else ""
            )
            raise ResolverError(f"limits: {key} switches the model's {key} limits on or off (True/False), got "
                                f"{short_repr(flag)}{hint}")  # fmt: skip
        return bool(flag)

    @staticmethod
    def _table(key: str, table: object) -> dict[str, float]:
        """A validated copy of an override table (joint name → number); read through a read-only view."""
        if not isinstance(table, Mapping):
            raise ResolverError(f"limits: {key} must be a mapping of joint names to numbers, got {short_repr(table)}")
        for jn, val in table.items():
            if not _is_number(val):
                raise ResolverError(f"limits: {key}['{jn}'] must be a number, got {short_repr(val)}")
            if np.isnan(val):
                raise ResolverError(f"limits: {key}['{jn}'] is NaN")
            if (key == "upper" and val == -np.inf) or (key == "lower" and val == np.inf):
                raise ResolverError(f"limits: {key}['{jn}'] = {val} leaves no admissible position")
            if key == "velocity_limits" and not val > 0:
                raise ResolverError(f"limits: velocity_limits['{jn}'] must be > 0, got {val}")
        return dict(table)

    @property
    def lower(self) -> Mapping[str, float]:
        """Overrides of lower position limits by joint name (read-only; assign a new mapping)."""
        return MappingProxyType(self._lower)

    @lower.setter
    def lower(self, table: Mapping[str, float]) -> None:
        self._lower = self._table("lower", table)
        self._rebind()

    @property
    def upper(self) -> Mapping[str, float]:
        """Overrides of upper position limits by joint name (read-only; assign a new mapping)."""
        return MappingProxyType(self._upper)

    @upper.setter
    def upper(self, table: Mapping[str, float]) -> None:
        self._upper = self._table("upper", table)
        self._rebind()

    @property
    def velocity_limits(self) -> Mapping[str, float]:
        """Overrides of velocity limits by joint name (read-only; assign a new mapping)."""
        return MappingProxyType(self._velocity_limits)

    @velocity_limits.setter
    def velocity_limits(self, table: Mapping[str, float]) -> None:
        self._velocity_limits = self._table("velocity_limits", table)
        self._rebind()

    @property
    def acceleration(self) -> float | Mapping[str, float] | None:
        """The rate limit a_max [rad/s²]: one number, a read-only mapping by joint name, or ``None`` (off)."""
        acc = self._acceleration
        return MappingProxyType(acc) if isinstance(acc, dict) else acc

    @acceleration.setter
    def acceleration(self, acceleration: float | Mapping[str, float] | None) -> None:
        self._acceleration = _per_joint_limit("acceleration", acceleration, "rad/s²")
        self._rebind()

    @property
    def jerk(self) -> float | Mapping[str, float] | None:
        """The jerk limit j_max [rad/s³]: one number, a read-only mapping by joint name, or ``None`` (off)."""
        jerk = self.__dict__.get("_jerk")
        return MappingProxyType(jerk) if isinstance(jerk, dict) else jerk

    @jerk.setter
    def jerk(self, jerk: float | Mapping[str, float] | None) -> None:
        self._jerk = _per_joint_limit("jerk", jerk, "rad/s³")
        self._rebind()

    @property
    def has_jerk(self) -> bool:
        """True when a jerk limit is set (the QP resolvers then compute every step's box with :meth:`box`)."""
        return self.__dict__.get("_jerk") is not None

    def __getstate__(self) -> dict[str, Any]:
        """The options, without the binding (a weak reference, and the robot's arrays): a copy or a pickle binds
        again at its first use."""
        state = self.__dict__.copy()
        state["_robot"] = None
        state["_args"] = None
        return state

    def bind(self, robot: RobotModel) -> None:
        """Resolve names and defaults against ``robot`` (done once per robot).

        Raises:
            ResolverError: an override names a joint the robot lacks (the message lists the valid names), or gives a
                position limit to a joint without a 1-dof position coordinate, or lower > upper.
        """
        names = robot.joint_names
        index = {n: k for k, n in enumerate(names)}
        acc = self.acceleration if isinstance(self.acceleration, Mapping) else {}
        jerk = self.jerk if isinstance(self.jerk, Mapping) else {}
        for key, table in (
            ("lower", self.lower),
            ("upper", self.upper),
            ("velocity_limits", self.velocity_limits),
            ("acceleration", acc),
            ("jerk", jerk),
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
        crossed = np.flatnonzero(lo > hi)
        if crossed.size:
            k = int(crossed[0])
            raise ResolverError(f"limits: joint '{names[k]}': lower {lo[k]} > upper {hi[k]}")
        vmax[~(vmax > 0) | (vmax >= _BIG)] = np.inf
        if isinstance(self.acceleration, Mapping):
            amax = np.full(nv, np.inf)
            for jn, val in self.acceleration.items():
                amax[index[jn]] = val
        else:
            amax = np.full(nv, np.inf if self.acceleration is None else float(self.acceleration))
        self._iq = np.maximum(iq, 0)  # q index per q̇ coordinate (0 where none: its limits are ±inf anyway)
        jmax = np.full(nv, np.inf)
        if isinstance(self.jerk, Mapping):
            for jn, val in self.jerk.items():
                jmax[index[jn]] = val
        elif self.jerk is not None:
            jmax[:] = float(self.jerk)
        lim = self._lim = np.empty((LIM_JERK_ROWS, nv))  # the kernels' record; the arrays below are its rows
        lim[LIM_LO], lim[LIM_HI], lim[LIM_AMAX], lim[LIM_JMAX] = lo, hi, amax, jmax
        lim[LIM_VMAX] = vmax if self.velocity else np.inf
        self._lo, self._hi, self._vmax = lim[LIM_LO], lim[LIM_HI], lim[LIM_VMAX]
        self._amax, self._jmax = lim[LIM_AMAX], lim[LIM_JMAX]
        self._has_rate = bool(np.isfinite(amax).any())
        self._no_prev = np.zeros((0, nv))
        self._names = names
        self._robot = weakref.ref(robot)
        self._args = None  # (kernel_args of the robot bound before: its arrays are the wrong size for this one)

    @property
    def joint_names(self) -> list[str]:
        """Joint names in q̇ order (after :meth:`bind`)."""
        return self._names

    @property
    def lower_position(self) -> np.ndarray:
        """Effective lower position limits by q̇ coordinate (after :meth:`bind`; ``-inf`` where none)."""
        return self._lo.copy()

    @property
    def upper_position(self) -> np.ndarray:
        """Effective upper position limits by q̇ coordinate (after :meth:`bind`; ``+inf`` where none)."""
        return self._hi.copy()

    def kernel_args(self, robot: RobotModel) -> tuple[Any, ...]:
        """(iq, lo, hi, vmax, amax, position, has_rate, gain), bound to ``robot``: the q index of each q̇ coordinate,
        the rows ``LIM_LO`` … ``LIM_AMAX`` of the joint-limit record (:mod:`redundik.resolvers.layouts`) and the
        options of ``K.limit_box`` (for a compiled step that computes its box inside, as ``wqp``'s and ``hqp``'s;
        a new tuple when the limits or their options changed)."""
        args = self._args
        bound = self._robot
        if bound is None or bound() is not robot:
            self.bind(robot)
            args = None
        if args is None or args[5] is not self.position or args[7] != self.position_gain:  # options read as now
            args = self._args = (
                self._iq, self._lo, self._hi, self._vmax, self._amax, self.position, self._has_rate, self.position_gain,
            )  # fmt: skip
        return args

    def previous(self, dq_prev: np.ndarray | None) -> np.ndarray:
        """The ``dq_prev`` argument of ``K.limit_box`` for one configuration: (1, nv) with a rate limit and a
        previous q̇, else (0, nv) (no rate window)."""
        if self._has_rate and dq_prev is not None:
            return np.asarray(dq_prev, dtype=float).reshape(1, -1)
        return self._no_prev

    def box_from(self, rows: np.ndarray, windowed: bool) -> LimitBox:
        """The :class:`LimitBox` of ``K.limit_box``'s output rows (lb, ub, pos_lo, pos_hi) of one configuration;
        ``windowed``: a rate window was applied (``previous`` gave a row)."""
        if windowed:
            return LimitBox(rows[0], rows[1], rows[2], rows[3], self._vmax, rows[0], rows[1])
        return LimitBox(rows[0], rows[1], rows[2], rows[3], self._vmax)

    def box(
        self,
        robot: RobotModel,
        q: np.ndarray,
        dt: float,
        dq_prev: np.ndarray | None = None,
        dq_prev2: np.ndarray | None = None,
    ) -> LimitBox:
        """Bounds on q̇ for a step dt [s] from q (see the module docstring); ``dq_prev``/``dq_prev2``: the last two
        q̇ [rad/s] (the second is read with a jerk limit only).

        ``q`` may also be a stack of N configurations (N, nq): the bounds are then (N, nv) (batches; not with a
        jerk limit).

        Raises:
            ResolverError: a stack of configurations with a jerk limit.
        """
        bound = self._robot
        if bound is None or bound() is not robot:
            self.bind(robot)
        if self.has_jerk:
            return jerk_limited_box(self, self._lim, q, float(dt), dq_prev, dq_prev2)
        if type(q) is np.ndarray and q.dtype == np.float64 and q.ndim == 1 and (dq_prev is None or not self._has_rate):
            # the control loop's case, in a few operations: one configuration, no rate window
            out1 = np.empty((OUT_BOX, 1, self._lo.shape[0]))
            K.limit_box(q.reshape(1, -1), self._iq, self._lim, self.position, self._has_rate, self.position_gain,
                        float(dt), self._no_prev, out1)  # fmt: skip
            return self.box_from(out1[:, 0], False)
        q = np.asarray(q, dtype=float)
        single = q.ndim == 1
        prev = self._no_prev
        if self._has_rate and dq_prev is not None:
            prev = np.asarray(dq_prev, dtype=float).reshape(1, -1) if single else np.asarray(dq_prev, dtype=float)
        qq = q.reshape(1, -1) if single else q
        out = np.empty((OUT_BOX, qq.shape[0], self._lo.shape[0]))
        # one compiled call: the module docstring's rules
        K.limit_box(qq, self._iq, self._lim, self.position, self._has_rate, self.position_gain, float(dt), prev, out)
        lb, ub, pl, pu = out[:, 0] if single else out
        if prev is not self._no_prev:
            return LimitBox(lb, ub, pl, pu, self._vmax, lb, ub)
        return LimitBox(lb, ub, pl, pu, self._vmax)

    def __repr__(self) -> str:
        return (
            f"JointLimits(position={self.position}, velocity={self.velocity}, acceleration={self.acceleration}, "
            f"jerk={self.jerk}, position_gain={self.position_gain})"
        )


def jerk_limited_box(limits: JointLimits, lim: np.ndarray, q: np.ndarray, dt: float, dq_prev: np.ndarray | None,
                     dq_prev2: np.ndarray | None) -> LimitBox:  # fmt: skip
    """The box of a bound ``limits`` with a jerk limit (module docstring), its joint-limit record ``lim``
    (``LIM_JERK_ROWS``, nv): the acceleration-limited box of every joint, then the jerk window and the viability
    bound where a jerk limit is set, relaxed in the documented order where they leave nothing.

    Raises:
        ResolverError: ``q`` is a stack of configurations.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 1:
        raise ResolverError("limits: a jerk limit needs one configuration per box (no batches of configurations)")
    nv = lim.shape[1]
    v1 = np.zeros(nv) if dq_prev is None else np.asarray(dq_prev, dtype=float).reshape(nv)
    v2 = (np.zeros(nv) if dq_prev is None else v1) if dq_prev2 is None else np.asarray(dq_prev2, dtype=float)
    position, rate, gain, q1 = limits.position, limits._has_rate, limits.position_gain, q.reshape(1, -1)
    base = np.empty((OUT_BOX, 1, nv))
    K.limit_box(q1, limits._iq, lim, position, rate, gain, dt, v1.reshape(1, -1) if rate else limits._no_prev, base)
    lb, ub, pl, pu = (row.copy() for row in base[:, 0])
    rate_lo, rate_hi = lb.copy(), ub.copy()
    out = np.empty((JERK_ROWS, nv))
    status = np.zeros(nv, dtype=np.int64)
    JK.jerk_box(q, limits._iq, lim, position, gain, dt, v1, v2, out, status)
    jmax = lim[LIM_JMAX]
    jerk = np.isfinite(jmax)
    ok = jerk & (status == 0)
    empty = jerk & (status != 0)
    lb[ok], ub[ok] = out[JERK_LB, ok], out[JERK_UB, ok]
    # the braking bound is the position's where it cuts the window (else the window's end is the jerk's or the rate's)
    pl[ok] = np.where(out[JERK_BRAKE_LO] > out[JERK_WINDOW_LO], out[JERK_BRAKE_LO], -np.inf)[ok]
    pu[ok] = np.where(out[JERK_BRAKE_HI] < out[JERK_WINDOW_HI], out[JERK_BRAKE_HI], np.inf)[ok]
    d1 = v1 - v2
    beta = jmax * dt * dt
    jlo, jhi = v1 + d1 - beta, v1 + d1 + beta
    rate_lo[ok], rate_hi[ok] = out[JERK_WINDOW_LO, ok], out[JERK_WINDOW_HI, ok]
    relaxed: tuple[str, ...] = ()
    if empty.any():  # jerk first: the acceleration-limited box, and in it the q̇ closest to the jerk window
        relaxed = (JERK_RELAXED,)
        lb[empty] = np.clip(jlo[empty], rate_lo[empty], rate_hi[empty])
        ub[empty] = np.clip(jhi[empty], rate_lo[empty], rate_hi[empty])
        if rate:  # then the acceleration: its window did not meet the position/velocity box
            free = np.empty((OUT_BOX, 1, nv))
            K.limit_box(q1, limits._iq, lim, position, rate, gain, dt, limits._no_prev, free)
            step = lim[LIM_AMAX] * dt
            moved = empty & ((v1 - step > free[OUT_UB, 0]) | (v1 + step < free[OUT_LB, 0]))
            if moved.any():
                relaxed += (ACCELERATION_RELAXED,)
    return LimitBox(lb, ub, pl, pu, lim[LIM_VMAX], rate_lo, rate_hi, jlo, jhi, relaxed)
