"""The plan of ``hqp``'s lean step (:mod:`redundik.resolvers.qp.hqp`): per stack membership, what each level is,
the buffers its rows are written into (A, b, w and C, d, in the layout the kernels read: ``meta``'s ``META_*``
rows), how the rows of a fused stack map onto them, the bound subtasks packed for the compiled damper rows, and the
constrained cascade's work arrays and level-QP buffer.
"""

from __future__ import annotations

import sys
import weakref
from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.resolvers.fused import ROW, ROWS, TARGET, FusedPlan
from redundik.resolvers.hqp_layout import (
    H_FRAME_STARTS,
    H_J,
    H_JOINT_STARTS,
    H_K,
    META_INEQ,
    META_KIND,
    META_LS,
    QS_COLUMNS,
)
from redundik.resolvers.linalg import _Kernels
from redundik.resolvers.qp.backends import Backend, DaqpBackend
from redundik.resolvers.qp.base import SAFETY_TOLERANCE
from redundik.resolvers.qp.daqp_native import NativeDaqp
from redundik.resolvers.qp.hqp_bounds import UNHELD, PackedBounds, WrittenRows, pack_bounds
from redundik.resolvers.qp.terms import StepRows
from redundik.tasks.base import Edits, TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack
from redundik.tasks.subtasks import BoundSubtask

#: :mod:`redundik.resolvers.hqp_kernels`, imported on first use (numba loads then, not when redundik is imported).
HK = _Kernels("hqp_kernels")


_EMPTY, _EMPTY_INT, _EMPTY_BOOL = np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.bool_)


