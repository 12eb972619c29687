"""Singularity-aware stepping and the joint-speed cap, shared by every resolver (issue 33, item 3).

Every :meth:`~redundik.resolvers.Resolver.step` passes its answer q̇ through a ``SpeedLimiter`` before
returning it. Two things may act there, both reported on the step's result:

**The joint-speed cap** (resolver option ``max_joint_speed`` [rad/s, or m/s for a prismatic joint]). When some
|q̇_i| exceeds its cap c_i, the whole q̇ is scaled by s = min_i c_i/|q̇_i| (the direction is kept, so the task-space
motion is the commanded one, slower). ``"auto"`` (the default) takes each joint's velocity limit from the robot
model, and :data:`DEFAULT_MAX_JOINT_SPEED` where the model has none; a number caps every joint at that value;
``None`` switches the cap off. Under ``wqp`` and ``hqp`` with the model's limits the QP already keeps q̇ inside the
velocity limits, so the cap never acts there; it catches what the closed forms (``pinv``, ``feedback``) and an
unlimited QP would otherwise return near a singularity or for a reference jump over a tiny dt (10⁸–10⁹ rad/s).
Acting, it sets ``result.info["capped"] = True`` and ``info["speed_scale"] = s``, and adds ``"max_joint_speed"`` to
``result.relaxed``.

**The singularity guard** (resolver option ``singularity``: a :class:`SingularityGuard`, a mapping of its fields,
``True`` for the defaults, ``None``/``False`` for none). At each step it measures the stacked main-task Jacobian J
(m×n, singular values σ_1 ≥ … ≥ σ_r, r = min(m, n)):

* σ_min = σ_r [unit of J], the condition number κ = σ_1/σ_r (∞ when σ_r = 0), and Yoshikawa's manipulability
  w = Π σ_i = √det(J Jᵀ) (for m ≤ n);
* states with hysteresis: ``"ok"`` → ``"decelerate"`` when κ > ``slow_at``; → ``"halt"`` when κ ≥ ``halt_at``; back
  to ``"ok"`` only when κ < ``release_at`` (< ``slow_at``), so a κ hovering at a threshold does not toggle states;
* ``"decelerate"``: when q̇ approaches the singularity (∇w·q̇ < 0, to first order), q̇ is scaled by the smoothstep
  s(x) = 1 − 3x² + 2x³ of x = (κ − slow_at)/(halt_at − slow_at) ∈ [0, 1]; motion away from it (∇w·q̇ ≥ 0) is not
  slowed;
* above ``release_at`` (any state but ``"halt"``) an approaching step is also scaled so that it loses at most the
  fraction ``max_loss`` of w to first order (−dt ∇w·q̇ ≤ max_loss·w, a velocity damper): a long step cannot jump
  across the singularity between two samples, so κ is seen rising and the guard halts in time;
* ``"halt"``: only motion that does not approach the singularity passes: when ∇w·q̇ < 0, its component along ∇w is
  removed (q̇ ← q̇ − (∇w·q̇/‖∇w‖²) ∇w, so ∇w·q̇ = 0), and what is left passes only if it still serves the command
  (Vᵀ J q̇ > 0 for the main tasks' commanded velocity V; else q̇ = 0: near a singularity the rest of a damped
  least-squares answer mostly swings the arm off the target); motion away (∇w·q̇ ≥ 0) passes whole. Without a
  gradient (a main task whose ∂J/∂q is not known, see below) an approaching halted step returns q̇ = 0.

∇w is exact: with J = Σ σ_i u_i v_iᵀ, ∂w/∂q_k = Σ_i (Π_{l≠i} σ_l) u_iᵀ (∂J/∂q_k) v_i (as
:class:`~redundik.tasks.Manipulability`), ∂J/∂q_k from
:meth:`~redundik.kinematics.RobotModel.frame_jacobian_derivatives` for frame tasks and 0 for identity rows (a
posture). Other main tasks have no known ∂J/∂q: the guard then scales without the direction test and halts fully.

The guard reports on every step (it is the only cost it adds: one SVD of J, plus ∂J/∂q near a singularity):
``result.info["condition"]``, ``["manipulability"]``, ``["singularity"]`` (the state),
``["singularity_state"]`` (0, 1, 2 for the run's CSV) and ``["singularity_scale"]`` (the factor applied, 1 when none);
when it changed q̇, ``"singularity"`` is added to ``result.relaxed`` (σ_min is ``result.sigma_min``, as without a
guard). Without a guard nothing is measured on the hot path; :func:`measure` gives the three measures of any step's
result on request.

Under ``wqp`` and ``hqp`` a changed q̇ is clipped again to the step's limit box (position, velocity and the rate
window around the previous q̇), so slowing down never brakes harder than the acceleration limits allow, and the
resolver's previous q̇ (its rate window and warm start) becomes the q̇ returned. ``dq_rank``/``dq_null`` stay the
resolver's parts before the limiter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from redundik.errors import ResolverError
from redundik.resolvers.linalg import K

if TYPE_CHECKING:
    from redundik.kinematics.model import RobotModel
    from redundik.resolvers.base import Resolver, StepResult
    from redundik.tasks.stack import TaskStack

#: The cap [rad/s or m/s] of a joint whose model gives no velocity limit (``max_joint_speed="auto"``).
DEFAULT_MAX_JOINT_SPEED = 10.0
#: ``SpeedLimiter.folded_caps`` of a resolver without a cap, or whose cap a compiled step does not test.
NO_CAPS = np.zeros(0)  # (writeable: a read-only array is another type for numba, another specialisation)
#: ``result.info["singularity"]`` values, and their codes in ``info["singularity_state"]`` (the run's CSV).
OK, DECELERATE, HALT = "ok", "decelerate", "halt"
STATE_CODES = {OK: 0, DECELERATE: 1, HALT: 2}


@dataclass(frozen=True)
class SingularityGuard:
    """Thresholds of the singularity guard on the condition number κ = σ_max/σ_min of the main-task Jacobian.

    The defaults sit above what the Panda's 6-D tool Jacobian shows in ordinary configurations (median κ ≈ 23 over
    random configurations; its position rows ≈ 4) and well below the boundary of its workspace (κ → ∞): pick
    thresholds from the measured ``info["condition"]`` of your own stack (the rows' units set κ's scale).

    Args:
        slow_at: κ above which a step that approaches the singularity is slowed down (> release_at).
        halt_at: κ at or above which the guard halts motion towards the singularity (≥ slow_at; ``inf``: never).
        release_at: κ below which a decelerating or halted guard returns to ``"ok"`` (≥ 1, < slow_at).
        max_loss: Largest fraction of the manipulability w a step above ``release_at`` may lose to first order,
            −dt ∇w·q̇ ≤ max_loss·w (in (0, 1]): the velocity damper that keeps a long step from jumping across the
            singularity between two samples (where κ would never be seen above ``halt_at``).

    Raises:
        ResolverError: a threshold that is not a number, or an order other than 1 ≤ release_at < slow_at ≤ halt_at.
    """

    slow_at: float = 40.0
    halt_at: float = 120.0
    release_at: float = 30.0
    max_loss: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            val = getattr(self, f.name)
            if isinstance(val, (bool, np.bool_)) or not isinstance(val, (int, float, np.integer, np.floating)):
                raise ResolverError(f"singularity.{f.name} must be a number, got {val!r}")
            if math.isnan(val):
                raise ResolverError(f"singularity.{f.name} must be a number, got NaN")
            object.__setattr__(self, f.name, float(val))
        if not 0.0 < self.max_loss <= 1.0:
            raise ResolverError(f"singularity.max_loss must be in (0, 1], got {self.max_loss:g}")
        if not (1.0 <= self.release_at < self.slow_at <= self.halt_at) or math.isinf(self.slow_at):
            raise ResolverError(
                "singularity: expected 1 ≤ release_at < slow_at ≤ halt_at (condition numbers; slow_at finite), got "
                f"release_at={self.release_at:g}, slow_at={self.slow_at:g}, halt_at={self.halt_at:g}"
            )

    def slowdown(self, kappa: float) -> float:
        """The deceleration factor s(κ) ∈ [0, 1]: 1 up to ``slow_at``, 0 from ``halt_at``, a smoothstep between."""
        if kappa <= self.slow_at:
            return 1.0
        if kappa >= self.halt_at:
            return 0.0
        x = (kappa - self.slow_at) / (self.halt_at - self.slow_at)
        return 1.0 - x * x * (3.0 - 2.0 * x)

    def next_state(self, state: str, kappa: float) -> str:
        """The state after ``state`` at condition number ``kappa`` (the hysteresis of the module docstring)."""
        if kappa >= self.halt_at:
            return HALT
        if state == OK:
            return DECELERATE if kappa > self.slow_at else OK
        if kappa < self.release_at:
            return OK
        if state == HALT:
            return HALT
        return DECELERATE

    @classmethod
    def coerce(cls, value: object, who: str) -> SingularityGuard | None:
        """The guard a resolver option gives: an instance, a mapping of its fields, ``True`` (defaults), or
        ``None``/``False`` (none).

        Raises:
            ResolverError: anything else, or an unknown key (names it and lists the known ones).
        """
        if value is None or value is False:
            return None
        if value is True:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, dict):
            known = [f.name for f in fields(cls)]
            bad = [str(k) for k in value if k not in known]
            if bad:
                raise ResolverError(f"{who}: singularity: unknown key(s) {bad}; expected some of {known}")
            try:
                return cls(**value)
            except ResolverError as exc:
                raise ResolverError(f"{who}: {exc}") from None
        raise ResolverError(
            f"{who}: singularity must be a SingularityGuard, a mapping of {[f.name for f in fields(cls)]}, true or "
            f"null, got {type(value).__name__} {value!r:.60}"
        )


def check_max_joint_speed(value: object, who: str) -> float | str | None:
    """The validated ``max_joint_speed`` option: ``"auto"``, ``None`` (no cap) or a finite number > 0 [rad/s].

    Raises:
        ResolverError: anything else.
    """
    if value is None or (isinstance(value, str) and value == "auto"):
        return value
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ResolverError(
            f"{who}: max_joint_speed must be a number > 0 [rad/s], 'auto' (the robot's velocity limits) or None "
            f"(no cap), got {type(value).__name__} {value!r:.60}"
        )
    if not (math.isfinite(value) and value > 0):
        raise ResolverError(f"{who}: max_joint_speed must be a finite number > 0 [rad/s], got {value!r}")
    return float(value)


def cap_rows(dq: np.ndarray, caps: np.ndarray) -> np.ndarray:
    """Scale in place each row of q̇ (N, nv) that has some |q̇_i| > caps_i, as one step's cap does (the batch
    form); returns which rows were scaled, shape (N,)."""
    if dq.size == 0:
        return np.zeros(dq.shape[0], dtype=bool)
    over = np.max(np.abs(dq) / caps, axis=1)
    mask = over > 1.0
    if mask.any():
        dq[mask] *= (1.0 / over[mask])[:, None]
    return np.asarray(mask)


def singular_values(J: np.ndarray) -> tuple[float, float, float]:
    """(σ_min, κ, w) of a Jacobian J [unit of J, 1, unit of J^r]: its smallest of r = min(m, n) singular values,
    the condition number σ_max/σ_min (∞ when σ_min = 0; 1 for an empty J) and Π σ_i = √det(J Jᵀ) for m ≤ n."""
    if J.size == 0:
        return math.inf, 1.0, 1.0
    # the eigenvalues σ_i² of the smaller Gram matrix (J Jᵀ or JᵀJ): a third of an SVD's time; κ keeps ~8 digits
    # up to 1e4 and stays a large number beyond, which is all the thresholds need
    gram = J @ J.T if J.shape[0] <= J.shape[1] else J.T @ J
    s = np.sqrt(np.maximum(np.linalg.eigvalsh(gram)[::-1], 0.0))
    smin, smax = float(s[-1]), float(s[0])
    kappa = smax / smin if smin > 0.0 else math.inf
    return smin, kappa, float(np.prod(s))


def main_jacobian(res: StepResult, nv: int) -> np.ndarray:
    """The main tasks' Jacobians of a step's result, stacked (m, nv)."""
    terms = res.main_terms
    if len(terms) == 1:
        return np.asarray(terms[0].J, dtype=float)
    if not terms:
        return np.zeros((0, nv))
    return np.vstack([t.J for t in terms])


def main_velocity(res: StepResult) -> np.ndarray:
    """The main tasks' commanded velocities V of a step's result, stacked (m,)."""
    terms = res.main_terms
    return np.concatenate([np.asarray(t.v, dtype=float).reshape(-1) for t in terms]) if terms else np.zeros(0)


def measure(res: StepResult, robot: RobotModel) -> dict[str, float]:
    """``{"sigma_min", "condition", "manipulability"}`` of a step's main-task Jacobian (what the guard reports),
    for a result of a resolver without a guard."""
    smin, kappa, w = singular_values(main_jacobian(res, robot.nv))
    return {"sigma_min": smin, "condition": kappa, "manipulability": w}


def _main_tasks(res: StepResult, stack: TaskStack) -> list[Any]:
    """The stack's tasks behind ``res.main_terms``, in that order (matched by name)."""
    by_name = {task.name: task for task in stack.tasks}
    return [by_name.get(term.name) for term in res.main_terms]


