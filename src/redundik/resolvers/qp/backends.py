"""QP backends: native fast paths for the dense solvers, qpsolvers for the rest; errors become SolverError.

Every backend solves a :class:`~redundik.resolvers.qp.problem.QPProblem` and returns a
:class:`~redundik.resolvers.qp.problem.QPSolution`; whatever goes wrong inside (an exception, "infeasible", an
iteration limit, a non-finite answer) is raised as :class:`~redundik.errors.SolverError` carrying the problem, so
no third-party exception leaks into a control loop.

* ``daqp`` (default): the dual active-set solver of Arnström et al. (2022) through its own ``daqp.solve``: bounds
  are native (no extra rows), exact to machine precision. Chosen as the default by measurement (/tmp script, a
  9-variable box-bounded QP the size of a Panda wqp step, median per solve including this wrapper, loaded 2-core
  machine): daqp 18 µs, proxsuite 36 µs (warm-started), ``qpsolvers:daqp`` 47 µs, quadprog 50 µs, osqp 1.07 ms;
  daqp and quadprog agree to 1e-8, proxsuite to 1e-6 and osqp to 1e-4 with the tolerances set here.
* ``quadprog``: Goldfarb–Idnani dual active set through ``quadprog.solve_qp`` (exact; bounds as rows).
* ``proxsuite``: ProxQP (augmented Lagrangian) through a cached ``proxsuite.proxqp.dense.QP`` object per problem
  size, updated in place and warm-started from the previous result; tolerances tightened to ``eps_abs = 1e-9``
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
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

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

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget warm-start state."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _checked(x: np.ndarray | None, problem: QPProblem, backend: str, status: object = "") -> np.ndarray:
    if x is None or not np.all(np.isfinite(x)):
        raise SolverError(f"{backend}: no finite solution for {problem.label} (status {status})", problem)
    return np.asarray(x, dtype=float)


class DaqpBackend(Backend):
    """daqp's native API: blower ≤ [I; G; A] x ≤ bupper with bounds as the first (simple) rows, equalities sensed."""

    name = "daqp"

    def __init__(self, iter_limit: int = 1000, primal_tol: float = 1e-10) -> None:
        import daqp

        self._solve = daqp.solve
        self.iter_limit, self.primal_tol = int(iter_limit), float(primal_tol)

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        p, e = problem.G.shape[0], problem.A.shape[0]
        M = problem.G if not e else (problem.A if not p else np.vstack([problem.G, problem.A]))
        bu = np.concatenate([problem.ub, problem.h, problem.b])
        bl = np.concatenate([problem.lb, np.full(p, -np.inf), problem.b])
        sense = np.zeros(bu.shape[0], dtype=np.int32)
        if e:
            sense[-e:] = 5
        t0 = time.perf_counter()
        try:
            x, _, flag, info = self._solve(
                problem.P, problem.q, M, bu, bl, sense, iter_limit=self.iter_limit, primal_tol=self.primal_tol
            )
        except Exception as exc:
            raise SolverError(f"daqp raised on {problem.label}: {exc}", problem) from exc
        if flag not in (1, 2):
            raise SolverError(f"daqp: {problem.label} not solved (exit flag {flag})", problem)
        x = _checked(x, problem, self.name, flag)
        return QPSolution(x, int(info.get("iterations", -1)), self.name, time.perf_counter() - t0)


class QuadprogBackend(Backend):
    """quadprog's native API: minimise ½xᵀPx − aᵀx s.t. Cᵀx ≥ b (equalities first); bounds as rows."""

    name = "quadprog"

    def __init__(self) -> None:
        import quadprog

        self._solve = quadprog.solve_qp

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        n = problem.n
        fh = np.isfinite(problem.h)
        fl, fu = np.flatnonzero(np.isfinite(problem.lb)), np.flatnonzero(np.isfinite(problem.ub))
        blocks = [problem.A, -problem.G[fh]]
        rhs = [problem.b, -problem.h[fh]]
        if fl.size:
            blocks.append(np.eye(n)[fl])
            rhs.append(problem.lb[fl])
        if fu.size:
            blocks.append(-np.eye(n)[fu])
            rhs.append(-problem.ub[fu])
        C = np.vstack(blocks)
        t0 = time.perf_counter()
        try:
            out = self._solve(problem.P, -problem.q, C.T.copy(), np.concatenate(rhs), problem.A.shape[0])
        except Exception as exc:
            raise SolverError(f"quadprog failed on {problem.label}: {exc}", problem) from exc
        x = _checked(out[0], problem, self.name)
        return QPSolution(x, int(out[3][0]), self.name, time.perf_counter() - t0)


