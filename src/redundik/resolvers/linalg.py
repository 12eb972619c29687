"""Generalised inverses (section 5.1) computed through the SVD, with a documented damping rule.

The Moore–Penrose pseudo-inverse J⁺ = V Σ⁺ Uᵀ satisfies the four conditions (5.4) and equals Jᵀ(JJᵀ)⁻¹ when J
has full row rank (the chapter's closed form), but unlike that closed form it stays defined when J loses rank.

Damping rule (damped least squares with a variable factor, Nakamura & Hanafusa 1986 / Chiaverini 1997):
with σ_min the smallest singular value among the m task directions and a threshold ε,

    λ² = 0                                   if σ_min ≥ ε,
    λ² = (1 − (σ_min/ε)²) · λ_max²           otherwise,

and J⁺_λ = V diag(σ_i / (σ_i² + λ²)) Uᵀ. Far from singularities the solution is the exact pseudo-inverse; near
one, ‖J⁺_λ‖ ≤ 1/(2λ) bounds the joint velocity. The null-space projector P_n = I − V_r V_rᵀ always uses the
numerical rank r (σ_i > rcond·σ_max), so J P_n = 0 holds whether or not the rank part was damped.

Fast path: when J has no more rows than columns and is well conditioned (σ_min ≥ ε and σ_min² > 1e-10·σ_max²),
the pseudo-inverse is the chapter's closed form J⁺ = Jᵀ(JJᵀ)⁻¹ (eq. 5.7), computed from the symmetric
eigendecomposition JJᵀ = U Λ Uᵀ of the small m×m matrix (LAPACK ``dsyevd``), which is several times cheaper than
the SVD of J; σ_min = √λ_min still decides the damping. Otherwise the SVD path above is used.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import lapack

#: Smallest λ_min/λ_max of JJᵀ for the eigendecomposition fast path (σ ratio 1e-5).
_FAST_PATH_RCOND = 1e-10


@lru_cache(maxsize=32)
def _identity(n: int) -> np.ndarray:
    eye = np.eye(n)
    eye.setflags(write=False)
    return eye


@dataclass(frozen=True)
class PseudoInverse:
    """J⁺ (possibly damped) and the null-space projector of one Jacobian.

    Attributes:
        pinv: J⁺ or J⁺_λ, shape (n, m).
        null_projector: P_n = I − J⁺J for the undamped numerical rank, shape (n, n).
        rank: Numerical rank of J.
        sigma_min: Smallest singular value among min(m, n) (0 if J has fewer columns than rows' rank).
        damping: λ (0 when not damped).
    """

    pinv: np.ndarray
    null_projector: np.ndarray
    rank: int
    sigma_min: float
    damping: float

    @property
    def damped(self) -> bool:
        """True when λ > 0."""
        return self.damping > 0.0


def pseudo_inverse(
    J: np.ndarray, *, epsilon: float = 1e-2, max_damping: float = 5e-2, rcond: float = 1e-10
) -> PseudoInverse:
    """Pseudo-inverse with the variable damping rule of this module's docstring.

    Args:
        J: Matrix (m, n).
        epsilon: ε, the singular value under which damping starts.
        max_damping: λ_max, the damping reached at σ_min = 0.
        rcond: Relative threshold of the numerical rank.

    Returns:
        A :class:`PseudoInverse`.
    """
    m, n = J.shape
    if m == 0:
        return PseudoInverse(np.zeros((n, 0)), np.eye(n), 0, np.inf, 0.0)
    if m <= n:
        lam, U, info = lapack.dsyevd(J @ J.T)  # ascending eigenvalues of JJᵀ
        if info == 0 and lam[-1] > 0 and lam[0] > _FAST_PATH_RCOND * lam[-1]:
            sigma_min = float(np.sqrt(lam[0]))
            if sigma_min >= epsilon:
                pinv = ((J.T @ U) / lam) @ U.T  # Jᵀ U Λ⁻¹ Uᵀ = Jᵀ(JJᵀ)⁻¹
                return PseudoInverse(pinv, _identity(n) - pinv @ J, m, sigma_min, 0.0)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)  # s sorted descending, size k = min(m, n)
    smax = s[0] if s.size else 0.0
    rank = int(np.sum(s > rcond * max(smax, 1e-300))) if smax > 0 else 0
    sigma_min = float(s[-1])
    lam2 = 0.0
    if sigma_min < epsilon and epsilon > 0:
        lam2 = (1.0 - (sigma_min / epsilon) ** 2) * max_damping**2
    if lam2 > 0:
        inv_s = s / (s * s + lam2)
    else:
        inv_s = np.zeros_like(s)
        inv_s[:rank] = 1.0 / s[:rank]
    pinv = (Vt.T * inv_s) @ U.T
    Vr = Vt[:rank]
    null = np.eye(n) - Vr.T @ Vr
    return PseudoInverse(pinv, null, rank, sigma_min, float(np.sqrt(lam2)))