def jacobian_derivatives(res: StepResult, robot: RobotModel, stack: TaskStack) -> np.ndarray | None:
    """∂J/∂q of the stacked main-task Jacobian, shape (m, nv, nv) with ``H[:, :, k] = ∂J/∂q_k``; ``None`` when a
    main task is neither a frame task (rows of its frame's base-aligned Jacobian) nor an identity block."""
    from redundik.tasks.base import FrameForm

    nv = robot.nv
    blocks = []
    for task, term in zip(_main_tasks(res, stack), res.main_terms, strict=True):
        if task is None:
            return None
        form = task.frame_form(robot)  # the task's rows are its frame's (its public form): ∂J/∂q is the frame's
        if isinstance(form, FrameForm):
            H = robot.frame_jacobian_derivatives(int(form.fid))
            blocks.append(H[np.asarray(form.rows)])
        elif getattr(task, "identity_jacobian", False) or task.joint_form(robot) is not None:  # (J = I[sel]: constant)
            blocks.append(np.zeros((term.J.shape[0], nv, nv)))
        else:
            return None
    return np.concatenate(blocks, axis=0) if blocks else np.zeros((0, nv, nv))


def manipulability_gradient(J: np.ndarray, H: np.ndarray) -> np.ndarray:
    """∇w of w = Π σ_i(J) (``H[:, :, k] = ∂J/∂q_k``): Σ_i (Π_{l≠i} σ_l) u_iᵀ (∂J/∂q_k) v_i, finite at a
    singularity (where w is not differentiable)."""
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    others = np.array([np.prod(np.delete(s, i)) for i in range(s.size)])
    dsig = np.einsum("mi,mnc,in->ic", U, H, Vt)
    return np.asarray(others @ dsig)


