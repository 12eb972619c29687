"""Compiled constrained cascade of ``hqp`` (numba): every level but the level QPs the backend solves, in one call per
stretch of levels (module docstring of :mod:`redundik.resolvers.qp.hqp`).

Per level: its least squares over q̇ = x + Z u — the damped SVD of A_k Z (the rule relative to the level's largest
weight), exact factors for identity rows (√w I, or the null-space objective's I), or the certified QR —, the ridge
solution û and, with the level shortcut, the test that û keeps every row of the level QP
(:func:`redundik.resolvers.hqp_level_qp.level_rows_ok`); when it does, û is the level's optimum, else the level QP
is written for the backend (or solved here through daqp's C entry point). The arguments are the records of
:mod:`redundik.resolvers.hqp_layout` (``rows``, ``work``, ``outs``, ``native``).
"""

from __future__ import annotations

import math

import numpy as np

from redundik.resolvers.hqp_algebra import (
    _add_basis_step,
    _basis_product,
    _certified_null,
    _certified_rows,
    _complement_projection,
    _level_scale,
    _projection,
    _ridge_triangular,
    _times_basis,
    _weighted_rows,
    identity_rows,
)
from redundik.resolvers.hqp_layout import (
    CASCADE_DONE,
    CASCADE_LEVEL_QP,
    CFG_CERTIFIED_QR,
    CFG_COMPLEMENT_FRACTION,
    CFG_COMPLEMENT_MIN_N,
    CFG_CONTRADICTION,
    CFG_EPSILON,
    CFG_FEASIBLE,
    CFG_IDENTITY,
    CFG_MAX_DAMPING,
    CFG_RCOND,
    CFG_REGULARIZATION,
    CFG_SHORTCUT,
    CFG_SLACK_TOL,
    COMPLEMENT_BASIS,
    GENERAL_BASIS,
    IDENTITY_BASIS,
    LEAST_SQUARES,
    META_INEQ,
    META_KIND,
    META_LS,
    NAT_FN,
    NAT_ITERS,
    NAT_LAST,
    NAT_SENSE,
    NAT_SOLVED,
    NAT_SPLIT_MIN,
    NULL_OBJECTIVE,
    QS_DAMPING,
    QS_FREE,
    QS_PROJECTED,
    QS_RANK,
    QS_SIGMA,
    QS_SOLVED,
    QS_WORST,
    SELECTION_BASIS,
    ST_CONTRADICTED,
    ST_LSQ,
    ST_MODE,
    ST_NCOLS,
    ST_NEQ,
    ST_NF,
    ST_NSEL,
    ST_NU,
    ST_R,
    Box,
    CascadeRows,
    Native,
    Outs,
    Resume,
    Rows,
    Work,
)
from redundik.resolvers.hqp_level_qp import level_qp_into, level_qp_joint_into, level_rows_ok, qp_views
from redundik.resolvers.hqp_native import native_quadprog
from redundik.resolvers.kernels import _jit, damped_svd_factors, damped_svd_thin, in_box

#: A level of the cascade as the step's helpers read it (a tuple): (k, first least-squares row s, end e, its rows m,
#: pure null-space objective, basis mode, free directions r, rows of the complement nw).
Level = tuple[int, int, int, int, bool, int, int, int]
#: A level's factors: (has least squares, scale, M, rhs, U, σ, Vt, rank, σ_min, damping, null-basis columns, factored
#: by the certified QR).
Factors = tuple[bool, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, float, float, int, bool]


