"""QP backends: native fast paths for the dense solvers, qpsolvers for the rest; errors become SolverError.

Every backend solves a :class:`~redundik.resolvers.qp.problem.QPProblem` and returns a
:class:`~redundik.resolvers.qp.problem.QPSolution`; whatever goes wrong inside (an exception, "infeasible", an
iteration limit, a non-finite answer) is raised as :class:`~redundik.errors.SolverError` carrying the problem, so
no third-party exception leaks into a control loop.

* ``daqp`` (default): the dual active-set solver of Arnström et al. (2022) through its own ``daqp.solve``: bounds
  are native (no extra rows), exact to machine precision. Chosen as the default by measurement (/tmp script, a
  9-variable box-bounded QP the size of a Panda wqp step, median per solve including this wrapper, loaded 2-core
  machine): daqp 18 µs, proxsuite 36 µs (warm-started), ``qpsolvers:daqp`` 47 µs, quadprog 50 µs, osqp 1.07 ms;
  daqp and quadprog agree to 1e-8, proxsuite to 1e-6 and osqp to 1e-4 with the tolerances set here. A problem that
  carries its Gram factor P = FᵀF + δI (``QPProblem.factor``, k ≤ n/2 rows,
  n ≥ ``LIFT_MIN_N``) is solved lifted to (x, s = F x), with the diagonal Hessian diag(δI, I): daqp's setup is
  then O((n + k)·k) instead of its dense O(n³) (2.5 ms → 0.16 ms a solve on the 160-joint snake's ``wqp`` QP).
* ``quadprog``: Goldfarb–Idnani dual active set through ``quadprog.solve_qp`` (exact; bounds as rows).
* ``proxsuite``: ProxQP (augmented Lagrangian) through a cached ``proxsuite.proxqp.dense.QP`` object per problem
  size, updated in place and warm-started from the previous result, at most 200 outer × 40 inner iterations (a
  stalled iterate is polished, ``polish``, or kept when feasible); tolerances tightened to ``eps_abs = 1e-9``
  (its default 1e-5 gives answers up to ~1 off the active-set ones on ill-conditioned steps) and the infeasibility
  thresholds to 1e-10 (the default 1e-4 declared a plainly feasible 1-variable, 14-row level QP infeasible), with
  the duality-gap check on (without it a "solved" answer was 1e-5 off on a 2-variable QP).
* ``osqp``: ADMM through qpsolvers with ``eps_abs = eps_rel = 1e-8`` and warm start, polishing off (OSQP prints
  "Polishing not needed" on stdout, whatever ``verbose`` says, whenever no constraint is active; the tolerances
  already meet :data:`TOLERANCE`); the slowest and least accurate here (kept for comparison and for very large
  sparse problems).
* ``qpsolvers:NAME``: any other solver qpsolvers knows, through ``qpsolvers.solve_problem``.

The tolerances in :data:`TOLERANCE` are what the tests hold each backend to (largest |x − x_ref| on well-scaled
problems).
"""

from __future__ import annotations

import importlib.util
import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from redundik._names import did_you_mean
from redundik.errors import SolverError
from redundik.resolvers.qp.problem import QPProblem, QPSolution

_INF = 1e20

#: Agreement with an exact active-set answer each backend is held to in the tests [unit of x].
TOLERANCE: dict[str, float] = {"daqp": 1e-8, "quadprog": 1e-8, "proxsuite": 1e-6, "osqp": 1e-4}

#: Python module each named backend needs, and the pip package that provides it.
_MODULES: dict[str, tuple[str, str]] = {
    "daqp": ("daqp", "daqp"),
    "quadprog": ("quadprog", "quadprog"),
    "proxsuite": ("proxsuite", "proxsuite"),
    "osqp": ("osqp", "osqp"),
}

DEFAULT_BACKEND = "daqp"


