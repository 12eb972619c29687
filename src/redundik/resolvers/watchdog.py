"""Command watchdog: when no target has been set for ``command_timeout`` seconds, bring the robot to rest.

A resolver with a watchdog (``resolver.command_timeout = 0.25``, or ``make_resolver("wqp", command_timeout=0.25)``)
compares, at every step, the targets its stack holds with those of the step before. A *command* is any of:

* ``FrameTask.set_target`` (even the same pose again: it moves the hold's ``Trajectory.revision``), a new
  ``FrameTask.trajectory``, a reset of a frame task that anchors its trajectory anew (a held target set with
  ``set_target`` survives a reset unchanged: not a command);
* ``PostureTask.set_target`` and ``CoMTask.set_target`` (each writes a new target array);
* a new value of a ``TargetSubtask``'s or ``PotentialTask``'s target or target rate (the same value again is not
  seen: call :meth:`Watchdog.feed` to keep such a stream alive);
* :meth:`Watchdog.feed`, an explicit keep-alive (for targets that arrive through other means).

Time is the ``t`` given to ``resolver.step``: when ``t`` − (time of the last command) exceeds the timeout, the
watchdog goes from ``"armed"`` to ``"stopping"``. The targets are left as they were (frozen: nothing is written into
the stack) and the resolver still solves every step, but the q̇ the step returns is the watchdog's: it decelerates
from the last q̇ sent to rest, within the deceleration limit a_max [rad/s²] (the watchdog's ``acceleration``, else the
resolver's ``limits.acceleration``) and, when one is configured, the jerk limit j_max [rad/s³] (the watchdog's
``jerk``, else the resolver's ``limits.jerk`` where its limits have one):

* without a jerk limit, q̇ is scaled down uniformly, q̇_k = (1 − r) q̇_{k−1} with r = min(1, min_i a_max,i dt / |q̇_i|):
  the joint that needs longest brakes at exactly a_max,i and the others in proportion, so the joint path keeps its
  direction (a category-2-like stop); rest is reached after ⌈max_i |q̇_i| / (a_max,i dt)⌉ steps;
* with a jerk limit, each joint brakes on its own with the largest deceleration from which the acceleration can
  return to zero at j_max exactly as the velocity reaches zero (a discrete S-curve, :func:`jerk_step`), so
  |q̈| ≤ a_max and |q⃛| ≤ j_max at every step from a state within them; the path's direction is not kept.

For ``wqp`` and ``hqp`` the decelerating q̇ is then clipped to the resolver's joint-limit box (position, velocity,
braking; :meth:`~redundik.resolvers.qp.limits.JointLimits.box`): position and velocity limits win over the stop
profile (the braking bound keeps a joint slow enough to stop in time, so the clip rarely acts). Once every q̇_i is 0
the state is ``"stopped"`` and q̇ = 0.

A new command while ``"stopping"`` or ``"stopped"`` resumes control smoothly: the state is ``"resuming"`` and the
watchdog moves the q̇ it sends towards the resolver's own q̇ within the same limits (uniformly, or per joint with
the jerk limit), and hands control back (``"armed"``) at the first step the resolver's q̇ is within reach. The QP
resolvers' rate windows are kept on the q̇ actually sent, so their next steps continue from it.

Each step reports, in ``result.info``: ``watchdog`` (the state), ``command_age`` [s] (t − the last command) and
``command_stale`` (True while ``"stopping"`` or ``"stopped"``: the flag to alarm on). ``t`` running backwards (a
loop restarted at 0) counts as a command.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from redundik.errors import ResolverError, short_repr

if TYPE_CHECKING:
    from redundik.kinematics.model import RobotModel
    from redundik.resolvers.base import Resolver, StepResult
    from redundik.tasks.stack import TaskStack

ARMED, STOPPING, STOPPED, RESUMING = "armed", "stopping", "stopped", "resuming"
#: States in which the commands are stale (``result.info["command_stale"]``).
STALE = frozenset((STOPPING, STOPPED))
#: |q̇_i| [rad/s] below which a joint braked with a jerk limit counts as at rest.
REST = 1e-12


def _limit(value: object, key: str, *, allow_inf: bool) -> float | np.ndarray | None:
    """A positive bound (one number or one per velocity coordinate), or ``None``; a ResolverError otherwise."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        raise ResolverError(f"watchdog: {key} must be a number > 0 or an array of them, got {short_repr(value)}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros(0)  # (refused below)
    ok = arr.ndim <= 1 and arr.size > 0 and bool(np.all(arr > 0)) and (allow_inf or bool(np.all(np.isfinite(arr))))
    if not ok:
        what = "> 0 (inf: no limit)" if allow_inf else "finite and > 0"
        raise ResolverError(f"watchdog: {key} must be {what} [per second], got {short_repr(value)}")
    return float(arr) if arr.ndim == 0 else arr.copy()


