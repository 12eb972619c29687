"""Generalised inverses (section 5.1) through one damped-SVD kernel shared by ``pinv``, ``feedback`` and ``hqp``.

The Moore–Penrose pseudo-inverse J⁺ = V Σ⁺ Uᵀ satisfies the four conditions (5.4) and equals Jᵀ(JJᵀ)⁻¹ when J
has full row rank (the chapter's closed form, eq. 5.7), but unlike that closed form it stays defined when J loses
rank.

Damping rule (damped least squares with a variable factor, Nakamura & Hanafusa 1986 / Chiaverini 1997, applied
*per direction*): with singular values σ_i, a threshold ε and the numerical rank r (σ_i > rcond·σ_max),

    σ_i ≥ ε                     →  1/σ_i                                 (exact),
    rcond·σ_max < σ_i < ε       →  σ_i / (σ_i² + λ_i²),  λ_i² = (1 − (σ_i/ε)²)·λ_max²   (damped),
    σ_i ≤ rcond·σ_max           →  0                                     (an exact zero: truncated).

Only the small *nonzero* singular directions are damped: an exactly rank-deficient J (a zero row, a row given twice)
is solved exactly, and well-conditioned directions are never touched. The map σ ↦ inverse is continuous and
‖J⁺_λ‖ ≤ max(1/ε, 1/(2λ_max√(1 − λ_max²/ε²))) (the second term only when λ_max < ε/√2); with the defaults
(ε = 1e-2, λ_max = 5e-2) ‖J⁺_λ V‖ ≤ 100‖V‖. The null-space projector P_n = I − V_r V_rᵀ always uses the
numerical rank r, so J P_n = 0 holds whether or not a direction was damped. ``sigma_min`` is the smallest nonzero
singular value.

Fast path: when J has no more rows than columns and is well conditioned (σ_min ≥ ε and κ(J) ≤ 1e3), the
pseudo-inverse is Jᵀ(JJᵀ)⁻¹ computed from the symmetric eigendecomposition of the small m×m matrix JJᵀ (LAPACK
``dsyevd``), several times cheaper than the SVD of J; with κ² ≤ 1e6 it agrees with the SVD solve to ~1e-10
relative (tested at 1e-9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from redundik._kernel_cache import KernelNamespace
from redundik.errors import ResolverError


class _Kernels(KernelNamespace):
    """The compiled kernels of a module of :mod:`redundik.resolvers`, imported on first use (numba loads then, not
    when redundik is imported); after the first access every kernel is a plain attribute."""

    def __init__(self, module: str = "kernels") -> None:
        super().__init__(f"redundik.resolvers.{module}")


#: The compiled kernels (``K.closed_form``, ``K.spd_solve_box``, …).
K = _Kernels()
#: The fused step's kernels (:mod:`redundik.resolvers.fused_kernels`).
FK = _Kernels("fused_kernels")


def damped_inverse_values(s: np.ndarray, epsilon: float, max_damping: float, rcond: float) -> tuple[np.ndarray, int]:
    """The per-direction inverse of singular values ``s`` (descending) by this module's rule, and the rank
    (the compiled :func:`redundik.resolvers.kernels.damped_inverse_values`)."""
    inv, rank = K.damped_inverse_values(np.ascontiguousarray(s, dtype=float), epsilon, max_damping, rcond)
    return inv, int(rank)


__all__ = [
    "RCOND",
    "DampedSVD",
    "K",
    "PseudoInverse",
    "contiguous",
    "damped_inverse_values",
    "damped_svd",
    "gram_sigma_min",
    "pseudo_inverse",
]
#: Default relative threshold of the numerical rank.
RCOND = 1e-10


@lru_cache(maxsize=32)
def _identity(n: int) -> np.ndarray:
    eye = np.eye(n)
    eye.setflags(write=False)
    return eye


@dataclass(frozen=True)
class DampedSVD:
    """The damped SVD of one matrix M (m, n): solve, pseudo-inverse, null-space basis.

    Attributes:
        U: Left singular vectors (m, k), k = min(m, n).
        s: Singular values (k,), descending.
        Vt: Right singular vectors, all n rows (n, n).
        inv: Damped inverse values (k,) (this module's rule).
        rank: Numerical rank r.
        sigma_min: Smallest nonzero singular value (∞ when M = 0 or has no rows).
        damping: Largest λ_i used (0 when no direction was damped).
    """

    U: np.ndarray
    s: np.ndarray
    Vt: np.ndarray
    inv: np.ndarray
    rank: int
    sigma_min: float
    damping: float

    @property
    def damped(self) -> bool:
        """True when at least one direction was damped."""
        return self.damping > 0.0

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x = M⁺_λ rhs (the minimum-norm damped least-squares solution)."""
        k = self.s.shape[0]
        return self.Vt[:k].T @ (self.inv * (self.U.T @ rhs))

    @property
    def pinv(self) -> np.ndarray:
        """M⁺_λ (n, m)."""
        k = self.s.shape[0]
        return (self.Vt[:k].T * self.inv) @ self.U.T

    @property
    def null_basis(self) -> np.ndarray:
        """Orthonormal basis of the null space of M (n, n − r)."""
        return self.Vt[self.rank :].T


def damped_svd(M: np.ndarray, *, epsilon: float, max_damping: float, rcond: float = RCOND) -> DampedSVD:
    """The damped SVD of ``M`` by this module's rule (the one kernel of ``pinv``, ``feedback`` and ``hqp``)."""
    m, n = M.shape
    if m == 0 or n == 0:  # no rows, or no unknowns left (every joint pinned by its limits): nothing to factor
        return DampedSVD(np.zeros((m, 0)), np.zeros(0), np.eye(n), np.zeros(0), 0, np.inf, 0.0)
    U, s, Vt, inv, rank, sigma_min, damping = K.damped_svd_factors(contiguous(M), epsilon, max_damping, rcond)
    return DampedSVD(U, s, Vt, inv, int(rank), float(sigma_min), float(damping))


class PseudoInverse:
    """J⁺ (possibly damped) and the null-space projector of one Jacobian, factored but not formed.

    The hot path never forms the n×n matrices: :meth:`solve` gives J⁺_λ b and :meth:`null_project` gives
    P_n z = z − V_r V_rᵀ z from the factors of ``factor`` (the m×m eigendecomposition
    of JJᵀ on the fast path, the damped SVD otherwise). :attr:`pinv` and :attr:`null_projector` are formed on first
    access and cached.

    Attributes:
        n: Number of columns of J.
        rank: Numerical rank of J.
        sigma_min: Smallest nonzero singular value (∞ for an empty or zero J) [unit of J].
        damping: Largest λ_i used (0 when not damped).
        fast: True when the eigendecomposition of JJᵀ alone gave the factors (J of full row rank, well conditioned).
    """

    __slots__ = (
        "_J",
        "_U",
        "_Vt",
        "_d",
        "_inv",
        "_null",
        "_pinv",
        "checked",
        "damping",
        "fast",
        "n",
        "rank",
        "sigma_min",
    )

    def __init__(self, J: np.ndarray, epsilon: float, max_damping: float, rcond: float) -> None:
        fast, U, d, Vt, inv, rank, smin, damping = K.factor(J, epsilon, max_damping, rcond)
        self._J, self._U, self._Vt, self._d, self._inv = J, U, Vt, d, inv
        self.fast, self.rank, self.sigma_min, self.damping = bool(fast), int(rank), float(smin), float(damping)
        self.n = int(J.shape[1])
        self.checked = True  # solve / null_project check their argument (off for the resolvers' own rows)
        self._pinv: np.ndarray | None = None
        self._null: np.ndarray | None = None

    @property
    def damped(self) -> bool:
        """True when a direction was damped."""
        return self.damping > 0.0

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """J⁺_λ rhs for rhs of shape (m,) (minimum-norm, damped least squares), shape (n,)."""
        if self.checked:
            rhs = _real_array(rhs, 1, "rhs", self._J.shape[0])
        if self._J.shape[0] == 0:
            return np.zeros(self.n)
        return K.solve_factored(self.fast, self._J, self._U, self._inv, self._Vt, rhs)

    def null_project(self, z: np.ndarray) -> np.ndarray:
        """P_n z = (I − V_r V_rᵀ) z, the projection of z (n,) on the null space of J (numerical rank r)."""
        if self.checked:
            z = _real_array(z, 1, "z", self.n)
        return K.null_project_factored(self.fast, self._J, self._U, self._d, self._Vt, self.rank, z)

    @property
    def pinv(self) -> np.ndarray:
        """J⁺ or J⁺_λ, shape (n, m) (formed on first access)."""
        if self._pinv is None:
            m = self._J.shape[0]
            eye = np.eye(m)
            self._pinv = np.column_stack([self.solve(eye[:, j]) for j in range(m)]) if m else np.zeros((self.n, 0))
        return self._pinv

    @property
    def null_projector(self) -> np.ndarray:
        """P_n = I − V_r V_rᵀ for the numerical rank, shape (n, n) (formed on first access)."""
        if self._null is None:
            eye = np.eye(self.n)
            self._null = np.column_stack([self.null_project(eye[:, j]) for j in range(self.n)])
        return self._null

    def __repr__(self) -> str:
        return (
            f"PseudoInverse(n={self.n}, rank={self.rank}, sigma_min={self.sigma_min:.3g}, damping={self.damping:.3g})"
        )


def gram_sigma_min(J: np.ndarray) -> float:
    """σ_min of J (m ≥ 1 rows, full row rank) from the eigenvalues of JJᵀ: what a step that solved J by Cholesky
    reports when its diagnostics are read; NaN for a non-finite J (its step fell back, the fallback says why)."""
    if not np.isfinite(J).all():
        return math.nan
    return float(np.sqrt(max(float(np.linalg.eigvalsh(J @ J.T)[0]), 0.0)))


def contiguous(J: np.ndarray) -> np.ndarray:
    """J as a C-contiguous float array (one compiled specialisation of the kernels; no copy when it already is)."""
    return np.ascontiguousarray(J, dtype=float)


def pseudo_inverse(
    J: np.ndarray, *, epsilon: float = 1e-2, max_damping: float = 5e-2, rcond: float = RCOND
) -> PseudoInverse:
    """Pseudo-inverse with this module's damping rule (and its fast path), factored but not formed.

    Args:
        J: Matrix (m, n).
        epsilon: ε, the singular value under which a direction is damped [unit of J].
        max_damping: λ_max, the damping reached as σ → 0.
        rcond: Relative threshold of the numerical rank.

    Raises:
        ResolverError: J not a 2-D array of finite real numbers, or an option not a finite number ≥ 0.

    Returns:
        A :class:`PseudoInverse` (``solve``/``null_project`` for the hot path; ``pinv``/``null_projector`` formed on
        request).
    """
    options = {"epsilon": epsilon, "max_damping": max_damping, "rcond": rcond}
    for key, value in options.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ResolverError(f"pseudo_inverse: {key} must be a number, got {type(value).__name__}")
        if not (math.isfinite(value) and value >= 0):
            raise ResolverError(f"pseudo_inverse: {key} must be finite and ≥ 0, got {value}")
    return PseudoInverse(_real_array(J, 2, "J"), float(epsilon), float(max_damping), float(rcond))


def pseudo_inverse_unchecked(J: np.ndarray, epsilon: float, max_damping: float) -> PseudoInverse:
    """:func:`pseudo_inverse` for the resolvers' own rows: no input checks, so a non-finite row reaches the step's
    diagnosed fallback as a non-finite q̇ (the resolvers report it) instead of raising mid-step."""
    pi = PseudoInverse(contiguous(J), float(epsilon), float(max_damping), RCOND)
    pi.checked = False
    return pi


def _real_array(value: object, ndim: int, what: str, size: int | None = None) -> np.ndarray:
    """``value`` as a C-contiguous float array of ``ndim`` dimensions (and ``size`` entries when given), finite;
    else a :class:`ResolverError` saying what it got (a numba TypingError or a NaN output before)."""
    raw = value if isinstance(value, np.ndarray) else np.asarray(value) if isinstance(value, (list, tuple)) else None
    if raw is None or raw.dtype.kind not in "fiu":
        kind = type(value).__name__ if raw is None else f"{raw.dtype} array"
        raise ResolverError(f"pseudo_inverse: {what} must be an array of real numbers, got {kind}")
    if raw.ndim != ndim or (size is not None and raw.shape[0] != size):
        want = f"shape ({size},)" if size is not None else f"{ndim} dimensions"
        raise ResolverError(f"pseudo_inverse: {what} must have {want}, got shape {raw.shape}")
    arr = np.ascontiguousarray(raw, dtype=float)
    if not math.isfinite(float(np.add.reduce(arr, axis=None))) and not np.isfinite(arr).all():
        raise ResolverError(f"pseudo_inverse: {what} contains NaN or infinite values")
    return arr