class Backend(ABC):
    """Solves a :class:`QPProblem`; raises :class:`SolverError` on any failure."""

    name: str = "backend"

    @abstractmethod
    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        """Solve ``problem``, optionally warm-started at ``warm`` (n,).

        Raises:
            SolverError: the backend raised, reported infeasibility or an iteration limit, or returned NaN.
        """

    def solve_stacked(
        self, P: np.ndarray, q: np.ndarray, G: np.ndarray, upper: np.ndarray, lower: np.ndarray, equalities: int = 0
    ) -> tuple[np.ndarray, int] | None:
        """A QP in daqp's form — lower ≤ (x, G x) ≤ upper, the n bounds on x first, the last ``equalities`` rows
        equalities (lower = upper), the other rows' lower bounds −∞ — solved without copying, as (x, iterations);
        ``None`` when this backend has no such path or did not solve it: the caller then poses the
        :class:`QPProblem` for :meth:`solve`, with every retry and its error. The arrays are C-ordered float64, and
        no backend may keep or change them.
        """
        return None

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget warm-start state."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _rows(M: np.ndarray, n: int) -> np.ndarray:
    """``M`` as a (rows, n) float array: a block without rows, of shape (0, n), (0, 0) or (0,), becomes (0, n)."""
    M = np.asarray(M, dtype=float)
    if M.size == 0:
        return np.zeros((0, n))
    return M.reshape(-1, n) if M.ndim == 1 else M


def _vec(v: np.ndarray, size: int) -> np.ndarray:
    """``v`` as a float vector; an empty one of any shape becomes (0,) when ``size`` is 0."""
    v = np.asarray(v, dtype=float).reshape(-1)
    return np.zeros(0) if size == 0 and v.size == 0 else v


def finite(x: np.ndarray) -> bool:
    """True when every entry of the float array x is finite.

    A vector first takes one dot product: a finite xᵀx means every entry is finite (an inf or NaN entry makes it
    inf or NaN), ~0.3 µs against ~1 µs for the element-wise test, which decides only when xᵀx is not finite (an
    entry that is, or entries beyond ~1e154 whose squares overflow: NumPy then warns of the overflow, or raises it
    under ``np.seterr(over="raise")``, which is caught here).
    """
    if x.ndim == 1:
        try:
            if math.isfinite(x.dot(x)):
                return True
        except FloatingPointError:
            pass
    return bool(np.isfinite(x).all())


def _joined(first: str | None, then: str) -> str:
    """``then`` after ``first`` (``None``: ``then`` alone), for :attr:`QPSolution.retried`."""
    return then if first is None else f"{first}; {then}"


def _checked(x: np.ndarray | None, problem: QPProblem, backend: str, status: object = "") -> np.ndarray:
    if x is None:
        raise SolverError(f"{backend}: no finite solution for {problem.label} (status {status})", problem)
    if type(x) is not np.ndarray or x.dtype != np.float64:
        x = np.asarray(x, dtype=float)
    if not finite(x):
        raise SolverError(f"{backend}: no finite solution for {problem.label} (status {status})", problem)
    return x


