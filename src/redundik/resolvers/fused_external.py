"""The Python writers of a mixed fused plan (issue 31's row protocol): the members without a compiled form (their
``evaluate``, a subtask's ``direction``) or with a compiled writer of their own (``Task.compiled_rows``), written into
a step's buffers before the resolver's compiled call. A mixin of ``FusedPlan``."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from redundik.kinematics.model import RobotModel
from redundik.resolvers.linalg import FK
from redundik.tasks.base import CompiledGradient, CompiledRows, TaskTerm
from redundik.tasks.conform import WEIGHT_MAX, conform_term

#: Roles of a member written from Python in a mixed plan: rows of the main system / of its level (``ROW``), a term of
#: the null-space objective z (``NULL``: z += v), a joint-space null term on Lie-group coordinates (``LIE_NULL``:
#: z[sel] += K (q_ref ⊖ q)[sel], Pinocchio's difference), a gradient subtask (``GRADIENT``: z += k η), or evaluated
#: for the step's terms only (``TERM``: a task the resolver leaves out of its closed form), or the one weighted row
#: ηᵀq̇ = ṗ_d + K (p_d − p) of a target subtask (``TARGET``: rows of its level, no task term of its own).
ROW, NULL, LIE_NULL, GRADIENT, TERM, TARGET = 0, 1, 2, 3, 4, 5
#: The roles whose members write rows of the system (their row counts size the step's buffers).
ROWS = (ROW, TARGET)
_F64 = np.dtype(np.float64)


class PythonWriters:
    """The Python-written members of a plan and their writing (``FusedPlan`` sets the attributes)."""

    external: list[tuple[int, Any, float]]
    writers: list[CompiledRows | CompiledGradient | None]
    external_rows: list[int]
    external_starts: list[int]
    repacked: bool
    level_forms: list[tuple[np.ndarray, np.ndarray]]
    lie_joints: list[int]
    joint_spans: list[tuple[int, int]]
    identity: list[bool]
    main_set: set[int]
    index: dict[int, int]
    poses: np.ndarray
    jw: np.ndarray
    eta: np.ndarray  # (nv,) scratch of a potential's compiled writer
    #: Per member, laid out at each packing (:meth:`lay_out_writes`): (index, role, member, scale, first row, end
    #: row, compiled writer or ``None``) — what :meth:`write_external` walks.
    writes: list[tuple[int, int, Any, float, int, int, CompiledRows | CompiledGradient | None]]
    #: Per member, in :attr:`external` order: (role, member, compiled writer or ``None``) — what
    #: :meth:`evaluate_external` walks (laid out with :attr:`writes`).
    evaluations: list[tuple[int, Any, CompiledRows | CompiledGradient | None]]
    null_external: bool  # a member writes a term of the null-space objective (``zx`` is read, zeroed first)
    has_targets: bool  # a member is a target subtask's row (:meth:`subtask_rows` has rows to give)
    direct_rows: list[int] | None  # every member a compiled writer of main rows: their row counts; else None
    #: Every member a main task written by its Python ``evaluate`` (the common mixed plan: a user's own task):
    #: :meth:`put_plain_rows` writes their blocks, nothing else is to be written.
    plain_rows: bool
    #: Every member a task with a compiled writer of main rows (``Task.compiled_rows``): :meth:`take_direct_rows`
    #: runs them straight into the step's work, nothing else is to be written.
    direct_main: bool

    def _pack(
        self,
        robot: RobotModel,
        iq: np.ndarray,
        level_forms: list[tuple[np.ndarray, np.ndarray]],
        identity: list[bool],
        main: set[int],
        index: dict[int, int],
    ) -> None:
        raise NotImplementedError  # (FusedPlan's)

    def lay_out_writes(self) -> None:
        """:attr:`writes`, :attr:`null_external` and :attr:`direct_rows` for the members' row counts and starts of
        this packing (``FusedPlan._pack`` calls it last)."""
        writers = self.writers if len(self.writers) == len(self.external) else [None] * len(self.external)
        writes = []
        k = 0
        for i, ((role, member, scale), writer) in enumerate(zip(self.external, writers, strict=True)):
            a = b = 0
            if role in ROWS:
                a = self.external_starts[k]
                b = a + self.external_rows[k]
                k += 1
            writes.append((i, role, member, scale, a, b, writer))
        self.writes = writes
        self.evaluations = [(role, member, w) for (role, member, _), w in zip(self.external, writers, strict=True)]
        self.null_external = any(role in (NULL, LIE_NULL, GRADIENT) for role, _, _ in self.external)
        self.has_targets = any(role == TARGET for role, _, _ in self.external)
        direct = all(_direct(role, w) for role, _, _, _, _, _, w in writes)
        counts = [w.rows if isinstance(w, CompiledRows) else 1 for _, _, _, _, _, _, w in writes]  # (a target: 1)
        self.direct_rows = counts if direct else None
        self.plain_rows = bool(writes) and all(role == ROW and w is None for _, role, _, _, _, _, w in writes)
        self.direct_main = bool(writes) and all(
            role == ROW and isinstance(w, CompiledRows) for _, role, _, _, _, _, w in writes
        )

    def take_plain_rows(
        self, robot: RobotModel, t: float, work: np.ndarray | None, at: tuple[int, int, int, int, int] = (0,) * 5
    ) -> list[TaskTerm | None] | None:
        """:meth:`evaluate_external` (``direct``) and :meth:`put_plain_rows` in one walk, for a :attr:`plain_rows`
        plan (a user's own tasks only): each member's ``evaluate``, its term checked in a few comparisons (float64,
        C-ordered blocks of the rows the plan laid out) and put into ``work`` by one compiled call. A term that is
        anything else (another row count, a TaskTerm subclass, lists, F-ordered arrays) sends the walk to
        :meth:`evaluate_external` with the terms already evaluated (no member is evaluated twice), which conforms
        them and packs the plan again when a row count moved (:attr:`repacked`: then ``work``, sized for the old
        plan, is left for the caller to allocate again). ``None``: as :meth:`evaluate_external`. ``work`` ``None``:
        the terms checked and returned, nothing put (``hqp`` puts them into its level buffers later)."""
        j0, first, e0, v0, w0 = at
        n = robot._nv
        put = FK.put_rows
        terms: list[Any] = []  # (each member's answer, a TaskTerm once checked)
        for _, _, member, scale, a, b, _ in self.writes:
            term = member.evaluate(robot, t)
            terms.append(term)
            if type(term) is TaskTerm:
                J, e, v, w = term.J, term.error, term.v, term.weight
                r = b - a
                if (
                    (type(w) is float or type(w) is int)
                    and 0.0 < w <= WEIGHT_MAX
                    and type(J) is np.ndarray
                    and type(e) is np.ndarray
                    and type(v) is np.ndarray
                    and J.shape == (r, n)
                    and e.shape == (r,)
                    and v.shape == (r,)
                    and J.dtype is _F64
                    and e.dtype is _F64
                    and v.dtype is _F64
                    and J.flags.carray
                    and e.flags.carray
                    and v.flags.carray
                ):
                    if work is None:
                        continue
                    put(work, j0 + (a - first) * n, e0 + a, v0 + a, J, e, v)
                    if w0 >= 0:
                        work[w0 + a - first : w0 + b - first] = w * scale
                    continue
            evaluated = self.evaluate_external(robot, t, direct=True, given=terms)  # (the general walk)
            if evaluated is not None and not self.repacked and work is not None:
                self.put_plain_rows(robot, evaluated, work, at)
            return evaluated
        self.repacked = False
        return terms

    def take_direct_rows(
        self, robot: RobotModel, t: float, work: np.ndarray, at: tuple[int, int, int, int, int]
    ) -> list[TaskTerm | None]:
        """:meth:`evaluate_external` (``direct``) and :meth:`write_external` in one walk, for a :attr:`direct_main`
        plan: each member's compiled writer called at t on its block of ``work`` (``at``: as for
        :meth:`put_plain_rows`), its J rows zeroed first (a writer fills the columns it supports), its weight × ρ^k
        written when the step has weights; the terms are views on those blocks."""
        j0, first, e0, v0, w0 = at
        n = robot._nv
        q, poses, jw = robot.q, self.poses, self.jw
        terms: list[TaskTerm | None] = []
        for _, _, member, scale, a, b, writer in self.writes:
            assert isinstance(writer, CompiledRows)
            j = j0 + (a - first) * n
            J = work[j : j + (b - a) * n].reshape(b - a, n)
            J.fill(0.0)
            e, v = work[e0 + a : e0 + b], work[v0 + a : v0 + b]
            writer.kernel(q, t, poses, jw, writer.ints, writer.floats, member.gain, J, e, v)
            weight = member.weight
            if w0 >= 0:
                work[w0 + a - first : w0 + b - first] = weight * scale
            terms.append(TaskTerm(member.name, J, v, e, weight))
        self.repacked = False
        return terms

    def take_direct_level_rows(
        self, robot: RobotModel, t: float, dest: np.ndarray, lsq: tuple[np.ndarray, np.ndarray, np.ndarray],
        ev: np.ndarray, Jx: np.ndarray,
    ) -> list[TaskTerm | None]:  # fmt: skip
        """:meth:`take_direct_rows` for ``hqp``, whose least-squares buffers (A, b, w of ``lsq``) outlive the step:
        each member's compiled writer called at t on its rows of the step's ``Jx`` (zeros, one block of the
        members' rows in order) and of ``ev`` (2, m), then its J, v and weight put into the rows ``dest`` gives it
        (a member's rows are contiguous there); the terms are views on the step's blocks."""
        A, b, w = lsq
        q, poses, jw = robot.q, self.poses, self.jw
        e_all, v_all = ev[0], ev[1]
        terms: list[TaskTerm | None] = []
        row = 0
        for _, _, member, _, a, end, writer in self.writes:
            assert isinstance(writer, CompiledRows)
            r = end - a
            J, e, v = Jx[row : row + r], e_all[a:end], v_all[a:end]
            row += r
            writer.kernel(q, t, poses, jw, writer.ints, writer.floats, member.gain, J, e, v)
            weight = member.weight
            if r:
                d = int(dest[a])
                A[d : d + r] = J
                b[d : d + r] = v
                w[d : d + r] = weight
            terms.append(TaskTerm(member.name, J, v, e, weight))
        self.repacked = False
        return terms

    def evaluate_external(
        self, robot: RobotModel, t: float, direct: bool = False, given: list[Any] | None = None
    ) -> list[TaskTerm | None] | None:
        """Each Python-written member's term at t (``None`` for what has no term of its own: a gradient subtask, a
        Lie-group null term), in :attr:`external` order; the plan is packed again when a member's row count moved.
        ``None``: a term is not a (r, nv) Jacobian with r-vectors v and e (the per-task path says what is wrong).

        ``direct``: a compiled writer of main rows is not called here but by :meth:`write_external`, straight into
        the step's buffers (its entry ``None`` until then); for a step whose buffers are its own (``pinv``, ``wqp``:
        the result's terms are views on them). ``given``: the terms of the first members, evaluated already
        (:meth:`take_plain_rows`, which a :attr:`plain_rows` plan's call without them goes to)."""
        if given is None and self.plain_rows:  # a user's own tasks only: checked in one quick walk
            return self.take_plain_rows(robot, t, None)
        if direct and self.direct_rows == self.external_rows:  # compiled writers only: nothing to evaluate here
            self.repacked = False
            return [None] * len(self.external)
        nv = robot._nv
        out: list[TaskTerm | None] = []
        rows: list[int] = []
        for k, (role, member, writer) in enumerate(self.evaluations):
            if writer is None and (role == ROW or role == NULL or role == TERM):  # (first: a user's task)
                term = member.evaluate(robot, t) if given is None or k >= len(given) else given[k]
                if type(term) is not TaskTerm:  # (given: a member's own answer, whatever it is)
                    term = conform_term(term, nv, member)  # (a TaskTerm subclass passes; anything else: TaskError)
                J, v, e, w = term.J, term.v, term.error, term.weight
                if not (
                    (type(w) is float or type(w) is int)
                    and 0.0 < w <= WEIGHT_MAX
                    and type(J) is np.ndarray
                    and type(v) is np.ndarray
                    and type(e) is np.ndarray
                    and J.ndim == 2
                    and J.shape[1] == nv
                    and v.shape == e.shape == (J.shape[0],)
                    and J.dtype is _F64
                    and v.dtype is _F64
                    and e.dtype is _F64
                ):
                    term = conform_term(term, nv, member)  # float64 arrays, or a TaskError naming the task
                    J = term.J
                if role == ROW:
                    rows.append(J.shape[0])
                elif role == NULL and J.shape[0] != nv:
                    return None
                out.append(term)
            elif role == GRADIENT:  # (written by ``write_external``: its compiled writer, or ``direction``)
                out.append(None)
            elif role == TARGET:  # one row: by its potential's compiled writer in write_external, or its ``row``
                rows.append(1)
                if direct and writer is not None:
                    out.append(None)
                    continue
                target_term = _target_term(member, writer, robot, self)
                if target_term is None:
                    return None  # (a gradient that is not a float vector (nv,): the per-task path says what is wrong)
                out.append(target_term)
            elif writer is not None:  # a compiled writer: its rows by construction of the right shapes
                assert isinstance(writer, CompiledRows)
                r = writer.rows
                if direct and role == ROW:
                    rows.append(r)
                    out.append(None)
                    continue
                J = np.zeros((r, nv))
                e, v = np.zeros(r), np.zeros(r)
                writer.kernel(robot.q, t, self.poses, self.jw, writer.ints, writer.floats, member.gain, J, e, v)
                if role == NULL and r != nv:
                    return None
                if role == ROW:
                    rows.append(r)
                out.append(TaskTerm(member.name, J, v, e, member.weight))
            else:  # (a Lie-group null term: written by ``write_external``)
                out.append(None)
        self.repacked = rows != self.external_rows
        if self.repacked:
            self.external_rows = rows
            iq = np.array([j.idx_q for j in robot.joints], dtype=np.int64)
            self._pack(robot, iq, self.level_forms, self.identity, self.main_set, self.index)
        return out

    def put_plain_rows(
        self, robot: RobotModel, terms: list[TaskTerm | None], work: np.ndarray, at: tuple[int, int, int, int, int]
    ) -> None:
        """:meth:`write_external` for a :attr:`plain_rows` plan into a step's flat ``work`` array, without views:
        ``at`` = (where the J row of the plan's row ``first`` starts, ``first``, where e starts, where v starts,
        where the weights of the rows from ``first`` start, or −1 for none). A block of C-ordered float64 arrays
        is put by one compiled call; any other (a user's F-ordered, strided or read-only array) by NumPy, as
        :meth:`write_external` does (the terms are float64: :meth:`evaluate_external` conformed them)."""
        j0, first, e0, v0, w0 = at
        n = robot._nv
        put = FK.put_rows
        for i, _, _, scale, a, b, _ in self.writes:
            term = terms[i]
            assert term is not None  # (a plain member's term: evaluate_external gave it)
            J, e, v = term.J, term.error, term.v
            j = j0 + (a - first) * n
            if J.flags.carray and e.flags.carray and v.flags.carray:  # (float64: evaluate_external conformed them)
                put(work, j, e0 + a, v0 + a, J, e, v)
            else:
                work[j : j + (b - a) * n].reshape(b - a, n)[:] = J
                work[e0 + a : e0 + b] = e
                work[v0 + a : v0 + b] = v
            if w0 >= 0:
                work[w0 + a - first : w0 + b - first] = term.weight * scale

    def put_plain_level_rows(
        self, terms: list[TaskTerm | None], dest: np.ndarray, A: np.ndarray, b: np.ndarray, w: np.ndarray,
        ev: np.ndarray,
    ) -> None:  # fmt: skip
        """:meth:`put_plain_rows` for ``hqp``: a member's J, v and weight into the least-squares rows ``dest``
        gives it (A, b, w: a member's rows are contiguous there) and its e and v into the step's ``ev`` (2, m)."""
        put = FK.put_level_rows
        for i, _, _, _, a, end, _ in self.writes:
            term = terms[i]
            assert term is not None  # (a plain member's term: evaluate_external gave it)
            J, e, v = term.J, term.error, term.v
            if a == end:  # (no rows this step: nothing to put, and no row of dest to read)
                continue
            d = int(dest[a])
            if J.flags.carray and e.flags.carray and v.flags.carray:  # (float64: evaluate_external conformed them)
                put(A, b, w, ev, d, a, float(term.weight), J, e, v)
            else:
                A[d : d + end - a] = J
                b[d : d + end - a] = v
                w[d : d + end - a] = term.weight
                ev[0, a:end] = e
                ev[1, a:end] = v

    def subtask_rows(self, terms: list[TaskTerm | None]) -> list[tuple[np.ndarray, float]]:
        """The target subtasks' rows (η, v) of a step whose Python members were evaluated (``terms``: every target
        subtask's term given), in :attr:`external` order — their levels' order."""
        rows = []
        for i, role, _, _, _, _, _ in self.writes:
            if role == TARGET:
                term = terms[i]
                assert term is not None
                rows.append((term.J[0], float(term.v[0])))
        return rows

    def write_joint_errors(self, robot: RobotModel, e: np.ndarray) -> None:
        """The errors (q_ref ⊖ q)[sel] of the level joint tasks on Lie-group coordinates (Pinocchio's
        ``difference``) into their rows of the step's e, before the compiled call reads them."""
        q, model = robot.q, robot.model
        seen = self.__dict__.setdefault("_whole", {})  # k → (sel, sel is every coordinate in order)
        for k in self.lie_joints:
            a, b = self.joint_spans[k]
            sel, target = self.level_forms[k]
            whole = seen.get(k)
            if whole is None or whole[0] is not sel:
                whole = seen[k] = (sel, bool(np.array_equal(sel, np.arange(robot._nv))))
            d = pin.difference(model, q, target)  # (RobotModel.difference, without its wrapper)
            e[a:b] = d if whole[1] else d[sel]

    def write_external(
        self,
        robot: RobotModel,
        terms: list[TaskTerm | None],
        Jrows: np.ndarray | None,
        offset: int,
        ev: np.ndarray,
        weights: np.ndarray | None,
        zx: np.ndarray,
        t: float = 0.0,
    ) -> None:
        """Write the Python members' blocks into a step's buffers: a ``ROW`` member's J into ``Jrows`` (its rows
        from ``offset``), its e and v into ``ev`` and its weight × ρ^k into ``weights`` (``wqp``); the null-space
        objective's Python terms into ``zx`` (z += v, z[sel] += K (q_ref ⊖ q)[sel], z += k η). ``Jrows`` ``None``:
        the caller writes the rows' J where its layout puts them. A compiled writer left by
        ``evaluate_external(direct=True)`` (its term ``None``) writes its rows in place here, at time t, and its
        term becomes views on them."""
        if self.null_external:
            zx.fill(0.0)
        q = robot.q
        e_all, v_all = ev[0], ev[1]
        for i, role, member, scale, a, b, writer in self.writes:
            if role == ROW:  # (first: the common member)
                term = terms[i]
                if term is None:  # a compiled writer, straight into the step's rows
                    assert Jrows is not None and isinstance(writer, CompiledRows)
                    J, e, v = Jrows[a - offset : b - offset], e_all[a:b], v_all[a:b]
                    J.fill(0.0)
                    writer.kernel(q, t, self.poses, self.jw, writer.ints, writer.floats, member.gain, J, e, v)
                    weight = member.weight
                    terms[i] = TaskTerm(member.name, J, v, e, weight)
                else:
                    if Jrows is not None:  # (``hqp`` places the rows itself, by its layout)
                        Jrows[a - offset : b - offset] = term.J
                    e_all[a:b] = term.error
                    v_all[a:b] = term.v
                    weight = term.weight
                if weights is not None:
                    weights[a - offset : b - offset] = weight * scale
            elif role == TARGET:
                term = terms[i]
                if term is None:  # its potential's compiled writer, straight into the step's row
                    assert Jrows is not None and isinstance(writer, CompiledGradient)
                    eta = Jrows[a - offset]
                    eta.fill(0.0)
                    p = writer.kernel(q, self.poses, self.jw, writer.ints, writer.floats, eta)
                    e_all[a] = err = member.target - p
                    v_all[a] = member.target_rate + member.rate * err
                else:
                    if Jrows is not None:
                        Jrows[a - offset] = term.J[0]
                    e_all[a] = term.error[0]
                    v_all[a] = term.v[0]
                if weights is not None:
                    weights[a - offset] = member.weight * scale
            elif role == NULL:
                term = terms[i]
                assert term is not None
                zx += term.v
            elif role == LIE_NULL:
                sel, target = member.joint_form(robot)
                zx[sel] += member.gain * robot.difference(robot.q, target)[sel]
            elif role == GRADIENT and member.gain != 0.0:
                if writer is None:
                    zx += member.direction(robot)
                else:  # its potential's compiled writer: z += k η (eq. 5.8)
                    assert isinstance(writer, CompiledGradient)
                    eta = self.eta
                    eta.fill(0.0)
                    writer.kernel(robot.q, self.poses, self.jw, writer.ints, writer.floats, eta)
                    zx += member.gain * eta


def _direct(role: int, writer: CompiledRows | CompiledGradient | None) -> bool:
    """A member that ``write_external`` writes straight into the step's rows (nothing to evaluate first): a task's
    compiled writer of main rows, or a target subtask whose potential has a compiled writer."""
    if role == ROW:
        return isinstance(writer, CompiledRows)
    return role == TARGET and isinstance(writer, CompiledGradient)


def _target_term(sub: Any, writer: CompiledRows | CompiledGradient | None, robot: RobotModel,
                 plan: PythonWriters) -> TaskTerm | None:  # fmt: skip
    """A target subtask's row as a term (1, nv): η, v = ṗ_d + K e, e = p_d − p (``TargetSubtask.row``), from its
    potential's compiled writer when it has one; ``None`` when its gradient is not a float vector (nv,)."""
    if isinstance(writer, CompiledGradient):
        eta = np.zeros(robot._nv)
        e = sub.target - writer.kernel(robot.q, plan.poses, plan.jw, writer.ints, writer.floats, eta)
        v = sub.target_rate + sub.rate * e
    else:
        eta, v, e = sub.row(robot)
        if not (type(eta) is np.ndarray and eta.dtype == np.float64 and eta.shape == (robot._nv,)):
            return None
    return TaskTerm(sub.name, eta.reshape(1, -1), np.array([float(v)]), np.array([float(e)]), sub.weight)