@_jit
def _absorb(
    k: int,
    u: np.ndarray,
    ineq: tuple[np.ndarray, np.ndarray, np.ndarray],
    tols: tuple[float, float],
    basis: Rows,
    fixed: tuple[np.ndarray, np.ndarray, np.ndarray],
    state: np.ndarray,
    x: np.ndarray,
    stats: np.ndarray,
) -> None:
    """Level k's step u into the cascade: x ← x + Z u; its inequality rows join the fixed rows with their optimal
    slack, C q̇ ≤ d + w* + tol, w* = max(C x − d, 0) (kept per row in ``slack``); and, for a level that solved a
    least squares, Z ← Z·N (N: the null basis of A_k Z, ``state[ST_NCOLS]`` columns).

    In the complement mode u is the joint-space step y itself (x ← x + y) and the level's new fixed directions —
    ``state[ST_NCOLS]`` rows of N — join the complement W; when it fills the space the mode becomes the empty basis
    (mode 2, r = 0). ``ineq`` = (C, d, meta), ``tols`` = (the slack tolerance, the contradiction tolerance),
    ``basis`` = (Z, N), ``fixed`` = (F, f, slack)."""
    C, d, meta = ineq
    tol, contradiction = tols
    Z, N = basis
    F, f, slack = fixed
    n = x.shape[0]
    mode, r = state[ST_MODE], state[ST_R]
    if mode == IDENTITY_BASIS or mode == COMPLEMENT_BASIS:
        for i in range(n):
            x[i] += u[i]
    else:
        _add_basis_step(x, Z, r, u)
    nf = state[ST_NF]
    worst = 0.0
    for i in range(meta[META_INEQ, k], meta[META_INEQ, k + 1]):
        acc = 0.0
        for j in range(n):
            acc += C[i, j] * x[j]
        wv = acc - d[i]
        if not wv > 0.0:
            wv = 0.0 if wv == wv else wv  # (a NaN row stays NaN, as np.maximum leaves it)
        slack[i] = wv
        for j in range(n):
            F[nf, j] = C[i, j]
        f[nf] = d[i] + wv + tol
        nf += 1
        if wv > worst:
            worst = wv
    state[ST_NF] = nf
    stats[k, QS_WORST] = worst
    if worst > contradiction:
        state[ST_CONTRADICTED] = 1
    if state[ST_LSQ]:
        _shrink_basis(state, Z, N, n)


@_jit
def _shrink_basis(state: np.ndarray, Z: np.ndarray, N: np.ndarray, n: int) -> None:
    """After a level that solved a least squares: Z ← Z·N (its null basis, ``state[ST_NCOLS]`` columns), or in the
    complement mode the level's fixed directions (rows of N) join W (the empty basis when W fills the space)."""
    mode, r = state[ST_MODE], state[ST_R]
    if mode == COMPLEMENT_BASIS:
        added = state[ST_NCOLS]
        if r - added > 0:
            nw = n - r
            for i in range(added):
                for j in range(n):
                    Z[nw + i, j] = N[i, j]
            state[ST_R] = r - added
        else:
            state[ST_MODE] = GENERAL_BASIS
            state[ST_R] = 0
        return
    rp = state[ST_NCOLS]
    if mode == IDENTITY_BASIS:
        for i in range(n):
            for j in range(rp):
                Z[i, j] = N[i, j]
    else:
        T = _basis_product(Z, r, N, rp)
        for i in range(n):
            for j in range(rp):
                Z[i, j] = T[i, j]
    state[ST_MODE] = GENERAL_BASIS
    state[ST_R] = rp


@_jit
def _start(
    lb: np.ndarray, ub: np.ndarray, state: np.ndarray, x: np.ndarray, Z: np.ndarray, free: np.ndarray, sel: np.ndarray
) -> None:
    """The cascade's start (``LimitBox.pinned``'s rule): a joint whose box is one value, ub − lb ≤ 1e-12·max(1,
    |ub|) with both finite, is fixed at its middle and left out of the basis: Z = I on the free joints (mode 1) when
    any is pinned, else Z = I (mode 0)."""
    n = x.shape[0]
    cnt = 0
    for j in range(n):
        x[j] = 0.0
        for c in range(n):
            Z[j, c] = 0.0
        lo, hi = lb[j], ub[j]
        if math.isfinite(lo) and math.isfinite(hi) and hi - lo <= 1e-12 * max(1.0, abs(hi)):
            x[j] = 0.5 * (lo + hi)
            free[j] = False
        else:
            free[j] = True
            sel[cnt] = j
            cnt += 1
    for i in range(cnt):
        Z[sel[i], i] = 1.0
    state[ST_MODE] = IDENTITY_BASIS if cnt == n else SELECTION_BASIS
    state[ST_R] = cnt
    state[ST_NF] = 0
    state[ST_NCOLS] = 0
    state[ST_LSQ] = 0
    state[ST_NSEL] = cnt if cnt < n else 0
    state[ST_CONTRADICTED] = 0
    state[ST_NU] = 0
    state[ST_NEQ] = 0