class ProxsuiteBackend(Backend):
    """ProxQP dense through a cached ``proxsuite.proxqp.dense.QP`` per problem size, warm-started in place."""

    name = "proxsuite"

    def __init__(self, eps_abs: float = 1e-9, max_iter: int = 10000) -> None:
        import proxsuite

        self._px = proxsuite.proxqp
        self.eps_abs, self.max_iter = float(eps_abs), int(max_iter)
        self._cache: dict[tuple[int, int, int], Any] = {}  # proxsuite QP objects (untyped)

    def reset(self) -> None:
        self._cache.clear()

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        n, p, e = problem.n, problem.G.shape[0], problem.A.shape[0]
        key = (n, e, p)
        l_in = np.full(p, -_INF)
        u_in = np.minimum(problem.h, _INF)
        lb, ub = np.maximum(problem.lb, -_INF), np.minimum(problem.ub, _INF)
        A = problem.A if e else None
        b = problem.b if e else None
        C = problem.G if p else None
        t0 = time.perf_counter()
        try:
            qp = self._cache.get(key)
            if qp is None:
                qp = self._px.dense.QP(n, e, p, True)
                qp.settings.eps_abs = self.eps_abs
                qp.settings.eps_rel = 0.0
                qp.settings.max_iter = self.max_iter
                # the default 1e-4 declares small feasible QPs "primal infeasible" (seen on 1-variable hqp levels)
                qp.settings.eps_primal_inf = 1e-10
                qp.settings.eps_dual_inf = 1e-10
                # without the duality-gap check "solved" can be 1e-5 off in x on a 2-variable QP
                qp.settings.check_duality_gap = True
                qp.settings.eps_duality_gap_abs = 1e-10
                qp.settings.eps_duality_gap_rel = 0.0
                qp.init(problem.P, problem.q, A, b, C, l_in if p else None, u_in if p else None, lb, ub)
                self._cache[key] = qp
            else:
                qp.settings.initial_guess = self._px.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
                qp.update(problem.P, problem.q, A, b, C, l_in if p else None, u_in if p else None, lb, ub)
            qp.solve()
        except Exception as exc:
            self._cache.pop(key, None)
            raise SolverError(f"proxsuite raised on {problem.label}: {exc}", problem) from exc
        status = qp.results.info.status
        if status != self._px.QPSolverOutput.PROXQP_SOLVED:
            self._cache.pop(key, None)
            raise SolverError(f"proxsuite: {problem.label} not solved ({status})", problem)
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
    """OSQP through qpsolvers, with sparse matrices built here (no conversion warnings) and tight tolerances."""

    def __init__(self) -> None:
        super().__init__(
            "osqp", eps_abs=1e-8, eps_rel=1e-8, polishing=False, max_iter=20000, verbose=False, raise_error=False
        )

    def solve(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        import scipy.sparse as sp

        sparse = QPProblem(
            sp.csc_matrix(problem.P),
            problem.q,
            sp.csc_matrix(problem.G),
            problem.h,
            sp.csc_matrix(problem.A),
            problem.b,
            problem.lb,
            problem.ub,
            problem.label,
        )
        return super().solve(sparse, warm)

    def __repr__(self) -> str:
        return "OsqpBackend()"


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
            f"unknown QP backend '{name}'; installed: {available_backends()} (or 'qpsolvers:NAME' for another "
            "solver qpsolvers knows)"
        )
    if not _installed(name):
        raise SolverError(
            f"QP backend '{name}' is not installed (pip install 'redundik[backends]', or pip install "
            f"{_MODULES[name][1]}); installed: {available_backends()}"
        )
    return _FACTORIES[name]()