def polish(problem: QPProblem, x: np.ndarray | None, tol: float = 1e-9, rounds: int = 12) -> np.ndarray | None:
    """The exact optimum near an approximate one, verified, or ``None``.

    From the constraints that an iterative solver (ADMM, augmented Lagrangian) left within δ of their bound at
    ``x`` (δ = 1e-9 … 1e-5, relative to max(1, ‖x‖∞)), solve the equality-constrained QP of that active set (its
    KKT system, by least squares so that dependent rows are allowed), then correct the set a few ``rounds`` as a
    primal-dual active-set method does (add the violated rows, drop the most negative multiplier). An answer is
    kept only if it satisfies the KKT conditions of the whole problem — stationarity, primal feasibility and
    non-negative multipliers within ``tol`` — so a wrong guess can cost time, never accuracy. This is OSQP's own
    polishing, but also from an iterate that stopped at the iteration limit (OSQP polishes only solved problems).
    """
    n = problem.n
    if x is None or np.shape(x) != (n,) or not np.all(np.isfinite(x)):
        return None
    G, A = _rows(problem.G, n), _rows(problem.A, n)
    h, b = _vec(problem.h, G.shape[0]), _vec(problem.b, A.shape[0])
    eye = np.eye(n)
    fh, fl, fu = np.isfinite(h), np.isfinite(problem.lb), np.isfinite(problem.ub)
    C = np.vstack([G[fh], eye[fu], -eye[fl]])
    d = np.concatenate([h[fh], problem.ub[fu], -problem.lb[fl]])
    e = A.shape[0]
    scale = max(1.0, float(np.max(np.abs(x))))
    k_scale = max(1.0, float(np.max(np.abs(problem.P))), float(np.max(np.abs(C), initial=0.0)))
    slack = d - C @ x
    tried: set[bytes] = set()
    for delta in (1e-9, 1e-8, 1e-7, 1e-6, 1e-5):
        act = slack <= delta * scale
        for _ in range(rounds):
            key = act.tobytes()
            if key in tried:
                break
            tried.add(key)
            M = np.vstack([A, C[act]])
            m = M.shape[0]
            K = np.block([[problem.P, M.T], [M, np.zeros((m, m))]])
            rhs = np.concatenate([-problem.q, b, d[act]])
            sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
            xs, lam = sol[:n], sol[n + e :]
            s2 = max(1.0, float(np.max(np.abs(sol))))
            if np.max(np.abs(K @ sol - rhs)) > tol * s2 * k_scale:
                break  # inconsistent active set: try the next δ
            # verified on the scale of the candidate, never of the iterate: an infeasibility certificate (OSQP's
            # iterate of ‖x‖ = 2e9 on a primal-infeasible wqp step) would otherwise excuse violations of 2
            vscale = max(1.0, float(np.max(np.abs(xs), initial=0.0)))
            over = C @ xs - d > tol * vscale
            neg = lam < -tol * s2
            if e and np.max(np.abs(A @ xs - b)) > tol * vscale:
                break
            if not over.any() and not neg.any():
                return xs
            act = act.copy()
            act[over] = True
            if neg.any():
                act[np.flatnonzero(act)[int(np.argmin(lam))]] = False
    return None


#: Largest constraint violation of a stalled iterate that an iterative backend may still return, relative to
#: max(1, the largest finite bound or right-hand side of the problem) [unit of x] (not to ‖x‖∞: an infeasibility
#: certificate is huge): the iteration limit on a degenerate but feasible QP leaves ADMM / ProxQP within their
#: accuracy of the optimum (osqp 1e-4, proxsuite 1e-6, see :data:`TOLERANCE`); the resolvers clip q̇ to the joint
#: limits afterwards in any case.
ITERATE_VIOLATION = 1e-6


def _stalled(problem: QPProblem, x: np.ndarray | None) -> np.ndarray | None:
    """The exact optimum polished from a stalled iterate (``polish``), else the iterate itself when it violates
    no constraint by more than :data:`ITERATE_VIOLATION`, else ``None``."""
    xp = polish(problem, x)
    if xp is not None or x is None:
        return xp
    x = np.asarray(x, dtype=float)
    if x.shape != (problem.n,) or not np.all(np.isfinite(x)):
        return None
    n = problem.n
    G, A = _rows(problem.G, n), _rows(problem.A, n)
    h, b = _vec(problem.h, G.shape[0]), _vec(problem.b, A.shape[0])
    viol = max(
        float(np.max(G @ x - h, initial=0.0)),
        float(np.max(np.abs(A @ x - b), initial=0.0)),
        float(np.max(problem.lb - x, initial=0.0)),
        float(np.max(x - problem.ub, initial=0.0)),
    )
    data = np.concatenate([h, b, problem.lb, problem.ub])
    data = data[np.isfinite(data)]
    return x if viol <= ITERATE_VIOLATION * max(1.0, float(np.max(np.abs(data), initial=0.0))) else None