@_jit
def _to_complement(state: np.ndarray, Z: np.ndarray, free: np.ndarray) -> None:
    """From Z = I (on the free joints) to the complement mode: W = the rows e_j of the pinned joints."""
    n = Z.shape[0]
    nw = 0
    for j in range(n):
        if not free[j]:
            for c in range(n):
                Z[nw, c] = 0.0
            Z[nw, j] = 1.0
            nw += 1
    state[ST_MODE] = COMPLEMENT_BASIS
    state[ST_R] = n - nw


@_jit
def _pure_closed_form(
    lv: Level, x: np.ndarray, z: np.ndarray, limits: Rows, Z: np.ndarray, fixed: Rows, state: np.ndarray, tol: float
) -> bool:
    """A pure null-space level without rows of its own: q̇ = x + P_Z(z − x) when that keeps the limits and the rows
    fixed above (x, the basis and r then updated: nothing is left below); False (nothing written) otherwise."""
    mode, r, nw = lv[5], lv[6], lv[7]
    F, f = fixed
    lb, ub = limits
    n = x.shape[0]
    nf = state[ST_NF]
    comp = mode == COMPLEMENT_BASIS
    if comp:
        cand = x + _complement_projection(z - x, Z, nw)
    else:
        cand = x + _projection(x, Z, r, z, 0)
    if not in_box(cand, lb, ub, tol):
        return False
    for i in range(nf):
        acc = 0.0
        for j in range(n):
            acc += F[i, j] * cand[j]
        if not (acc <= f[i] + tol):
            return False
    for i in range(n):
        x[i] = cand[i]
    if mode == IDENTITY_BASIS:
        state[ST_MODE] = GENERAL_BASIS  # (Z = the empty basis; a selection stays one)
    if comp:
        state[ST_MODE] = GENERAL_BASIS
    state[ST_R] = 0
    return True


