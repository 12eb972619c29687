"""Compiled linear algebra of ``hqp``'s cascades (numba): the Householder QR and its certificate that nothing would
be damped, the level's weighted rows, the products with a null-space basis Z and with the complement W, the ridge
solution from a triangular factor.

A level's least squares is over q̇ = x + Z u (Z: orthonormal columns spanning the directions the levels above left
free). Where the QR of (A_k Z)ᵀ certifies σ_min ≥ ε (:func:`qr_certificate`), the damped pseudo-inverse of
:mod:`redundik.resolvers.linalg` leaves every direction exact: the QR then gives the same M⁺ and null basis,
several times cheaper than the SVD (``kernels.damped_svd_factors``, the one implementation of the damping rule).
"""

from __future__ import annotations

import math

import numpy as np

from redundik.resolvers.kernels import _jit, _reflect, householder_reflectors


@_jit
def householder_qr(B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B = Q[:, :q] R for B (p, q), p ≥ q, by Householder reflections H = I − 2vvᵀ/vᵀv: Q (p, p) orthogonal,
    R (q, q) upper triangular (its diagonal may be zero or negative; no pivoting)."""
    p, q = B.shape
    W = B.copy()
    Q = np.eye(p)
    v = np.empty(p)
    for j in range(q):
        nrm2 = 0.0
        for i in range(j, p):
            nrm2 += W[i, j] * W[i, j]
        if nrm2 == 0.0:
            continue
        alpha = -math.sqrt(nrm2) if W[j, j] >= 0.0 else math.sqrt(nrm2)  # reflect x onto −sign(x_0)‖x‖ e_0
        vv = 0.0
        for i in range(j, p):
            v[i] = W[i, j]
        v[j] -= alpha
        for i in range(j, p):
            vv += v[i] * v[i]
        if vv == 0.0:
            continue
        for c in range(j, q):  # W ← H W
            t = 0.0
            for i in range(j, p):
                t += v[i] * W[i, c]
            f = 2.0 * t / vv
            for i in range(j, p):
                W[i, c] -= f * v[i]
        for r in range(p):  # Q ← Q H
            t = 0.0
            for i in range(j, p):
                t += Q[r, i] * v[i]
            f = 2.0 * t / vv
            for i in range(j, p):
                Q[r, i] -= f * v[i]
    R = np.zeros((q, q))
    for i in range(q):
        for c in range(i, q):
            R[i, c] = W[i, c]
    return Q, R


@_jit
def upper_inverse(R: np.ndarray) -> tuple[np.ndarray, bool]:
    """R⁻¹ of an upper triangular R (q, q) by back substitution; False (and zeros) when a diagonal entry is 0."""
    q = R.shape[0]
    Ri = np.zeros((q, q))
    for i in range(q):
        if R[i, i] == 0.0 or not math.isfinite(R[i, i]):
            return Ri, False
    for c in range(q):
        Ri[c, c] = 1.0 / R[c, c]
        for i in range(c - 1, -1, -1):
            t = 0.0
            for k in range(i + 1, c + 1):
                t += R[i, k] * Ri[k, c]
            Ri[i, c] = -t / R[i, i]
    return Ri, True


@_jit
def qr_certificate(R: np.ndarray, Ri: np.ndarray, epsilon: float, rcond: float) -> bool:
    """True when every singular value σ of R is ≥ ε and > rcond·σ_max, so that the damping rule of
    :mod:`redundik.resolvers.linalg` leaves every direction exact (1/σ) and the rank full.

    From σ_min ≥ 1/‖R⁻¹‖_F and σ_max ≤ ‖R‖_F (‖·‖₂ ≤ ‖·‖_F): a sufficient test, two Frobenius norms.
    """
    fr = 0.0
    fi = 0.0
    for i in range(R.shape[0]):
        for c in range(R.shape[1]):
            fr += R[i, c] * R[i, c]
            fi += Ri[i, c] * Ri[i, c]
    if not (fi > 0.0) or not math.isfinite(fi) or not math.isfinite(fr):
        return False
    lo = 1.0 / math.sqrt(fi)
    return lo >= epsilon and lo > rcond * math.sqrt(fr)


@_jit
def identity_rows(A: np.ndarray, w: np.ndarray, s: int, n: int, epsilon: float) -> bool:
    """True when the rows A[s:s + n] are exactly the identity I (n, n) with one weight w for all of them and
    √w ≥ ε (with a relative margin of 1e-9): the level's least squares ‖√w (q̇ − b)‖² restricted to an orthonormal
    basis Z has the singular values √w only, none of them damped by the rule of :mod:`redundik.resolvers.linalg`."""
    w0 = w[s]
    if not (math.sqrt(w0) >= epsilon * (1.0 + 1e-9)):  # (false for a NaN or negative weight)
        return False
    for i in range(n):
        if w[s + i] != w0:
            return False
        for j in range(n):
            if A[s + i, j] != (1.0 if i == j else 0.0):
                return False
    return True


@_jit
def _level_scale(w: np.ndarray, s: int, e: int) -> float:
    """√ of the largest weight of the rows s..e (``Level.scale``; 1 when none is > 0): the damping rule relative to
    the level's scale, so that scaling every row of a level leaves its optimum unchanged."""
    wmax = 0.0
    for i in range(s, e):
        if w[i] > wmax:
            wmax = w[i]
    return math.sqrt(wmax) if wmax > 0.0 else 1.0


@_jit
def _projection(x: np.ndarray, Z: np.ndarray, r: int, v: np.ndarray, s: int) -> np.ndarray:
    """Z Zᵀ(v[s:s + n] − x) (n,): the step to the target v projected on the basis Z (its first r columns)."""
    n = x.shape[0]
    t = np.zeros(r)
    for i in range(n):
        vi = v[s + i] - x[i]
        for j in range(r):
            t[j] += Z[i, j] * vi
    out = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(r):
            acc += Z[i, j] * t[j]
        out[i] = acc
    return out


@_jit
def _weighted_rows(
    A: np.ndarray, b: np.ndarray, w: np.ndarray, s: int, m: int, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The rows s..s + m as √w A and the residual target √w b − √w A x."""
    n = x.shape[0]
    Ak = np.empty((m, n))
    rhs = np.empty(m)
    for i in range(m):
        wi = w[s + i]
        sc = math.sqrt(wi) if wi != 1.0 else 1.0
        acc = 0.0
        for j in range(n):
            a = A[s + i, j] * sc if wi != 1.0 else A[s + i, j]
            Ak[i, j] = a
            acc += a * x[j]
        bi = b[s + i] * sc if wi != 1.0 else b[s + i]
        rhs[i] = bi - acc
    return Ak, rhs


@_jit
def _times_basis(Ak: np.ndarray, Z: np.ndarray, r: int) -> np.ndarray:
    """A Z (m, r) for the basis Z's first r columns (zero entries of A skipped)."""
    m, n = Ak.shape
    M = np.zeros((m, r))
    for i in range(m):
        for l in range(n):
            a = Ak[i, l]
            if a != 0.0:
                for j in range(r):
                    M[i, j] += a * Z[l, j]
    return M


@_jit
def _add_basis_step(x: np.ndarray, Z: np.ndarray, r: int, u: np.ndarray) -> None:
    """x ← x + Z u for the basis Z's first r columns."""
    for i in range(x.shape[0]):
        acc = 0.0
        for c in range(r):
            acc += Z[i, c] * u[c]
        x[i] += acc


@_jit
def _basis_product(Z: np.ndarray, r: int, N: np.ndarray, rp: int) -> np.ndarray:
    """Z·N (n, rp): the basis Z (first r columns) times the null basis N (r, rp) of a level's projected rows."""
    n = Z.shape[0]
    T = np.zeros((n, rp))
    for i in range(n):
        for c in range(r):
            zic = Z[i, c]
            if zic != 0.0:
                for j in range(rp):
                    T[i, j] += zic * N[c, j]
    return T


@_jit
def _certified_null(M: np.ndarray, epsilon: float, rcond: float, N: np.ndarray, rrow: np.ndarray) -> bool:
    """For M (m, r), m ≤ r, the Householder QR Mᵀ = Q [R; 0] when it certifies σ_min(M) ≥ ε and the full rank
    (:func:`qr_certificate`: what the damped SVD would leave undamped): Q₂ = Q[:, m:] (null(M), orthonormal)
    into N[:r, :r − m], Q₁ into N[:r, r − m : r], R row by row into rrow[:m²]; False (nothing written that is
    read) otherwise."""
    m, r = M.shape
    Q, R = householder_qr(np.ascontiguousarray(M.T))
    Ri, ok = upper_inverse(R)
    if not ok or not qr_certificate(R, Ri, epsilon, rcond):
        return False
    for i in range(r):
        for j in range(r - m):
            N[i, j] = Q[i, m + j]
        for j in range(m):
            N[i, r - m + j] = Q[i, j]
    for i in range(m):
        for j in range(m):
            rrow[i * m + j] = R[i, j]
    return True


@_jit
def _certified_rows(M: np.ndarray, epsilon: float, rcond: float, N: np.ndarray, rrow: np.ndarray) -> bool:
    """:func:`_certified_null` for the complement mode, M (m, n) with m ≤ n: the thin Householder QR Mᵀ = Q₁R
    (Q₁ (n, m) formed from the reflections alone, O(n m²) — no n × n Q) when it certifies σ_min(M) ≥ ε; Q₁ᵀ, an
    orthonormal basis of M's row space (the SVD's Vt[:m] up to a rotation), into N[:m, :n], R into rrow[:m²]."""
    m, n = M.shape
    W = np.ascontiguousarray(M.T).copy()  # (n, m), reduced in place to R
    V, beta = householder_reflectors(W, m)
    R = np.zeros((m, m))
    for i in range(m):
        for c in range(i, m):
            R[i, c] = W[i, c]
    Ri, ok = upper_inverse(R)
    if not ok or not qr_certificate(R, Ri, epsilon, rcond):
        return False
    Q1 = np.zeros((n, m))  # H_0 ⋯ H_{m−1} [I; 0], from the last reflection on (H_j leaves the columns < j alone)
    for i in range(m):
        Q1[i, i] = 1.0
    for j in range(m - 1, -1, -1):
        if beta[j] != 0.0:
            _reflect(V[j], beta[j], Q1, j, j)
    for i in range(m):
        for j in range(n):
            N[i, j] = Q1[j, i]
        for j in range(m):
            rrow[i * m + j] = R[i, j]
    return True


@_jit
def _ridge_triangular(rrow: np.ndarray, m: int, rhs: np.ndarray, eps: float) -> np.ndarray:
    """t = argmin ‖Rᵀt − rhs‖² + ε‖t‖² for R (m, m) upper triangular, stored row by row in rrow[:m²]: the
    Householder QR of [Rᵀ; √ε I] (2m, m) applied to [rhs; 0] and back substitution (no normal equations: the
    accuracy of the SVD's σ/(σ² + ε), without squaring R's condition number)."""
    B = np.zeros((2 * m, m + 1))  # [Rᵀ rhs; √ε I 0]: the right-hand side as its last column
    se = math.sqrt(eps)
    for i in range(m):
        for j in range(i + 1):
            B[i, j] = rrow[j * m + i]  # Rᵀ: lower triangular
        B[m + i, i] = se
        B[i, m] = rhs[i]
    householder_reflectors(B, m)
    t = np.zeros(m)
    for i in range(m - 1, -1, -1):
        acc = B[i, m]
        for j in range(i + 1, m):
            acc -= B[i, j] * t[j]
        t[i] = acc / B[i, i]
    return t


@_jit
def _complement_projection(v: np.ndarray, Z: np.ndarray, nw: int) -> np.ndarray:
    """(I − WᵀW) v (n,): v projected on null(W), W the complement's nw rows (kept in ``Z``'s rows)."""
    n = v.shape[0]
    out = v.copy()
    for i in range(nw):
        acc = 0.0
        for j in range(n):
            acc += Z[i, j] * v[j]
        if acc != 0.0:
            for j in range(n):
                out[j] -= acc * Z[i, j]
    return out