def _writable(a: np.ndarray) -> np.ndarray:
    """``a``, or a C-contiguous copy when it is read-only (daqp's typed memoryviews refuse read-only buffers: a
    broadcast view, a row of a frozen array) or not contiguous (daqp reads its vectors and matrices from their first
    element's address on: a strided view — a column, every other entry — would be read as the wrong numbers)."""
    flags = a.flags
    return a if flags.writeable and flags.c_contiguous else np.array(a, dtype=float, order="C")


#: Smallest n³ − n_c³ (n variables, n_c of them coupled) for which a bounds-only QP is split
#: (:func:`redundik.resolvers.kernels.split_separable`) before daqp solves it. daqp's setup — a Cholesky
#: factorisation of P and the inverse of its factor, ≈ 0.27 ns per n³ on this machine (15 µs of its 16 µs on Talos's
#: 38-variable ``wqp`` QP) — is what the split saves; the split costs ≈ 1.5 µs (one compiled call and one scatter),
#: i.e. ≈ 5 500 units of n³: below twice that it does not pay.
SPLIT_MIN_SAVING = 11000

#: Smallest n for which a QP that carries its Gram factor (``QPProblem.factor``, k rows) is solved lifted by
#: daqp (``DaqpBackend._solve_lifted``), and the bound k ≤ n / LIFT_MAX_ROWS_PER_VARIABLE. Measured on the
#: snake's ``wqp`` QPs (k = 6, 40 QPs × 5, median per solve, this wrapper included): n = 20 lifted 57 µs vs dense
#: 40, n = 40 66 vs 82, n = 80 85 vs 384, n = 160 164 vs 2 458 — daqp's dense setup grows as n³, the lifted one
#: as (n + k)·k.
LIFT_MIN_N = 40
LIFT_MAX_ROWS_PER_VARIABLE = 2