@_jit
def _identity_factors(
    n: int, r: int, mode: int, Z: np.ndarray, sigma: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The SVD (U, σ, Vt) of the rows σ I over the basis (Z = I in mode 0): (Z, σ, I)."""
    U = np.empty((n, r))
    for i in range(n):
        for j in range(r):
            U[i, j] = (1.0 if i == j else 0.0) if mode == IDENTITY_BASIS else Z[i, j]
    return U, np.full(r, sigma), np.eye(r)


@_jit
def _level_factors(
    lv: Level,
    ls: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    mixed: bool,
    x: np.ndarray,
    basis: Rows,
    cfg: np.ndarray,
    rk: np.ndarray,
    empty: tuple[np.ndarray, np.ndarray],
) -> Factors:
    """Level lv's least squares over u (:data:`Factors`): its weighted rows M = A_k Z and residual target rhs and
    their factors — (U, σ, Vt, rank, σ_min, λ) and the null basis into N, or the certified QR (R into ``rk``, the
    null basis or, in the complement mode, the fixed directions into N). In the complement mode over y ∈ null(W):
    Vt's rows in joint space, and the rows it fixes into N's rows."""
    _, s, e, m, pure, mode, r, nw = lv
    A, b, w, z = ls
    Z, N = basis
    epsilon, max_damping, rcond = cfg[CFG_EPSILON], cfg[CFG_MAX_DAMPING], cfg[CFG_RCOND]
    certified_qr = cfg[CFG_CERTIFIED_QR] != 0.0
    n = x.shape[0]
    comp = mode == COMPLEMENT_BASIS
    empty2, empty1 = empty  # (allocated once per call of the cascade)
    M, rhs, U, sv, Vt = empty2, empty1, empty2, empty1, empty2
    scale, rank, sigma_min, damping, ncols, qr_level = 1.0, 0, np.inf, 0.0, 0, False
    if pure and comp:  # rows I on null(W): every direction left, singular values 1
        rhs = z - x
        rank, sigma_min, ncols = r, (1.0 if r else np.inf), r
    elif pure:  # rows I: M = Z (orthonormal columns), its SVD is (Z, 1, I)
        rhs = np.empty(n)
        for i in range(n):
            rhs[i] = z[i] - x[i]
        U, sv, Vt = _identity_factors(n, r, mode, Z, 1.0)
        rank, sigma_min = r, (1.0 if r else np.inf)
    elif m > 0 and comp:  # M = A_k (I − WᵀW): its thin SVD, the fixed directions Vt[:rank]
        scale = _level_scale(w, s, e)
        Ak, rhs = _weighted_rows(A, b, w, s, m, x)
        M = np.empty((m, n))
        for a in range(m):
            M[a] = _complement_projection(Ak[a], Z, nw)
        if certified_qr and m <= r and m * m <= rk.shape[0] and _certified_rows(M, epsilon * scale, rcond, N, rk):
            # Mᵀ = Q₁R certifies σ_min ≥ ε: the fixed directions Q₁ᵀ are N's first m rows, R in rfac[k]
            qr_level = True
            rank, sigma_min, ncols = m, np.nan, m
        else:
            U, sv, Vt, _, rank, sigma_min, damping = damped_svd_thin(M, epsilon * scale, max_damping * scale, rcond)
            rank = min(rank, r)  # (M's rows lie in null(W), of dimension r)
            for i in range(rank):
                for j in range(n):
                    N[i, j] = Vt[i, j]
            ncols = rank
    elif m > 0:
        scale = _level_scale(w, s, e)
        Ak, rhs = _weighted_rows(A, b, w, s, m, x)
        M = Ak if mode == IDENTITY_BASIS else _times_basis(Ak, Z, r)
        identity = cfg[CFG_IDENTITY] != 0.0 and r > 0 and not mixed and m == n
        if identity and identity_rows(A, w, s, n, epsilon * scale):
            sw = math.sqrt(w[s])
            U, sv, Vt = _identity_factors(n, r, mode, Z, sw)
            rank, sigma_min = r, sw
        elif r == 0:
            U, sv, Vt = np.zeros((m, 0)), np.zeros(0), np.eye(0)
        elif certified_qr and m <= r and m * m <= rk.shape[0] and _certified_null(M, epsilon * scale, rcond, N, rk):
            # Mᵀ = Q₁R certifies σ_min ≥ ε (nothing damped, rank m): null(M) = Q₂ is in N, R in rfac[k] (σ_min
            # from it when the diagnostics are read), and the ridge takes R instead of the SVD
            qr_level = True
            rank, sigma_min, ncols = m, np.nan, r - m
        else:
            U, sv, Vt, _, rank, sigma_min, damping = damped_svd_factors(
                np.ascontiguousarray(M), epsilon * scale, max_damping * scale, rcond
            )
            ncols = Vt.shape[0] - rank
            for i in range(Vt.shape[0]):
                for j in range(ncols):
                    N[i, j] = Vt[rank + j, i]
    has_lsq = pure or m > 0
    return has_lsq, scale, M, rhs, U, sv, Vt, rank, sigma_min, damping, ncols, qr_level


@_jit
def _ridge(
    lv: Level, svd: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], flags: tuple[bool, bool], Z: np.ndarray,
    N: np.ndarray, rk: np.ndarray, eps: float, nu: int,
) -> np.ndarray:  # fmt: skip
    """The level's ridge solution û = argmin ‖M u − rhs‖² + ε‖u‖² (nu entries; zero without least squares): from the
    SVD V diag(σ/(σ² + ε)) Uᵀ rhs, from the certified QR M = RᵀQ₁ᵀ (u = Q₁ t, t = argmin ‖Rᵀt − rhs‖² + ε‖t‖²), or
    (I − WᵀW) rhs / (1 + ε) for the null-space objective's rows I in the complement mode. ``svd`` = (rhs, U, σ, Vt),
    ``flags`` = (has least squares, factored by the certified QR)."""
    m, pure, mode, r, nw = lv[3], lv[4], lv[5], lv[6], lv[7]
    rhs, U, sv, Vt = svd
    has_lsq, qr_level = flags
    comp = mode == COMPLEMENT_BASIS
    n = Z.shape[0]
    u = np.zeros(nu)
    if has_lsq and pure and comp:
        proj = _complement_projection(rhs, Z, nw)
        for i in range(n):
            u[i] = proj[i] / (1.0 + eps)
    elif qr_level:
        t = _ridge_triangular(rk, m, rhs, eps)
        for c in range(nu):
            acc = 0.0
            for j in range(m):
                acc += (N[j, c] if comp else N[c, r - m + j]) * t[j]
            u[c] = acc
    elif has_lsq:
        kk = sv.shape[0]
        for j in range(kk):
            acc = 0.0
            for i in range(rhs.shape[0]):
                acc += U[i, j] * rhs[i]
            tj = sv[j] / (sv[j] * sv[j] + eps) * acc
            if tj != 0.0:
                for c in range(nu):
                    u[c] += Vt[j, c] * tj
    return u


@_jit
def _write_level_qp(lv: Level, ls: tuple[float, np.ndarray, np.ndarray, np.ndarray], eps: float, level: Rows,
                    x: np.ndarray, box: Box, native: bool, qp_work: tuple[np.ndarray, np.ndarray, np.ndarray,
                    np.ndarray, np.ndarray], tol: float, qbuf: np.ndarray) -> tuple[int, int, float]:  # fmt: skip
    """Level lv's QP for the backend into ``qbuf`` (:func:`level_qp_into`, or :func:`level_qp_joint_into` in the
    complement mode; ``native``: the limits as the variables' own bounds, at the level where Z = I or I on the free
    joints): (nvar, nr, ε of u); ``state[ST_NU]``, ``state[ST_NEQ]``: the step's variables and the
    equality rows. A level of least squares only is divided by its scale² (the same optimum)."""
    m, pure, mode, r, nw = lv[3], lv[4], lv[5], lv[6], lv[7]
    scale, M, rhs, U = ls
    Z, F, f, state, sel_buf = qp_work
    nf = state[ST_NF]
    sel = sel_buf[: state[ST_NSEL]]
    n = x.shape[0]
    C, d = level
    Mq, rq, eq = M, rhs, eps
    if m > 0 and C.shape[0] == 0 and scale != 1.0:  # least squares only: divided by its scale², the same optimum
        Mq = np.empty_like(M)
        rq = np.empty_like(rhs)
        for i in range(M.shape[0]):
            for j in range(M.shape[1]):
                Mq[i, j] = M[i, j] / scale
            rq[i] = rhs[i] / scale
        eq = eps / (scale * scale)
    cd = (np.ascontiguousarray(C), np.ascontiguousarray(d))
    fixed = (np.ascontiguousarray(F[:nf]), np.ascontiguousarray(f[:nf]))
    neq = 0
    if mode == COMPLEMENT_BASIS:
        if pure or m == 0:
            Mq = np.zeros((0, n))
            rq = rhs
        ls4 = (np.ascontiguousarray(Mq), rq, eq, 1.0 if pure else 0.0)
        nvar, nr, neq = level_qp_joint_into(ls4, cd, x, Z[:nw], fixed, box, native, tol, qbuf)
        state[ST_NU] = n
    else:
        if pure or m == 0:
            Mq, rq = np.zeros((0, r)), np.zeros(0)
        basis = (Z[:, :r] if mode == GENERAL_BASIS else Z[:, :0], mode, sel)
        nvar, nr = level_qp_into((np.ascontiguousarray(Mq), rq, eq), cd, x, basis, fixed, box, tol, qbuf)
        if pure:  # ½‖Zu − (z − x)‖²: MᵀM = I, Mᵀ rhs = Zᵀ(z − x)
            P, q = qp_views(qbuf, nvar, nr)[:2]
            for i in range(r):
                P[i, i] += 1.0
                acc = 0.0
                for l in range(n):
                    acc += U[l, i] * rhs[l]
                q[i] = -acc
        state[ST_NU] = r
    state[ST_NEQ] = neq
    return nvar, nr, eq


@_jit
def _native_level(k: int, native: Native, qbuf: np.ndarray, dims: tuple[int, int, int]) -> bool:
    """Level k's QP in ``qbuf`` (``dims`` = (nvar, nr, neq)) solved here through daqp's C entry point when the
    ``native`` record (ctl, nx) enables it (``ctl[NAT_FN]`` set for daqp as the backend, ``daqp_native.NativeDaqp``;
    not a bounds-only QP the backend splits): True when daqp solved it at once (exit flag 1 or 2, a finite x, in
    ``nx``; the caller absorbs it); False leaves it to the caller, which poses it with every retry."""
    ctl, nx = native
    nvar, nr, neq = dims
    if not (ctl.shape[0] > NAT_SENSE and ctl[NAT_FN] != 0 and not (nr == 0 and nvar >= ctl[NAT_SPLIT_MIN])):
        return False
    flag, iters = native_quadprog(ctl, nx, qbuf, nvar, nr, neq)
    solved = flag == 1 or flag == 2
    for i in range(nvar):
        if solved and not math.isfinite(nx[i]):
            solved = False
    if not solved:
        return False
    ctl[NAT_SOLVED] += 1
    ctl[NAT_ITERS] += max(iters, 0)
    ctl[NAT_LAST] = k
    return True


@_jit
def _level_stats(stats: np.ndarray, k: int, fac: tuple[int, float, float], r: int, projected: bool) -> None:
    """The level's record in ``stats`` (``QS_*``) when it solved a least squares; ``fac`` = (rank, σ_min, λ)."""
    stats[k, QS_SIGMA] = fac[1]
    stats[k, QS_DAMPING] = fac[2]
    stats[k, QS_RANK] = fac[0]
    stats[k, QS_FREE] = r
    stats[k, QS_PROJECTED] = 1.0 if projected else 0.0
    stats[k, QS_SOLVED] = 1.0


