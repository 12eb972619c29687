"""Compiled level QPs of ``hqp``'s constrained cascade (numba): a level's QP over the step in the null space of the
levels above, written into one flat buffer in daqp's form (:func:`qp_views`), posed over the basis Z
(:func:`level_qp_into`) or in joint space for the complement mode (:func:`level_qp_joint_into`); the test that a
candidate step keeps the level's rows (:func:`level_rows_ok`); the buffer's sizes.

The arguments are records (tuples, :mod:`redundik.resolvers.hqp_layout`): ``box`` = (lb, ub, free), ``level`` =
(C, d) the level's inequality rows, ``fixed`` = (F, f) the rows fixed by the levels above, ``ls`` the level's least
squares, ``basis`` = (Z, mode, sel).
"""

from __future__ import annotations

import math

import numpy as np

from redundik.resolvers.hqp_layout import META_INEQ, META_LS, Basis, Box, JointLeastSquares, LeastSquares, Rows
from redundik.resolvers.kernels import _jit


@_jit
def level_rows_ok(
    step: np.ndarray, x: np.ndarray, box: Box, native: bool, level: Rows, fixed: Rows, margin: float, tol: float
) -> bool:
    """Whether q̇ = x + step keeps the rows of an ``hqp`` level QP (``HierarchicalQPResolver._level_feasible``);
    ``box`` = (lb, ub, free), ``level`` = (C, d) the level's rows, ``fixed`` = (F, f) the rows fixed above.

    The level's own inequalities C(x + step) ≤ d + tol (slack w = 0); the levels above F step ≤ max(f − F x, 0) +
    margin + tol; the free joints' limits, as native bounds lb − x − tol ≤ step ≤ ub − x + tol (``native``: the
    first level, Z = I on the free joints) or as the rows ±step_j ≤ max(±(ub_j or lb_j) − x_j), 0) + margin + tol.
    """
    lb, ub, free = box
    C, d = level
    F, f = fixed
    n = x.shape[0]
    for i in range(C.shape[0]):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * (x[j] + step[j])
        if acc > d[i] + tol:
            return False
    for i in range(F.shape[0]):
        a = 0.0
        b = 0.0
        for j in range(n):
            a += F[i, j] * step[j]
            b += F[i, j] * x[j]
        if a > max(f[i] - b, 0.0) + margin + tol:
            return False
    for j in range(n):
        if not free[j]:
            continue
        if native:
            if step[j] < lb[j] - x[j] - tol or step[j] > ub[j] - x[j] + tol:
                return False
        else:
            if math.isfinite(ub[j]) and step[j] > max(ub[j] - x[j], 0.0) + margin + tol:
                return False
            if math.isfinite(lb[j]) and -step[j] > max(x[j] - lb[j], 0.0) + margin + tol:
                return False
    return True


@_jit
def _project_row(row: np.ndarray, out: np.ndarray, mode: int, sel: np.ndarray, Z: np.ndarray, r: int) -> None:
    """out[:r] = row Z for a row (n,): Z = I (mode 0), I on the joints ``sel`` (1), or the basis Z (2)."""
    if mode == 0:
        for j in range(r):
            out[j] = row[j]
    elif mode == 1:
        for j in range(r):
            out[j] = row[sel[j]]
    else:
        n = row.shape[0]
        for j in range(r):
            acc = 0.0
            for i in range(n):
                acc += row[i] * Z[i, j]
            out[j] = acc


@_jit
def qp_buffer_size(n: int, p_max: int, rows: int) -> int:
    """Length of a flat buffer that holds any level QP of :func:`level_qp_into` for n joints, at most ``p_max``
    inequality rows a level and ``rows`` in all (the levels above, fixed, are among them)."""
    nvar, nr = n + p_max, p_max + rows + 2 * n
    return nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)


@_jit
def cascade_qp_dims(n: int, meta: np.ndarray) -> tuple[int, int, int]:
    """(most variables, most rows) of a level QP of :func:`level_qp_into` or :func:`level_qp_joint_into` for the
    levels packed in ``meta`` (their least-squares rows start at ``meta[META_LS]``, their inequality rows at
    ``meta[META_INEQ]``),
    and the most least-squares rows of a level."""
    L = meta.shape[1] - 1
    p_max = 0
    m_max = 0
    for k in range(L):
        p_max = max(p_max, meta[META_INEQ, k + 1] - meta[META_INEQ, k])
        m_max = max(m_max, meta[META_LS, k + 1] - meta[META_LS, k])
    return n + p_max + m_max, p_max + meta[META_INEQ, L] + 2 * n + m_max, m_max


