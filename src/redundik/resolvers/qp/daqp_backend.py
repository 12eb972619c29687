"""The default QP backend: daqp's native API (Arnström et al. 2022), with bounds as its simple rows, bounds-only QPs
split into their separable variables and the rest, and QPs that carry their Gram factor solved lifted (see
:mod:`redundik.resolvers.qp.backends` for the measurements behind the choice)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from redundik.errors import SolverError
from redundik.resolvers.linalg import K
from redundik.resolvers.qp.backend_base import (
    Backend,
    _checked,
    _joined,
    _rows,
    _stalled,
    _vec,
    _writable,
    finite,
    polish,
)
from redundik.resolvers.qp.problem import QPProblem, QPSolution

#: Smallest n³ − n_c³ (n variables, n_c of them coupled) for which a bounds-only QP is split
#: (:func:`redundik.resolvers.kernels.split_separable`) before daqp solves it. daqp's setup — a Cholesky
#: factorisation of P and the inverse of its factor, ≈ 0.27 ns per n³ (measured), most of a bounds-only solve — is
#: what the split saves; the split costs ≈ 1.5 µs (one compiled call and one scatter), i.e. ≈ 5 500 units of n³:
#: below twice that it does not pay.
SPLIT_MIN_SAVING = 11000

#: Smallest n for which a QP that carries its Gram factor (``QPProblem.factor``, k rows) is solved lifted by
#: daqp (``DaqpBackend._solve_lifted``), and the bound k ≤ n / LIFT_MAX_ROWS_PER_VARIABLE: on the snake's ``wqp``
#: QPs (k = 6) the lifted solve is measured faster from n = 40 on, slower at n = 20 — daqp's dense setup grows as
#: n³, the lifted one as (n + k)·k.
LIFT_MIN_N = 40
LIFT_MAX_ROWS_PER_VARIABLE = 2


def split_kernel() -> Callable[..., tuple[int, int]]:
    """The compiled split of a bounds-only QP, :func:`redundik.resolvers.kernels.split_separable`, looked up in the
    kernel namespace at each call (numba loads when a split is first tried, not when redundik is imported; during a
    cold start the namespace holds its interpreted twin, so the caller's thread does not compile it)."""
    kernel: Callable[..., tuple[int, int]] = K.split_separable
    return kernel


def first_run_cost() -> dict[str, float]:
    """Seconds the split kernel (:func:`split_kernel`) takes on its first call in this process (JIT compile, or
    loading numba's on-disk cache); later calls are the steady-state cost (≈ 1 µs)."""
    P = np.diag([2.0, 1.0, 1.0])
    P[1, 2] = P[2, 1] = 0.5
    t0 = time.perf_counter()
    split_kernel()(P, np.ones(3), -np.ones(3), np.ones(3), 0, np.empty((7, 3)), np.empty(3, dtype=np.int64))
    return {"split_separable": time.perf_counter() - t0}


class DaqpBackend(Backend):
    """daqp's native API: blower ≤ [I; G; A] x ≤ bupper with bounds as the first (simple) rows, equalities sensed.

    A bounds-only QP of at least ``round(SPLIT_MIN_SAVING ** (1/3))`` variables with separable ones is split first
    (:meth:`_solve_split`). The split's work buffers belong to the instance: one instance solves one QP at a time
    (as a resolver steps one robot at a time; give each thread its own resolver, hence its own backend).
    """

    name = "daqp"

    def __init__(self, iter_limit: int = 1000, primal_tol: float = 1e-10) -> None:
        import daqp

        self._solve = daqp.solve
        self.iter_limit, self.primal_tol = int(iter_limit), float(primal_tol)
        #: Smallest n of a bounds-only QP that is tested for separable variables (n³ ≥ SPLIT_MIN_SAVING).
        self._split_min_n = round(SPLIT_MIN_SAVING ** (1 / 3))
        self._split_work: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._split_cache: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}
        #: Smallest n of a QP that carries its Gram factor (``QPProblem.factor``) solved lifted
        #: (``_solve_lifted``); ``LIFT_MIN_N`` by default.
        self.lift_min_n = LIFT_MIN_N
        self._lift_cache: dict[tuple[int, int], tuple[np.ndarray, float]] = {}
        #: What failed in this solve before its answer (``QPSolution.retried``), reset at each :meth:`solve`.
        self._miss: str | None = None

    def __getstate__(self) -> dict[str, Any]:
        """The backend without the split's work buffers and their views (made again at the copy's first split).

        ``_split_cache`` holds views of the arrays in ``_split_work``; copy.deepcopy and pickle turn each view into
        an array of its own, so a copy's split kernel would write the problem into the copied buffer while daqp
        solved the stale copied views: a wrong q̇ at every split solve of the copy."""
        state = self.__dict__.copy()
        state["_split_work"], state["_split_cache"] = {}, {}
        return state

    def _split_views(self, n: int, nc: int) -> tuple[np.ndarray, ...]:
        """The work buffers of the split kernel (:func:`split_kernel`) for n variables and the views daqp reads for
        n_c coupled ones (x, q_c, lb_c, ub_c, P_cc, the coupled indices, daqp's empty constraint matrix and its
        sense), cached by (n, n_c) — both are the same step after step."""
        views = self._split_cache.get((n, nc))
        if views is None:
            work, idx = self._split_work.get(n, (None, None))
            if work is None or idx is None:
                work, idx = np.empty((4 + n, n)), np.empty(n, dtype=np.int64)
                self._split_work[n] = (work, idx)
            Pc = work[4:].reshape(-1)[: nc * nc].reshape(nc, nc)
            views = (work, idx, work[1, :nc], work[2, :nc], work[3, :nc], Pc, idx[:nc])
            views += (np.zeros((0, nc)), np.zeros(nc, dtype=np.int32))
            self._split_cache[(n, nc)] = views
        return views

    def _solve_split(self, problem: QPProblem) -> QPSolution | None:
        """A bounds-only QP with separable variables (:func:`split_kernel`): daqp on the coupled ones, the others
        in closed form; ``None`` when the split is not made or daqp does not solve the coupled QP (the caller then
        solves the whole problem, with every retry, as without the split).

        The answer is the whole problem's optimum (its KKT conditions decouple); the iterations reported are
        daqp's on the coupled QP plus one per separable variable clipped onto a bound — the constraints daqp's
        dual active set adds for them on the whole problem (the same counts on 2 569 random split problems and on
        every Talos ``wqp`` QP of the benchmark).
        """
        t0 = time.perf_counter()
        n = problem.q.shape[0]
        buffers = self._split_work.get(n)
        work, idx = self._split_views(n, 0)[:2] if buffers is None else buffers
        kernel = K.split_separable
        try:
            # (writable C-ordered arrays, as daqp needs them anyway: the kernel is then always called with the types
            # it was compiled for — a read-only or strided view would compile another specialisation mid-loop)
            P, q, lb, ub = _writable(problem.P), _writable(problem.q), _writable(problem.lb), _writable(problem.ub)
            nc, clipped = kernel(P, q, lb, ub, SPLIT_MIN_SAVING, work, idx)
        except Exception:  # data numba cannot type (an object array): the whole problem's solve deals with it
            return None
        if nc < 0:
            return None
        _, _, qc, lbc, ubc, Pc, ic, M, sense = self._split_views(n, nc)
        try:
            xc, _, flag, info = self._solve(
                Pc, qc, M, ubc, lbc, sense, iter_limit=self.iter_limit, primal_tol=self.primal_tol
            )
        except Exception as exc:  # (the whole problem's solve reports it)
            self._miss = f"daqp raised on the split problem ({exc})"
            return None
        if (flag != 1 and flag != 2) or type(xc) is not np.ndarray or xc.shape != (nc,) or not finite(xc):
            self._miss = f"daqp did not solve the split problem (exit flag {flag})"
            return None
        x = work[0].copy()  # (the separable entries are finite: the kernel checked them)
        x[ic] = xc
        return QPSolution(x, int(info.get("iterations", -1)) + clipped, self.name, time.perf_counter() - t0)

    def _lifted_hessian(self, n: int, k: int, delta: float) -> np.ndarray:
        """diag(δ·1_n, 1_k), in a buffer kept per (n, k) (daqp reads H, never writes it): only the diagonal is
        rewritten when δ changes."""
        cached = self._lift_cache.get((n, k))
        if cached is None or cached[1] != delta:
            H = cached[0] if cached is not None else np.zeros((n + k, n + k))
            diag = H.reshape(-1)[:: n + k + 1]
            diag[:n] = delta
            diag[n:] = 1.0
            self._lift_cache[(n, k)] = (H, delta)
            return H
        return cached[0]

    def _solve_lifted(self, problem: QPProblem) -> QPSolution | None:
        """The problem lifted to (x, s), s = F x, when it carries its Gram factor P = FᵀF + δI
        (``QPProblem.factor``): minimise ½δ‖x‖² + ½‖s‖² + qᵀx with the rows F x − s = 0 as equalities, the
        same optimum x, but a diagonal Hessian — daqp's setup factors n + k diagonal entries instead of the dense
        n × n P, O((n + k)·k) instead of O(n³). ``None`` when daqp does not solve it (the caller then solves P as
        given, with every retry)."""
        assert problem.factor is not None
        F, delta = problem.factor
        t0 = time.perf_counter()
        n, k = problem.n, F.shape[0]
        G, A = _rows(problem.G, n), _rows(problem.A, n)
        p, e = G.shape[0], A.shape[0]
        h, b = _vec(problem.h, p), _vec(problem.b, e)
        M = np.zeros((p + k + e, n + k))
        M[:p, :n] = G
        M[p : p + k, :n] = F
        M[p : p + k, n:] = -np.eye(k)
        M[p + k :, :n] = A
        bu = np.concatenate([problem.ub, np.full(k, np.inf), h, np.zeros(k), b])
        bl = np.concatenate([problem.lb, np.full(k, -np.inf), np.full(p, -np.inf), np.zeros(k), b])
        sense = np.zeros(bu.shape[0], dtype=np.int32)
        sense[n + k + p :] = 5
        f = np.concatenate([problem.q, np.zeros(k)])
        try:
            y, _, flag, info = self._solve(
                self._lifted_hessian(n, k, delta), f, M, bu, bl, sense, iter_limit=self.iter_limit,
                primal_tol=self.primal_tol,
            )  # fmt: skip
        except Exception as exc:  # (the problem as given reports it)
            self._miss = f"daqp raised on the lifted problem ({exc})"
            return None
        if (flag != 1 and flag != 2) or type(y) is not np.ndarray or y.shape != (n + k,) or not finite(y):
            self._miss = f"daqp did not solve the lifted problem (exit flag {flag})"
            return None
        return QPSolution(y[:n].copy(), int(info.get("iterations", -1)), self.name, time.perf_counter() - t0)

    def solve_stacked(
        self, P: np.ndarray, q: np.ndarray, G: np.ndarray, upper: np.ndarray, lower: np.ndarray, equalities: int = 0
    ) -> tuple[np.ndarray, int] | None:
        """daqp on the arrays as given: the call :meth:`solve` makes, without assembling them (``None`` on a
        bounds-only QP that :meth:`solve` would split, and whenever daqp does not solve it at once: :meth:`solve`
        then runs its retries)."""
        n = q.shape[0]
        if G.shape[0] == 0 and n >= self._split_min_n:
            return None
        sense = np.zeros(upper.shape[0], dtype=np.int32)
        if equalities:
            sense[-equalities:] = 5
        try:
            x, _, flag, info = self._solve(
                P, q, G, upper, lower, sense, iter_limit=self.iter_limit, primal_tol=self.primal_tol
            )
        except Exception:  # (solve reports it)
            return None
        if (flag != 1 and flag != 2) or type(x) is not np.ndarray or x.shape != (n,) or not finite(x):
            return None
        return x, int(info.get("iterations", -1))

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        self._miss = None
        q = problem.q
        n = q.shape[0]
        G, A = problem.G, problem.A
        bounds_only = G.shape == (0, n) and A.shape == (0, n)
        if bounds_only and n >= self._split_min_n:  # separable variables first: the split's QP is smaller still
            sol = self._solve_split(problem)
            if sol is not None:
                return sol
        factor = problem.factor
        if (
            factor is not None
            and n >= self.lift_min_n
            and factor[0].shape[0] * LIFT_MAX_ROWS_PER_VARIABLE <= n
            and factor[1] > 0.0
        ):
            sol = self._solve_lifted(problem)
            if sol is not None:
                return sol
        if bounds_only:  # (wqp's common QP): the bounds are daqp's rows
            M, bu, bl = G, _writable(problem.ub), _writable(problem.lb)
            sense = np.zeros(n, dtype=np.int32)
        else:
            G, A = _rows(G, n), _rows(A, n)
            p, e = G.shape[0], A.shape[0]
            h, b = _vec(problem.h, p), _vec(problem.b, e)
            M = G if not e else (A if not p else np.vstack([G, A]))
            bu = np.concatenate([problem.ub, h, b])
            bl = np.concatenate([problem.lb, np.full(p, -np.inf), b])
            sense = np.zeros(bu.shape[0], dtype=np.int32)
            if e:
                sense[-e:] = 5
        t0 = time.perf_counter()
        P, q = _writable(problem.P), _writable(q)
        try:
            x, _, flag, info = self._solve(
                P, q, M, bu, bl, sense, iter_limit=self.iter_limit, primal_tol=self.primal_tol
            )
            if x is not None and (type(x) is not np.ndarray or x.shape != (n,)) and np.shape(x) != (n,):
                raise ValueError(f"returned x of shape {np.shape(x)} for {n} variables")
            if flag not in (1, 2) and self.primal_tol < 1e-6:
                # at primal_tol 1e-10 daqp stopped (exit flag 4) on a feasible 2-variable hqp level whose slack is
                # 267 while u has a 3e-7 window; at its default 1e-6 it solves it in 3 iterations. The retry's
                # answer is polished to the verified exact optimum (KKT conditions to 1e-9) where its active set
                # allows, else kept only if it violates no constraint by more than ITERATE_VIOLATION.
                x2, _, flag2, info2 = self._solve(P, q, M, bu, bl, sense, iter_limit=self.iter_limit, primal_tol=1e-6)
                xp = _stalled(problem, x2) if flag2 in (1, 2) and x2 is not None else None
                self._miss = _joined(self._miss, f"daqp exit flag {flag} at primal_tol {self.primal_tol:g}")
                if xp is not None:
                    x, flag, info = xp, flag2, info2
            if flag not in (1, 2, -1):
                # a stall that is not an infeasibility certificate (-1): on a stress-run wqp step (cond(P) ≈ 7e10,
                # its lowest level weighing λ = 1e-10; a 1e-4 window left by a rate limit) daqp stopped with exit
                # flag 4 at every tolerance, where quadprog and osqp solve it. With P + εI it solves in a few
                # iterations, and the answer is polished to the exact optimum of the problem as given (its KKT
                # conditions verified to 1e-9), or not kept at all.
                eps = 1e-9 * max(1.0, float(np.max(np.abs(np.diag(P)))))
                x3, _, flag3, info3 = self._solve(
                    P + eps * np.eye(n), q, M, bu, bl, sense, iter_limit=self.iter_limit, primal_tol=self.primal_tol
                )
                xp = polish(problem, x3) if flag3 in (1, 2) and x3 is not None else None
                self._miss = _joined(self._miss, f"daqp exit flag {flag} (solved with P + {eps:.2g} I, then polished)")
                if xp is not None:
                    x, flag, info = xp, flag3, info3
        except Exception as exc:
            raise SolverError(f"daqp raised on {problem.label}: {exc}", problem) from exc
        if flag not in (1, 2):
            raise SolverError(f"daqp: {problem.label} not solved (exit flag {flag})", problem)
        x = _checked(x, problem, self.name, flag)
        return QPSolution(x, int(info.get("iterations", -1)), self.name, time.perf_counter() - t0, self._miss)
