"""Direction-preserving scaling of ``wqp`` and ``hqp`` (``scaling="direction"``): the main tasks' commanded velocity
V is scaled, never bent, by the hard limits.

Unscaled, a QP resolver tracks V as closely as the limits allow: when a limit binds, J q̇ leaves V's direction (the
hand of a teleoperated arm swerves; 16° median on random Panda states, ``benchmarks/direction_scaling.py``). With
``scaling="direction"`` a step whose limits bind solves, lexicographically,

1. the largest α ∈ [0, 1] such that J q̇ = α V has a solution q̇ within every hard limit — the joint-limit box of the
   step (position through dt, velocity, rate window with braking: :mod:`redundik.resolvers.qp.limits`) and the hard
   inequality rows (``wqp``: every bound subtask, as its QP enforces them; ``hqp``: the safety rows, collision
   dampers, which its template guards last). This is a linear program; with J = U Σ Wᵀ (rank r), x₀ = J⁺V and N an
   orthonormal basis of null(J), every solution is q̇ = α x₀ + N u, and the LP is posed over (α, u) ∈ R^(1 + n − r)
   (scipy's HiGHS, tolerances 1e-10) on the box and rows tightened by a margin of 1e-10 [rad/s, row units], so its
   answer holds the untightened limits with room to spare;
2. the lower levels in what is left, q̇ ∈ {α* x₀ + N u} within the limits: for ``wqp`` its own weighted objective
   ½q̇ᵀPq̇ + qᵀq̇ restricted to u (every level below the main tasks, the null-space objective and the damping); for
   ``hqp`` its own cascade run with the main tasks' targets α*V, whose answer is then moved to the nearest point
   (in ‖q̇‖) of the same set — the hierarchy below the main tasks as the cascade resolves it, the main tasks exact.
   Both are small QPs over u solved by the resolver's backend; their answer is checked against the untightened
   limits and, if a backend's tolerance left it outside, moved toward the LP's point (inside by the margin) until it
   is inside. J q̇ = α* V holds to rounding by construction (q̇ = α* x₀ + N u for every u).

A step whose limits do not bind has α = 1 without an LP. For ``hqp``: its unconstrained cascade is within every
limit (``info["qp"] == 0``, no fallback) and meets V (‖J q̇ − V‖ ≤ 1e-9‖V‖; a damped singular step does not): the
unscaled step itself, the same q̇ bit for bit. For ``wqp``: its objective minimised on J q̇ = V (a closed form) is
within every limit: that q̇, which differs from the unscaled one by the O(``level_ratio``) pull of the levels below
the main tasks (and of the damping) on J q̇ — the unscaled ``wqp`` bends V by up to ~1e-3 rad even when no limit
binds, the direction mode does not.

Where no α > 0 exists: a rank-deficient main-task Jacobian whose V leaves its range (‖V − UUᵀV‖ > 1e-9‖V‖, r from
σ > 1e-10 σ_max), or limits that allow no motion along V, give α = 0, and q̇ comes from the lower levels within
{J q̇ = 0} and the limits (q̇ = 0 when they ask nothing). When even α = 0 is out of reach (a rate window or a start
outside a limit that forces a motion J cannot avoid; hard rows contradicting the box), the step is the unscaled one
with ``scale`` 0 and ``stuck`` set, and ``fallback`` says why; a ``wqp`` whose bound subtasks make the LP
infeasible first drops those that are not safety rows, as its QP does (``fallback`` says so).

``result.scale`` is α (1.0 when not scaling), ``result.stuck`` is α < ``stuck_below`` (default 1e-3);
``info["scale"]`` logs α per step and ``info["direction"]`` how the step went (``"free"``, ``"scaled"``,
``"unreachable"``). The mode takes the interpreted step (each member's ``evaluate``, then build): the fused
compiled steps do not express the LP. A binding step (the LP through scipy's HiGHS, most of it scipy's wrapper, and
a second QP; ``hqp`` also its cascade at αV) takes ~5 ms on the Panda against ~1 ms unscaled
(``benchmarks/direction_scaling.py``): a mode for teleoperation and servoing at a few hundred hertz, not for the
kilohertz loops of the compiled path. The batch API refuses it.

Drake's ``DoDifferentialInverseKinematics`` poses one QP with the same constraint J q̇ = αV and a cost −100 α plus the
nominal-posture terms, so α trades against the lower objectives with a weight of 100; here α comes first, strictly.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import StepResult
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.settings import Setting
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import TaskStack

if TYPE_CHECKING:
    from redundik.resolvers.qp.base import QPResolverBase

#: The values of the ``scaling`` setting.
SCALING_MODES = ("off", "direction")
#: Margin [rad/s, row units] by which the LP tightens every hard limit (its answer is inside by this much).
MARGIN = 1e-10
#: Relative singular value under which a direction of the main-task Jacobian counts as lost (rank).
RANK_RCOND = 1e-10
#: Relative part of V outside range(J) above which no α > 0 exists.
RANGE_TOL = 1e-9


def scaling_mode(who: str, key: str, val: object) -> str:
    """One of :data:`SCALING_MODES`."""
    if not isinstance(val, str) or val not in SCALING_MODES:
        raise ResolverError(f"{who}: {key} must be one of {list(SCALING_MODES)}, got {val!r}")
    return val


def stuck_threshold(who: str, key: str, val: object) -> float:
    """A number in [0, 1]."""
    if isinstance(val, (bool, np.bool_)) or not isinstance(val, (int, float, np.integer, np.floating)):
        raise ResolverError(f"{who}: {key} must be a number in [0, 1], got {type(val).__name__} {val!r}")
    x = float(val)
    if not 0.0 <= x <= 1.0:
        raise ResolverError(f"{who}: {key} must be a number in [0, 1], got {val!r}")
    return x


class DirectionScaling:
    """The settings of the direction-preserving mode, shared by ``wqp`` and ``hqp`` (this module's docstring).

    Attributes:
        scaling: ``"off"`` (default: the resolver's own answer) or ``"direction"``.
        stuck_below: α under which ``result.stuck`` is set, in [0, 1] (default 1e-3).
    """

    scaling = Setting(scaling_mode)
    stuck_below = Setting(stuck_threshold)


class Affine:
    """The solutions of J q̇ = α V: q̇ = α x₀ + N u (x₀ = J⁺V, N an orthonormal basis of null(J), n × k).

    Attributes:
        x0: J⁺V (n,) [q̇ per unit α]; zero when V leaves range(J) (``reachable`` False).
        N: Null-space basis (n, k).
        reachable: False when V has a part outside range(J) (then only α = 0 solves J q̇ = αV).
    """

    def __init__(self, J: np.ndarray, V: np.ndarray) -> None:
        n = J.shape[1]
        if J.shape[0] == 0:
            self.x0, self.N, self.reachable = np.zeros(n), np.eye(n), True
            return
        U, s, Wt = np.linalg.svd(J)
        r = int(np.sum(s > RANK_RCOND * s[0])) if s.size and s[0] > 0.0 else 0
        Ur = U[:, :r]
        c = Ur.T @ V
        outside = float(np.linalg.norm(V - Ur @ c))
        self.reachable = outside <= RANGE_TOL * max(float(np.linalg.norm(V)), 1e-300) or not V.any()
        self.x0 = Wt[:r].T @ (c / s[:r]) if self.reachable else np.zeros(n)
        self.N = np.ascontiguousarray(Wt[r:].T)


def _rows(lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray, margin: float) -> tuple[np.ndarray, ...]:
    """The hard limits as rows M q̇ ≤ c (finite box bounds and the inequality rows), tightened by ``margin`` (the box
    by at most half its width, so a pinned joint stays pinned)."""
    n = lb.shape[0]
    width = np.where(np.isfinite(lb) & np.isfinite(ub), ub - lb, np.inf)
    mu = np.minimum(margin, 0.5 * np.maximum(width, 0.0))
    up, lo = np.isfinite(ub), np.isfinite(lb)
    eye = np.eye(n)
    M = np.vstack([eye[up], -eye[lo], G])
    c = np.concatenate([ub[up] - mu[up], -(lb[lo] + mu[lo]), h - margin])
    return M, c


def max_scale(
    aff: Affine, lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray, margin: float = MARGIN
) -> tuple[float, np.ndarray] | None:
    """(α*, u*): the largest α ∈ [0, 1] (0 when V is not reachable) with α x₀ + N u* within the limits tightened by
    ``margin``, by HiGHS; ``None`` when no α ∈ [0, 1] has one."""
    from scipy.optimize import linprog

    M, c = _rows(lb, ub, G, h, margin)
    k = aff.N.shape[1]
    A = np.hstack([(M @ aff.x0)[:, None], M @ aff.N])
    cost = np.zeros(1 + k)
    cost[0] = -1.0
    top = 1.0 if aff.reachable else 0.0
    bounds = [(0.0, top)] + [(None, None)] * k
    opts = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
    res = linprog(cost, A_ub=A, b_ub=c, bounds=bounds, method="highs", options=opts)
    if res.status != 0 or res.x is None:
        return None
    alpha = float(min(max(res.x[0], 0.0), top))
    return alpha, np.asarray(res.x[1:], dtype=float)


def within(dq: np.ndarray, lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray) -> bool:
    """True when q̇ holds the box and the rows (untightened, no tolerance)."""
    return bool((dq >= lb).all() and (dq <= ub).all() and (not G.shape[0] or (G @ dq <= h).all()))


def toward_inside(
    dq: np.ndarray, anchor: np.ndarray, lb: np.ndarray, ub: np.ndarray, G: np.ndarray, h: np.ndarray
) -> np.ndarray:
    """The point anchor + θ(q̇ − anchor) with the largest θ ∈ [0, 1] within the limits (``anchor``, the LP's point, is
    inside by the margin, to the LP's tolerance)."""
    M, c = _rows(lb, ub, G, h, 0.0)
    d = dq - anchor
    slope = M @ d
    room = c - M @ anchor
    grow = slope > 0.0
    theta = float(np.min(np.clip(room[grow] / slope[grow], 0.0, 1.0), initial=1.0))
    out = anchor + theta * d
    if within(out, lb, ub, G, h):
        return out
    return np.minimum(np.maximum(anchor, lb), ub)  # (the LP's point outside by its tolerance, ≤ 1e-10: clipped)


def restricted(
    resolver: QPResolverBase,
    aff: Affine,
    alpha: float,
    H: np.ndarray,
    g: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    G: np.ndarray,
    h: np.ndarray,
) -> np.ndarray | None:
    """argmin ½uᵀHu + gᵀu with α x₀ + N u within the limits tightened by half the LP's margin, by the resolver's
    backend; ``None`` when the backend fails (the caller keeps the LP's point)."""
    k = aff.N.shape[1]
    M, c = _rows(lb, ub, G, h, 0.5 * MARGIN)
    prob = QPProblem.unconstrained(0.5 * (H + H.T), g, "direction: lower levels")
    prob.G, prob.h = M @ aff.N, c - M @ (alpha * aff.x0)
    prob.row_names = [f"limit:{i}" for i in range(prob.G.shape[0])]
    try:
        return resolver._solve_qp(prob, None).x if k else np.zeros(0)
    except SolverError:
        return None


def _main_indices(resolver: QPResolverBase, stack: TaskStack) -> list[int]:
    """The main tasks to scale: every main task for ``wqp``, those of the top level holding main tasks for
    ``hqp`` (its strict hierarchy puts the levels below them in what is left)."""
    layout = resolver.layout(stack)
    main = set(layout.main)
    if resolver.name != "hqp":
        return list(layout.main)
    for level in layout.levels:
        top = [i for i in level.tasks if i in main]
        if top:
            return top
    return []


Rows = tuple[np.ndarray, np.ndarray]


def _hard_rows(built: Any, resolver: QPResolverBase, stack: TaskStack) -> tuple[list[Rows], str]:
    """The inequality rows to hold, as candidates to try in turn: ``wqp``'s bound rows (all, then only the safety
    rows), ``hqp``'s safety rows; with a note for the relaxed candidate."""
    n = built.box.lb.shape[0]
    none = (np.zeros((0, n)), np.zeros(0))
    problem = getattr(built, "problem", None)
    if problem is not None:  # wqp: its QP's rows, and its relaxation
        if not problem.G.shape[0]:
            return [none], ""
        safe = built.safe if built.safe is not None else np.zeros(problem.G.shape[0], dtype=bool)
        cands = [(problem.G, problem.h)]
        if not safe.all():
            cands.append((problem.G[safe], problem.h[safe]))
        return cands, "direction: bound subtasks other than safety rows dropped (no α with them)"
    rows = resolver._safety_rows(built, stack)
    return [rows if rows is not None else none], ""


def solve_direction(
    resolver: QPResolverBase, robot: RobotModel, stack: TaskStack, t: float, dt: float, stuck_below: float
) -> StepResult:
    """One step of ``resolver`` with direction-preserving scaling (this module's docstring)."""
    t0 = time.perf_counter()
    prev = resolver._dq_prev
    terms = stack.evaluate(robot, t)
    built = resolver.build(robot, stack, t, dt, terms)
    t1 = time.perf_counter()
    res = resolver._finish(robot, stack, terms, built, t0, t1)
    d = res.__dict__
    info: dict[str, object] = d["_info"] if "_info" in d else res.info  # (the eager dict: not wrapped here)
    main = _main_indices(resolver, stack)
    if not main:
        return _mark(res, info, 1.0, "free", stuck_below)
    J = np.vstack([terms[i].J for i in main])
    V = np.concatenate([terms[i].v for i in main])
    if not (np.isfinite(J).all() and np.isfinite(V).all()):
        return _mark(res, info, 0.0, "unreachable", stuck_below, "direction: non-finite main-task rows")
    problem = getattr(built, "problem", None)
    if problem is None and info.get("qp") == 0 and res.fallback is None:  # hqp: its cascade kept, no limit binds
        if np.linalg.norm(J @ res.dq - V) <= RANGE_TOL * max(float(np.linalg.norm(V)), 1e-300):
            return _mark(res, info, 1.0, "free", stuck_below)
    box = built.box
    lb, ub = box.lb, box.ub
    aff = Affine(J, V)
    cands, relax_note = _hard_rows(built, resolver, stack)
    if problem is not None and aff.reachable:  # wqp: its objective with J q̇ = V, kept when no limit binds
        dq = aff.x0 + aff.N @ _equality_optimum(problem.P, problem.q, aff.N, aff.x0)
        if np.isfinite(dq).all() and within(dq, lb, ub, *cands[0]):
            return _commit(res, resolver, built, info, dq, 1.0, "free", stuck_below)
    found, note = None, None
    for k, (G, h) in enumerate(cands):
        found = max_scale(aff, lb, ub, G, h)
        if found is not None:
            note = relax_note if k else None
            break
    if found is None:
        why = "direction: no q̇ within the hard limits solves J q̇ = αV for any α ∈ [0, 1]; the unscaled step"
        return _mark(res, info, 0.0, "unreachable", stuck_below, why)
    alpha, u_lp = found
    anchor = alpha * aff.x0 + aff.N @ u_lp
    dq = _lower_levels(resolver, robot, stack, terms, built, main, aff, alpha, anchor, res.dq, prev, (t, dt), G, h)
    if not within(dq, lb, ub, G, h):
        dq = toward_inside(dq, anchor, lb, ub, G, h)
    return _commit(res, resolver, built, info, dq, alpha, "scaled", stuck_below, note)


def _equality_optimum(P: np.ndarray, q: np.ndarray, N: np.ndarray, base: np.ndarray) -> np.ndarray:
    """u minimising ½q̇ᵀPq̇ + qᵀq̇ over q̇ = base + N u (no limits; P is positive definite)."""
    if not N.shape[1]:
        return np.zeros(0)
    H = N.T @ P @ N
    return np.asarray(-np.linalg.solve(0.5 * (H + H.T), N.T @ (P @ base + q)))


def _commit(
    res: StepResult,
    resolver: QPResolverBase,
    built: Any,
    info: dict[str, object],
    dq: np.ndarray,
    alpha: float,
    how: str,
    stuck_below: float,
    note: str | None = None,
) -> StepResult:
    """The result with q̇ replaced by the direction-preserving one (kept as the previous q̇: rate window, warm
    start), its diagnostics computed at it, and marked."""
    resolver._dq_prev = dq.copy()
    d = res.__dict__
    d["dq"] = dq
    d.pop("_dq_norm", None)  # (what a compiled call computed of the q̇ replaced)
    d.pop("_cap_ratio", None)
    _replace_diagnostics(res, resolver, built, dq)
    return _mark(res, info, alpha, how, stuck_below, note)


def _lower_levels(
    resolver: QPResolverBase,
    robot: RobotModel,
    stack: TaskStack,
    terms: list[TaskTerm],
    built: Any,
    main: list[int],
    aff: Affine,
    alpha: float,
    anchor: np.ndarray,
    unscaled: np.ndarray,
    prev: np.ndarray | None,
    when: tuple[float, float],
    G: np.ndarray,
    h: np.ndarray,
) -> np.ndarray:
    """q̇ = α x₀ + N u with u from the lower levels (module docstring, step 2); the LP's point when there is no
    freedom left or the backend fails."""
    N = aff.N
    if not N.shape[1]:
        return anchor
    base = alpha * aff.x0
    problem = getattr(built, "problem", None)
    if problem is not None:  # wqp: its own objective over u
        P = problem.P
        H, g = N.T @ P @ N, N.T @ (P @ base + problem.q)
    else:  # hqp: its cascade with targets αV, then the nearest point of the set
        candidate = unscaled if alpha >= 1.0 else _cascade_at(resolver, robot, stack, terms, main, alpha, prev, when)
        H, g = np.eye(N.shape[1]), -(N.T @ ((anchor if candidate is None else candidate) - base))
    u = restricted(resolver, aff, alpha, H, g, built.box.lb, built.box.ub, G, h)
    return anchor if u is None or not np.isfinite(u).all() else base + N @ u


def _cascade_at(
    resolver: QPResolverBase,
    robot: RobotModel,
    stack: TaskStack,
    terms: list[TaskTerm],
    main: list[int],
    alpha: float,
    prev: np.ndarray | None,
    when: tuple[float, float],
) -> np.ndarray | None:
    """``hqp``'s cascade on the step's rows with the main tasks' targets scaled by α (the same limit box: the rate
    window of the previous q̇); ``None`` when it fails."""
    from redundik.resolvers.qp.base import QPDiagnostics

    scaled = list(terms)
    for i in main:
        tm = terms[i]
        scaled[i] = TaskTerm(tm.name, tm.J, alpha * tm.v, tm.error, tm.weight)
    kept = resolver._dq_prev
    resolver._dq_prev = prev
    try:
        built = resolver.build(robot, stack, when[0], when[1], scaled)
        x, _ = resolver._resolve(built, QPDiagnostics())
    except SolverError:
        return None
    finally:
        resolver._dq_prev = kept
    return x if np.isfinite(x).all() else None


def _replace_diagnostics(res: StepResult, resolver: QPResolverBase, built: Any, dq: np.ndarray) -> None:
    """The result's diagnostics (active limits, residuals, σ_min) computed at the scaled q̇ on first read."""
    from redundik.resolvers.qp.base import QPDiagnostics

    d = res.__dict__
    info = d.get("_info")
    eager = dict(info) if type(info) is dict else {}
    box, names = built.box, resolver.limits.joint_names

    def diagnostics() -> tuple[float, bool, dict[str, object]]:
        diag = QPDiagnostics()
        diag.active_limits = box.active(dq, names)
        resolver._diagnose(built, dq, diag)
        out = diag.as_info()
        for key in ("backend", "qp", "iterations"):  # the step's own, as reported eagerly
            if key in eager:
                out[key] = eager[key]
        return diag.sigma_min, bool(diag.damped_levels), out

    if "pending" in d:
        d["pending"] = diagnostics


def _mark(
    res: StepResult, info: dict[str, object], alpha: float, how: str, stuck_below: float, note: str | None = None
) -> StepResult:
    """Set ``scale``, ``stuck``, ``info["scale"]``/``info["direction"]`` and a fallback note on the result."""
    d = res.__dict__
    d["scale"] = float(alpha)
    d["stuck"] = bool(alpha < stuck_below) if math.isfinite(alpha) else True
    dict.__setitem__(info, "scale", float(alpha))
    dict.__setitem__(info, "direction", how)
    if note:
        res.fallback = note if res.fallback is None else f"{res.fallback}; {note}"
    return res
