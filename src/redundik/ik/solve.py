"""``solve_ik``: inverse kinematics to convergence, every configuration within the joint limits.

The iteration (:mod:`redundik.ik.kernels`): a Levenberg–Marquardt step on the stacked frame residuals
(w_p (p_d − p), log3(R_d Rᵀ)) [rad] with damping λ + c·½‖r‖² (Sugihara's error-proportional term plus an adaptive
λ: λ ← λ/3 after a step that lowers the cost, 4λ after one that does not), box-constrained by the joint limits
(clipped into the box, with an active set for joints that sit on a bound and are pushed outwards), so every iterate
is inside the limits. An attempt ends when both tolerances are met, when it stalls (the cost fell by less than half
over 10 iterations, λ beyond 1e8, or no step is left) or after ``max_iterations``; the next attempt starts from a
configuration drawn uniformly within the limits from the seeded generator, until the time budget or
``max_restarts`` runs out. Kinematics by Pinocchio (one ``computeFrameJacobian`` per frame and iteration),
configurations composed with ``pin.integrate`` on models whose q does not add up (free-flyers, unbounded revolute
joints), one compiled kernel call per iteration.

Per call, the frames' :class:`Problem` and the buffers are built once per thread and robot (:func:`cached_solver`),
targets that are SE3s or float 4×4 arrays are checked by a compiled test, and the restarts' generator is made only
when a restart needs it, so that a call costs little beyond its iterations.
"""

from __future__ import annotations

import threading
import time
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from redundik._coldstart import compiled_now
from redundik.errors import ResolverError
from redundik.ik import kernels as K
from redundik.ik.layouts import (
    CURRENT,
    ERR_POS,
    ERR_ROT,
    IK_MODES,
    IK_NQ,
    N_PARAMS,
    P_COST_DAMPING,
    P_RATIO,
    P_TOL_POS,
    P_TOL_ROT,
    P_WINDOW,
    P_WPOS,
    TRIAL,
)
from redundik.ik.problem import (
    Problem,
    build_problem,
    count,
    frames_and_targets,
    positive,
    restart_configuration,
    start_configuration,
    target_arrays,
)
from redundik.kinematics.model import RobotModel

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

#: Reasons of an :class:`IKResult`.
REASONS = ("converged", "timeout", "max_restarts")
#: Stall rule: an attempt stops when its cost fell by less than this factor over this many iterations.
STALL_WINDOW, STALL_RATIO = 10, 0.5
#: Weight of a position error against an orientation error in the cost [rad/m], and the damping per unit of cost
#: (λ + c·½‖r‖², :mod:`redundik.ik.kernels`): measured best of 1, 2, 3 and of 0.03, 0.05, 0.1, 1, 3 on the Panda's
#: and the UR5's reachable poses.
POSITION_WEIGHT, COST_DAMPING = 2.0, 0.1

Seed = int | Sequence[int] | np.random.Generator | None


@dataclass
class IKResult:
    """What :func:`solve_ik` found.

    Attributes:
        q: The configuration (nq,), within the joint limits whether or not it succeeded (on failure the best one
            found: lowest error relative to the tolerances).
        success: Every frame within both tolerances.
        iterations: Iterations over all attempts (one Jacobian per frame each).
        position_error: Largest position error over the frames ‖p_d − p‖ [m].
        orientation_error: Largest orientation error over the pose frames, the angle of R_d Rᵀ [rad] (0 when
            every target is a position).
        reason: ``"converged"``, ``"timeout"`` (the time budget ran out) or ``"max_restarts"``.
        restarts: Attempts after the first.
        elapsed: Wall time [s].
        frame_errors: Per frame, (position error [m], orientation error [rad]).
    """

    q: np.ndarray
    success: bool
    iterations: int
    position_error: float
    orientation_error: float
    reason: str
    restarts: int
    elapsed: float
    frame_errors: dict[str, tuple[float, float]] = field(default_factory=dict)