@_jit
def qp_cascade_run(
    rows: CascadeRows, mixed: np.ndarray, limits: Rows, cfg: np.ndarray, work: Work, outs: Outs, resume: Resume,
    native: Native,
) -> tuple[int, int, int, int, float]:  # fmt: skip
    """``hqp``'s constrained cascade (module docstring of :mod:`redundik.resolvers.qp.hqp`) from a level on, up to
    the next level that needs the backend: the whole of it but the level QPs, which the caller solves.

    Args:
        rows: (A, b, w, C, d, z, meta): the packed rows of ``closed_cascade``; ``mixed[k]``: a least-squares level
            that carries the null-space objective's identity rows after its own.
        limits: (lb, ub) of the joint-limit box.
        cfg: ``CFG_*``: ε, λ_max, rcond, the regulariser, the slack tolerance, the shortcut's feasibility
            tolerance, identity levels (1/0), the level shortcut (1/0), the contradiction tolerance, the complement
            mode's smallest n and fraction, and the certified QR (1/0: a least-squares level of m ≤ r rows whose
            QR of (A_k Z)ᵀ certifies σ_min ≥ ε, ``qr_certificate``, is factored by it — the same ridge and null
            basis as its SVD's, nothing damped — instead of its SVD).
        work: (Z (n, n), N (n, n), F, f (the fixed rows), slack (one per C row), state (``ST_*``, int64), free,
            sel), kept between calls.
        outs: (x, stats (L, 7), rfac, qbuf): q̇; the per-level records; per level the R (m, m) of a level of m rows
            whose QR certified σ_min ≥ ε (its σ_min then NaN in ``stats``; a level of more than √(rfac.shape[1])
            rows takes the SVD); where a level QP is written (read it through ``qp_views``).
        resume: (k0, absorb, u): the level to start at; with ``absorb``, the level whose QP the caller solved: its
            u is absorbed first and the cascade goes on at k0 + 1 (without it: a level the caller skipped, or the
            start).
        native: (ctl, nx): ``_native_level`` (``ctl`` empty: every level QP is returned to the caller).

    Returns:
        (``CASCADE_DONE``, L, 0, 0, 0) when the cascade is done (q̇ in x); (``CASCADE_LEVEL_QP``, k, nvar, nr, ε)
        when level k needs its QP: nvar variables (u, w') and nr rows, in ``qbuf``; ε its regulariser on u.
    """
    A, b, w, C, d, z, meta = rows
    Z, N, F, f, slack, state, free, sel_buf = work
    x, stats, rfac, qbuf = outs
    k, absorb, u_in = resume
    lb, ub = limits
    n = x.shape[0]
    L = meta.shape[1] - 1
    if state.shape[0] <= ST_NEQ or cfg.shape[0] <= CFG_CERTIFIED_QR or Z.shape[0] < n or N.shape[0] < n:
        raise ValueError("qp_cascade_run: state, cfg, Z or N is shorter than the layout it is read in")
    tol, feas, contra = cfg[CFG_SLACK_TOL], cfg[CFG_FEASIBLE], cfg[CFG_CONTRADICTION]
    cmin, cfrac = cfg[CFG_COMPLEMENT_MIN_N], cfg[CFG_COMPLEMENT_FRACTION]
    box = (lb, ub, free)
    ineq, tols, basis, fixed = (C, d, meta), (tol, contra), (Z, N), (F, f, slack)
    empty = (np.zeros((0, 0)), np.zeros(0))
    if k == 0 and not absorb:  # the start: x = 0 but on the pinned joints, Z = I (or I on the free joints)
        _start(lb, ub, state, x, Z, free, sel_buf)
    if absorb:
        _absorb(k, u_in, ineq, tols, basis, fixed, state, x, stats)
        k += 1
    while k < L:
        kind = meta[META_KIND, k]
        c0, c1 = meta[META_INEQ, k], meta[META_INEQ, k + 1]
        s, e = meta[META_LS, k], meta[META_LS, k + 1]
        m = e - s if kind == LEAST_SQUARES else 0
        pure = kind == NULL_OBJECTIVE
        mode, r, nf = state[ST_MODE], state[ST_R], state[ST_NF]
        p = c1 - c0
        if p == 0 and (r == 0 or (m == 0 and not pure)):
            k += 1
            continue
        native_box = mode == IDENTITY_BASIS or mode == SELECTION_BASIS  # the limits as the variables' own bounds
        if native_box and m > 0 and m < n and n >= cmin and cfrac * ((n - r) + m) <= n:
            _to_complement(state, Z, free)  # a least-squares level that leaves few fixed directions: from here on
            mode, r = COMPLEMENT_BASIS, state[ST_R]
            projected = False
        else:
            projected = mode == GENERAL_BASIS or mode == COMPLEMENT_BASIS
        comp = mode == COMPLEMENT_BASIS
        lv = (k, s, e, m, pure, mode, r, n - r if comp else 0)
        if pure and p == 0 and mode != IDENTITY_BASIS and _pure_closed_form(lv, x, z, limits, Z, (F, f), state, tol):
            k += 1
            continue
        fac = _level_factors(lv, (A, b, w, z), mixed[k], x, basis, cfg, rfac[k], empty)
        eps = cfg[CFG_REGULARIZATION] * fac[1] * fac[1]
        if fac[0]:
            eps = max(eps, fac[9] * fac[9])
            _level_stats(stats, k, (fac[7], fac[8], fac[9]), r, projected)
        state[ST_NCOLS] = fac[10]
        state[ST_LSQ] = 1 if fac[0] else 0
        level = (C[c0:c1], d[c0:c1])
        if cfg[CFG_SHORTCUT] != 0.0:
            u = _ridge(lv, (fac[3], fac[4], fac[5], fac[6]), (fac[0], fac[11]), Z, N, rfac[k], eps, n if comp else r)
            if mode == IDENTITY_BASIS or comp:
                step = u
            else:
                step = np.zeros(n)
                _add_basis_step(step, Z, r, u)
            if level_rows_ok(step, x, box, native_box, level, (F[:nf], f[:nf]), tol, feas):
                _absorb(k, u, ineq, tols, basis, fixed, state, x, stats)
                k += 1
                continue
        ls = (fac[1], fac[2], fac[3], fac[4])
        nvar, nr, eq = _write_level_qp(lv, ls, eps, level, x, box, native_box, (Z, F, f, state, sel_buf), tol, qbuf)
        if _native_level(k, native, qbuf, (nvar, nr, state[ST_NEQ])):
            _absorb(k, native[1][: state[ST_NU]], ineq, tols, basis, fixed, state, x, stats)
            k += 1
            continue
        return CASCADE_LEVEL_QP, k, nvar, nr, eq
    return CASCADE_DONE, L, 0, 0, 0.0