class SpeedLimiter:
    """One resolver's cap and guard, with the guard's state between steps (see the module docstring)."""

    def __init__(self, guard: SingularityGuard | None, cap: float | str | None) -> None:
        self.guard = guard
        self.cap = cap
        self.state = OK
        self._caps: tuple[Any, np.ndarray, float] | None = None  # (robot, per-joint cap, its smallest entry)
        self._inv = np.zeros(0)  # 1 / the per-joint cap
        self.floor = 0.0  # ‖q̇‖₂ at or below which no joint can exceed its cap (the hot path's test)
        #: a QP resolver's previous q̇ as the last step left it (the rate window of the next step), else ``None``
        self.seen: np.ndarray | None = None

    def __getstate__(self) -> dict[str, Any]:
        """Copied and pickled without the caps (built for one robot object; built again on first use)."""
        state = dict(self.__dict__)
        state["_caps"], state["floor"] = None, 0.0
        return state

    def reset(self) -> None:
        """Forget the guard's state, the previous q̇ and the caps (``Resolver.reset``; a new robot may follow)."""
        self.state = OK
        self.seen = None
        self._caps = None
        self.floor = 0.0

    def caps(self, robot: RobotModel) -> np.ndarray | None:
        """The per-joint cap for ``robot`` (built once per robot), or ``None`` without a cap."""
        if self.cap is None:
            return None
        cached = self._caps
        if cached is None or cached[0] is not robot:
            if self.cap == "auto":
                vel = np.asarray(robot.velocity_limits, dtype=float)
                c = np.where(np.isfinite(vel) & (vel > 0.0), vel, DEFAULT_MAX_JOINT_SPEED)
            else:
                c = np.full(robot.nv, float(self.cap))
            cached = self._caps = (robot, c, float(c.min()) if c.size else math.inf)
            self.floor, self._inv = cached[2], 1.0 / c
        return cached[1]

    def folded_caps(self, robot: RobotModel) -> np.ndarray:
        """1 / the per-joint caps [s/rad] for a compiled step to test its q̇ against (``fused_kernels.cap_ratio``:
        max_i |q̇_i| / c_i, returned with q̇), when that test is the whole of :meth:`binds`: no guard and the caps
        built for ``robot``; else an empty array (the step's q̇ goes through :meth:`binds`)."""
        cached = self._caps
        if self.guard is None and cached is not None and cached[0] is robot:
            return self._inv
        return NO_CAPS

    def binds(self, dq: np.ndarray, norm: float) -> bool:
        """Whether :meth:`apply` has work this step: a guard is set, the caps are not built yet, or ‖q̇‖ [rad/s]
        exceeds :attr:`floor` and some joint its cap (max_i |q̇_i| / c_i > 1: one compiled call)."""
        if self.guard is not None or self._caps is None:
            return True
        return norm > self.floor and float(K.scaled_max(dq, self._inv)) > 1.0

    def apply(
        self, resolver: Resolver, robot: RobotModel, stack: TaskStack, res: StepResult, dt: float, norm: float
    ) -> tuple[StepResult, float]:
        """The step's result after the guard and the cap, and its ‖q̇‖ (``Resolver.step`` calls this when a guard
        is set or ‖q̇‖ exceeds :attr:`floor`)."""
        dq = res.dq
        relaxed: list[str] = []
        if self.guard is not None:
            dq = self._guard(robot, stack, res, dq, dt)
            if dq is not res.dq:
                relaxed.append("singularity")
                norm = math.sqrt(float(dq.dot(dq)))
        caps = self.caps(robot)
        if caps is not None and norm > self.floor:
            over = float(K.scaled_max(dq, self._inv))  # max_i |q̇_i| / c_i, one compiled call
            if over > 1.0:
                s = 1.0 / over
                dq = dq * s
                relaxed.append("max_joint_speed")
                info = res.info
                info["capped"], info["speed_scale"] = True, s
        if relaxed:
            dq = _reclip(resolver, robot, dq, dt, self.seen)
            res.dq = dq
            res.relaxed = (*res.relaxed, *relaxed)
            norm = math.sqrt(float(dq.dot(dq)))
        return res, norm

    def _guard(self, robot: RobotModel, stack: TaskStack, res: StepResult, dq: np.ndarray, dt: float) -> np.ndarray:
        """q̇ after the guard (``dq`` itself when unchanged); writes the measures and the state into the info."""
        guard = self.guard
        assert guard is not None
        J = main_jacobian(res, robot.nv)
        _, kappa, w = singular_values(J)
        state = self.state = guard.next_state(self.state, kappa)
        info = res.info
        info["condition"], info["manipulability"] = kappa, w
        info["singularity"], info["singularity_state"] = state, STATE_CODES[state]
        scale, out = 1.0, dq
        if state != OK or kappa > guard.release_at:
            H = jacobian_derivatives(res, robot, stack)
            g = None if H is None else manipulability_gradient(J, H)
            slope = -math.inf if g is None else float(g.dot(dq))  # ∇w·q̇; without ∇w: treated as approaching
            if slope < 0.0:
                if state == HALT:
                    gg = 0.0 if g is None else float(g.dot(g))
                    out = dq - (slope / gg) * g if g is not None and gg > 0.0 else np.zeros_like(dq)
                    V = main_velocity(res)
                    if float(V.dot(J @ out)) <= 0.0:  # what is left does not serve the command: stand still
                        out = np.zeros_like(dq)
                    n0 = float(dq.dot(dq))
                    scale = math.sqrt(float(out.dot(out)) / n0) if n0 > 0.0 else 0.0
                else:
                    scale = guard.slowdown(kappa) if state == DECELERATE else 1.0
                    if g is not None:  # the velocity damper needs ∇w
                        scale = min(scale, guard.max_loss * w / (-slope * dt))
                    if scale < 1.0:
                        out = dq * scale
        info["singularity_scale"] = scale
        return out