@dataclass
class Settings:
    """Checked options of one solve (see :func:`solve_ik`)."""

    params: np.ndarray  # layouts.PARAMS: tolerances [m, rad], stall window and ratio, position weight, cost damping
    max_iterations: int
    timeout: float | None
    max_restarts: int | None


def settings(
    position_tolerance: object, orientation_tolerance: object, max_iterations: object, timeout: object,
    max_restarts: object,
) -> Settings:  # fmt: skip
    """The options checked (:class:`ResolverError` naming the one that is wrong)."""
    tp = positive(position_tolerance, "position_tolerance", "m")
    tr = positive(orientation_tolerance, "orientation_tolerance", "rad")
    it = count(max_iterations, "max_iterations", 1)
    budget = positive(timeout, "timeout", "s", allow_none=True)
    restarts = count(max_restarts, "max_restarts", 0, allow_none=True)
    if budget is None and restarts is None:
        raise ResolverError("solve_ik: give a timeout [s] or max_restarts (or both): with neither it could run forever")
    params = np.empty(N_PARAMS)
    params[P_TOL_POS], params[P_TOL_ROT], params[P_WINDOW], params[P_RATIO] = tp, tr, STALL_WINDOW, STALL_RATIO
    params[P_WPOS], params[P_COST_DAMPING] = POSITION_WEIGHT, COST_DAMPING
    return Settings(params, int(it or 1), budget, restarts)


