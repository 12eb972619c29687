"""QP backends: native fast paths for the dense solvers, qpsolvers for the rest; errors become SolverError.

Every backend solves a :class:`~redundik.resolvers.qp.problem.QPProblem` and returns a
:class:`~redundik.resolvers.qp.problem.QPSolution`; whatever goes wrong inside (an exception, "infeasible", an
iteration limit, a non-finite answer) is raised as :class:`~redundik.errors.SolverError` carrying the problem, so
no third-party exception leaks into a control loop.

* ``daqp`` (default): the dual active-set solver of Arnström et al. (2022) through its own ``daqp.solve``: bounds
  are native (no extra rows), exact to machine precision. The default because it is the fastest of these backends
  on a box-bounded QP the size of a Panda ``wqp`` step (measured per solve, this wrapper included); daqp and
  quadprog agree to 1e-8, proxsuite to 1e-6 and osqp to 1e-4 with the tolerances set here.
  A problem that carries its Gram factor P = FᵀF + δI (``QPProblem.factor``, k ≤ n/2 rows, n ≥ ``LIFT_MIN_N``) is
  solved lifted to (x, s = F x), with the diagonal Hessian diag(δI, I): daqp's setup is then O((n + k)·k) instead
  of its dense O(n³).
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
import time
from typing import Any

import numpy as np

from redundik._names import did_you_mean
from redundik.errors import SolverError
from redundik.resolvers.qp.backend_base import _INF, _checked, _rows, _stalled, _vec, _writable
from redundik.resolvers.qp.backend_base import ITERATE_VIOLATION as ITERATE_VIOLATION
from redundik.resolvers.qp.backend_base import Backend as Backend
from redundik.resolvers.qp.backend_base import finite as finite
from redundik.resolvers.qp.backend_base import polish as polish
from redundik.resolvers.qp.daqp_backend import LIFT_MAX_ROWS_PER_VARIABLE as LIFT_MAX_ROWS_PER_VARIABLE
from redundik.resolvers.qp.daqp_backend import LIFT_MIN_N as LIFT_MIN_N
from redundik.resolvers.qp.daqp_backend import SPLIT_MIN_SAVING as SPLIT_MIN_SAVING
from redundik.resolvers.qp.daqp_backend import DaqpBackend as DaqpBackend
from redundik.resolvers.qp.daqp_backend import first_run_cost as first_run_cost
from redundik.resolvers.qp.daqp_backend import split_kernel as split_kernel
from redundik.resolvers.qp.problem import QPProblem, QPSolution

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

    def __getstate__(self) -> dict[str, Any]:
        """The settings for a copy or a pickle, without proxsuite's module (a module does not pickle;
        :meth:`__setstate__` imports it again) and without the cached QPs: a copied ``dense.QP`` forgets that it was
        made with box constraints (its next ``update`` raises), so the copy solves its first QP of each size cold, as
        a new backend does. ProxQP's answer depends on its warm start (to its tolerance): a copy's q̇ may differ from
        the original's by that much."""
        state = self.__dict__.copy()
        del state["_px"]
        state["_cache"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        import proxsuite

        self.__dict__.update(state)
        self._px = proxsuite.proxqp

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

    def __getstate__(self) -> dict[str, Any]:
        """The solver's name and settings for a copy or a pickle, without the qpsolvers module (a module does not
        pickle; :meth:`__setstate__` imports it again)."""
        state = self.__dict__.copy()
        del state["_qps"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        import qpsolvers

        self.__dict__.update(state)
        self._qps = qpsolvers

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