@_jit
def cascade_qp_size(n: int, meta: np.ndarray) -> int:
    """Length of a buffer (the layout of :func:`qp_views`) that holds any level QP of the levels packed in
    ``meta``."""
    nvar, nr, _ = cascade_qp_dims(n, meta)
    return nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr)


@_jit
def qp_views(buf: np.ndarray, nvar: int, nr: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(P (nvar, nvar), q (nvar), G (nr, nvar), upper (nvar + nr), lower (nvar + nr)): the level QP in ``buf``, as
    views in daqp's form — the bounds on the variables first, then the rows' (their lower bounds −∞)."""
    a = nvar * nvar
    b = a + nvar
    c = b + nr * nvar
    d = c + nvar + nr
    return (
        buf[0:a].reshape((nvar, nvar)),
        buf[a:b],
        buf[b:c].reshape((nr, nvar)),
        buf[c:d],
        buf[d : d + nvar + nr],
    )


@_jit
def _slack_rows(G: np.ndarray, P: np.ndarray, q: np.ndarray, h: np.ndarray, level: Rows, x: np.ndarray, o: int) -> None:
    """The level's rows C(x + step) − w' ≤ d + w₀ with their slacks w' (the variables from ``o``): G's row k gets −1
    at o + k, P and q the slack's ½‖w'‖² + w₀ᵀw', h the bound (d − C x) + w₀, w₀ = max(C x − d, 0). The rows'
    step part of G is the caller's."""
    C, d = level
    n = x.shape[0]
    for k in range(C.shape[0]):
        G[k, o + k] = -1.0
        cx = 0.0
        for j in range(n):
            cx += C[k, j] * x[j]
        s0 = d[k] - cx
        w0 = max(-s0, 0.0)
        P[o + k, o + k] = 1.0
        q[o + k] = w0
        h[k] = s0 + w0


@_jit
def _fixed_bounds(h: np.ndarray, fixed: Rows, x: np.ndarray, p: int, tol: float) -> None:
    """The bounds max(f − F x, 0) + tol of the rows fixed above, into h from row p."""
    F, f = fixed
    n = x.shape[0]
    for k in range(F.shape[0]):
        fx = 0.0
        for j in range(n):
            fx += F[k, j] * x[j]
        h[p + k] = max(f[k] - fx, 0.0) + tol


@_jit
def _basis_limits(G: np.ndarray, h: np.ndarray, x: np.ndarray, Z: np.ndarray, box: Box, o: int, tol: float) -> None:
    """The limits of the free joints with a finite bound as rows of the basis Z (r columns) from row o:
    Z_j u ≤ max(ub_j − x_j, 0) + tol (upper bounds first), −Z_j u ≤ max(x_j − lb_j, 0) + tol."""
    lb, ub, free = box
    n, r = Z.shape[0], Z.shape[1]
    for i in range(n):
        if free[i] and math.isfinite(ub[i]):
            for j in range(r):
                G[o, j] = Z[i, j]
            h[o] = max(ub[i] - x[i], 0.0) + tol
            o += 1
    for i in range(n):
        if free[i] and math.isfinite(lb[i]):
            for j in range(r):
                G[o, j] = -Z[i, j]
            h[o] = max(x[i] - lb[i], 0.0) + tol
            o += 1


@_jit
def level_qp_into(
    ls: LeastSquares, level: Rows, x: np.ndarray, basis: Basis, fixed: Rows, box: Box, tol: float, buf: np.ndarray
) -> tuple[int, int]:
    """One ``hqp`` level QP over (u, w') (module docstring of :mod:`redundik.resolvers.qp.hqp`) into ``buf``, in the
    layout of :func:`qp_views` (P, q, G, upper = (u_b, h), lower = (l, −∞)):

        minimise  ½ uᵀ(MᵀM + εI)u − (Mᵀ rhs)ᵀu + ½‖w'‖² + w₀ᵀw'
        subject to  C Z u − w' ≤ (d − C x) + w₀,  w₀ = max(C x − d, 0)          (the level's rows, w = w₀ + w')
                    F Z u ≤ max(f − F x, 0) + tol                              (the levels above)
                    l ≤ (u, w') ≤ u_b  and, below the first level, ±Z_j u ≤ max(±(ub_j or lb_j) − x_j), 0) + tol

    ``ls`` = (M, rhs, ε), ``level`` = (C, d), ``basis`` = (Z, mode, sel), ``fixed`` = (F, f), ``box`` = (lb, ub,
    free). ``mode``: 0 — Z = I (``Z`` not read), native bounds lb − x ≤ u ≤ ub − x; 1 — Z = I on the joints ``sel``
    (native bounds on those); 2 — the limits of the ``free`` joints with a finite bound as rows of Z. M has r
    columns (r = n in mode 0) and no rows for a level without least squares.

    Returns:
        (nvar, nr): the variables (u, w') and the rows of G.
    """
    M, rhs, eps = ls
    C = level[0]
    Z, mode, sel = basis
    F = fixed[0]
    lb, ub, free = box
    n = x.shape[0]
    r = M.shape[1]
    p = C.shape[0]
    nvar = r + p
    nfu = 0
    nfl = 0
    if mode == 2:
        for j in range(n):
            if free[j] and math.isfinite(ub[j]):
                nfu += 1
            if free[j] and math.isfinite(lb[j]):
                nfl += 1
    nf = F.shape[0]
    nr = p + nf + nfu + nfl
    if buf.shape[0] < nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr):
        raise ValueError("level_qp_into: the QP buffer is too small for this level")
    P, q, G, up, low = qp_views(buf, nvar, nr)
    P[:, :] = 0.0
    q[:] = 0.0
    G[:, :] = 0.0
    lo, hi, h = low[:nvar], up[:nvar], up[nvar:]
    low[nvar:] = -np.inf
    for a in range(M.shape[0]):
        ra = rhs[a]
        for i in range(r):
            mi = M[a, i]
            if mi != 0.0:
                q[i] -= mi * ra
                for j in range(r):
                    P[i, j] += mi * M[a, j]
    for i in range(r):
        P[i, i] += eps
    for k in range(p):
        _project_row(C[k], G[k], mode, sel, Z, r)
    _slack_rows(G, P, q, h, level, x, r)
    for k in range(nf):
        _project_row(F[k], G[p + k], mode, sel, Z, r)
    _fixed_bounds(h, fixed, x, p, tol)
    lo[:] = -np.inf
    hi[:] = np.inf
    if mode == 0:
        for j in range(r):
            lo[j] = lb[j] - x[j]
            hi[j] = ub[j] - x[j]
    elif mode == 1:
        for j in range(r):
            lo[j] = lb[sel[j]] - x[sel[j]]
            hi[j] = ub[sel[j]] - x[sel[j]]
    else:
        _basis_limits(G, h, x, Z, box, p + nf, tol)
    return nvar, nr