class CommandReader:
    """Where a stack's members hold their targets (see the module docstring for what counts), read at every step.

    Built once per stack membership: the (member ``__dict__``, key) pairs of the target objects and numbers, and the
    dicts of the frame tasks whose trajectory's ``revision`` moves on an in-place target write. :meth:`changed`
    compares them with the last step's values: objects by identity, numbers by value.

    A copy or a pickle (made together with the stack, as a resolver's is) reads the copied members: the dicts are
    taken again from the copied members (``__setstate__``; a copied ``__dict__`` would be a detached dict that
    no target write reaches), and the last values are the copied targets, so the copy's next step sees a command
    exactly when the original's would.
    """

    _KEYS = ("_trajectory", "_given", "_pending_position", "_target", "_target_rate")

    def __init__(self, stack: TaskStack) -> None:
        self.sources: list[tuple[object, str]] = []  # (member, key): where each entry is read
        self.owned: list[object] = []  # members with a trajectory
        for member in (*stack.tasks, *stack.subtasks):
            self._add(member)
        self._bind()
        self.values: list[object] = [d.get(key) for d, key in self.entries]
        self.revisions: list[int] = [getattr(d.get("_trajectory"), "_revision", 0) for d in self.owners]

    def _add(self, member: object) -> None:
        d = getattr(member, "__dict__", None)
        if d is None:
            return
        for key in self._KEYS:
            if key in d:
                self.sources.append((member, key))
        if "_trajectory" in d:
            self.owned.append(member)
        row = d.get("_row")
        if row is not None:  # a PotentialTask's target subtask
            self._add(row)

    def _bind(self) -> None:
        """The members' ``__dict__`` objects :meth:`changed` reads (one lookup per entry at each step)."""
        self.entries: list[tuple[dict[str, object], str]] = [(vars(m), key) for m, key in self.sources]
        self.owners: list[dict[str, object]] = [vars(m) for m in self.owned]

    def __getstate__(self) -> dict[str, object]:
        """The members, keys and last values, without the members' dicts (taken again from the copied members)."""
        state = self.__dict__.copy()
        del state["entries"], state["owners"]
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self._bind()

    def changed(self) -> bool:
        """True when a target was set since the last call (the values are updated)."""
        fresh = False
        values = self.values
        for i, (d, key) in enumerate(self.entries):
            v = d.get(key)
            old = values[i]
            if v is not old and not (type(v) is float and v == old):
                values[i] = v
                fresh = True
        revisions = self.revisions
        for i, d in enumerate(self.owners):
            rev = getattr(d.get("_trajectory"), "_revision", 0)
            if rev != revisions[i]:
                revisions[i] = rev
                fresh = True
        return fresh


def uniform_brake(v: np.ndarray, amax: np.ndarray, dt: float) -> np.ndarray:
    """One step of the direction-keeping stop: (1 − r) v with r = min(1, min_i amax_i dt / |v_i|) [rad/s]."""
    mag = np.abs(v)
    moving = mag > 0.0
    if not moving.any():
        return np.zeros_like(v)
    r = min(1.0, float(np.min(amax[moving] * dt / mag[moving])))
    return np.zeros_like(v) if r >= 1.0 else v * (1.0 - r)