class _Plan:
    """What the lean cascade does per level, fixed while the stack's membership is (see ``_plan_for``): the level
    kinds, the offsets table and the buffers the rows are copied into (grown when a level brings more rows)."""

    def __init__(self, layout: StackLayout, n: int, params: np.ndarray) -> None:
        self.layout, self.n, self.params = layout, n, params
        L = len(layout.levels)
        self.meta = np.zeros((3, L + 1), dtype=np.int64)
        self.mixed: list[bool] = []  # a level with rows of its own and the null-space objective: + identity rows
        for k, plan in enumerate(layout.levels):
            has_rows = bool(plan.tasks or plan.targets)
            has_z = plan.null_objective and layout.has_null_objective
            self.meta[META_KIND, k] = HK.LEAST_SQUARES if has_rows else (HK.NULL_OBJECTIVE if has_z else HK.SKIP)
            self.mixed.append(has_rows and has_z)
        self.mixed_flags = np.array(self.mixed, dtype=np.bool_)
        self.A, self.b, self.w = np.zeros((16, n)), np.zeros(16), np.ones(16)
        self.C, self.d = np.zeros((4, n)), np.zeros(4)
        self.eye, self.zero = np.eye(n), np.zeros(n)
        #: safety rows (a critical barrier's): the fused step keeps its answer only when they hold, else the template
        self.critical = any(b.critical for level in layout.levels for b in level.bounds)
        #: the safety rows' (first, end) rows of C, d as the last :meth:`fused_bounds` wrote them
        self.safety_rows: list[tuple[int, int]] = []
        self._weights: list[tuple[int, int, float]] = []  # per block (first row, end, weight) last written into w
        #: Per level, what :meth:`gather` evaluates: (task indices, target subtasks, bound subtasks, whether the level
        #: carries the null-space objective, whether it adds the objective's identity rows after its own).
        self.members = [
            (list(lv.tasks), list(lv.targets), list(lv.bounds), lv.null_objective, mixed)
            for lv, mixed in zip(layout.levels, self.mixed, strict=True)
        ]
        self._offsets: list[tuple[int, int]] = []  # the offsets gather last wrote into meta
        #: The fused form of the stack (:meth:`fuse`): ``None`` not planned yet, False none.
        self.fused: FusedPlan | str | bool | None = None
        self.dest = np.zeros(0, dtype=np.int64)  # per fused row its row of A, then the mixed levels' first rows
        self.ls_offsets: list[int] = []
        self._written: weakref.ref[WrittenRows] | None = None  # the record of the rows now in C, d
        #: (packed bounds, the records list) of the last :meth:`written_bounds`: reused while nobody else holds it
        self._last_written: tuple[PackedBounds, list[tuple[Any, Any, list[str]]]] | None = None
        #: the other pair of inequality buffers, with its (record, records list): :meth:`written_bounds` writes a
        #: step's rows there while a kept result still reads the last step's (:meth:`_swap_ineq`)
        self._spare: tuple[np.ndarray, np.ndarray, Any, Any] | None = None
        self._cascade: tuple[np.ndarray, ...] | None = None  # the constrained cascade's work arrays
        self.cascade_blocks: tuple[np.ndarray, np.ndarray, np.ndarray] = (_EMPTY, _EMPTY_INT, _EMPTY_BOOL)
        self._qp_buf = np.zeros(0)  # where the cascade writes a level QP (``hqp_kernels.level_qp_into``)
        self._qp_views: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}  # its views, per (variables, rows)
        self._native: NativeDaqp | None = None  # daqp's C call from the cascade (``daqp_native``)
        self.r_size = 0  # m² of the level of most least-squares rows (``qp_arrays``): a row of the cascade's rfac
        #: (the ``_offsets`` they were read for, most variables and rows of a level QP, inequality rows in all) of
        #: :meth:`qp_arrays`: read again only when meta was rewritten
        self._dims: tuple[object, int, int, int] | None = None
        #: (Edits.count, robot data) the bound subtasks were packed for, and the packing (``packed_bounds``)
        self._packed_key: tuple[int, Any] | None = None
        self._packed: PackedBounds | None = None

    def __getstate__(self) -> dict[str, Any]:
        """The plan without its weak reference to the last gather's record (a copy holds no step's rows) and without
        the views of its own buffers, made again at the copy's first use: the level QPs' views (``_qp_views``, of
        ``_qp_buf``) and the constrained cascade's work arrays (``_cascade``, views of ``cascade_blocks``). Copied,
        each view would be an array of its own: the cascade would write a level QP into the copied buffer while the
        backend solved the copied views' stale one, and read its state (the level's variables) from a frozen copy.
        A copy or a pickle of a resolver steps as the original."""
        state = self.__dict__.copy()
        state["_written"] = state["_last_written"] = state["_spare"] = None
        state["_qp_views"], state["_cascade"] = {}, None
        state["cascade_blocks"] = (_EMPTY, _EMPTY_INT, _EMPTY_BOOL)  # (cascade_buffers makes both again)
        return state

    def _keep_written(self) -> None:
        """Before the buffers are written again: copy the damper rows now in them if their record is held."""
        last = self._written
        if last is not None:
            self._written = None
            held = last()
            if held is not None:
                held.keep()

    def _swap_ineq(self) -> None:
        """Make the spare inequality buffers the plan's (grown to the same rows), and the plan's the spare."""
        spare = self._spare
        C, d = self.C, self.d
        if spare is None or spare[0].shape[0] < C.shape[0]:
            spare = (np.zeros_like(C), np.zeros_like(d), None, None)
        self._spare = (C, d, self._written, self._last_written)
        self.C, self.d, self._written, self._last_written = spare

    def gather(
        self, robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], dt: float
    ) -> tuple[np.ndarray | None, list[tuple[np.ndarray, float]], list[tuple[Any, Any, list[str]]]]:
        """The step's rows straight into the buffers, as ``gather_rows`` followed by :meth:`fill` would lay them
        (the members evaluated in the same order, the same rows, weights and offsets), without building the
        per-level lists. A bound subtask on a potential writes its damper rows (C = −η, d = γ(p − lower) for a lower
        bound, the velocity damper of ``BoundSubtask.rows_into``, the one implementation) into the buffers itself;
        those rows are copied (for :meth:`step_rows`, which may be asked after the buffers were reused) only when
        asked, or before the buffers are next written while this step's record of them is still held.

        Returns:
            (z of the null-space objective or ``None``, the target subtasks' (η, v) in layout order, the bound
            subtasks' (C, d, row names) in layout order — for rows written by ``rows_into``, (their
            :class:`WrittenRows` record, the rows' slice, names)): what :meth:`step_rows` needs to build the step's
            :class:`~redundik.resolvers.qp.terms.StepRows` when it is asked for.
        """
        if self._written is not None:
            self._keep_written()
        meta, n, key = self.meta, self.n, self._weights
        A, b, w = self.A, self.b, self.w
        targets: list[tuple[np.ndarray, float]] = []
        bounds: list[tuple[Any, Any, list[str]]] = []  # (C, d, names), or (written, rows' slice, names)
        written: WrittenRows | None = None  # the record of the rows written by rows_into
        z = None
        ms = cs = 0
        blk = 0
        offsets = []  # per level (first least-squares row, first inequality row): written into meta when they move
        for tasks, subs, bsubs, null_objective, mixed in self.members:
            offsets.append((ms, cs))
            for i in tasks:
                term = terms[i]
                J = term.J
                e = ms + J.shape[0]
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms:e] = J
                b[ms:e] = term.v
                weight = term.weight
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            for sub in subs:
                eta, vt, _ = sub.row(robot)
                targets.append((eta, vt))
                e = ms + 1
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms] = eta
                b[ms] = vt
                weight = sub.weight
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            if bsubs:
                cs, written = self._bound_rows(robot, dt, bsubs, cs, bounds, written)
            if null_objective:
                z = stack.null_target(robot, terms, self.layout)
            if mixed and z is not None:
                e = ms + n
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                b[ms:e] = z
                if blk >= len(key) or key[blk] != (ms, e, -1.0):
                    A[ms:e] = self.eye
                    w[ms:e] = 1.0
                    key[blk:] = [(ms, e, -1.0)]
                blk += 1
                ms = e
        offsets.append((ms, cs))
        if written is not None:
            written.src = (self.C, self.d, cs)
            self._written = weakref.ref(written)
        if offsets != self._offsets:
            for k, (ls_row, ineq_row) in enumerate(offsets):
                meta[META_LS, k], meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = offsets
        return z, targets, bounds

    def _bound_rows(
        self,
        robot: RobotModel,
        dt: float,
        bsubs: list[BoundSubtask],
        cs: int,
        bounds: list[tuple[Any, Any, list[str]]],
        written: WrittenRows | None,
        safety: list[tuple[int, int]] | None = None,
    ) -> tuple[int, WrittenRows | None]:
        """A level's bound subtasks' rows into C, d from row ``cs`` (:meth:`gather`'s, appended to ``bounds``);
        returns the next row and the record of the rows written by ``rows_into``. ``safety``: the (first, end) rows
        of the critical ones are appended to it."""
        C, d = self.C, self.d
        for bsub in bsubs:
            k = bsub.fixed_rows
            if k is not None:  # a potential's damper rows, written into the buffers by the subtask itself
                e = cs + k
                if e > C.shape[0]:
                    C, d = self._grow_ineq(e)
                bsub.rows_into(robot, dt, C, d, cs)
                if written is None:
                    written = WrittenRows()
                bounds.append((written, slice(cs, e), bsub.row_names))
            else:
                Ci, di, rn = bsub.rows(robot, dt)
                bounds.append((Ci, di, rn))
                e = cs + Ci.shape[0]
                if e > C.shape[0]:
                    C, d = self._grow_ineq(e)
                C[cs:e] = Ci
                d[cs:e] = di
            if safety is not None and bsub.critical:
                safety.append((cs, e))
            cs = e
        return cs, written

    def fused_bounds(self, robot: RobotModel, dt: float) -> list[tuple[Any, Any, list[str]]]:
        """The bound subtasks' rows into C, d and the offsets table, for a fused step (:meth:`fuse`): the
        least-squares rows are the compiled call's, at the offsets :meth:`fuse` laid out; :meth:`gather`'s
        ``bounds``."""
        if self._written is not None:
            self._keep_written()
        meta = self.meta
        bounds: list[tuple[Any, Any, list[str]]] = []
        written: WrittenRows | None = None
        cs = 0
        offsets = []
        safety: list[tuple[int, int]] = []
        for (_, _, bsubs, _, _), ls_row in zip(self.members, self.ls_offsets, strict=False):
            offsets.append((ls_row, cs))
            if bsubs:
                cs, written = self._bound_rows(robot, dt, bsubs, cs, bounds, written, safety)
        self.safety_rows = safety
        offsets.append((self.ls_offsets[-1], cs))
        if written is not None:
            written.src = (self.C, self.d, cs)
            self._written = weakref.ref(written)
        if offsets != self._offsets:
            for k, (ls_row, ineq_row) in enumerate(offsets):
                meta[META_LS, k], meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = offsets
        return bounds

    def keeps_safety_rows(self, dq: np.ndarray) -> bool:
        """Every safety row of the last :meth:`fused_bounds` holds at ``dq`` to ``keep_safe``'s tolerance."""
        C, d = self.C, self.d
        for a, e in self.safety_rows:
            if e > a and not bool((C[a:e] @ dq <= d[a:e] + SAFETY_TOLERANCE).all()):
                return False
        return True

    def packed_bounds(self, robot: RobotModel) -> PackedBounds | None:
        """The bound subtasks packed for the fused step's compiled damper rows (``hqp_fused.clearance_rows``),
        when every one gives its ``clearance_form`` (a bound on a clearance, read through verified views of
        Pinocchio's memory, as the fused step reads it); ``None``: :meth:`fused_bounds` evaluates them in Python.
        Packed again when ``Edits`` moved (an assigned centre, radius, frame, axes, bound, rate or name) or for
        another robot's data."""
        key = self._packed_key
        if key is not None and key[0] == Edits.count and key[1] is robot.data:
            return self._packed
        self._packed = self._pack_bounds(robot)
        self._packed_key = (Edits.count, robot.data)
        return self._packed

    def _pack_bounds(self, robot: RobotModel) -> PackedBounds | None:
        """:meth:`packed_bounds`' packing (``hqp_bounds.pack_bounds``), with C, d grown to its rows."""
        packed = pack_bounds(robot, [bs for _, _, bs, _, _ in self.members], self.ls_offsets, self.n)
        if packed is not None and packed.rows > self.C.shape[0]:
            self._grow_ineq(packed.rows)
        return packed

    def written_bounds(self, packed: PackedBounds) -> list[tuple[Any, Any, list[str]]]:
        """:meth:`fused_bounds` for packed bounds, whose rows the compiled call writes: the offsets table and this
        step's records (``bounds`` of :meth:`gather`), which read the rows from the buffers they were written into.

        The compiled call writes every entry of their rows (``clearance_rows``: whole rows of C and their d) into the
        plan's inequality buffers — no allocation a step. A record's rows are copied when first asked, or before
        those buffers are written again while the record is still held (a kept result's diagnostics).

        When nobody but this plan holds the last step's records (its result was dropped: the list's reference count
        is that of a list held by the plan alone, ``UNHELD``) and their rows were never copied, they describe this
        step's rows as well and are returned again. When a result still holds them (a loop's ``res = step(...)``
        keeps the last result while it steps), this step writes the spare buffers, whose records the result before
        it left: a control loop makes no record and copies no row a step."""
        last = self._last_written
        if (
            last is not None
            and last[0] is packed
            and self._offsets is packed.offsets
            and self._written is not None
            and last[1][0][0].C is None
        ):
            if sys.getrefcount(last[1]) == UNHELD:
                return last[1]
            self._swap_ineq()  # (a kept result reads the rows now in C, d)
            last = self._last_written
            if (
                last is not None
                and last[0] is packed
                and self._written is not None
                and sys.getrefcount(last[1]) == UNHELD
                and last[1][0][0].C is None
            ):
                return last[1]
        if self._written is not None:
            self._keep_written()
        if packed.rows > self.C.shape[0]:
            self._grow_ineq(packed.rows)
        if self._offsets is not packed.offsets:
            if self._offsets != packed.offsets:
                for k, (ls_row, ineq_row) in enumerate(packed.offsets):
                    self.meta[META_LS, k], self.meta[META_INEQ, k] = ls_row, ineq_row
            self._offsets = packed.offsets
        if not packed.slices:
            return []
        written = WrittenRows()
        written.src = (self.C, self.d, packed.rows)
        self._written = weakref.ref(written)
        bounds: list[tuple[Any, Any, list[str]]] = [(written, sl, names) for sl, names in packed.slices]
        self._last_written = (packed, bounds)
        return bounds

    def fuse(self, robot: RobotModel, stack: TaskStack, t: float = 0.0) -> FusedPlan | str | bool:
        """The fused form of this plan's stack (:mod:`redundik.resolvers.fused`): every task a frame task or a
        joint-space task or written from Python (a target subtask's row after its level's tasks, as :meth:`gather`
        lays it; bound subtasks are evaluated as :meth:`gather` does); the rows of
        its least-squares buffers each fused row goes to (``dest``, :func:`hqp_fused.fused_hqp_step`). Returns
        the plan, ``FusedPlan.NOT_YET`` or False (the per-task path)."""
        layout = self.layout
        null = set(layout.null_tasks)
        scales = {i: (1.0, bool(task.identity_jacobian)) for i, task in enumerate(stack.tasks) if i not in null}
        targets = [(sub, 1.0) for level in layout.levels for sub in level.targets]
        built = FusedPlan.build(robot, stack, layout, scales, 1.0, mixed=True, targets=targets)
        if not isinstance(built, FusedPlan):
            return False if built is None else built
        if any(role in ROWS for role, _, _ in built.external):  # their row counts size the buffers: evaluated now,
            terms = built.evaluate_external(robot, t)  # and these terms used by this step (no second evaluate)
            if terms is None:
                return False
            built.pending_external = terms
        built.external_names += tuple(  # (bound rows from Python: named as a mixed step's Python writers)
            b.name for _, _, bounds, _, _ in self.members for b in bounds if not b.rows_compiled(robot)
        )
        self.lay_out(built)
        return built

    def lay_out(self, built: FusedPlan) -> None:
        """The rows of the least-squares buffers each row of the fused plan ``built`` goes to (``dest``) and the
        levels' first rows (``ls_offsets``), for its row counts now; again whenever a Python-written member's row
        count moves (the bound subtasks are packed again for the new offsets)."""
        ints = built.ints
        K, J = int(ints[H_K]), int(ints[H_J])
        starts = ints[ints[H_FRAME_STARTS] : ints[H_FRAME_STARTS] + K + 1].tolist()
        jstarts = ints[ints[H_JOINT_STARTS] : ints[H_JOINT_STARTS] + J + 1].tolist()
        mf = starts[K]
        spans: dict[int, tuple[int, int]] = {}
        for i, (kind, k) in enumerate(built.order):
            if kind == "f":
                spans[i] = (starts[k], starts[k + 1])
            elif kind == "j":
                spans[i] = (mf + jstarts[k], mf + jstarts[k + 1])
        rows_of = iter(zip(built.external_starts, built.external_rows, strict=True))
        target_rows: dict[int, int] = {}  # a target subtask's one row, by the subtask's id
        for role, member, _ in built.external:
            if role == ROW:
                a, r = next(rows_of)
                spans[built.index[id(member)]] = (a, a + r)
            elif role == TARGET:
                target_rows[id(member)] = next(rows_of)[0]
        dest = [0] * built.m
        mixed_starts: list[int] = []
        ls_offsets = []
        ms = 0
        for tasks, subs, _, _, mixed in self.members:
            ls_offsets.append(ms)
            for i in tasks:
                a, e = spans[i]
                dest[a:e] = range(ms, ms + e - a)
                ms += e - a
            for sub in subs:  # (after the level's tasks, as ``gather`` lays them)
                dest[target_rows[id(sub)]] = ms
                ms += 1
            if mixed:
                mixed_starts.append(ms)
                ms += self.n
        ls_offsets.append(ms)
        if ms > self.A.shape[0]:
            self._grow_ls(ms)
        self._weights = []  # the fused call writes the weights and identity rows: gather rewrites them after
        self.dest = np.array(dest + mixed_starts, dtype=np.int64)
        self.ls_offsets = ls_offsets
        self._packed_key = None  # (the packed bounds hold the levels' offsets)

    def step_rows(
        self,
        terms: list[TaskTerm],
        z: np.ndarray | None,
        targets: list[tuple[np.ndarray, float]],
        bounds: list[tuple[Any, Any, list[str]]],
    ) -> StepRows:
        """The :class:`~redundik.resolvers.qp.terms.StepRows` that ``gather_rows`` gives for the rows :meth:`gather`
        evaluated (the same arrays, grouped per level)."""
        n = self.n
        ls: list[list[tuple[np.ndarray, np.ndarray, float]]] = []
        ineq: list[list[tuple[np.ndarray, np.ndarray, list[str], BoundSubtask]]] = []
        it, ib = iter(targets), iter(bounds)
        for tasks, subs, bsubs, _, _ in self.members:
            blocks = [(terms[i].J, terms[i].v, terms[i].weight) for i in tasks]
            for sub in subs:
                eta, vt = next(it)
                blocks.append((eta.reshape(1, n), np.array([vt]), sub.weight))
            ls.append(blocks)
            rows = []
            for bsub in bsubs:
                Ci, di, rn = next(ib)
                if type(di) is slice:  # rows written by rows_into: their copies, as rows() gives them
                    held = Ci
                    held.keep()  # (copied once: the buffers may be written again)
                    Ci, di = held.C[di], held.d[di]
                rows.append((Ci, di, list(rn), bsub))
            ineq.append(rows)
        return StepRows(self.layout, terms, ls, ineq, z, n)

    def fill(self, rows: StepRows) -> None:
        """Copy the step's rows into the buffers and write the offsets table (row 0: A, row 1: C); the weights and
        identity rows are rewritten only where they changed since the last step."""
        if self._written is not None:
            self._keep_written()
        meta, n, key = self.meta, self.n, self._weights
        A, b, w, C, d = self.A, self.b, self.w, self.C, self.d
        ms = cs = 0
        blk = 0
        for k, (blocks, ineq) in enumerate(zip(rows.ls, rows.ineq, strict=True)):
            meta[META_LS, k], meta[META_INEQ, k] = ms, cs
            for J, v, weight in blocks:
                e = ms + J.shape[0]
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                A[ms:e] = J
                b[ms:e] = v
                if blk >= len(key) or key[blk] != (ms, e, weight):
                    w[ms:e] = weight
                    key[blk:] = [(ms, e, weight)]
                blk += 1
                ms = e
            if self.mixed[k] and rows.z is not None:
                e = ms + n
                if e > A.shape[0]:
                    A, b, w = self._grow_ls(e)
                b[ms:e] = rows.z
                if blk >= len(key) or key[blk] != (ms, e, -1.0):
                    A[ms:e] = self.eye
                    w[ms:e] = 1.0
                    key[blk:] = [(ms, e, -1.0)]
                blk += 1
                ms = e
            for Ci, di, _, _ in ineq:
                e = cs + Ci.shape[0]
                if e > C.shape[0]:
                    C, d = self._grow_ineq(e)
                C[cs:e] = Ci
                d[cs:e] = di
                cs = e
        L = meta.shape[1] - 1
        meta[META_LS, L], meta[META_INEQ, L] = ms, cs
        self._offsets = []  # (meta written here: gather rewrites it)

    def _grow_ls(self, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        cap = max(rows, 2 * self.A.shape[0])
        # the rows written so far are copied: what ``_weights`` records still holds
        self.A = np.concatenate([self.A, np.zeros((cap - self.A.shape[0], self.n))])
        self.b = np.concatenate([self.b, np.zeros(cap - self.b.shape[0])])
        self.w = np.concatenate([self.w, np.ones(cap - self.w.shape[0])])
        return self.A, self.b, self.w

    def rows(self, z: np.ndarray) -> tuple[np.ndarray, ...]:
        """The cascade's rows record (A, b, w, C, d, z, meta) of the kernels (``hqp_layout.CascadeRows``), with the
        null-space objective's target ``z``."""
        return self.A, self.b, self.w, self.C, self.d, z, self.meta

    def cascade_buffers(self, rows: int) -> tuple[np.ndarray, ...]:
        """The constrained cascade's work arrays (Z, N, the fixed rows F, f, their slacks, its state, the free-joint
        mask and indices), kept between steps and grown to ``rows`` inequality rows; the cascade's first call
        initialises what it reads. Views of :attr:`cascade_blocks` (``hqp_cascade_call``'s ``fwork``, ``iwork``,
        ``free``)."""
        bufs = self._cascade
        if bufs is None or bufs[2].shape[0] < max(rows, 1):
            n, cap = self.n, max(rows, 1, 2 * (bufs[2].shape[0] if bufs is not None else 0))
            sizes = HK.cascade_work_sizes(n, cap)
            fwork, iwork, free = np.zeros(sizes[0]), np.zeros(sizes[1], dtype=np.int64), np.ones(n, dtype=np.bool_)
            Z, N, F, f, slack, state, sel = HK.cascade_work_views(fwork, iwork, n)  # (once per growth)
            bufs = self._cascade = (Z, N, F, f, slack, state, free, sel)
            self.cascade_blocks = (fwork, iwork, free)  # (what ``qp_cascade_call`` takes: the same memory)
        return bufs

    def cascade_outputs(self, levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A new ``out`` block of ``qp_cascade_call`` (zeros) and its parts q̇ (n,), the per-level records (levels, 7)
        and R's (levels, r²), sliced here as ``hqp_cascade_call.cascade_out_views`` slices them in compiled code
        (its call from Python would box three arrays)."""
        n, r = self.n, self.r_size
        out = np.zeros(n + levels * (QS_COLUMNS + r))
        a = n + levels * QS_COLUMNS
        return out, out[:n], out[n:a].reshape(levels, QS_COLUMNS), out[a:].reshape(levels, r)

    def qp_arrays(self, backend: Backend) -> tuple[np.ndarray, NativeDaqp | None]:
        """The level QPs' buffer, grown to the largest level QP of the rows now in ``meta`` (``hqp_kernels.
        cascade_qp_dims``; growing it forgets the views of :meth:`qp_views`), and, for daqp as ``backend``, the arrays
        through which the cascade calls daqp itself (:mod:`redundik.resolvers.qp.daqp_native`; ``None`` when that
        call is off)."""
        dims = self._dims
        if dims is None or dims[0] is not self._offsets:  # meta rewritten since (its writers renew _offsets)
            nvar, nr, m_max = HK.cascade_qp_dims(self.n, self.meta)
            L = self.meta.shape[1] - 1
            dims = self._dims = (self._offsets, nvar, nr, int(self.meta[META_INEQ, L]))
            self.r_size = m_max * m_max
            size = nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)
            if self._qp_buf.shape[0] < size:
                self._qp_buf = np.empty(max(size, 2 * self._qp_buf.shape[0]))
                self._qp_views = {}
        nvar, nr = dims[1], dims[2]
        if type(backend) is not DaqpBackend:
            return self._qp_buf, None
        native = self._native
        if native is None or not native.serves(backend, nvar, nr):
            native = self._native = NativeDaqp.for_backend(backend, nvar, nr, native)
        return self._qp_buf, native

    def qp_views(self, nvar: int, nr: int) -> tuple[np.ndarray, ...]:
        """(P, q, G, upper, lower) of the level QP in the buffer (``hqp_kernels.qp_views``), kept per size: the
        same few sizes come back step after step."""
        views = self._qp_views.get((nvar, nr))
        if views is None:
            views = self._qp_views[(nvar, nr)] = HK.qp_views(self._qp_buf, nvar, nr)
        return views

    def _grow_ineq(self, rows: int) -> tuple[np.ndarray, np.ndarray]:
        cap = max(rows, 2 * self.C.shape[0])
        self.C = np.concatenate([self.C, np.zeros((cap - self.C.shape[0], self.n))])
        self.d = np.concatenate([self.d, np.zeros(cap - self.d.shape[0])])
        return self.C, self.d
