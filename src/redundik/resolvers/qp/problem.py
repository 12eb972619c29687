"""The QP record every backend solves, kept separate from the solving (build, inspect, save, then solve).

    minimise    ½ xᵀ P x + qᵀ x
    subject to  G x ≤ h,   A x = b,   lb ≤ x ≤ ub.

Infinite entries of ``lb``/``ub``/``h`` mean "no constraint". Shapes: P (n, n), q (n,), G (p, n), h (p,),
A (e, n), b (e,), lb and ub (n,). Empty constraint blocks have zero rows (never ``None``), so backends never branch
on presence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class QPProblem:
    """One quadratic program in the form of this module's docstring.

    Attributes:
        P: Hessian (n, n), symmetric positive definite (every redundik QP is regularised).
        q: Linear cost (n,).
        G: Inequality matrix (p, n).
        h: Inequality bound (p,).
        A: Equality matrix (e, n).
        b: Equality value (e,).
        lb: Lower bound on x (n,), ``-inf`` where free.
        ub: Upper bound on x (n,), ``+inf`` where free.
        label: What the problem is (``"wqp"``, ``"hqp level 1"``) for messages.
        row_names: Names of the inequality rows, for diagnostics.
        factor: Optionally (F, δ) with P = FᵀF + δI (to rounding; F (k, n), δ > 0): the structure of a Gram
            Hessian, given by the builder that knows it. A backend may then solve the same problem lifted to
            (x, s) with s = F x, whose Hessian diag(δI, I) is diagonal (``DaqpBackend``: a factorisation of
            n + k diagonal entries instead of a dense n × n one). ``None``: P only.
    """

    P: np.ndarray
    q: np.ndarray
    G: np.ndarray
    h: np.ndarray
    A: np.ndarray
    b: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    label: str = "qp"
    row_names: list[str] = field(default_factory=list)
    factor: tuple[np.ndarray, float] | None = None

    @classmethod
    def unconstrained(cls, P: np.ndarray, q: np.ndarray, label: str = "qp") -> QPProblem:
        """A problem with no constraints (zero-row G and A, infinite bounds); fill them in afterwards."""
        n = q.shape[0]
        return cls(
            P,
            q,
            np.zeros((0, n)),
            np.zeros(0),
            np.zeros((0, n)),
            np.zeros(0),
            np.full(n, -np.inf),
            np.full(n, np.inf),
            label,
        )

    @property
    def n(self) -> int:
        """Number of variables."""
        return int(self.q.shape[0])

    @property
    def has_bounds(self) -> bool:
        """True when at least one finite bound on x exists."""
        return bool(np.any(np.isfinite(self.lb)) or np.any(np.isfinite(self.ub)))

    def objective(self, x: np.ndarray) -> float:
        """½ xᵀPx + qᵀx."""
        return float(0.5 * x @ self.P @ x + self.q @ x)

    def violation(self, x: np.ndarray) -> float:
        """Largest constraint violation of x (0 when feasible)."""
        v = 0.0
        if self.G.shape[0]:
            v = max(v, float(np.max(self.G @ x - self.h, initial=0.0)))
        if self.A.shape[0]:
            v = max(v, float(np.max(np.abs(self.A @ x - self.b))))
        v = max(v, float(np.max(self.lb - x, initial=0.0)), float(np.max(x - self.ub, initial=0.0)))
        return v

    def check(self) -> None:
        """Validate shapes and finiteness.

        Raises:
            ValueError: on a shape mismatch or NaN data (an internal error: resolvers build consistent problems).
        """
        n = self.n
        shapes = {
            "P": (self.P.shape, (n, n)),
            "G": (self.G.shape[1:], (n,)),
            "A": (self.A.shape[1:], (n,)),
            "h": (self.h.shape, (self.G.shape[0],)),
            "b": (self.b.shape, (self.A.shape[0],)),
            "lb": (self.lb.shape, (n,)),
            "ub": (self.ub.shape, (n,)),
        }
        for key, (got, want) in shapes.items():
            if tuple(got) != tuple(want):
                raise ValueError(f"{self.label}: {key} has shape {got}, expected {want}")
        for key in ("P", "q", "G", "A", "b"):
            if not np.all(np.isfinite(getattr(self, key))):
                raise ValueError(f"{self.label}: {key} contains NaN or infinite values")
        if np.any(np.isnan(self.h)) or np.any(np.isnan(self.lb)) or np.any(np.isnan(self.ub)):
            raise ValueError(f"{self.label}: bounds contain NaN")

    def to_qpsolvers(self) -> Any:
        """The same problem as a ``qpsolvers.Problem`` (infinite bounds kept; qpsolvers handles them)."""
        import qpsolvers

        G = self.G if self.G.shape[0] else None
        h = self.h if self.G.shape[0] else None
        A = self.A if self.A.shape[0] else None
        b = self.b if self.A.shape[0] else None
        lb = self.lb if np.any(np.isfinite(self.lb)) else None
        ub = self.ub if np.any(np.isfinite(self.ub)) else None
        return qpsolvers.Problem(self.P, self.q, G, h, A, b, lb, ub)

    def save(self, path: str) -> None:
        """Write the problem to an ``.npz`` file for inspection (e.g. a QP that failed)."""
        np.savez(
            path, P=self.P, q=self.q, G=self.G, h=self.h, A=self.A, b=self.b, lb=self.lb, ub=self.ub, label=self.label
        )

    @classmethod
    def load(cls, path: str) -> QPProblem:
        """Read a problem written by :meth:`save`."""
        with np.load(path) as f:
            return cls(f["P"], f["q"], f["G"], f["h"], f["A"], f["b"], f["lb"], f["ub"], str(f["label"]))


@dataclass
class QPSolution:
    """What a backend returns.

    Attributes:
        x: Primal solution (n,).
        iterations: Backend iterations (-1 if unknown).
        backend: Backend name.
        solve_time: Seconds spent in the backend.
        retried: What failed before this answer, when the backend's first attempt did not solve the problem and a
            retry of its own did (another tolerance, a regularised Hessian, a polished stalled iterate, the problem
            posed another way); ``None`` when the first attempt solved it. The resolvers count it in
            ``StepResult.relaxed`` (``"<label> (backend retried)"``) and tell it in ``info["retries"]``.
    """

    x: np.ndarray
    iterations: int = -1
    backend: str = ""
    solve_time: float = 0.0
    retried: str | None = None


def infeasible(problem: QPProblem, tol: float = 1e-9) -> bool:
    """True when the constraints of ``problem`` — G x ≤ h + ``tol``, A x = b, lb ≤ x ≤ ub — admit no x (run only
    after a backend refused the QP).

    A row that no x of the box meets (min over the box of Gᵢ x, in closed form, above hᵢ + ``tol``) decides it at
    once, and a single row that the box meets means a feasible problem; several rows that the box meets one by one,
    or equalities, go to a linear program (scipy's HiGHS, ~1–4 ms), whose end other than "infeasible" (an iteration
    limit, a numerical failure) says False: the backend's refusal then counts as its failure.
    """
    n, lb, ub = problem.n, problem.lb, problem.ub
    if np.any(lb > ub):
        return True
    G, h = problem.G, problem.h
    keep = np.isfinite(h)
    if not keep.all():
        G, h = G[keep], h[keep]
    with np.errstate(invalid="ignore"):  # (0 · inf terms are dropped by the where)
        low = np.where(G > 0.0, G * lb, np.where(G < 0.0, G * ub, 0.0)).sum(axis=1)
    if np.any(low > h + tol):
        return True
    A = problem.A if problem.A.shape[0] else None
    if A is None and G.shape[0] <= 1:
        return False
    from scipy.optimize import linprog

    bounds = [(a if math.isfinite(a) else None, b if math.isfinite(b) else None) for a, b in zip(lb, ub, strict=True)]
    try:
        out = linprog(
            np.zeros(n),
            A_ub=G if G.shape[0] else None,
            b_ub=h + tol if G.shape[0] else None,
            A_eq=A,
            b_eq=problem.b if A is not None else None,
            bounds=bounds,
            method="highs",
        )
    except (ValueError, np.linalg.LinAlgError):
        return False
    return bool(out.status == 2)
