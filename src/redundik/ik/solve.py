"""``solve_ik``: inverse kinematics to convergence, every configuration within the joint limits.

The iteration (:mod:`redundik.ik.kernels`): a Levenberg–Marquardt step on the stacked frame residuals
(p_d − p, log3(R_d Rᵀ)) [m, rad] with adaptive damping (λ ← λ/3 after a step that lowers the cost, 4λ after one
that does not), box-constrained by the joint limits (clipped into the box, with an active set for joints that sit
on a bound and are pushed outwards), so every iterate is inside the limits. An attempt ends when both tolerances
are met, when it stalls (the cost fell by less than half over 10 iterations, λ beyond 1e8, or no step is left) or
after ``max_iterations``; the next attempt starts from a configuration drawn uniformly within the limits from the
seeded generator, until the time budget or ``max_restarts`` runs out. Kinematics by Pinocchio (one
``computeFrameJacobian`` per frame and iteration), configurations composed with ``pin.integrate`` on models whose
q does not add up (free-flyers, unbounded revolute joints).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from redundik.errors import ResolverError
from redundik.ik import kernels as K
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

    tol: np.ndarray  # (position [m], orientation [rad], stall window, stall ratio)
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
    tol = np.array([tp, tr, STALL_WINDOW, STALL_RATIO], dtype=float)
    return Settings(tol, int(it or 1), budget, restarts)


class Solver:
    """The iteration's buffers for one :class:`Problem` (reused over targets by the batch form)."""

    def __init__(self, problem: Problem) -> None:
        self.p = problem
        robot = problem.robot
        k, nv, nq = len(problem.fids), robot.nv, robot.nq
        self.model, self.data = robot.model, robot.model.createData()
        self.J6, self.M = np.zeros((k, 6, nv)), np.zeros((k, 4, 4))
        m = 6 * k
        self.work = (np.zeros((m, nv)), np.zeros(m), np.zeros((k, 2)))
        self.cur = (np.zeros((m, nv)), np.zeros(m), np.zeros((k, 2)), np.zeros(nq))
        self.out = (np.zeros(nv), np.zeros(nq))
        self.st, self.ist = np.zeros(3), np.zeros(2, dtype=np.int64)

    def _kinematics(self, q: np.ndarray) -> None:
        model, data, J6, M = self.model, self.data, self.J6, self.M
        fids = self.p.fids
        if len(fids) == 1:
            J6[0] = pin.computeFrameJacobian(model, data, q, fids[0], _LWA)
            M[0] = data.oMf[fids[0]].homogeneous
            return
        pin.computeJointJacobians(model, data, q)
        for k, f in enumerate(fids):
            M[k] = pin.updateFramePlacement(model, data, f).homogeneous
            J6[k] = pin.getFrameJacobian(model, data, f, _LWA)

    def attempt(
        self, q: np.ndarray, T: np.ndarray, mode: np.ndarray, s: Settings, deadline: float
    ) -> tuple[int, int, bool]:
        """Iterate from q (within the limits); (code, iterations, out of time). The attempt's best iterate is
        ``self.cur`` (its q, errors)."""
        p = self.p
        qt = q
        first = True
        dq, qn = self.out
        for it in range(s.max_iterations + 1):
            self._kinematics(qt)
            code = K.lm_update(
                first, self.J6, self.M, T, mode, qt, s.tol, p.qmap, p.lo, p.hi, self.st, self.ist, self.work,
                self.cur, self.out,
            )  # fmt: skip
            first = False
            if code != K.CONTINUE:
                return code, it, False
            if time.perf_counter() > deadline:
                return K.STALLED, it + 1, True
            if p.additive:
                qt = qn
            else:
                qt = np.minimum(np.maximum(pin.integrate(self.model, self.cur[3], dq), p.q_lo), p.q_hi)
        return K.STALLED, s.max_iterations, False

    def run(
        self, q_start: np.ndarray, T: np.ndarray, mode: np.ndarray, s: Settings, rng: np.random.Generator
    ) -> IKResult:
        """Attempts from ``q_start`` then from random configurations until success, the time budget or
        ``max_restarts``."""
        t0 = time.perf_counter()
        deadline = t0 + s.timeout if s.timeout is not None else np.inf
        tol_p, tol_r = s.tol[0], s.tol[1]
        q, restarts, iterations = q_start, 0, 0
        best_score, best_q, best_err = np.inf, q_start.copy(), np.full((len(self.p.fids), 2), np.inf)
        while True:
            code, its, late = self.attempt(q, T, mode, s, deadline)
            iterations += its
            err = self.cur[2]
            score = float(max(np.max(err[:, 0]) / tol_p, np.max(err[:, 1]) / tol_r))
            if score < best_score:
                best_score, best_q, best_err = score, self.cur[3].copy(), err.copy()
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
            q = restart_configuration(self.p, q_start, rng)
        q_out = np.minimum(np.maximum(best_q, self.p.q_lo), self.p.q_hi)  # rounding only: iterates are in the box
        return IKResult(
            q=q_out, success=reason == "converged", iterations=iterations,
            position_error=float(np.max(best_err[:, 0])), orientation_error=float(np.max(best_err[:, 1])),
            reason=reason, restarts=restarts, elapsed=time.perf_counter() - t0,
            frame_errors={n: (float(e[0]), float(e[1])) for n, e in zip(self.p.names, best_err, strict=True)},
        )  # fmt: skip


_warm = False


def warm_up() -> None:
    """Compile (or load from numba's cache) the iteration's kernel on a one-joint dummy, once per process, so that
    no time budget pays for it."""
    global _warm
    if _warm:
        return
    J6, M, T = np.zeros((1, 6, 1)), np.eye(4)[None], np.eye(4)[None]
    J6[0, 0, 0] = 1.0
    work = (np.zeros((6, 1)), np.zeros(6), np.zeros((1, 2)))
    cur = (np.zeros((6, 1)), np.zeros(6), np.zeros((1, 2)), np.zeros(1))
    out = (np.zeros(1), np.zeros(1))
    tol = np.array([1e-5, 1e-4, STALL_WINDOW, STALL_RATIO])
    lo, hi = np.array([-1.0]), np.array([1.0])
    st, ist = np.zeros(3), np.zeros(2, dtype=np.int64)
    mode, qmap = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
    K.lm_update(True, J6, M, T, mode, np.zeros(1), tol, qmap, lo, hi, st, ist, work, cur, out)
    _warm = True


def generator(seed: Seed) -> np.random.Generator:
    """The restarts' generator: ``seed`` itself if a Generator, else NumPy's default generator seeded with it."""
    if isinstance(seed, np.random.Generator):
        return seed
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise ResolverError(f"solve_ik: seed must be an int ≥ 0, a list of them or a numpy Generator: {exc}") from None


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
    s = settings(position_tolerance, orientation_tolerance, max_iterations, timeout, max_restarts)
    names, targets = frames_and_targets(frame, target)
    problem = build_problem(robot, names)
    T, mode = target_arrays(names, targets)
    q = start_configuration(problem, q0)
    warm_up()
    return Solver(problem).run(q, T, mode, s, generator(seed))
