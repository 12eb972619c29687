"""Batches: N independent pose problems on one robot model, resolved at once (``pinv`` and ``wqp``).

Problem i is one control step from configuration q_i towards a target pose T_i of one frame, with the stack

    [FrameTask(frame, target T_i, gain K, axes)]  +  [PostureTask(q_ref, gain K_p)]   (the null-space objective)

exactly what :meth:`BatchResolver.loop_stack` builds for the one-by-one loop (:meth:`BatchResolver.solve_loop`).
Vectorised over problems:

* kinematics: one ``pinocchio.computeFrameJacobian`` per problem into preallocated (N, 6, nv) / (N, 4, 4) buffers;
  pose errors e = (p_d − p, log(R_d Rᵀ)) for all N at once;
* ``pinv``: q̇ = J⁺V + (I − J⁺J)z through :func:`redundik.resolvers.kernels.closed_form_batch` — the very kernel of
  the single ``pinv`` step, problem by problem;
* ``wqp``: P = w JᵀJ + ρ I + λ I and q = −w JᵀV − ρ z for all N (batched products), the unconstrained optimum and its
  box test by ``spd_solve_batch`` (the kernel of the single ``wqp`` step), the
  joint-limit boxes of all N by one call of :meth:`JointLimits.box` on a (N, nq) array. Only the problems whose
  optimum leaves the box (a limit binds) call the QP backend, with the single step's QP (the same P, q and box,
  so the loop's answer): under daqp all of them in one compiled loop through daqp's C entry point (the call its
  Python wrapper makes, bit for bit; ``hqp_kernels.box_qps_native``), under another backend one ``solve`` each; a
  problem daqp does not solve at once is posed to ``backend.solve`` with its retries, and a problem the backend
  refuses goes through the single-problem ``wqp`` step itself (its relaxation and fallback, exactly as the loop).

Agreement with the loop: ≤ 1e-9 in q̇ (tested); the differences are rounding in the kinematics (Pinocchio's
``computeFrameJacobian`` vs ``computeJointJacobians``) and in batched products.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
import pinocchio as pin

from redundik._coldstart import compiled_now
from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver
from redundik.resolvers.linalg import RCOND, K
from redundik.resolvers.pinv import PinvResolver
from redundik.resolvers.qp.backends import DaqpBackend
from redundik.resolvers.qp.daqp_native import HK, NativeDaqp
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.wqp import WeightedQPResolver
from redundik.resolvers.singularity import cap_rows
from redundik.tasks.base import Task
from redundik.tasks.frame import FrameTask, PostureTask, resolve_axes
from redundik.tasks.stack import TaskStack

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class BatchResult:
    """N resolved problems.

    Attributes:
        dq: Joint velocities q̇, shape (N, nv).
        task_error: Norm of each problem's frame-task error before the step, shape (N,) [m and rad mixed].
        qp: True where the QP backend was called (a limit bound), shape (N,) (all false for ``pinv``).
        fallback: Per problem, why its step fell back (``None`` for none), only filled for problems run one by one.
        relaxed: Per problem, the documented relaxations of its step (``StepResult.relaxed``: a QP a backend retry
            solved, ``"wqp (backend retried)"``); an empty tuple for none.
        capped: True where the resolver's joint-speed cap scaled q̇ (``max_joint_speed``), shape (N,).
    """

    dq: np.ndarray
    task_error: np.ndarray
    qp: np.ndarray
    fallback: list[str | None] = field(default_factory=list)
    relaxed: list[tuple[str, ...]] = field(default_factory=list)
    capped: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def qp_fraction(self) -> float:
        """Fraction of the problems that needed the QP backend."""
        return float(np.mean(self.qp)) if self.qp.size else 0.0


def batch_log3(R: np.ndarray) -> np.ndarray:
    """log(R) ∈ so(3) as rotation vectors for R of shape (N, 3, 3) [rad], shape (N, 3).

    The frame task's one formula (:func:`redundik.resolvers.kernels.batch_log3_small`, the atan2 form below
    θ = 0.45 rad) for every problem it covers, Pinocchio's ``log3`` for the others (robust up to θ = π).
    """
    R = np.ascontiguousarray(R, dtype=float)
    out = np.empty((R.shape[0], 3))
    done = np.empty(R.shape[0], dtype=np.bool_)
    K.batch_log3_small(R, out, done)
    for i in np.flatnonzero(~done):
        out[i] = pin.log3(R[i])
    return out


class BatchResolver:
    """Resolve N pose problems at once with ``pinv`` or ``wqp`` (see the module docstring).

    Args:
        resolver: A :class:`PinvResolver` or :class:`WeightedQPResolver` (its options — damping, limits, level
            ratio, backend — are the batch's).
        robot: The robot model (one for all problems).
        frame: The frame to place.
        axes: Frame-task rows (``"pose"``, ``"position"``, …).
        gain: K [1/s] of the frame task (v = K e).
        posture_gain: K_p [1/s] of the posture task (0: no posture).
        posture_target: q_ref (nq,); ``None``: each problem's own start configuration.

    Raises:
        ResolverError: a resolver other than pinv/wqp, wqp level overrides, or a frame the robot lacks.
    """

    def __init__(
        self,
        resolver: Resolver,
        robot: RobotModel,
        frame: str,
        *,
        axes: str | Sequence[str] = "pose",
        gain: float = 1.0,
        posture_gain: float = 1.0,
        posture_target: np.ndarray | None = None,
    ) -> None:
        if type(resolver) not in (PinvResolver, WeightedQPResolver):
            raise ResolverError(
                f"batch: resolver {resolver!r} is not supported; batches take 'pinv' (PinvResolver) or 'wqp' "
                "(WeightedQPResolver)"
            )
        if isinstance(resolver, WeightedQPResolver) and resolver.levels:
            raise ResolverError("batch: wqp level overrides are not supported in a batch")
        if isinstance(resolver, WeightedQPResolver) and resolver.scaling != "off":
            raise ResolverError("batch: wqp scaling='direction' is not supported in a batch (step one by one)")
        self.resolver, self.robot, self.frame = resolver, robot, frame
        self.axes = resolve_axes(axes)
        self.rows = np.array([("x", "y", "z", "rx", "ry", "rz").index(a) for a in self.axes])
        for key, value in (("gain", gain), ("posture_gain", posture_gain)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise ResolverError(f"batch: {key} must be a number [1/s], got {type(value).__name__}")
            if not (math.isfinite(value) and value >= 0):
                raise ResolverError(f"batch: {key} must be a finite number ≥ 0 [1/s], got {value}")
        self.gain, self.posture_gain = float(gain), float(posture_gain)
        self.posture_target = (
            None if posture_target is None else robot.check_configuration(posture_target, "batch: posture_target")
        )
        self.fid = robot.frame_id(frame)
        if robot.model.frames[self.fid].parentJoint == 0:
            raise ResolverError(
                f"batch: frame '{frame}' is fixed to the world (no joint moves it): no target could ever be reached"
            )
        self._data = robot.model.createData()
        self._native: NativeDaqp | None = None  # daqp's C entry for the binding problems' box QPs (kept)
        self._qbuf = np.empty(0)

    # ------------------------------------------------------------------ the one-by-one reference
    def loop_stack(self, q: np.ndarray, target: np.ndarray) -> TaskStack:
        """The stack problem i means, for the loop: frame task towards ``target`` (4×4), posture (if any)."""
        task = FrameTask(self.frame, axes=self.axes, gain=self.gain)
        task.set_target(target)
        tasks: list[Task] = [task]
        if self.posture_gain > 0:
            tasks.append(PostureTask(self.posture_target, gain=self.posture_gain))
        return TaskStack(tasks)

    def solve_loop(self, q: np.ndarray, targets: np.ndarray, dt: float) -> BatchResult:
        """The same N problems one by one through ``resolver.step`` (the reference the batch must equal)."""
        N = q.shape[0]
        dq = np.empty((N, self.robot.nv))
        err = np.empty(N)
        used = np.zeros(N, dtype=bool)
        capped = np.zeros(N, dtype=bool)
        notes: list[str | None] = []
        relaxed: list[tuple[str, ...]] = []
        stack = self.loop_stack(q[0], targets[0]) if N else TaskStack()
        for i in range(N):
            stack.tasks[0].set_target(targets[i])  # type: ignore[attr-defined]
            if self.posture_gain > 0:
                ref = q[i] if self.posture_target is None else self.posture_target
                stack.tasks[1].set_target(ref)  # type: ignore[attr-defined]
            self.robot.update(q[i])
            if i == 0:
                stack.reset(self.robot)
            self.resolver.reset()  # independent problems: no previous q̇ (rate window), no warm start
            res = self.resolver.step(self.robot, stack, q[i], 0.0, dt)
            dq[i] = res.dq
            err[i] = res.terms[0].error_norm
            used[i] = bool(res.info.get("qp", 0))
            notes.append(res.fallback)
            relaxed.append(res.relaxed)
            capped[i] = "max_joint_speed" in res.relaxed
        return BatchResult(dq, err, used, notes, relaxed, capped)

    # ------------------------------------------------------------------ the batch
    def _kinematics(self, q: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(J (N, m, nv), e (N, m), posture error (N, nv)) at the N configurations."""
        model, data, fid = self.robot.model, self._data, self.fid
        N, nv = q.shape[0], self.robot.nv
        J6 = np.empty((N, 6, nv))
        M = np.empty((N, 4, 4))
        for i in range(N):
            J6[i] = pin.computeFrameJacobian(model, data, q[i], fid, _LWA)
            M[i] = data.oMf[fid].homogeneous
        e6 = np.empty((N, 6))
        e6[:, :3] = targets[:, :3, 3] - M[:, :3, 3]
        if np.any(self.rows >= 3):
            e6[:, 3:] = batch_log3(targets[:, :3, :3] @ M[:, :3, :3].transpose(0, 2, 1))
        else:
            e6[:, 3:] = 0.0
        if self.posture_gain > 0:
            ref = q if self.posture_target is None else np.broadcast_to(self.posture_target, q.shape)
            if self.robot.nq == nv:
                ep = ref - q
            else:
                ep = np.stack([pin.difference(model, q[i], ref[i]) for i in range(N)])
        else:
            ep = np.zeros((N, nv))
        return J6[:, self.rows], e6[:, self.rows], ep

    def _check(self, q: np.ndarray, targets: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """q (N, nq) and targets (N, 4, 4) as float arrays, checked with dt; raises :class:`ResolverError`."""
        arrays = []
        for key, value in (("q", q), ("targets", targets)):
            raw = np.asarray(value)
            if raw.dtype.kind not in "fiu":  # bool, complex, strings, objects: not numbers to compute with
                raise ResolverError(f"batch: {key} must be an array of real numbers, got dtype {raw.dtype}")
            arrays.append(np.ascontiguousarray(raw, dtype=float))
        q, targets = arrays
        N = q.shape[0] if q.ndim == 2 else -1
        if q.ndim != 2 or q.shape[1] != self.robot.nq or targets.shape != (N, 4, 4):
            raise ResolverError(
                f"batch: expected q (N, {self.robot.nq}) and targets (N, 4, 4), got {q.shape} and {targets.shape}"
            )
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
            raise ResolverError(f"batch: dt must be a number [s], got {type(dt).__name__}")
        if not (math.isfinite(dt) and dt > 0):
            raise ResolverError(f"batch: dt must be finite and > 0 [s], got {dt}")
        for key, arr in (("q", q), ("targets", targets)):
            bad = ~np.isfinite(arr.reshape(N, int(np.prod(arr.shape[1:])))).all(axis=1)
            if bad.any():
                raise ResolverError(
                    f"batch: {key} of problems {np.flatnonzero(bad)[:8].tolist()} contain NaN or infinite values"
                )
        R = targets[:, :3, :3]
        rigid = (
            np.all(np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)) <= 1e-6, axis=(1, 2))
            & (np.linalg.det(R) > 0)
            & np.all(np.abs(targets[:, 3] - (0.0, 0.0, 0.0, 1.0)) <= 1e-12, axis=1)
        )
        if not rigid.all():
            raise ResolverError(
                f"batch: targets of problems {np.flatnonzero(~rigid)[:8].tolist()} are not rigid transforms "
                "(a proper rotation and a last row (0, 0, 0, 1))"
            )
        return q, targets

    def solve(self, q: np.ndarray, targets: np.ndarray, dt: float) -> BatchResult:
        """Resolve the N problems (q (N, nq), targets (N, 4, 4)) for one step dt [s].

        Raises:
            ResolverError: shapes that do not match, non-finite inputs or dt ≤ 0.
        """
        compiled_now()  # (a batch is compiled from its first call)
        q, targets = self._check(q, targets, dt)
        N = q.shape[0]
        J, e, ep = self._kinematics(q, targets)
        V = self.gain * e
        z = self.posture_gain * ep
        err = np.linalg.norm(e, axis=1)
        r = self.resolver
        if r.singularity is not None:
            raise ResolverError(
                f"batch: {r.name} has a singularity guard, whose state follows one robot from step to step; a batch "
                "resolves independent problems: set singularity=None for the batch, or step the problems one by one"
            )
        if isinstance(r, PinvResolver):
            dq_r, dq_n, _, _, _ = K.closed_form_batch(
                np.ascontiguousarray(J), V, z, self.posture_gain > 0, r.epsilon, r.max_damping, RCOND
            )
            out = BatchResult(dq_r + dq_n, err, np.zeros(N, dtype=bool), [None] * N, [()] * N)
        else:
            out = self._solve_wqp(cast(WeightedQPResolver, r), q, targets, J, V, z, e, err, dt)
        limiter = r._limiter  # the joint-speed cap, as each problem's step applies it (resolvers/singularity.py)
        caps = None if limiter is None else limiter.caps(self.robot)
        out.capped = np.zeros(N, dtype=bool) if caps is None else cap_rows(out.dq, caps)
        return out

    def _solve_wqp(
        self,
        r: WeightedQPResolver,
        q: np.ndarray,
        targets: np.ndarray,
        J: np.ndarray,
        V: np.ndarray,
        z: np.ndarray,
        e: np.ndarray,
        err: np.ndarray,
        dt: float,
    ) -> BatchResult:
        N, nv = q.shape[0], self.robot.nv
        has_posture = self.posture_gain > 0
        scale = r.level_ratio if has_posture else 1.0  # ρ^(L−1): the lowest level's weight
        Jt = J.transpose(0, 2, 1)  # (N, nv, m); the frame task's weight is 1 at level 0
        P = Jt @ J
        qv = -(Jt @ V[:, :, None])[:, :, 0]
        idx = np.arange(nv)
        if has_posture:
            P[:, idx, idx] += scale
            qv -= scale * z
        lam = np.full(N, r.damping * scale)
        if r.lm_damping:
            lam += r.lm_damping * np.einsum("nm,nm->n", e, e)
        P[:, idx, idx] += lam[:, None]
        r.limits.bind(self.robot)
        box = r.limits.box(self.robot, q, dt)  # (N, nv) bounds: one call for every problem
        lb = np.ascontiguousarray(np.broadcast_to(box.lb, (N, nv)))
        ub = np.ascontiguousarray(np.broadcast_to(box.ub, (N, nv)))
        x, _, inside = K.spd_solve_batch(np.ascontiguousarray(P), qv, lb, ub, 1e-12)
        dq = np.minimum(np.maximum(x, lb), ub)
        notes: list[str | None] = [None] * N
        relaxed: list[tuple[str, ...]] = [()] * N
        bind = np.flatnonzero(~inside)
        if bind.size:
            bind = self._native_box_qps(r, P, qv, lb, ub, bind, dq)
        empty_rows, empty = np.zeros((0, nv)), np.zeros(0)
        hard: list[int] = []
        for i in bind:  # a limit binds: the single step's QP (same P, q, box), straight to its backend
            prob = QPProblem(P[i], qv[i], empty_rows, empty, empty_rows, empty, lb[i], ub[i], "wqp")
            try:
                sol = r._solve_qp(prob)
            except SolverError:
                hard.append(int(i))
                continue
            dq[i] = np.minimum(np.maximum(sol.x, lb[i]), ub[i])
            if getattr(sol, "retried", None):  # a backend failure a retry rescued: counted, as in the single step
                relaxed[i] = ("wqp (backend retried)",)
        if hard:  # the backend refused: the single-problem step (its fallbacks), exactly as the loop
            sub = self.solve_loop(q[hard], targets[hard], dt)
            dq[hard] = sub.dq
            for k, j in enumerate(hard):
                notes[j], relaxed[j] = sub.fallback[k], sub.relaxed[k]
        used = ~inside
        return BatchResult(dq, err, used, notes, relaxed)

    def _native_box_qps(
        self,
        r: WeightedQPResolver,
        P: np.ndarray,
        qv: np.ndarray,
        lb: np.ndarray,
        ub: np.ndarray,
        bind: np.ndarray,
        dq: np.ndarray,
    ) -> np.ndarray:
        """The box QPs of the problems ``bind`` (a limit binds) solved in one compiled loop through daqp's C entry
        point, into ``dq`` (``hqp_kernels.box_qps_native``: the call ``DaqpBackend.solve`` makes on such a QP,
        without its Python wrapper; ≈ 3.5 against ≈ 44 µs a problem in one sweep chunk's profile). Only under a daqp
        backend whose ``solve`` poses the QP as it is (fewer variables than its split size) and while the native
        call is on (:func:`redundik.resolvers.qp.daqp_native.status`).

        Returns:
            The problems left for the backend's own ``solve``: every one when the native call is off, else those
            daqp did not solve at once.
        """
        backend = r.backend
        nv = P.shape[1]
        if type(backend) is not DaqpBackend or nv >= backend._split_min_n:
            return bind
        native = self._native = NativeDaqp.for_backend(backend, nv, 0, self._native)
        if native is None:
            return bind
        if self._qbuf.shape[0] < nv * nv + 3 * nv:
            self._qbuf = np.empty(nv * nv + 3 * nv)
        solved = np.zeros(bind.shape[0], dtype=np.bool_)
        HK.box_qps_native(native.ctl, native.x, self._qbuf, P, qv, lb, ub, bind, dq, solved)
        return bind[~solved]


def solve_batch(
    resolver: Resolver,
    robot: RobotModel,
    frame: str,
    q: np.ndarray,
    targets: np.ndarray,
    dt: float,
    **options: object,
) -> BatchResult:
    """One call: :class:`BatchResolver` (``options``: axes, gain, posture_gain, posture_target) then ``solve``."""
    return BatchResolver(resolver, robot, frame, **options).solve(q, targets, dt)  # type: ignore[arg-type]