class Solver:
    """The iteration's buffers for one :class:`Problem` (reused over targets by the batch form and, per thread, by
    :func:`solve_ik` on the same robot and frames).

    Attributes:
        ws: The kernel's workspace (``workspace``); ``q`` (2, nq) the trial and current
            configurations, ``err`` (2, k, 2) their errors, ``dq`` the step, ``st`` the state: views of it.
        ints: (nq, mode (k,), qmap (nv,)) (``layouts.IK_NQ``, ``IK_MODES``); ``mode`` a view of it, set per target.
    """

    def __init__(self, problem: Problem) -> None:
        self.p = problem
        robot = problem.robot
        k, nv, nq = len(problem.fids), robot.nv, robot.nq
        self.model, self.data = robot.model, robot.model.createData()
        self.J6, self.M = np.zeros((6 * k, nv)), np.zeros((4 * k, 4))
        self.ws = np.zeros(K.offsets(k, nv, nq)[-1])
        _, _, self.err, self.q, self.dq, self.st = K.workspace(self.ws, k, nv, nq)
        self.ints = np.zeros(IK_MODES + k + nv, dtype=np.int64)
        self.ints[IK_NQ], self.ints[IK_MODES + k :] = nq, problem.qmap
        self.mode = self.ints[IK_MODES : IK_MODES + k]

    def kinematics(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J6 (6k, nv), M (4k, 4)): the frames' LOCAL_WORLD_ALIGNED Jacobians and poses at q (Pinocchio)."""
        model, data, fids = self.model, self.data, self.p.fids
        if len(fids) == 1:  # one call; Pinocchio's own arrays go to the kernel as they are
            J = pin.computeFrameJacobian(model, data, q, fids[0], _LWA)
            return J, data.oMf[fids[0]].homogeneous
        J6, M = self.J6, self.M
        pin.computeJointJacobians(model, data, q)
        for k, f in enumerate(fids):
            M[4 * k : 4 * k + 4] = pin.updateFramePlacement(model, data, f).homogeneous
            J6[6 * k : 6 * k + 6] = pin.getFrameJacobian(model, data, f, _LWA)
        return J6, M

    def attempt(self, q: np.ndarray, T: np.ndarray, consts: np.ndarray, s: Settings, deadline: float) -> tuple[
        int, int, bool
    ]:  # fmt: skip
        """Iterate from q (within the limits) towards T; (code, iterations, out of time). The attempt's best iterate
        is ``self.q[CURRENT]`` (its errors ``self.err[CURRENT]``)."""
        p, ints, ws = self.p, self.ints, self.ws
        qt = self.q[TRIAL]
        qt[:] = q
        kin, update, clock = self.kinematics, K.lm_update, time.perf_counter
        first = True
        for it in range(s.max_iterations + 1):
            J6, M = kin(qt)
            code = update(first, J6, M, T, consts, ints, ws)
            first = False
            if code != K.CONTINUE:
                return code, it, False
            if clock() > deadline:
                return K.STALLED, it + 1, True
            if not p.additive:
                qt[:] = np.minimum(np.maximum(pin.integrate(self.model, self.q[CURRENT], self.dq), p.q_lo), p.q_hi)
        return K.STALLED, s.max_iterations, False

    def run(self, q_start: np.ndarray, T: np.ndarray, mode: np.ndarray, s: Settings, seed: Seed) -> IKResult:
        """Attempts from ``q_start`` then from random configurations until success, the time budget or
        ``max_restarts``; the restarts' generator (:func:`generator` of ``seed``) is made at the first restart."""
        t0 = time.perf_counter()
        deadline = t0 + s.timeout if s.timeout is not None else np.inf
        p = self.p
        self.mode[:] = mode
        consts = np.concatenate([s.params, p.lo, p.hi])
        tol_p, tol_r = s.params[P_TOL_POS], s.params[P_TOL_ROT]
        q, restarts, iterations = q_start, 0, 0
        rng: np.random.Generator | None = None
        best_score, best_q, best_err = np.inf, q_start, np.full((len(p.fids), 2), np.inf)
        while True:
            code, its, late = self.attempt(q, T, consts, s, deadline)
            iterations += its
            err = self.err[CURRENT]
            score = max(float(err[:, ERR_POS].max()) / tol_p, float(err[:, ERR_ROT].max()) / tol_r)
            if score < best_score:
                best_score, best_q, best_err = score, self.q[CURRENT].copy(), err.copy()
            if code == K.CONVERGED:
                reason = "converged"
                break
            if late or time.perf_counter() > deadline:
                reason = "timeout"
                break
            if s.max_restarts is not None and restarts >= s.max_restarts:
                reason = "max_restarts"
                break
            restarts += 1
            if rng is None:
                rng = generator(seed)
            q = restart_configuration(p, q_start, rng)
        q_out = np.minimum(np.maximum(best_q, p.q_lo), p.q_hi)  # rounding only: iterates are in the box
        return IKResult(
            q=q_out, success=reason == "converged", iterations=iterations,
            position_error=float(best_err[:, ERR_POS].max()), orientation_error=float(best_err[:, ERR_ROT].max()),
            reason=reason, restarts=restarts, elapsed=time.perf_counter() - t0,
            frame_errors={n: (float(e[ERR_POS]), float(e[ERR_ROT])) for n, e in zip(p.names, best_err, strict=True)},
        )  # fmt: skip


_warm = False


def warm_up(solver: Solver) -> None:
    """Compile (or load from numba's cache) the iteration's kernels, once per process, on ``solver``'s own
    kinematics (the same array types as the timed calls), so that no time budget pays for it."""
    global _warm
    if _warm:
        return
    p = solver.p
    q = solver.q[TRIAL]
    q[:] = p.q_mid
    T = np.tile(np.eye(4), (len(p.fids), 1))
    consts = np.concatenate([settings(1e-5, 1e-4, 1, None, 0).params, p.lo, p.hi])
    J6, M = solver.kinematics(q)
    K.lm_update(True, J6, M, T, consts, solver.ints, solver.ws)
    K.rigid_transform(T[:4], 1.0)
    _warm = True


def generator(seed: Seed) -> np.random.Generator:
    """The restarts' generator: ``seed`` itself if a Generator, else NumPy's default generator seeded with it."""
    if isinstance(seed, np.random.Generator):
        return seed
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise ResolverError(f"solve_ik: seed must be an int ≥ 0, a list of them or a numpy Generator: {exc}") from None


