"""daqp's C entry point called from compiled code (numba): a level QP of ``hqp``'s cascade, or the box QPs of a batch,
solved by the very call ``daqp.solve`` makes, without the Python wrapper (:mod:`redundik.resolvers.qp.daqp_native`
checks the structs' layout for daqp's version and lays out the ``native`` array, ``NAT_*`` of
:mod:`redundik.resolvers.hqp_layout`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.box_kernels import split_separable
from redundik.resolvers.hqp_layout import NAT_FN, NAT_PROBLEM, NAT_RESULT, NAT_SENSE, NAT_SETTINGS
from redundik.resolvers.hqp_level_qp import qp_views
from redundik.resolvers.kernels import _jit
from redundik.resolvers.layouts import OUT_DQ, OUT_KEPT, OUT_LB, OUT_UB

#: Words of daqp's ``DAQPProblem`` from ``NAT_PROBLEM``: (n, m) as two int32, ms, the addresses of H, f, A, bupper,
#: blower, sense and break_points, (nh, problem_type) as two int32.
DP_SIZES, DP_MS, DP_H, DP_F, DP_A, DP_BUPPER, DP_BLOWER, DP_SENSE, DP_BREAKS, DP_KIND = range(10)
#: Words of daqp's ``DAQPResult`` from ``NAT_RESULT``: the addresses of x and of the multipliers, …, (exitflag,
#: iter) as two int32 at ``DR_FLAGS``; 8 words in all.
DR_X, DR_LAM, DR_FLAGS, DR_WORDS = 0, 1, 4, 8
#: daqp's ``sense`` of an equality row.
SENSE_EQUALITY = 5


def _make_call_ppp() -> Any:
    """The intrinsic ``_call_ppp(fn, a, b, c)``: call the C function at address ``fn`` as
    ``void fn(void*, void*, void*)`` with the three addresses (made when numba is imported:
    ``_kernel_cache.later``)."""
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def _call_ppp(typingctx, fn, a, b, c):  # type: ignore[no-untyped-def]
        sig = types.void(types.int64, types.int64, types.int64, types.int64)

        def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
            vp = ir.IntType(8).as_pointer()
            fnty = ir.FunctionType(ir.VoidType(), [vp, vp, vp])
            target = builder.inttoptr(args[0], fnty.as_pointer())
            builder.call(target, [builder.inttoptr(x, vp) for x in args[1:]])
            return context.get_dummy_value()

        return sig, codegen

    return _call_ppp


_call_ppp = _kernel_cache.later(__name__, "_call_ppp", _make_call_ppp)


@_jit
def native_quadprog(
    native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, nvar: int, nr: int, neq: int
) -> tuple[int, int]:
    """daqp on the level QP in ``qbuf`` (the layout of :func:`qp_views`), called through its C entry point: the call
    ``daqp.solve`` makes — the same structs, every setting but the two of the backend at daqp's defaults, the sense
    of the last ``neq`` rows equality and of the others inequality — without the Python wrapper. The solution goes to
    ``nx[:nvar]``, the multipliers after it.

    ``native`` is laid out by ``redundik.resolvers.qp.daqp_native.NativeDaqp`` (``NAT_*``), which checked the
    layout of daqp's structs for its version. Returns (daqp's exit flag, iterations); (0, 0) when the QP does not fit
    the buffers (never written past them).
    """
    m = nvar + nr
    if 2 * (native.shape[0] - NAT_SENSE) < m or nx.shape[0] < nvar + m:
        return 0, 0
    sense = native[NAT_SENSE:].view(np.int32)
    for i in range(m):
        sense[i] = SENSE_EQUALITY if i >= m - neq else 0
    a = nvar * nvar
    b = a + nvar
    c = b + nr * nvar
    d = c + m
    base = qbuf.ctypes.data
    me = native.ctypes.data
    xa = nx.ctypes.data
    problem = native[NAT_PROBLEM : NAT_PROBLEM + DP_KIND + 1]
    problem[DP_SIZES] = nvar | (m << 32)  # int n, int m
    problem[DP_MS] = nvar  # int ms: the bounds on the variables
    problem[DP_H] = base
    problem[DP_F] = base + 8 * a
    problem[DP_A] = base + 8 * b if nr > 0 else 0
    problem[DP_BUPPER] = base + 8 * c
    problem[DP_BLOWER] = base + 8 * d
    problem[DP_SENSE] = me + 8 * NAT_SENSE
    problem[DP_BREAKS] = 0
    problem[DP_KIND] = 0  # int nh, int problem_type (a QP)
    result = native[NAT_RESULT : NAT_RESULT + DR_WORDS]
    result[DR_X] = xa
    result[DR_LAM] = xa + 8 * nvar
    for i in range(DR_LAM + 1, DR_WORDS):
        result[i] = 0
    _call_ppp(native[NAT_FN], me + 8 * NAT_RESULT, me + 8 * NAT_PROBLEM, native[NAT_SETTINGS])
    flags = result[DR_FLAGS : DR_FLAGS + 1].view(np.int32)  # int exitflag, int iter
    return flags[0], flags[1]


@_jit
def box_qps_native(
    native: np.ndarray,
    nx: np.ndarray,
    qbuf: np.ndarray,
    P: np.ndarray,
    q: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    idx: np.ndarray,
    dq: np.ndarray,
    solved: np.ndarray,
) -> int:
    """The box QPs min ½xᵀP_i x + q_iᵀx s.t. lb_i ≤ x ≤ ub_i of the problems ``idx`` of a batch (P (N, n, n), q, lb,
    ub (N, n)), each through :func:`native_quadprog` — the call ``DaqpBackend.solve`` makes on a bounds-only QP
    below its split size, on the same arrays. Where daqp solves problem i at once (exit flag 1 or 2, x finite),
    ``dq[i]`` = x clipped to the box and ``solved[k]`` = True; elsewhere ``solved[k]`` = False and ``dq[i]`` is left
    as it was (the caller poses that QP with the backend's retries). Returns daqp's iterations summed."""
    n = P.shape[1]
    Pv, qv, _, upper, lower = qp_views(qbuf, n, 0)
    total = 0
    for k in range(idx.shape[0]):
        i = idx[k]
        Pv[:, :] = P[i]
        qv[:] = q[i]
        upper[:] = ub[i]
        lower[:] = lb[i]
        flag, iters = native_quadprog(native, nx, qbuf, n, 0, 0)
        ok = flag == 1 or flag == 2
        if ok:
            for j in range(n):
                if not math.isfinite(nx[j]):
                    ok = False
        solved[k] = ok
        if ok:
            total += iters
            for j in range(n):
                dq[i, j] = min(max(nx[j], lb[i, j]), ub[i, j])
    return total


@_jit
def box_qp_native_into(native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, P: np.ndarray, q: np.ndarray,
                       out: np.ndarray) -> tuple[int, int]:  # fmt: skip
    """The box QP min ½xᵀPx + qᵀx s.t. lb ≤ x ≤ ub of one ``wqp`` step (P (n, n), q (n,); lb, ub the rows
    ``OUT_LB``, ``OUT_UB`` of ``out`` (``layouts.OUT_ROWS``, n)) through :func:`native_quadprog`: the call
    ``DaqpBackend.solve`` makes on a bounds-only QP below its split size, on the same numbers. Where daqp solves it at
    once (exit flag 1 or 2) and x is finite, x clipped to the box (``clip_twice``'s projection) goes to the rows
    ``OUT_DQ`` and ``OUT_KEPT``; otherwise nothing is written there (the caller poses the QP with the backend's
    retries). Returns (daqp's exit flag, its iterations); the flag is 0 when x is not finite."""
    n = P.shape[0]
    Pv, qv, _, upper, lower = qp_views(qbuf, n, 0)
    Pv[:, :] = P
    qv[:] = q
    upper[:] = out[OUT_UB]
    lower[:] = out[OUT_LB]
    return _solve_clipped(native, nx, qbuf, n, 0, 0, out)


@_jit
def rows_qp_native_into(native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, P: np.ndarray, q: np.ndarray,
                        out: np.ndarray, G: np.ndarray, h: np.ndarray) -> tuple[int, int]:  # fmt: skip
    """:func:`box_qp_native_into` with inequality rows G x ≤ h (G (nr, n), h (nr,)) beside the box: daqp's
    constraints are the box, then the rows with upper bound h and lower bound −∞ — the QP ``DaqpBackend.solve``
    poses for a ``QPProblem`` with rows below its lift size, on the same numbers. x, clipped to the box, goes to the
    rows ``OUT_DQ`` and ``OUT_KEPT`` of ``out`` where daqp solves it at once and x is finite. Returns (daqp's exit
    flag, its iterations); the flag is 0 when x is not finite."""
    n, nr = P.shape[0], G.shape[0]
    Pv, qv, Gv, upper, lower = qp_views(qbuf, n, nr)
    Pv[:, :] = P
    qv[:] = q
    Gv[:, :] = G
    upper[:n] = out[OUT_UB]
    lower[:n] = out[OUT_LB]
    upper[n:] = h
    lower[n:] = -np.inf
    return _solve_clipped(native, nx, qbuf, n, nr, 0, out)


@_jit
def lifted_rows_qp_native_into(native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, F: np.ndarray, delta: float,
                               q: np.ndarray, out: np.ndarray, G: np.ndarray,
                               h: np.ndarray) -> tuple[int, int]:  # fmt: skip
    """The QP min ½xᵀ(FᵀF + δI)x + qᵀx s.t. lb ≤ x ≤ ub, G x ≤ h (F (k, n), G (p, n); the box the rows ``OUT_LB``,
    ``OUT_UB`` of ``out``) lifted as ``DaqpBackend._solve_lifted`` poses it, on the same numbers: the variables
    (x, s), the Hessian diag(δ·1_n, 1_k), f = (q, 0); the box and s free, then the rows [G 0] (upper h, lower −∞) and
    the equalities [F −I] (x, s) = 0. x, clipped to the box, goes to the rows ``OUT_DQ`` and ``OUT_KEPT`` where daqp
    solves it at once and x is finite. Returns (daqp's exit flag — 0 when x is not finite —, its iterations)."""
    n, k, p = q.shape[0], F.shape[0], G.shape[0]
    nv = n + k
    Pv, qv, Mv, upper, lower = qp_views(qbuf, nv, p + k)
    Pv[:, :] = 0.0
    for j in range(nv):
        Pv[j, j] = delta if j < n else 1.0
    qv[:n] = q
    qv[n:] = 0.0
    Mv[:, :] = 0.0
    Mv[:p, :n] = G
    Mv[p:, :n] = F
    for r in range(k):
        Mv[p + r, n + r] = -1.0
    upper[:n] = out[OUT_UB]
    lower[:n] = out[OUT_LB]
    upper[n:nv] = np.inf
    lower[n:nv] = -np.inf
    upper[nv : nv + p] = h
    lower[nv : nv + p] = -np.inf
    upper[nv + p :] = 0.0
    lower[nv + p :] = 0.0
    return _solve_clipped(native, nx, qbuf, nv, p + k, k, out)


@_jit
def _solve_clipped(native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, nvar: int, nr: int, neq: int,
                   out: np.ndarray) -> tuple[int, int]:  # fmt: skip
    """daqp on the QP of ``nvar`` variables and ``nr`` rows (the last ``neq`` equalities) in ``qbuf``
    (:func:`native_quadprog`); where it is solved at once and the step's n = ``out.shape[1]`` first variables x are
    finite, x clipped to the box (rows ``OUT_LB``, ``OUT_UB`` of ``out``) into the rows ``OUT_DQ`` and ``OUT_KEPT``.
    Returns (daqp's exit flag — 0 when x is not finite —, its iterations)."""
    n = out.shape[1]
    flag, iters = native_quadprog(native, nx, qbuf, nvar, nr, neq)
    if flag != 1 and flag != 2:
        return flag, iters
    for j in range(n):
        if not math.isfinite(nx[j]):
            return 0, iters
    for j in range(n):
        v = min(max(nx[j], out[OUT_LB, j]), out[OUT_UB, j])
        out[OUT_DQ, j] = v
        out[OUT_KEPT, j] = v
    return flag, iters


@_jit
def box_qp_native_split_into(native: np.ndarray, nx: np.ndarray, qbuf: np.ndarray, P: np.ndarray, q: np.ndarray,
                             out: np.ndarray, min_saving: int, work: np.ndarray,
                             idx: np.ndarray) -> tuple[int, int, int]:  # fmt: skip
    """:func:`box_qp_native_into` for a QP at or above ``DaqpBackend``'s split size: the separable variables in
    closed form and daqp on the coupled ones (``box_kernels.split_separable``, then :func:`native_quadprog` on the
    coupled QP as ``DaqpBackend._solve_split`` poses it), x assembled and clipped into the rows ``OUT_DQ`` and
    ``OUT_KEPT`` of ``out``; ``work`` (4 + n, n) and ``idx`` (n,) are the split's scratch.

    Returns:
        (daqp's exit flag, its iterations plus the separable variables clipped onto a bound, n_c): n_c = −1 when the
        split is not made (nothing solved: the caller poses the whole QP); flag 0 when x is not finite.
    """
    n = P.shape[0]
    lb, ub = out[OUT_LB], out[OUT_UB]
    nc, clipped = split_separable(P, q, lb, ub, min_saving, work, idx)
    if nc < 0:
        return 0, 0, -1
    Pv, qv, _, upper, lower = qp_views(qbuf, nc, 0)
    Pc = work[4:].reshape(-1)
    for a in range(nc):
        qv[a] = work[1, a]
        lower[a] = work[2, a]
        upper[a] = work[3, a]
        for c in range(nc):
            Pv[a, c] = Pc[a * nc + c]
    flag, iters = native_quadprog(native, nx, qbuf, nc, 0, 0)
    if flag != 1 and flag != 2:
        return flag, iters, nc
    for a in range(nc):
        if not math.isfinite(nx[a]):
            return 0, iters, nc
    x = work[0]  # (the separable entries, from the split; the coupled ones from daqp)
    for a in range(nc):
        x[idx[a]] = nx[a]
    for j in range(n):
        v = min(max(x[j], lb[j]), ub[j])
        out[OUT_DQ, j] = v
        out[OUT_KEPT, j] = v
    return flag, iters + clipped, nc
