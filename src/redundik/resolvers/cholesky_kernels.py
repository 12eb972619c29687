"""Compiled Cholesky solves (numba): x = −P⁻¹q for a weighted QP's Hessian with only its coupled block factored
(``coupled_coordinates`` finds the coordinates with no off-diagonal entry), the unblocked factorisation and
triangular solves, and the weighted rows P += w JᵀJ, q −= w Jᵀv that make P and q."""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Largest SPD block :func:`spd_solve_into` factors in plain loops; LAPACK's ``dpotrf`` above.
CHOLESKY_LOOPS_MAX = 48


@_jit
def _chol_in_place(A: np.ndarray) -> bool:
    """A ← L (lower triangle) with A = L Lᵀ, unblocked; False when A is not numerically positive definite."""
    m = A.shape[0]
    for j in range(m):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not (s > 0.0):
            return False
        ljj = math.sqrt(s)
        A[j, j] = ljj
        for i in range(j + 1, m):
            t = A[i, j]
            for k in range(j):
                t -= A[i, k] * A[j, k]
            A[i, j] = t / ljj
    return True


@_jit
def _chol_solve(L: np.ndarray, b: np.ndarray, y: np.ndarray) -> None:
    """y = (L Lᵀ)⁻¹ b from the lower factor L, into ``y`` (which may be ``b`` itself: each entry of b is read
    before it is overwritten)."""
    m = L.shape[0]
    for i in range(m):
        t = b[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(m - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, m):
            t -= L[k, i] * y[k]
        y[i] = t / L[i, i]


@_jit
def gram_update(P: np.ndarray, q: np.ndarray, J: np.ndarray, v: np.ndarray, w: float, reset: bool) -> None:
    """P += w JᵀJ and q −= w Jᵀv in place (P (n, n), q (n,), J (m, n), v (m,)): one task's rows of a weighted QP;
    ``reset``: P and q are zeroed first (the first task of a step)."""
    m, n = J.shape
    if reset:
        P[:, :] = 0.0
        q[:] = 0.0
    for a in range(m):
        va = w * v[a]
        for i in range(n):
            ji = w * J[a, i]
            if ji != 0.0:
                q[i] -= J[a, i] * va
                for j in range(n):
                    P[i, j] += ji * J[a, j]


@_jit
def gram_diagonal_matches(F: np.ndarray, shift: float, diag: np.ndarray, rtol: float) -> bool:
    """diag(FᵀF) + shift equals ``diag`` to ``rtol`` relative (NumPy's ``allclose`` rule, |a − b| ≤ atol + rtol |b|,
    with atol = 1e-12·max|diag(FᵀF) + shift|, at least 1e-12): the test that a weighted QP's Hessian is the one its
    rows FᵀF + δI make (``wqp``'s lifted factor), in one pass."""
    m, n = F.shape
    if diag.shape[0] != n:
        return False
    g = np.empty(n)
    big = 1.0
    for j in range(n):
        t = shift
        for i in range(m):
            t += F[i, j] * F[i, j]
        g[j] = t
        if abs(t) > big or t != t:
            big = abs(t)
    atol = 1e-12 * big
    for j in range(n):
        if not abs(g[j] - diag[j]) <= atol + rtol * abs(diag[j]):
            return False
    return True


@_jit
def coupled_coordinates(P: np.ndarray, idx: np.ndarray, lower: bool) -> int:
    """The coupled coordinates of P (n, n), written in ascending order into ``idx[:n_c]``; returns n_c.

    Coordinate i is separable when P_ii > 0 and the off-diagonal entries of row i and column i of P are zero (a NaN
    counts as non-zero), coupled otherwise: its part of ½xᵀPx + qᵀx is then ½P_ii x_i² + q_i x_i, decoupled from
    the rest of any problem in P (Talos's legs, head and grippers under a posture and two hand tasks: 16 of its 38
    coordinates). With ``lower`` only the lower triangle is read — P_ij for j < i and P_ki for k > i, the entries
    a Cholesky factorisation reads of a symmetric P (:func:`spd_solve_into`) —, else both triangles (daqp's split of
    bounds-only QPs, :func:`split_separable`). The one implementation of this test.

    Cost: the scan of a row stops at its first off-diagonal non-zero (one or two reads per row of a dense P), a
    separable coordinate takes n − 1 reads (2(n − 1) without ``lower``): O(n) on a dense P, O(n²) at most.
    """
    n = P.shape[0]
    nc = 0
    for i in range(n):
        coupled = not P[i, i] > 0.0
        if not coupled:
            for j in range(i):
                if P[i, j] != 0.0:
                    coupled = True
                    break
        if not coupled:
            for k in range(i + 1, n):
                if P[k, i] != 0.0:
                    coupled = True
                    break
        if not coupled and not lower:
            for j in range(i + 1, n):
                if P[i, j] != 0.0:
                    coupled = True
                    break
            if not coupled:
                for k in range(i):
                    if P[k, i] != 0.0:
                        coupled = True
                        break
        if coupled:
            idx[nc] = i
            nc += 1
    return nc


@_jit
def _all_finite(x: np.ndarray) -> bool:
    """True when every entry of x is finite."""
    ok = True
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            ok = False
    return ok


@_jit
def _cholesky_solve_neg(L: np.ndarray, q: np.ndarray, x: np.ndarray) -> None:
    """x = −(L Lᵀ)⁻¹ q from a lower factor L (LAPACK's)."""
    n = q.shape[0]
    y = np.empty(n)
    for i in range(n):  # L y = −q
        t = -q[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        t = y[i]
        for k in range(i + 1, n):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]


@_jit
def _spd_solve_full(P: np.ndarray, q: np.ndarray, x: np.ndarray, buf: np.ndarray) -> bool:
    """:func:`spd_solve_into` by a Cholesky factorisation of the whole of P (no separable coordinate, or the split
    solve failed); ``buf`` (≥ 2n + n², or 2n beyond :data:`CHOLESKY_LOOPS_MAX`) is scratch: y in buf[n:2n],
    the factor's rows from buf[2n] on."""
    n = q.shape[0]
    o = 2 * n
    if n > CHOLESKY_LOOPS_MAX:
        try:
            L = np.linalg.cholesky(P)
        except Exception:  # not positive definite
            x[:] = 0.0
            return False
        _cholesky_solve_neg(L, q, x)
        return _all_finite(x)
    L = buf[o : o + n * n].reshape((n, n))  # (only its lower triangle is written and read)
    y = buf[n:o]
    for j in range(n):
        s = P[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0):
            x[:] = 0.0
            return False
        ljj = math.sqrt(s)
        L[j, j] = ljj
        for i in range(j + 1, n):
            t = P[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / ljj
    for i in range(n):  # L y = −q
        t = -q[i]
        for k in range(i):
            t -= L[i, k] * y[k]
        y[i] = t / L[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        t = y[i]
        for k in range(i + 1, n):
            t -= L[k, i] * x[k]
        x[i] = t / L[i, i]
    return _all_finite(x)


@_jit
def _spd_solve_split(P: np.ndarray, q: np.ndarray, nc: int, x: np.ndarray, buf: np.ndarray) -> bool:
    """:func:`spd_solve_into` with the coupled coordinates buf[:nc] (``coupled_coordinates``, stored as floats)
    solved by a Cholesky factorisation of their block P_cc alone, and each separable one as x_i = (−q_i/√P_ii)/√P_ii;
    false (x then undefined) when P_cc is not numerically SPD or x is not finite. ``buf`` (≥ 2n + n_c², or 2n beyond
    :data:`CHOLESKY_LOOPS_MAX`) is scratch:
    y in buf[n:n + n_c], the factor's rows from buf[2n] on.

    With n_c ≤ :data:`CHOLESKY_LOOPS_MAX` the arithmetic is the full factorisation's minus its exact zeros: the
    factor of P is zero off the diagonal in a separable row and column (every entry there is (0 − Σ 0·ℓ)/ℓ_jj), so
    the full loops only add and subtract exact zeros outside P_cc's factor and compute x_i as (−q_i/ℓ_ii)/ℓ_ii with
    ℓ_ii = √P_ii — the same x, bit for bit, whenever the answer is finite (every factor entry is then finite or, on
    the diagonal, only a divisor).
    """
    n = q.shape[0]
    o = 2 * n
    k = 0
    for i in range(n):  # the separable coordinates
        if k < nc and int(buf[k]) == i:
            k += 1
            continue
        lii = math.sqrt(P[i, i])
        x[i] = (-q[i] / lii) / lii
        if not math.isfinite(x[i]):
            return False
    if nc == 0:
        return True
    if nc > CHOLESKY_LOOPS_MAX:
        Pc = np.empty((nc, nc))
        qc = np.empty(nc)
        for a in range(nc):
            qc[a] = q[int(buf[a])]
            for b in range(nc):
                Pc[a, b] = P[int(buf[a]), int(buf[b])]
        try:
            L = np.linalg.cholesky(Pc)
        except Exception:  # not positive definite
            return False
        xc = np.empty(nc)
        _cholesky_solve_neg(L, qc, xc)
        if not _all_finite(xc):
            return False
        for a in range(nc):
            x[int(buf[a])] = xc[a]
        return True
    L = buf[o : o + nc * nc].reshape((nc, nc))  # (only its lower triangle is written and read)
    y = buf[n : n + nc]
    for b in range(nc):
        j = int(buf[b])
        s = P[j, j]
        for k in range(b):
            s -= L[b, k] * L[b, k]
        if not (s > 0.0):
            return False
        lbb = math.sqrt(s)
        L[b, b] = lbb
        for a in range(b + 1, nc):
            t = P[int(buf[a]), j]
            for k in range(b):
                t -= L[a, k] * L[b, k]
            L[a, b] = t / lbb
    for a in range(nc):  # L y = −q_c
        t = -q[int(buf[a])]
        for k in range(a):
            t -= L[a, k] * y[k]
        y[a] = t / L[a, a]
    for a in range(nc - 1, -1, -1):  # Lᵀ x_c = y, in place
        t = y[a]
        for k in range(a + 1, nc):
            t -= L[k, a] * y[k]
        t /= L[a, a]
        if not math.isfinite(t):
            return False
        y[a] = t
    for a in range(nc):
        x[int(buf[a])] = y[a]
    return True


@_jit
def spd_solve_into(P: np.ndarray, q: np.ndarray, x: np.ndarray) -> bool:
    """x = −P⁻¹ q by Cholesky into ``x`` (P (n, n) symmetric positive definite, its lower triangle read); false when
    P is not numerically SPD (x is then zero) or x is not finite.

    The separable coordinates of P (``coupled_coordinates``) are solved in closed form and only the coupled
    block is factored (``_spd_solve_split``: the same x, bit for bit, for n_c ≤ :data:`CHOLESKY_LOOPS_MAX`): the
    factorisation's O(n³) shrinks to O(n_c³), and a dense P pays only the detection's few reads per row. When that
    solve fails, or no coordinate is separable, the whole of P is factored, so that every failure (non-finite data,
    P not SPD) is the full factorisation's, x included.

    Unblocked loops up to :data:`CHOLESKY_LOOPS_MAX` coordinates, where they are faster than LAPACK's call, LAPACK
    ``dpotrf`` (``np.linalg.cholesky``) above.
    """
    n = q.shape[0]
    m = min(n, CHOLESKY_LOOPS_MAX)  # (a larger block is factored by LAPACK, into its own array)
    buf = np.empty(2 * n + m * m)  # (one scratch allocation: the coupled indices, y and the factor)
    nc = coupled_coordinates(P, buf, True)
    if nc < n and _spd_solve_split(P, q, nc, x, buf):
        return True
    return _spd_solve_full(P, q, x, buf)


@_jit
def spd_solve(P: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, bool]:
    """x = −P⁻¹ q by Cholesky (:func:`spd_solve_into`); ``ok`` false when P is not numerically SPD."""
    x = np.empty(q.shape[0])
    ok = spd_solve_into(P, q, x)
    return x, ok
