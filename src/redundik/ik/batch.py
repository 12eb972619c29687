"""``solve_ik_batch``: :func:`redundik.solve_ik` over N targets of the same frames, one problem after the other.

Problem i is exactly ``solve_ik(robot, frame, targets[i], q0_i, seed=(seed, i), ...)`` (the same iterates, bit for
bit; tested): the frames, bounds and buffers are prepared once and reused. Why not through
:class:`redundik.resolvers.batch.BatchResolver`: that API resolves one differential step (gain, posture, a
velocity box over dt) of one frame for N problems at once; vectorised, it still computes each problem's Jacobian in
a Python loop, which alone costs about what one compiled IK iteration here costs (≈ 5–8 µs), while problems that
converge after 5 and after 500 iterations, and restart at different times, would leave most of a vectorised batch
idle. One problem at a time keeps each one on its own fastest path and the answer equal to the single call.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from redundik._coldstart import compiled_now
from redundik.errors import ResolverError
from redundik.ik.problem import build_problem, frames_and_targets, start_configuration, target_arrays
from redundik.ik.solve import IKResult, Solver, settings, warm_up
from redundik.kinematics.model import RobotModel


@dataclass
class IKBatchResult:
    """N :class:`IKResult` as arrays (problem order).

    Attributes:
        q: Configurations (N, nq), each within the joint limits.
        success: (N,) bool.
        iterations: (N,) iterations per problem.
        position_error: (N,) largest position error over the frames [m].
        orientation_error: (N,) largest orientation error over the pose frames [rad].
        reason: N reasons (``converged``, ``timeout``, ``max_restarts``).
        restarts: (N,) restarts per problem.
        elapsed: (N,) wall time per problem [s].
    """

    q: np.ndarray
    success: np.ndarray
    iterations: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    reason: list[str]
    restarts: np.ndarray
    elapsed: np.ndarray

    @property
    def success_rate(self) -> float:
        """Fraction of the problems solved [1]."""
        return float(np.mean(self.success)) if self.success.size else 0.0

    def __len__(self) -> int:
        return int(self.success.shape[0])


def _starts(q0: object, n: int, nq: int) -> list[object]:
    """q0 per problem: ``None``, one configuration for all, or one per problem (N, nq)."""
    if q0 is None:
        return [None] * n
    try:
        arr = np.asarray(q0)
    except ValueError:  # ragged: left to the configuration check, which names the problem
        return [q0] * n
    if arr.ndim == 2:
        if arr.shape[0] != n:
            raise ResolverError(f"solve_ik_batch: q0 has {arr.shape[0]} rows for {n} targets (expected (N, {nq}))")
        return list(arr)
    return [q0] * n


def solve_ik_batch(
    robot: RobotModel,
    frame: str | Sequence[str],
    targets: Sequence[object] | np.ndarray,
    q0: np.ndarray | Sequence[float] | None = None,
    *,
    position_tolerance: float = 1e-5,
    orientation_tolerance: float = 1e-4,
    timeout: float | None = 0.05,
    max_restarts: int | None = None,
    max_iterations: int = 100,
    seed: int = 0,
) -> IKBatchResult:
    """Solve N IK problems of the same frames (module docstring); the options are :func:`redundik.solve_ik`'s,
    per problem (``timeout`` is each problem's budget [s]).

    Args:
        robot: The robot.
        frame: A frame name, or a list of names.
        targets: N targets: for one frame an array (N, 4, 4) of poses or (N, 3) of positions [m], or any sequence
            of what ``solve_ik`` takes as ``target``; for k frames, N lists of k targets.
        q0: ``None`` (mid-range), one start (nq,) for all, or one per problem (N, nq).
        seed: Problem i's restarts are seeded with ``(seed, i)``.

    Raises:
        ModelError, TaskError, ResolverError: as :func:`redundik.solve_ik`, the message naming the problem.
    """
    compiled_now()
    s = settings(position_tolerance, orientation_tolerance, max_iterations, timeout, max_restarts)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ResolverError(f"solve_ik_batch: seed must be an int ≥ 0, got {seed!r:.60}")
    if isinstance(targets, (str, bytes, Mapping)) or not isinstance(targets, (Sequence, np.ndarray)):
        # (a mapping is solve_ik's frame → target form: here it was indexed 0, 1, ... and ended in a KeyError)
        raise ResolverError(
            f"solve_ik_batch: targets must be a sequence (a list, a tuple) or an array of N targets, got "
            f"{type(targets).__name__} {targets!r:.60}"
        )
    n = len(targets)
    names, _ = frames_and_targets(frame, [None] * len(frame) if not isinstance(frame, str) else None)
    problem = build_problem(robot, names)
    starts = _starts(q0, n, robot.nq)
    prepared = []
    for i in range(n):  # every input checked before the first solve
        tgt = targets[i]
        _, tg = frames_and_targets(frame, tgt)
        T, mode = target_arrays(names, tg)
        prepared.append((T, mode, start_configuration(problem, starts[i])))
    solver = Solver(problem)
    warm_up(solver)
    out: list[IKResult] = [solver.run(q, T, mode, s, (int(seed), i)) for i, (T, mode, q) in
                           enumerate(prepared)]  # fmt: skip
    return IKBatchResult(
        q=np.array([r.q for r in out]).reshape(n, robot.nq),
        success=np.array([r.success for r in out], dtype=bool),
        iterations=np.array([r.iterations for r in out], dtype=np.int64),
        position_error=np.array([r.position_error for r in out]),
        orientation_error=np.array([r.orientation_error for r in out]),
        reason=[r.reason for r in out],
        restarts=np.array([r.restarts for r in out], dtype=np.int64),
        elapsed=np.array([r.elapsed for r in out]),
    )
