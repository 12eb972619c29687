"""What every QP backend shares: the :class:`Backend` interface, the finiteness test of an answer, the checks that
turn a missing or non-finite answer into :class:`~redundik.errors.SolverError`, and the polish of an iterative
solver's approximate optimum into the exact one (verified by the KKT conditions)."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from redundik.errors import SolverError
from redundik.resolvers.qp.problem import QPProblem, QPSolution

#: A bound or right-hand side beyond this magnitude counts as infinite in the backends' row forms.
_INF = 1e20


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
    inf or NaN), cheaper than the element-wise test, which decides only when xᵀx is not finite (an
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
