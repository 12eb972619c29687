"""``hqp``'s constrained cascade from Python (:mod:`redundik.resolvers.qp.hqp`): the compiled cascade
(``hqp_kernels.qp_cascade_run``) run on the plan's buffers, each level QP it leaves solved by the backend — from the
buffer as it is when the backend can, else as a ``QPProblem`` with the regularised retries — and the levels
contradicted by those above named; the settings the cascade reads; ``HQPBuild``, a built step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from redundik.errors import SolverError
from redundik.resolvers.hqp_layout import (
    META_INEQ,
    QS_WORST,
)
from redundik.resolvers.qp.backends import CHECKED_ANSWERS, polish
from redundik.resolvers.qp.base import QPDiagnostics, QPResolverBase
from redundik.resolvers.qp.hqp_plan import HK, _Plan
from redundik.resolvers.qp.limits import LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.terms import Level, StepRows
from redundik.resolvers.settings import Setting, count, flag, nonnegative, positive, unit_interval
from redundik.tasks.stack import StackLayout

#: Slack above which a level's bound rows count as contradicted (reported in ``StepResult.relaxed``).
CONTRADICTION_TOLERANCE = 1e-6
#: Defaults of ``HierarchicalQPResolver.complement_min_n`` and ``complement_fraction`` (joint-space level QPs from
#: this many joints on, below levels that leave at most a third of the directions fixed).
COMPLEMENT_MIN_N, COMPLEMENT_FRACTION = 40, 3.0


_NO_U = np.zeros(0)
_NO_NATIVE = np.zeros(0, dtype=np.int64)
#: Violation up to which a level QP's unconstrained optimum counts as satisfying the QP's rows (kept without a QP).
_FEASIBLE = 1e-12


class HQPBuild:
    """A built ``hqp`` step: its rows as evaluated, the joint-limit box, and what the lean cascade left.

    Attributes:
        rows: Every level's rows (:class:`~redundik.resolvers.qp.terms.StepRows`; given, or built on first access
            from a callable); :attr:`levels` stacks them.
        box: The joint-limit box of the step.
        n: Number of velocity coordinates.
        stats: Per level (σ_min, λ, rank, free directions before it) of the unconstrained cascade when its answer
            was kept (:func:`redundik.resolvers.hqp_kernels.closed_cascade`), else ``None``; read by the
            diagnostics only.
        infeasible: True when the unconstrained cascade was already found infeasible (the lean step): straight to
            the QPs.
        layout: The stack's layout; z: the null-space objective's target (``None`` without one) — the rows' own.
        filled: True when the plan's buffers already hold these rows (the lean step wrote them there: the
            constrained cascade reads them as they are, without :meth:`_Plan.fill`).
        critical: False when no bound subtask is critical (no safety rows to guard: the rows need not be built for
            them).
        qp_stats: Per level the constrained cascade's records (``hqp_kernels.QS_*``), read by the diagnostics;
            ``None`` when the step solved no constrained cascade.
        qp_r: Per level the R of its certified QR (``qp_cascade_run``'s ``rfac``; σ_min NaN in ``qp_stats``), the
            singular values of the level for the diagnostics.
    """

    __slots__ = ("_make_rows", "_rows", "box", "critical", "filled", "infeasible", "layout", "n", "qp_r",
                 "qp_stats", "stats", "z")  # fmt: skip

    def __init__(
        self,
        rows: StepRows | Callable[[], StepRows],
        box: LimitBox,
        n: int,
        stats: np.ndarray | None = None,
        infeasible: bool = False,
        *,
        layout: StackLayout | None = None,
        z: np.ndarray | None = None,
        filled: bool = False,
        critical: bool = True,
    ) -> None:
        if isinstance(rows, StepRows):
            self._rows: StepRows | None = rows
            self._make_rows: Callable[[], StepRows] | None = None
            self.layout: StackLayout = rows.layout
            self.z: np.ndarray | None = rows.z
        else:
            if layout is None:
                raise TypeError("HQPBuild: rows given as a callable need their layout")
            self._rows, self._make_rows, self.layout, self.z = None, rows, layout, z
        self.box, self.n, self.stats, self.infeasible = box, n, stats, infeasible
        self.filled, self.critical = filled, critical
        self.qp_stats: np.ndarray | None = None
        self.qp_r: np.ndarray | None = None

    @property
    def rows(self) -> StepRows:
        rows = self._rows
        if rows is None:
            assert self._make_rows is not None
            rows = self._rows = self._make_rows()
            self._make_rows = None
        return rows

    @property
    def levels(self) -> list[Level]:
        """The levels as :class:`~redundik.resolvers.qp.terms.Level` records (built on first access)."""
        return self.rows.levels


class ConstrainedCascade(QPResolverBase):
    """The constrained cascade of :class:`~redundik.resolvers.qp.hqp.HierarchicalQPResolver` and the settings it
    reads (documented there)."""

    epsilon = Setting(nonnegative, resets=("_plan", "_cfg"))
    max_damping = Setting(nonnegative, resets=("_plan", "_cfg"))
    regularization = Setting(positive, resets=("_cfg",))
    rcond = Setting(unit_interval, resets=("_plan", "_cfg"))
    slack_tolerance = Setting(nonnegative, resets=("_cfg",))
    level_shortcut = Setting(flag, resets=("_cfg",))
    identity_levels = Setting(flag, resets=("_cfg",))
    complement_min_n = Setting(count, resets=("_cfg",))
    complement_fraction = Setting(nonnegative, resets=("_cfg",))
    certified_qr = Setting(flag, resets=("_cfg",))

    _plan: _Plan | None
    _cfg: np.ndarray | None

    def _plan_for(self, layout: StackLayout, n: int) -> _Plan:
        """The lean cascade's plan and buffers, laid out once per stack membership (the layout object) and size."""
        plan = self._plan
        if plan is None or plan.layout is not layout or plan.n != n:
            params = np.array([self.epsilon, self.max_damping, self.rcond, 1e-12, 0.0])
            plan = self._plan = _Plan(layout, n, params)
        return plan

    def _regularized_retry(
        self, prob: QPProblem, r: int, eps: float, diag: QPDiagnostics, failed: SolverError | None = None
    ) -> QPSolution:
        """Solve a level QP the backend refused, with a stronger minimum-norm regulariser on u.

        Dual active-set solvers (daqp) work with P⁻¹ and can misjudge a level whose u-block is regularised by 1e-9
        only as infeasible (every level below 0 is feasible by construction: u = 0, w' = 0). First ε = 1e-6, kept as
        solved (far below the slack's unit weight); then ε = 1e-4, kept only as the verified exact optimum of the
        level as posed (``polish`` from its active set: on a degenerate vertex of the stress run, 5 rows active in
        4 unknowns, daqp needed it and quadprog agrees). ``failed``: the backend's first error (for the note the
        retry leaves in :attr:`QPDiagnostics.retries`: counted in ``StepResult.relaxed``, told in ``info``).
        """
        diag.regularization_retry = 1
        last: SolverError | None = None
        for boost, verify in ((max(1e-6, 1e3 * eps), False), (1e-4, True)):
            P = prob.P.copy()
            P[:r, :r] += (boost - eps) * np.eye(r)
            try:
                sol = self._solve_qp(replace(prob, P=P), None, diag)
            except SolverError as exc:
                last = exc
                continue
            if not verify:
                diag.retries.append((prob.label, f"{failed}; solved with the regulariser raised to {boost:.3g}"))
                return sol
            exact = polish(prob, sol.x)
            if exact is not None:
                diag.retries.append((prob.label, f"{failed}; solved with the regulariser raised to {boost:.3g}"))
                return replace(sol, x=exact)
        assert last is not None
        raise last

    def _cascade_cfg(self) -> np.ndarray:
        """The ``cfg`` array of ``hqp_kernels.qp_cascade_run`` for the resolver's settings as they are now."""
        cfg = self._cfg
        if cfg is None:  # (every setting read here is a Setting: its assignment drops the array)
            key = (self.epsilon, self.max_damping, self.rcond, self.regularization, self.slack_tolerance,
                   self.identity_levels, self.level_shortcut, self.complement_min_n, self.complement_fraction,
                   self.certified_qr)  # fmt: skip
            cfg = self._cfg = np.array(
                [*key[:5], _FEASIBLE, *map(float, key[5:7]), CONTRADICTION_TOLERANCE, *map(float, key[7:])]
            )
        return cfg

    def _native_cascade(
        self, plan: _Plan, lb: np.ndarray, ub: np.ndarray, z: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int] | None:
        """:meth:`_qp_cascade` of a fused step when daqp, called from the compiled cascade (``daqp_native``),
        solves every level QP at once and no level is contradicted: the one compiled call and nothing of the loop
        around it. Returns (x, the per-level records, the certified R's, QPs solved, iterations), or ``None`` when
        the native call is off or the cascade needs more (a level QP daqp did not solve at once, a contradicted
        level): :meth:`_qp_cascade` then runs it from the start (the same answer) and goes on."""
        qbuf, native = plan.qp_arrays(self.backend)
        if native is None:
            return None
        L = plan.meta.shape[1] - 1
        assert plan._dims is not None
        state = plan.cascade_buffers(plan._dims[3])[5]
        fwork, iwork, free = plan.cascade_blocks
        out, x, stats, rfac = plan.cascade_outputs(L)  # q̇, the per-level records, their R
        ctl = native.ctl
        ctl[HK.NAT_SOLVED] = ctl[HK.NAT_ITERS] = 0
        status = HK.qp_cascade_call(
            plan.A, plan.b, plan.w, plan.C, plan.d, z, plan.meta, plan.mixed_flags, lb, ub, self._cascade_cfg(), fwork,
            iwork, free, out, qbuf, 0, False, _NO_U, ctl, native.x,
        )[0]  # fmt: skip
        if status != HK.CASCADE_DONE or state[HK.ST_CONTRADICTED]:
            return None
        return x, stats, rfac, int(ctl[HK.NAT_SOLVED]), int(ctl[HK.NAT_ITERS])

    def _qp_cascade(self, built: HQPBuild, diag: QPDiagnostics) -> tuple[np.ndarray, list[str]]:
        """The constrained cascade (module docstring): every level but its QP in compiled code
        (``hqp_kernels.qp_cascade_run``, on the step's rows in the plan's buffers), each level QP it writes into the
        plan's QP buffer solved by the backend here — from the buffer as it is when the backend can
        (``Backend.solve_stacked``), else as a ``QPProblem`` with the retries; the per-level records (σ_min, damping,
        rank) are kept on ``built`` for the diagnostics.

        Returns:
            (q̇, notes: the levels skipped after a backend failure); the members of the levels contradicted by
            those above go to :attr:`QPDiagnostics.relaxed`.
        """
        n, box = built.n, built.box
        layout = built.layout
        plan = self._plan_for(layout, n)
        if not built.filled:  # (the lean steps wrote their rows into these buffers already)
            plan.fill(built.rows)
        L = len(layout.levels)
        cfg = self._cascade_cfg()
        # the start (in the first compiled call): joints whose box is one value (a rate window squeezed to a point, a
        # joint held at its limit) are not unknowns but fixed first and left out of the basis, so that no level QP
        # carries a window of zero width (as the pair of rows ±Z_j u ≤ tol, it left proxsuite a 1e-7-wide feasible
        # set that it declared infeasible)
        _, _, _, _, slack, state, _, _ = plan.cascade_buffers(int(plan.meta[META_INEQ, L]))
        fwork, iwork, free = plan.cascade_blocks
        z = built.z if built.z is not None else plan.zero
        notes: list[tuple[int, str]] = []
        k, absorb, u = 0, False, _NO_U
        backend = self.backend
        # daqp itself: the cascade calls its C entry point and absorbs what it solves at once (``daqp_native``)
        qbuf, native = plan.qp_arrays(backend)
        # q̇, the per-level records and the R of the levels factored by their certified QR (σ_min when read)
        out, x, stats, rfac = plan.cascade_outputs(L)
        # a built-in backend that checks its answers takes the QP in the kernel's buffer as it is (daqp: no copy);
        # anything else, and any QP it does not solve at once, goes through QPProblem and the retries below
        stacked = backend.solve_stacked if type(backend) in CHECKED_ANSWERS else None
        if native is not None:
            ctl, nx = native.ctl, native.x
            ctl[HK.NAT_SOLVED] = ctl[HK.NAT_ITERS] = 0
        else:
            ctl, nx = _NO_NATIVE, _NO_U
        last_here = -1  # the last level whose QP was solved here (the record's backend is the last solver's)
        while True:
            status, k, nvar, nr, eps = HK.qp_cascade_call(
                plan.A, plan.b, plan.w, plan.C, plan.d, z, plan.meta, plan.mixed_flags, box.lb, box.ub, cfg, fwork,
                iwork, free, out, qbuf, k, absorb, u, ctl, nx,
            )  # fmt: skip
            if status == HK.CASCADE_DONE:
                break
            last_here = k
            nu, neq = int(state[HK.ST_NU]), int(state[HK.ST_NEQ])  # the step's variables, the equality rows (last)
            P, q, G, upper, lower = plan.qp_views(nvar, nr)
            quick = None if stacked is None else stacked(P, q, G, upper, lower, neq)
            if quick is not None:
                diag.qp += 1
                diag.iterations += max(quick[1], 0)
                diag.backend = backend.name
                u, absorb = quick[0][:nu], True
                continue
            priority = layout.levels[k].priority
            ni = nr - neq
            prob = QPProblem(
                P.copy(), q.copy(), G[:ni].copy(), upper[nvar : nvar + ni].copy(), G[ni:].copy(),
                upper[nvar + ni :].copy(), lower[:nvar].copy(), upper[:nvar].copy(), f"hqp level {priority}",
            )  # fmt: skip
            try:
                try:
                    sol = self._solve_qp(prob, None, diag)
                except SolverError as first:
                    sol = self._regularized_retry(prob, nu, eps, diag, first)
            except SolverError as exc:
                if k == 0:
                    raise  # nothing of the cascade is worth keeping: the base falls back to the closed form
                notes.append((k, f"level {priority} skipped ({exc})"))
                stats[k, HK.QS_SOLVED] = 0.0
                k, absorb = k + 1, False
                continue
            diag.qp += 1
            diag.iterations += max(sol.iterations, 0)
            diag.backend = sol.backend
            u, absorb = sol.x[:nu], True
        if native is not None and ctl[HK.NAT_SOLVED]:
            diag.qp += int(ctl[HK.NAT_SOLVED])
            diag.iterations += int(ctl[HK.NAT_ITERS])
            if ctl[HK.NAT_LAST] > last_here:
                diag.backend = backend.name
        if state[HK.ST_CONTRADICTED]:
            _relax_contradicted(built, plan.meta, stats, slack, diag)
        built.qp_stats, built.qp_r = stats, rfac
        notes.sort(key=lambda item: item[0])
        return x, [text for _, text in notes]


def _relax_contradicted(
    built: HQPBuild, meta: np.ndarray, stats: np.ndarray, slack: np.ndarray, diag: QPDiagnostics
) -> None:
    """The levels whose slack exceeded the contradiction tolerance (the documented relaxation: named in
    ``StepResult.relaxed``, not a fallback): their worst slack per priority, and the bound subtasks of the rows
    that carry it (the level itself when no row names one)."""
    for k in np.flatnonzero(stats[:, QS_WORST] > CONTRADICTION_TOLERANCE).tolist():
        worst = float(stats[k, QS_WORST])
        lv = built.levels[k]
        diag.contradicted[lv.priority] = worst
        c0, c1 = int(meta[META_INEQ, k]), int(meta[META_INEQ, k + 1])
        owner = [bsub.name for C, _, _, bsub in built.rows.ineq[k] for _ in range(C.shape[0])]
        over = np.flatnonzero(slack[c0:c1] > CONTRADICTION_TOLERANCE).tolist()
        diag.relaxed += [owner[i] for i in over if i < len(owner)] or [f"level {lv.priority}"]
