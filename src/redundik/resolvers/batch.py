"""Batches: N independent pose problems on one robot model, resolved at once (``pinv`` and ``wqp``).

Problem i is one control step from configuration q_i towards a target pose T_i of one frame, with the stack

    [FrameTask(frame, target T_i, gain K, axes)]  +  [PostureTask(q_ref, gain K_p)]   (the null-space objective)

exactly what :meth:`BatchResolver.loop_stack` builds for the one-by-one loop (:meth:`BatchResolver.solve_loop`).
Vectorised over problems:

* kinematics: one ``pinocchio.computeJointJacobians`` per problem (what ``RobotModel.update`` computes for a step),
  its joint Jacobians and the frame's parent placement copied out through verified views of the Data (two copies a
  problem, into buffers kept per N); then one compiled loop over the N problems
  (``batch_kernels.frame_rows_batch``) for the frame placement, its base-aligned Jacobian and the pose errors
  e = (p_d − p, log(R_d Rᵀ)) (Pinocchio's ``log3`` for the rotation errors beyond the small-angle formula);
* ``pinv``: q̇ = J⁺V + (I − J⁺J)z as the single step computes it, with its kernel
  (``kernels.closed_form_into``: Cholesky when J has full row rank and nothing is damped, else the damped
  factorisation), in one compiled loop over the N problems (:func:`redundik.resolvers.kernels.closed_form_batch`);
* ``wqp``: P = w JᵀJ + ρ I + λ I, q = −w JᵀV − ρ z, the unconstrained optimum and its box test (the kernels of the
  single ``wqp`` step: ``gram_update``, ``spd_solve_box_into``) in one compiled loop over the N problems
  (``batch_kernels.wqp_box_batch``), the joint-limit boxes of all N by one call of :meth:`JointLimits.box` on a (N, nq)
  array. Only the problems whose optimum leaves the box (a limit binds) call the QP backend, with the single step's QP
  (the same P, q and box, so the loop's answer): under daqp all of them in one compiled loop through daqp's C entry
  point (the call its Python wrapper makes, bit for bit; ``hqp_kernels.box_qps_native``), under another backend one
  ``solve`` each; a problem daqp does not solve at once is posed to ``backend.solve`` with its retries, and a problem
  the backend refuses goes through the single-problem ``wqp`` step itself (its relaxation and fallback, exactly as the
  loop).

Agreement with the loop: ≤ 1e-9 in q̇ (tested); the differences are rounding (the batch's frame rows against
Pinocchio's in the single step; ``wqp`` matched the loop bit for bit on panda_batch1000).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pinocchio as pin

from redundik._coldstart import compiled_now
from redundik.errors import ResolverError, SolverError
from redundik.kinematics.memory import jacobian_view, se3_vector_view
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import MAX_Q, Resolver
from redundik.resolvers.layouts import CF_DQ, CF_ROWS
from redundik.resolvers.linalg import RCOND, K, _Kernels
from redundik.resolvers.pinv import PinvResolver
from redundik.resolvers.qp.backends import DaqpBackend
from redundik.resolvers.qp.daqp_native import HK, NativeDaqp
from redundik.resolvers.qp.problem import QPProblem
from redundik.resolvers.qp.wqp import WeightedQPResolver
from redundik.resolvers.singularity import cap_rows
from redundik.tasks.base import Task
from redundik.tasks.frame import FrameTask, PostureTask, resolve_axes
from redundik.tasks.stack import TaskStack

BK = _Kernels("batch_kernels")  # (numba loads on first use, not when redundik is imported)


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


def _placement_map(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """W (12, 12) such that x W, for x = (R_i column-major, t_i) a joint's placement oMi in the world (as
    :func:`redundik.kinematics.memory.se3_vector_view` lays it out), is (R_f row-major, p_f) of the frame placed at
    (R, p) in that joint: oMf = oMi · (R, p), R_f = R_i R and p_f = R_i p + t_i [m]; N placements then take one
    matrix product (N, 12) · (12, 12)."""
    W = np.zeros((12, 12))
    for a in range(3):
        for b in range(3):  # (R_i)_ab is x[3b + a]
            W[3 * b + a, 3 * a : 3 * a + 3] = R[b]  # (R_f)_ac += (R_i)_ab R_bc
            W[3 * b + a, 9 + a] = p[b]  # (p_f)_a += (R_i)_ab p_b
        W[9 + a, 9 + a] = 1.0  # (p_f)_a += (t_i)_a
    return W


def _supporting_columns(robot: RobotModel, fid: int) -> np.ndarray:
    """(nv,) bool: True on the velocity columns of the joints that support frame ``fid`` (those its Jacobian may have
    nonzero, as ``fused._frame_columns``)."""
    model = robot.model
    columns = np.zeros(robot.nv, dtype=bool)
    for j in model.supports[model.frames[fid].parentJoint]:
        if j > 0:
            jm = model.joints[j]
            columns[jm.idx_v : jm.idx_v + jm.nv] = True
    return columns


def _copy_plan(
    JwT: np.ndarray, placement: np.ndarray, views: tuple[np.ndarray, np.ndarray] | None
) -> tuple[list[Any], list[Any], tuple[Any, Any] | None]:
    """How :meth:`BatchResolver._kinematics` copies each problem's Pinocchio data into the rows of ``JwT`` and
    ``placement``: (destinations of J, destinations of the placement, their sources), each a byte ``memoryview``
    when the live views and the rows are C-contiguous (a memoryview's slice assignment is one ``memcpy``, about half
    a NumPy assignment's cost on these 54 + 12 numbers); the rows and the views themselves otherwise, and the
    sources ``None`` without live views (the caller then reads Pinocchio's objects)."""
    if views is None:
        return list(JwT), list(placement), None
    if all(a.flags.c_contiguous for a in (*views, JwT, placement)):
        J_view, M_view = views
        J_rows = [row.data.cast("B") for row in JwT]  # (ndarray.data: the array's buffer as a memoryview)
        M_rows = [row.data.cast("B") for row in placement]
        return J_rows, M_rows, (J_view.data.cast("B"), M_view.data.cast("B"))
    return list(JwT), list(placement), views


def _all_rigid(T: np.ndarray) -> bool:
    """Whether every transform of T (N ≥ 1, 4, 4; finite) is rigid by :meth:`BatchResolver._check`'s test — RRᵀ
    within 1e-6 of I, det R > 0 and a last row (0, 0, 0, 1) within 1e-12 — in one compiled loop
    (``batch_kernels.all_rigid``; the per-problem test then only names the problems that fail)."""
    return bool(BK.all_rigid(T, 1e-6, 1e-12))


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
        placed = robot.model.frames[self.fid]
        self._parent = int(placed.parentJoint)
        self._to_frame = _placement_map(np.array(placed.placement.rotation), np.array(placed.placement.translation))
        self._columns = _supporting_columns(robot, self.fid)
        self._bind_views()
        self._native: NativeDaqp | None = None  # daqp's C entry for the binding problems' box QPs (kept)
        self._qbuf = np.empty(0)
        self._done = np.empty(0, dtype=np.bool_)  # frame_rows_batch's small-angle flags (kept per N)

    def _bind_views(self) -> None:
        """The live views of this batch's own Pinocchio data (made again for a copy, whose data is another object:
        a view copied with it would read the original's memory, or a frozen copy of it), and empty scratch."""
        self._views: tuple[np.ndarray, np.ndarray] | None = None  # (data.J, data.oMi[parent]) as live views, or None
        J_view, placements = jacobian_view(self._data), se3_vector_view(self._data.oMi)
        if J_view is not None and placements is not None:
            self._views = (J_view.T, placements[self._parent])  # (nv, 6) C-ordered, and R (column-major), t (12,)
        #: Scratch arrays kept from call to call (:meth:`_buffer`), and the per-problem copy plan of the kinematics
        self._buffers: dict[str, np.ndarray] = {}
        self._rows_of: tuple[np.ndarray, np.ndarray, list[Any], list[Any], tuple[Any, Any] | None] | None = None

    def __getstate__(self) -> dict[str, Any]:
        """The batch without its views of Pinocchio's memory, its scratch and daqp's C entry (made again)."""
        state = self.__dict__.copy()
        for key in ("_views", "_rows_of", "_native"):
            state[key] = None
        state["_buffers"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind_views()

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
    def _buffer(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """A float64 scratch array of ``shape`` (contents undefined), the same one from call to call while the shape
        stays: a batch's intermediates (a few MB for 1000 Panda problems) are not allocated afresh each call, whose
        pages the allocator would otherwise return to the system and fault in again at each call. Valid until the next
        call of the batch."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape != shape:
            buf = self._buffers[name] = np.empty(shape)
        return buf

    def _kinematics(self, q: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(J (N, m, nv), e (N, m), posture error (N, nv)) at the N configurations.

        Per problem one ``pinocchio.computeJointJacobians`` (the joint placements and the joint Jacobians in the
        world frame, as ``RobotModel.update`` computes them for a step), read through verified views of the Data
        (:mod:`redundik.kinematics.memory`; two copies a problem); then one compiled loop
        (``batch_kernels.frame_rows_batch``): the frame's placement oMf = oMi(parent) · placement, its base-aligned
        Jacobian rows (``lie_kernels.frame_jacobian_lwa``: Pinocchio's ``LOCAL_WORLD_ALIGNED`` frame Jacobian) and the
        error e = (p_d − p [m], log3(R_d Rᵀ) [rad]) (``lie_kernels.frame_error_rp``; Pinocchio's ``log3`` where the
        rotation error exceeds its small-angle range)."""
        model, data = self.robot.model, self._data
        N, nv = q.shape[0], self.robot.nv
        JwT = self._buffer("JwT", (N, nv, 6))  # joint Jacobians in the world frame, transposed [m/rad, 1]
        placement = self._buffer("placement", (N, 12))  # the parent joint's rotation (column-major), origin [m]
        rows_of = self._rows_of
        if rows_of is None or rows_of[0] is not JwT or rows_of[1] is not placement:
            rows_of = self._rows_of = (JwT, placement, *_copy_plan(JwT, placement, self._views))
        _, _, J_rows, M_rows, sources = rows_of
        jacobians = pin.computeJointJacobians
        if sources is not None:
            J_src, M_src = sources
            for qi, J_row, M_row in zip(q, J_rows, M_rows, strict=True):  # (the Pinocchio call, two copies a problem)
                jacobians(model, data, qi)
                J_row[:] = J_src
                M_row[:] = M_src
        else:  # (bindings that return copies: read Pinocchio's objects problem by problem)
            for i, qi in enumerate(q):
                jacobians(model, data, qi)
                JwT[i] = np.asarray(data.J).reshape(6, nv).T
                M = data.oMi[self._parent]
                placement[i, :9] = M.rotation.ravel(order="F")
                placement[i, 9:] = M.translation
        rows = self.rows
        J = self._buffer("J", (N, rows.shape[0], nv))
        e = self._buffer("e", (N, rows.shape[0]))
        done = self._done if self._done.shape[0] == N else np.empty(N, dtype=np.bool_)
        self._done = done
        rotation = bool(np.any(rows >= 3))
        BK.frame_rows_batch(JwT, placement, self._to_frame, targets, self._columns, rows, rotation, J, e, done)
        for k in np.flatnonzero(~done).tolist():  # a rotation error beyond the small-angle log3: Pinocchio's log3
            frame = placement[k] @ self._to_frame
            R, p = frame[:9].reshape(3, 3), frame[9:]
            err6 = np.concatenate((targets[k, :3, 3] - p, pin.log3(targets[k, :3, :3] @ R.T)))
            e[k] = err6[rows]
        if self.posture_gain > 0:
            ref = q if self.posture_target is None else np.broadcast_to(self.posture_target, q.shape)
            if self.robot.nq == nv:
                ep = np.subtract(ref, q, out=self._buffer("ep", (N, nv)))
            else:
                ep = np.stack([pin.difference(model, q[i], ref[i]) for i in range(N)])
        else:
            ep = np.zeros((N, nv))
        return J, e, ep

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
        finite = N > 0 and math.isfinite(float(np.add.reduce(q, axis=None)) + float(np.add.reduce(targets, axis=None)))
        if not finite:  # (a finite sum: every entry is finite; else the per-problem test names the problems)
            for key, arr in (("q", q), ("targets", targets)):
                bad = ~np.isfinite(arr.reshape(N, int(np.prod(arr.shape[1:])))).all(axis=1)
                if bad.any():
                    raise ResolverError(
                        f"batch: {key} of problems {np.flatnonzero(bad)[:8].tolist()} contain NaN or infinite values"
                    )
        if N and not float(np.max(np.abs(q))) <= MAX_Q:  # (a step refuses such a q: no configuration)
            huge = np.flatnonzero(~(np.abs(q) <= MAX_Q).all(axis=1))
            raise ResolverError(
                f"batch: q of problems {huge[:8].tolist()} have entries beyond ±{MAX_Q:g} [rad or length unit]: not "
                "configurations (a diverged loop, or a unit mistake?)"
            )
        if N and _all_rigid(targets):
            return q, targets
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
        z = np.multiply(self.posture_gain, ep, out=self._buffer("z", ep.shape))
        r = self.resolver
        if r.singularity is not None:
            raise ResolverError(
                f"batch: {r.name} has a singularity guard, whose state follows one robot from step to step; a batch "
                "resolves independent problems: set singularity=None for the batch, or step the problems one by one"
            )
        if isinstance(r, PinvResolver):
            V = np.multiply(self.gain, e, out=self._buffer("V", e.shape))
            dq = self._solve_pinv(r, J, V, z)
            out = BatchResult(dq, np.linalg.norm(e, axis=1), np.zeros(N, dtype=bool), [None] * N, [()] * N)
        else:
            out = self._solve_wqp(cast(WeightedQPResolver, r), q, targets, J, z, e, dt)
        limiter = r._limiter  # the joint-speed cap, as each problem's step applies it (resolvers/singularity.py)
        caps = None if limiter is None else limiter.caps(self.robot)
        if caps is None or (N and float(np.max(np.abs(out.dq) / caps)) <= 1.0):  # (no row over its caps: none scaled)
            out.capped = np.zeros(N, dtype=bool)
        else:
            out.capped = cap_rows(out.dq, caps)
        return out

    def _solve_pinv(self, r: PinvResolver, J: np.ndarray, V: np.ndarray, z: np.ndarray) -> np.ndarray:
        """q̇ = J⁺V + (I − J⁺J)z (eq. 5.8) of the N problems (J (N, m, n), V (N, m) [m/s, rad/s], z (N, n)
        [rad/s]), shape (N, n) [rad/s]: each problem solved by the single ``pinv`` step's kernel
        (``kernels.closed_form_into`` with its lazy σ_min: Jᵀ(JJᵀ)⁻¹ by Cholesky when J has full row rank and
        nothing is damped, else the damped factorisation), in one compiled loop over the problems."""
        N, _, n = J.shape
        out = self._buffer("closed_forms", (N, CF_ROWS, n))  # (q̇_r, q̇_n, q̇) per problem; q̇ is copied out
        K.closed_form_batch(J, V, z, self.posture_gain > 0, r.epsilon, r.max_damping, RCOND, out)
        return out[:, CF_DQ].copy()  # (always a copy: out is the batch's buffer, reused by the next call)

    def _solve_wqp(
        self,
        r: WeightedQPResolver,
        q: np.ndarray,
        targets: np.ndarray,
        J: np.ndarray,
        z: np.ndarray,
        e: np.ndarray,
        dt: float,
    ) -> BatchResult:
        """q̇ (N, nv) [rad/s] of the N ``wqp`` problems (J (N, m, nv), z (N, nv) [rad/s], e (N, m) [m, rad]): each
        problem's P, q, unconstrained optimum and box test in one compiled loop (``batch_kernels.wqp_box_batch``),
        the joint-limit boxes of all N by one :meth:`JointLimits.box` call; the problems whose optimum leaves the box
        take the single step's QP (see the module docstring)."""
        N, nv = q.shape[0], self.robot.nv
        has_posture = self.posture_gain > 0
        scale = r.level_ratio if has_posture else 1.0  # ρ^(L−1): the lowest level's weight
        box = r.limits.box(self.robot, q, dt)  # (N, nv) bounds: one call for every problem (bound to the robot)
        bounds = self._buffer("box", (2, N, nv))  # lb, ub: the kernel's record
        np.copyto(bounds[0], box.lb)
        np.copyto(bounds[1], box.ub)
        lb, ub = bounds[0], bounds[1]
        P = self._buffer("P", (N, nv, nv))
        qv = self._buffer("qv", (N, nv))
        dq = np.empty((N, nv))
        inside = np.empty(N, dtype=np.bool_)
        err = np.empty(N)
        coef = np.empty(BK.WB_COEFS)
        coef[BK.WB_GAIN], coef[BK.WB_SCALE], coef[BK.WB_POSTURE] = self.gain, scale, float(has_posture)
        coef[BK.WB_DAMPING], coef[BK.WB_LM], coef[BK.WB_TOL] = r.damping * scale, float(r.lm_damping or 0.0), 1e-12
        BK.wqp_box_batch(J, e, z, coef, bounds, P, qv, dq, inside, err)
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
        without its Python wrapper, whose overhead outweighs such a small QP's solve). Only under a daqp
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