@_jit
def level_qp_arrays(
    ls: LeastSquares, level: Rows, x: np.ndarray, basis: Basis, fixed: Rows, box: Box, tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(P, q, G, h, l, u) of :func:`level_qp_into`'s level QP, in arrays of their own."""
    n = x.shape[0]
    p = level[0].shape[0]
    buf = np.empty(qp_buffer_size(n, p, p + fixed[0].shape[0]))
    nvar, nr = level_qp_into(ls, level, x, basis, fixed, box, tol, buf)
    P, q, G, up, low = qp_views(buf, nvar, nr)
    return P.copy(), q.copy(), G.copy(), up[nvar:].copy(), low[:nvar].copy(), up[:nvar].copy()


@_jit
def level_qp_joint_into(
    ls: JointLeastSquares, level: Rows, x: np.ndarray, W: np.ndarray, fixed: Rows, box: Box, native: bool,
    tol: float, buf: np.ndarray,
) -> tuple[int, int, int]:  # fmt: skip
    """The level QP of :func:`level_qp_into` posed in joint space, for the complement mode (the free directions
    null(W), W (nw, n) with orthonormal rows): over y = Z u ∈ null(W) — ‖u‖ = ‖y‖ and A Z u = A y there — the same
    problem, the same optimum, with the joint limits as simple bounds on y instead of 2n rows of Z, and without Z:

        minimise  ½ ε‖y‖² + ½‖s − rhs‖² + ½ diagonal·‖y‖² − diagonal·rhsᵀy + ½‖w'‖² + w₀ᵀw'
        subject to  C y − w' ≤ (d − C x) + w₀          F y ≤ max(f − F x, 0) + tol
                    M y − s = 0,  W y = 0            (equalities, the last rows)
                    −(max(x − lb, 0) + tol) ≤ y ≤ max(ub − x, 0) + tol   on the free joints with a bound
                    (``native``, the level where the mode changes: lb − x ≤ y ≤ ub − x, as :func:`level_qp_into`'s
                    modes 0 and 1 bound u)

    ``ls`` = (M, rhs, ε, diagonal), ``level`` = (C, d), ``fixed`` = (F, f), ``box`` = (lb, ub, free). The least
    squares ½‖M y − rhs‖² is lifted (s = M y, m more variables and rows) so that the Hessian stays diagonal, which
    daqp factors in O(n); ``diagonal`` > 0 instead poses ½‖y − rhs‖² (scaled; the null-space objective's rows I: M
    then has no rows). Variables (y, s, w'), in the layout of :func:`qp_views`.

    Returns:
        (nvar, nr, neq): the variables, the rows of G, and how many of them (the last) are equalities.
    """
    M, rhs, eps, diagonal = ls
    C = level[0]
    F = fixed[0]
    n = x.shape[0]
    m = M.shape[0]
    p = C.shape[0]
    nw = W.shape[0]
    nf = F.shape[0]
    nvar = n + m + p
    neq = m + nw
    nr = p + nf + neq
    if buf.shape[0] < nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr):
        raise ValueError("level_qp_joint_into: the QP buffer is too small for this level")
    P, q, G, up, low = qp_views(buf, nvar, nr)
    P[:, :] = 0.0
    q[:] = 0.0
    G[:, :] = 0.0
    lo, hi, h = low[:nvar], up[:nvar], up[nvar:]
    lo[:] = -np.inf
    hi[:] = np.inf
    for i in range(n):
        P[i, i] = eps + diagonal
        if diagonal != 0.0:
            q[i] = -diagonal * rhs[i]
    for a in range(m):
        P[n + a, n + a] = 1.0
        q[n + a] = -rhs[a]
    for k in range(p):
        G[k, :n] = C[k]
        low[nvar + k] = -np.inf
    _slack_rows(G, P, q, h, level, x, n + m)
    for k in range(nf):
        G[p + k, :n] = F[k]
        low[nvar + p + k] = -np.inf
    _fixed_bounds(h, fixed, x, p, tol)
    _joint_equalities(G, h, low[nvar:], M, W, p + nf, n)
    _joint_limits(lo, hi, x, box, native, tol)
    return nvar, nr, neq