@lru_cache(maxsize=1)
def split_kernel() -> Callable[..., tuple[int, int]]:
    """The compiled split of a bounds-only QP, :func:`redundik.resolvers.kernels.split_separable` (imported on first
    use: numba loads when a split is first tried, not when redundik is imported)."""
    from redundik.resolvers.kernels import split_separable

    return split_separable


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
        self._split_kernel: Callable[..., tuple[int, int]] | None = None
        self._split_work: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._split_cache: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}
        #: Smallest n of a QP that carries its Gram factor (``QPProblem.factor``) solved lifted
        #: (``_solve_lifted``); ``LIFT_MIN_N`` by default.
        self.lift_min_n = LIFT_MIN_N
        self._lift_cache: dict[tuple[int, int], tuple[np.ndarray, float]] = {}
        #: What failed in this solve before its answer (``QPSolution.retried``), reset at each :meth:`solve`.
        self._miss: str | None = None

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
        kernel = self._split_kernel
        if kernel is None:
            kernel = self._split_kernel = split_kernel()
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
        n × n P (on the 160-joint snake's ``wqp`` QP, 6 task rows: 0.6–2.6 ms → 70–110 µs a solve). ``None`` when
        daqp does not solve it (the caller then solves P as given, with every retry)."""
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


class QuadprogBackend(Backend):
    """quadprog's native API: minimise ½xᵀPx − aᵀx s.t. Cᵀx ≥ b (equalities first); bounds as rows."""

    name = "quadprog"

    def __init__(self) -> None:
        import quadprog

        self._solve = quadprog.solve_qp

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        """Solve with equalities first, then finite inequality and bound rows as Cᵀx ≥ b.

        Zero-row blocks of any shape ((0, n), (0, 0)) are skipped; with no constraint row at all the trivial row
        0·x ≥ −1 is passed (quadprog needs at least one column in C).
        """
        n = problem.n
        t0 = time.perf_counter()
        try:
            G, A = _rows(problem.G, n), _rows(problem.A, n)
            h, b = _vec(problem.h, G.shape[0]), _vec(problem.b, A.shape[0])
            fh = np.isfinite(h)
            lb, ub = problem.lb, problem.ub
            # a bound with lb = ub (a rate window squeezed onto one velocity) is an equality: as two opposite rows
            # quadprog's dual steps can call it "inconsistent" through rounding
            pinned = np.flatnonzero(np.isfinite(lb) & np.isfinite(ub) & (ub - lb <= 1e-12 * np.maximum(1.0, abs(ub))))
            fl = np.flatnonzero(np.isfinite(lb) & ~np.isin(np.arange(n), pinned))
            fu = np.flatnonzero(np.isfinite(ub) & ~np.isin(np.arange(n), pinned))
            blocks = [A, np.eye(n)[pinned], -G[fh]]
            rhs = [b, 0.5 * (lb[pinned] + ub[pinned]), -h[fh]]
            meq = A.shape[0] + pinned.size
            if fl.size:
                blocks.append(np.eye(n)[fl])
                rhs.append(lb[fl])
            if fu.size:
                blocks.append(-np.eye(n)[fu])
                rhs.append(-ub[fu])
            C = np.vstack(blocks)
            d = np.concatenate(rhs)
            if not C.shape[0]:
                C, d = np.zeros((1, n)), np.array([-1.0])
            out = self._solve(_writable(problem.P), -problem.q, C.T.copy(), d, meq)
        except Exception as exc:
            raise SolverError(f"quadprog failed on {problem.label}: {exc}", problem) from exc
        x = _checked(out[0], problem, self.name)
        return QPSolution(x, int(out[3][0]), self.name, time.perf_counter() - t0)


class ProxsuiteBackend(Backend):
    """ProxQP dense through a cached ``proxsuite.proxqp.dense.QP`` per problem size, warm-started in place."""

    name = "proxsuite"

    def __init__(self, eps_abs: float = 1e-9, max_iter: int = 200, max_iter_in: int = 40) -> None:
        import proxsuite

        self._px = proxsuite.proxqp
        self.eps_abs, self.max_iter, self.max_iter_in = float(eps_abs), int(max_iter), int(max_iter_in)
        self._cache: dict[tuple[int, int, int], Any] = {}  # proxsuite QP objects (untyped)

    def reset(self) -> None:
        self._cache.clear()

    def _new_qp(self, n: int, e: int, p: int, duality_gap: bool) -> Any:
        qp = self._px.dense.QP(n, e, p, True)
        qp.settings.eps_abs = self.eps_abs
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = self.max_iter
        # bounded effort: on a level whose u-part is fixed only by the 1e-9 regulariser (a pure bound level of hqp)
        # ProxQP at eps_abs 1e-9 ran 2.9e6 inner iterations (45 s); stopped earlier, the iterate is polished or
        # kept when feasible (_stalled)
        qp.settings.max_iter_in = self.max_iter_in
        # the default 1e-4 declares small feasible QPs "primal infeasible" (seen on 1-variable hqp levels)
        qp.settings.eps_primal_inf = 1e-10
        qp.settings.eps_dual_inf = 1e-10
        # without the duality-gap check "solved" can be 1e-5 off in x on a 2-variable QP
        qp.settings.check_duality_gap = duality_gap
        qp.settings.eps_duality_gap_abs = 1e-10
        qp.settings.eps_duality_gap_rel = 0.0
        return qp

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        n = problem.n
        G, Aeq = _rows(problem.G, n), _rows(problem.A, n)
        p, e = G.shape[0], Aeq.shape[0]
        key = (n, e, p)
        l_in = np.full(p, -_INF)
        u_in = np.minimum(_vec(problem.h, p), _INF)
        lb, ub = np.maximum(problem.lb, -_INF), np.minimum(problem.ub, _INF)
        A = Aeq if e else None
        b = _vec(problem.b, e) if e else None
        C = G if p else None
        t0 = time.perf_counter()
        try:
            qp = self._cache.get(key)
            if qp is None:
                qp = self._new_qp(n, e, p, duality_gap=True)
                qp.init(problem.P, problem.q, A, b, C, l_in if p else None, u_in if p else None, lb, ub)
                self._cache[key] = qp
            else:
                qp.settings.initial_guess = self._px.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
                qp.update(problem.P, problem.q, A, b, C, l_in if p else None, u_in if p else None, lb, ub)
            qp.solve()
            status = qp.results.info.status
            if status != self._px.QPSolverOutput.PROXQP_SOLVED:
                self._cache.pop(key, None)
                # a degenerate feasible QP can stall (iteration limit) or trip the infeasibility test: polish the
                # iterate; failing that, solve once more from scratch without the duality-gap check, which on a
                # 2-variable hqp level whose feasible window is 3e-7 wide made ProxQP report a plainly feasible QP
                # "primal infeasible" (it solves it in 10 iterations without the check, and daqp agrees)
                xp = _stalled(problem, np.array(qp.results.x))
                note = f"proxsuite status {status} (its iterate polished)"
                if xp is not None:
                    return QPSolution(xp, int(qp.results.info.iter), self.name, time.perf_counter() - t0, note)
                qp = self._new_qp(n, e, p, duality_gap=False)
                qp.init(problem.P, problem.q, A, b, C, l_in if p else None, u_in if p else None, lb, ub)
                qp.solve()
                retry = qp.results.info.status
                if retry != self._px.QPSolverOutput.PROXQP_SOLVED:
                    raise SolverError(f"proxsuite: {problem.label} not solved ({status}, then {retry})", problem)
                x = polish(problem, np.array(qp.results.x))
                x = _checked(np.array(qp.results.x) if x is None else x, problem, self.name, retry)
                note = f"proxsuite status {status} (solved again without the duality-gap check)"
                return QPSolution(x, int(qp.results.info.iter), self.name, time.perf_counter() - t0, note)
        except SolverError:
            raise
        except Exception as exc:
            self._cache.pop(key, None)
            raise SolverError(f"proxsuite raised on {problem.label}: {exc}", problem) from exc
        x = _checked(np.array(qp.results.x), problem, self.name, status)
        return QPSolution(x, int(qp.results.info.iter), self.name, time.perf_counter() - t0)


class QpsolversBackend(Backend):
    """Any solver known to qpsolvers, through ``qpsolvers.solve_problem`` (with warm start when given)."""

    def __init__(self, solver: str, **settings: float) -> None:
        import qpsolvers

        if solver not in qpsolvers.available_solvers:
            raise SolverError(
                f"qpsolvers backend '{solver}' is not installed; installed: {sorted(qpsolvers.available_solvers)}"
            )
        self._qps = qpsolvers
        self.solver = solver
        self.name = solver if solver == "osqp" else f"qpsolvers:{solver}"
        self.settings: dict[str, Any] = dict(settings)

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        t0 = time.perf_counter()
        try:
            sol = self._qps.solve_problem(problem.to_qpsolvers(), solver=self.solver, initvals=warm, **self.settings)
        except Exception as exc:
            raise SolverError(f"{self.name} raised on {problem.label}: {exc}", problem) from exc
        if not sol.found:
            raise SolverError(f"{self.name}: {problem.label} not solved", problem)
        x = _checked(sol.x, problem, self.name)
        iters = -1
        info = getattr(sol, "extras", {}).get("info")
        if info is not None:
            iters = int(getattr(info, "iter", getattr(info, "iterations", -1)))
        return QPSolution(x, iters, self.name, time.perf_counter() - t0)

    def __repr__(self) -> str:
        return f"QpsolversBackend({self.solver!r})"


class OsqpBackend(QpsolversBackend):
    """OSQP through qpsolvers, with sparse matrices built here (no conversion warnings) and tight tolerances.

    ADMM stalls on degenerate QPs (several constraints active at a 1e-7 margin, seen on hqp levels): whatever OSQP
    stops with that is not "solved" — the iteration limit, "solved inaccurate", a spurious infeasibility — is
    polished (``polish``, kept only if the polished point verifies the KKT conditions), else kept if it
    violates no constraint by more than :data:`ITERATE_VIOLATION`, else a :class:`SolverError`.
    """

    def __init__(self) -> None:
        super().__init__(
            "osqp", eps_abs=1e-8, eps_rel=1e-8, polishing=False, max_iter=20000, verbose=False, raise_error=False
        )

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        import warnings

        import scipy.sparse as sp

        n = problem.n
        G, A = _rows(problem.G, n), _rows(problem.A, n)
        sparse = QPProblem(
            sp.csc_matrix(problem.P),
            problem.q,
            sp.csc_matrix(G),
            _vec(problem.h, G.shape[0]),
            sp.csc_matrix(A),
            _vec(problem.b, A.shape[0]),
            problem.lb,
            problem.ub,
            problem.label,
        )
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # qpsolvers warns on every non-solved status: handled here
                sol = self._qps.solve_problem(sparse.to_qpsolvers(), solver="osqp", initvals=warm, **self.settings)
        except Exception as exc:
            raise SolverError(f"osqp raised on {problem.label}: {exc}", problem) from exc
        info = getattr(sol, "extras", {}).get("info")
        iters = int(getattr(info, "iter", -1)) if info is not None else -1
        if sol.found and sol.x is not None and np.all(np.isfinite(sol.x)):
            return QPSolution(np.asarray(sol.x, dtype=float), iters, self.name, time.perf_counter() - t0)
        x = _stalled(problem, sol.x)
        status = getattr(info, "status", "?")
        if x is None:
            raise SolverError(f"osqp: {problem.label} not solved ({status})", problem)
        return QPSolution(x, iters, self.name, time.perf_counter() - t0, f"osqp status {status} (its iterate polished)")

    def __repr__(self) -> str:
        return "OsqpBackend()"


#: Backends (exact types) whose ``solve`` itself guarantees a finite float x of shape (n,) on every return — daqp's
#: every path ends in :func:`_checked` or :func:`finite` — so that the resolvers' template does not test it again.
CHECKED_ANSWERS: frozenset[type[Backend]] = frozenset({DaqpBackend})

_FACTORIES = {"daqp": DaqpBackend, "quadprog": QuadprogBackend, "proxsuite": ProxsuiteBackend, "osqp": OsqpBackend}


def _installed(name: str) -> bool:
    return importlib.util.find_spec(_MODULES[name][0]) is not None


def available_backends() -> list[str]:
    """Names of the backends usable here (their Python modules import), default first."""
    names = [n for n in _FACTORIES if _installed(n)]
    return sorted(names, key=lambda n: (n != DEFAULT_BACKEND, n))


def make_backend(name: str | Backend = DEFAULT_BACKEND) -> Backend:
    """A backend by name (``"daqp"``, ``"quadprog"``, ``"proxsuite"``, ``"osqp"``, ``"qpsolvers:NAME"``) or as is.

    Raises:
        SolverError: unknown name (lists the installed backends) or a known backend that is not installed (says which
            package to install).
    """
    if isinstance(name, Backend):
        return name
    if not isinstance(name, str):
        raise SolverError(f"QP backend must be a name, got {name!r}; installed: {available_backends()}")
    if name.startswith("qpsolvers:"):
        return QpsolversBackend(name.split(":", 1)[1])
    if name not in _FACTORIES:
        raise SolverError(
            f"unknown QP backend '{name}'; {did_you_mean(name, _FACTORIES)}installed: {available_backends()} (or "
            "'qpsolvers:NAME' for another "
            "solver qpsolvers knows)"
        )
    if not _installed(name):
        raise SolverError(
            f"QP backend '{name}' is not installed (pip install 'redundik[backends]', or pip install "
            f"{_MODULES[name][1]}); installed: {available_backends()}"
        )
    return _FACTORIES[name]()