def uniform_approach(v: np.ndarray, target: np.ndarray, amax: np.ndarray, dt: float) -> tuple[np.ndarray, bool]:
    """One step from v towards ``target`` along the straight line, |Δv_i| ≤ amax_i dt; (v', reached)."""
    delta = target - v
    mag = np.abs(delta)
    moving = mag > 0.0
    if not moving.any():
        return target.copy(), True
    beta = float(np.min(amax[moving] * dt / mag[moving]))
    if beta >= 1.0:
        return target.copy(), True
    return v + beta * delta, False


def jerk_step(
    v: np.ndarray, a: np.ndarray, target: np.ndarray, amax: np.ndarray, jmax: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """One step of each joint towards the velocity ``target`` with |q̈| ≤ amax and |q⃛| ≤ jmax; (v', a').

    The acceleration a' is the one from which ramping it back to zero at jmax (h = jmax·dt per step) brings the
    velocity error e = v − target exactly to zero: with n further steps of nonzero acceleration, the error changes by
    dt·(a' + Σ_{k=1..n} (a' − sign(a') k h)) — piecewise linear and increasing in a' — so
    n = ⌈√(2|e|/(dt h) + ¼) − 3/2⌉⁺ and |a'| = (|e|/dt + h n(n+1)/2)/(n + 1). a' is then clipped to the step's window
    [a − h, a + h] ∩ [−amax, amax]: clipped, the joint brakes as hard as it may and the next step tries again (a
    time-optimal discrete S-curve, as in Kröger's online trajectory generation, Kröger & Wahl, IEEE T-RO 26(1), 2010).
    """
    e = v - target
    h = jmax * dt  # (inf on a joint without a jerk limit: n = 0 there, and the ramp term is dropped)
    n = np.maximum(0.0, np.ceil(np.sqrt(2.0 * np.abs(e) / (dt * h) + 0.25) - 1.5))
    mag = (np.abs(e) / dt + np.where(np.isfinite(h), h, 0.0) * n * (n + 1.0) / 2.0) / (n + 1.0)
    want = -np.sign(e) * mag
    lo = np.maximum(a - h, -amax)
    hi = np.minimum(a + h, amax)
    crossed = lo > hi  # (a start beyond amax + h: back towards the limits as fast as the jerk allows)
    lo = np.where(crossed, np.clip(a - h, -amax, amax), lo)
    hi = np.where(crossed, lo, hi)
    a_new = np.clip(want, lo, hi)
    return v + a_new * dt, a_new


class Watchdog:
    """Stops the robot when the commands go stale (see the module docstring).

    Args:
        timeout: command_timeout [s] > 0: the longest time without a command before the stop.
        acceleration: Deceleration limit a_max [rad/s² or m/s²]: one number or one per velocity coordinate (``inf``
            stops that coordinate at once); ``None``: the resolver's ``limits.acceleration`` (``wqp``, ``hqp``).
        jerk: Jerk limit j_max [rad/s³]: one number or one per coordinate; ``None``: none (uniform stop).

    Raises:
        ResolverError: a timeout that is not a finite number > 0, or limits that are not > 0.
    """

    def __init__(
        self,
        timeout: float,
        *,
        acceleration: float | np.ndarray | None = None,
        jerk: float | np.ndarray | None = None,
    ) -> None:
        self.timeout = timeout
        self.acceleration = acceleration
        self.jerk = jerk
        self.reset()

    @property
    def timeout(self) -> float:
        """command_timeout [s]."""
        return self._timeout

    @timeout.setter
    def timeout(self, value: float) -> None:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ResolverError(f"watchdog: command_timeout must be a number [s], got {short_repr(value)}")
        if not (math.isfinite(value) and value > 0):
            raise ResolverError(f"watchdog: command_timeout must be finite and > 0 [s], got {value!r}")
        self._timeout = float(value)

    @property
    def acceleration(self) -> float | np.ndarray | None:
        """Deceleration limit a_max [rad/s²] (``None``: the resolver's limits')."""
        return self._acceleration

    @acceleration.setter
    def acceleration(self, value: float | np.ndarray | None) -> None:
        self._acceleration = _limit(value, "acceleration", allow_inf=True)

    @property
    def jerk(self) -> float | np.ndarray | None:
        """Jerk limit j_max [rad/s³] (``None``: none)."""
        return self._jerk

    @jerk.setter
    def jerk(self, value: float | np.ndarray | None) -> None:
        self._jerk = _limit(value, "jerk", allow_inf=False)

    def reset(self) -> None:
        """Forget the last command, the q̇ sent and the state (``"armed"``); the next step counts as a command."""
        self.state = ARMED
        self.last_command: float | None = None
        #: (the membership it was built for, the reader): kept by a copy made with the resolver's stack and robot
        #: (it then reads the copied members), so that the copy's next step is not taken for a command
        self._reader: tuple[object, CommandReader] | None = None
        self._fed: float | None = None
        self._dq: np.ndarray | None = None  # the q̇ sent at the last step, and at the step before [rad/s]
        self._before: np.ndarray | None = None
        self._dt = 1.0  # the last step's dt [s]

    def feed(self, t: float | None = None) -> None:
        """Count a command at time ``t`` [s] (``None``: at the next step's t), as a target set would."""
        self._fed = -math.inf if t is None else float(t)

    def apply(
        self, resolver: Resolver, robot: RobotModel, stack: TaskStack, t: float, dt: float, res: StepResult
    ) -> None:
        """Watch one step: update the state from the stack's targets at time ``t`` [s], replace ``res.dq`` while
        stopping, stopped or resuming, and write the state into ``res.info``."""
        key = resolver._members  # (the membership the step checked: a new tuple whenever it changed)
        pair = self._reader
        if pair is None or pair[0] is not key:
            self._reader = (key, CommandReader(stack))
            fresh = True
        else:
            fresh = pair[1].changed()
        last = self.last_command
        if fresh or last is None or t < last:
            last = t
            fresh = True
        if self._fed is not None:
            last = t if self._fed == -math.inf else max(self._fed, last)
            self._fed, fresh = None, True
        self.last_command = last
        age = t - last
        if self._dq is None:  # the first step: the robot is taken to be at rest before it
            self._amax(resolver, robot)  # (a stop without a deceleration limit is refused now, not when it is due)
            self._dq, self._before = np.zeros(robot._nv), np.zeros(robot._nv)
        state = self.state
        if state in (ARMED, RESUMING) and age > self._timeout:
            state = STOPPING
        elif state in STALE and fresh:
            state = RESUMING
        if state == ARMED:
            dq = res.dq
        else:
            dq, state = self._override(resolver, robot, res.dq, state, dt)
            _replace_dq(resolver, res, dq, self._dq)
        # new arrays, never written in place: a shallow snapshot of this object (the simulation's StateGuard around
        # integrator stages) puts the state back; the resolver's q̇ may be a view of its buffers: copied
        self._before, self._dq, self._dt = self._dq, np.array(dq, dtype=float), dt
        self.state = state
        info = _info_dict(res)
        if info is not None:
            dict.__setitem__(info, "watchdog", state)
            dict.__setitem__(info, "command_age", age)
            dict.__setitem__(info, "command_stale", state in STALE)

    def _override(
        self, resolver: Resolver, robot: RobotModel, wanted: np.ndarray, state: str, dt: float
    ) -> tuple[np.ndarray, str]:
        """The q̇ to send while not armed, and the state after this step."""
        prev, before = self._dq, self._before
        assert prev is not None and before is not None
        acc = (prev - before) / self._dt  # the q̈ of the last step [rad/s²]
        if state == STOPPED:
            return np.zeros_like(prev), STOPPED
        amax = self._amax(resolver, robot)
        jmax = self._jmax(resolver, robot)
        target = np.zeros_like(prev) if state == STOPPING else np.asarray(wanted, dtype=float)
        if jmax is None:
            if state == STOPPING:
                dq = uniform_brake(prev, amax, dt)
                reached = not dq.any()
            else:
                dq, reached = uniform_approach(prev, target, amax, dt)
        else:
            dq, a_new = jerk_step(prev, acc, target, amax, jmax, dt)
            near = np.abs(dq - target) <= REST
            reached = bool(near.all() and np.all(np.abs(a_new) <= jmax * dt * (1 + 1e-12)))
            if reached:
                dq = target.copy()
        dq = _clip_to_limits(resolver, robot, dq, prev, before, dt)
        if state == STOPPING:
            return (np.zeros_like(prev), STOPPED) if reached and not dq.any() else (dq, STOPPING)
        return dq, (ARMED if reached else RESUMING)

    @staticmethod
    def _per_joint(value: float | np.ndarray, key: str, nv: int) -> np.ndarray:
        """``value`` as one number per velocity coordinate (a ResolverError when its size is not nv)."""
        if np.ndim(value) and np.size(value) != nv:
            raise ResolverError(f"watchdog: {key} has {np.size(value)} entries, the robot has nv = {nv}")
        return np.broadcast_to(np.asarray(value, dtype=float), (nv,))

    def _jmax(self, resolver: Resolver, robot: RobotModel) -> np.ndarray | None:
        """The jerk limits per velocity coordinate [rad/s³] (inf: none on that joint): the watchdog's, else the
        resolver's ``limits.jerk`` when its limits have one (a number or by joint name); ``None``: no jerk limit."""
        nv = robot._nv
        if self._jerk is not None:
            return self._per_joint(self._jerk, "jerk", nv)
        limits = getattr(resolver, "limits", None)
        jerk = getattr(limits, "jerk", None)
        if jerk is None:
            return None
        if isinstance(jerk, Mapping):
            names = list(getattr(limits, "joint_names", robot.joint_names))
            out = np.full(nv, np.inf)
            for name, value in jerk.items():
                out[names.index(name)] = float(value)
            return out if np.isfinite(out).any() else None
        return np.full(nv, float(jerk))

    def _amax(self, resolver: Resolver, robot: RobotModel) -> np.ndarray:
        """The deceleration limits per velocity coordinate [rad/s²]: the watchdog's, else the resolver's."""
        nv = robot._nv
        given = self._acceleration
        if given is not None:
            return self._per_joint(given, "acceleration", nv)
        limits = getattr(resolver, "limits", None)
        amax = None
        if limits is not None and hasattr(limits, "kernel_args"):
            amax = np.asarray(limits.kernel_args(robot)[4], dtype=float)
        if amax is None or not np.all(np.isfinite(amax)):
            raise ResolverError(
                f"{resolver.name}: command_timeout: the commands went stale but there is no deceleration limit for "
                "every joint to stop with; give the watchdog one (resolver.watchdog.acceleration = a_max [rad/s²], "
                "make_resolver(..., stop_acceleration=...)) or the resolver's limits an acceleration"
            )
        return amax


def _replace_dq(resolver: Resolver, res: StepResult, dq: np.ndarray, prev: np.ndarray | None) -> None:
    """Put the watchdog's q̇ in the result, drop what described the resolver's own, and keep a QP resolver's rate
    (and jerk) window on the q̇ sent: its last q̇ and, where it keeps one, the one before (``prev``)."""
    d = res.__dict__
    d["dq"] = dq
    d.pop("_dq_norm", None)
    d.pop("_cap_ratio", None)
    res.dq_rank = None
    res.dq_null = None
    state = resolver.__dict__
    if "_dq_prev" in state:
        kept = state["_dq_prev"] = dq.copy()
        if "_dq_hist" in state and prev is not None:  # (a resolver that keeps the last two q̇ for a jerk window)
            state["_dq_hist"] = (kept, prev.copy())


def _clip_to_limits(
    resolver: Resolver, robot: RobotModel, dq: np.ndarray, prev: np.ndarray, before: np.ndarray, dt: float
) -> np.ndarray:
    """``dq`` clipped to a QP resolver's joint-limit box for this step (its windows on the last q̇ ``prev`` and, for
    limits that take it, the one ``before``)."""
    limits = getattr(resolver, "limits", None)
    if limits is None or not hasattr(limits, "box"):
        return dq
    if "dq_prev2" in inspect.signature(limits.box).parameters:
        box = limits.box(robot, robot.q, dt, prev, before)
    else:
        box = limits.box(robot, robot.q, dt, prev)
    out: np.ndarray = box.clip(dq)
    return out


def _info_dict(res: StepResult) -> dict[str, Any] | None:
    d = res.__dict__
    info = d["_info"] if "_info" in d else d.get("info")
    return info if isinstance(info, dict) else None