def _reclip(resolver: Resolver, robot: RobotModel, dq: np.ndarray, dt: float, prev: np.ndarray | None) -> np.ndarray:
    """A QP resolver's changed q̇ clipped again to its step's limit box (``prev``: the q̇ its rate window was built
    around), and made its previous q̇; any other resolver's q̇ as it is."""
    limits = getattr(resolver, "limits", None)
    if limits is None or "_dq_prev" not in resolver.__dict__ or not hasattr(limits, "box"):
        return dq
    box = limits.box(robot, robot.q, dt, prev)
    out = np.asarray(box.clip(dq), dtype=float)
    resolver._dq_prev = out.copy()  # type: ignore[attr-defined]
    return out


class LimiterOption:
    """A resolver option of its ``SpeedLimiter`` (``singularity`` or ``max_joint_speed``), validated on
    assignment; an assignment rebuilds the limiter (the guard's state starts at ``"ok"``). Unset, both are ``None``:
    a :class:`~redundik.resolvers.Resolver` subclass that never assigns them has neither cap nor guard."""

    def __init__(self) -> None:
        self._name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self._name = name

    def __get__(self, obj: object, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        return obj.__dict__.get("_opt_" + self._name)

    def __set__(self, obj: Any, value: object) -> None:
        who = str(getattr(obj, "name", type(obj).__name__))
        d = obj.__dict__
        if self._name == "singularity":
            d["_opt_singularity"] = SingularityGuard.coerce(value, who)
        else:
            d["_opt_" + self._name] = check_max_joint_speed(value, who)
        guard, cap = d.get("_opt_singularity"), d.get("_opt_max_joint_speed")
        d["_limiter"] = None if guard is None and cap is None else SpeedLimiter(guard, cap)