@_jit
def _joint_equalities(
    G: np.ndarray, h: np.ndarray, low: np.ndarray, M: np.ndarray, W: np.ndarray, o: int, n: int
) -> None:
    """The equality rows of :func:`level_qp_joint_into` from row o: M y − s = 0 (s the variables from n), W y = 0
    (``low``: the rows' lower bounds)."""
    m = M.shape[0]
    for a in range(m):  # M y − s = 0
        G[o + a, :n] = M[a]
        G[o + a, n + a] = -1.0
        h[o + a] = 0.0
        low[o + a] = 0.0
    o += m
    for i in range(W.shape[0]):  # W y = 0
        G[o + i, :n] = W[i]
        h[o + i] = 0.0
        low[o + i] = 0.0


@_jit
def _joint_limits(lo: np.ndarray, hi: np.ndarray, x: np.ndarray, box: Box, native: bool, tol: float) -> None:
    """The free joints' limits as bounds on the joint-space step y (``native``: lb − x ≤ y ≤ ub − x; else the
    margins max(ub − x, 0) + tol and max(x − lb, 0) + tol where a bound is finite)."""
    lb, ub, free = box
    for j in range(x.shape[0]):
        if free[j] and native:
            lo[j] = lb[j] - x[j]
            hi[j] = ub[j] - x[j]
        elif free[j]:
            if math.isfinite(ub[j]):
                hi[j] = max(ub[j] - x[j], 0.0) + tol
            if math.isfinite(lb[j]):
                lo[j] = -(max(x[j] - lb[j], 0.0) + tol)