def check_seed(seed: object) -> Seed:
    """``seed`` if :func:`generator` accepts it (checked without making the generator when it is an int ≥ 0 or a
    tuple of them, the common case: the generator is made only if a restart needs it), else a
    :class:`ResolverError`."""
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0:
        return int(seed)
    if isinstance(seed, tuple) and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in seed):
        return seed
    generator(seed)  # type: ignore[arg-type]
    return seed  # type: ignore[return-value]


_local = threading.local()
#: Most (robot, frames) solvers kept per thread.
CACHE_SIZE = 8


def cached_solver(robot: RobotModel, names: list[str]) -> Solver:
    """The :class:`Solver` of ``names`` on ``robot``, built once per thread and kept while the robot lives and its
    joint limits are unchanged (:func:`build_problem` checks everything the first time)."""
    cache: dict[tuple[int, tuple[str, ...]], tuple[weakref.ref[RobotModel], object, Solver]] = getattr(
        _local, "cache", None
    ) or _local.__dict__.setdefault("cache", {})
    key = (id(robot), tuple(names))
    stamp = None
    if isinstance(robot, RobotModel):
        model = robot.model
        stamp = (id(model), id(robot.joints), model.lowerPositionLimit.tobytes(), model.upperPositionLimit.tobytes())
    hit = cache.get(key)
    if hit is not None and hit[0]() is robot and hit[1] == stamp:
        return hit[2]
    solver = Solver(build_problem(robot, names))
    if len(cache) >= CACHE_SIZE:
        cache.clear()
    cache[key] = (weakref.ref(robot), stamp, solver)
    return solver


def solve_ik(
    robot: RobotModel,
    frame: str | Sequence[str] | dict[str, object],
    target: object = None,
    q0: np.ndarray | Sequence[float] | None = None,
    *,
    position_tolerance: float = 1e-5,
    orientation_tolerance: float = 1e-4,
    timeout: float | None = 0.05,
    max_restarts: int | None = None,
    max_iterations: int = 100,
    seed: Seed = 0,
) -> IKResult:
    """Joint positions that place ``frame`` at ``target``, within the joint limits (module docstring: the method).

    Args:
        robot: The robot.
        frame: A frame name, a list of names (then ``target`` a list of as many targets) or a mapping name →
            target (then no ``target``).
        target: Per frame a ``pin.SE3`` or 4×4 homogeneous matrix (a pose: position and orientation) or a position
            (3,) [m] (orientation free).
        q0: The first attempt's start (nq,) [rad, m]; clipped into the limits. ``None``: mid-range.
        position_tolerance: Success when every frame's ‖p_d − p‖ is at most this [m] (> 0) ...
        orientation_tolerance: ... and every pose frame's rotation error at most this [rad] (> 0).
        timeout: Time budget [s] (> 0; ``None``: only ``max_restarts`` stops); checked every iteration.
        max_restarts: Random restarts allowed after the first attempt (``None``: until the time budget).
        max_iterations: Iterations of one attempt (≥ 1).
        seed: Seed of the restarts' generator (an int, a list of ints or a ``numpy.random.Generator``). The
            result is a function of the inputs and the seed unless the time budget cuts the search short.

    Returns:
        An :class:`IKResult`; its ``q`` is within the limits even when ``success`` is False.

    Raises:
        ModelError: an unknown frame (the valid names listed), a frame fixed to the world, a bad ``q0``.
        TaskError: a target that is not an SE3, a rigid 4×4 matrix or a finite position (3,).
        ResolverError: a tolerance, budget or count that is not a positive number, or a bad seed.
    """
    compiled_now()  # (the kernels compiled from the first call: its time budget is for solving)
    s = settings(position_tolerance, orientation_tolerance, max_iterations, timeout, max_restarts)
    names, targets = frames_and_targets(frame, target)
    solver = cached_solver(robot, names)
    T, mode = target_arrays(names, targets)
    q = start_configuration(solver.p, q0)
    seed = check_seed(seed)
    warm_up(solver)
    return solver.run(q, T, mode, s, seed)
