"""Compiled kernels (numba) of :func:`redundik.solve_ik`: pose residuals and one box-constrained Levenberg–Marquardt
iteration, one call per iteration.

Why compiled: Pinocchio gives a frame's pose and Jacobian in ≈ 1.5 µs, while the NumPy route for the rest of an
iteration (residual, normal equations, a solve, the box) is a dozen small-array calls (≈ 20 µs of call overhead);
one compiled call does it in about a microsecond, so an IK iteration costs a few microseconds.

Residual of frame k (rows selected by ``mode[k]``: 0 pose, 1 position):

    r_k = (p_d − p, log3(R_d Rᵀ))   [m, rad],    ∂r_k/∂q ≈ −J_k   (J_k: the frame's LOCAL_WORLD_ALIGNED Jacobian)

With E = R_d Rᵀ and a world angular velocity ω, Ė = −E[ω]ₓ (a right perturbation of E), so θ = log3(E) moves by
−Jr⁻¹(θ) ω: the rotation rows are Jr⁻¹(θ) J_ω (``jr_inv``), the exact Jacobian of the residual.

Step: (JᵀJ + λ I) Δ = Jᵀ r on the free joints, Δ clipped into the box [lo − q, hi − q]; a joint whose step leaves
the box while it already sits on that bound is fixed and the system solved again without it (projected LM with an
active set on the bounds, at most nv passes). Accepted when the cost ½‖r‖² decreases (λ ← λ/3), else rejected
(λ ← 4λ).
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Codes returned by :func:`lm_update`.
CONTINUE, CONVERGED, STALLED = 0, 1, 2
#: Indices of the float state ``st``.
S_COST, S_LAM, S_WINDOW_COST = 0, 1, 2
#: Indices of the int state ``ist``.
I_ITER, I_WINDOW_START = 0, 1

LAM_MIN, LAM_MAX = 1e-12, 1e8


@_jit
def log3(R: np.ndarray, out: np.ndarray) -> None:
    """out ← log(R) as a rotation vector [rad] (R a 3×3 rotation; robust up to θ = π)."""
    wx = 0.5 * (R[2, 1] - R[1, 2])
    wy = 0.5 * (R[0, 2] - R[2, 0])
    wz = 0.5 * (R[1, 0] - R[0, 1])
    c = min(1.0, max(-1.0, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)))
    s = math.sqrt(wx * wx + wy * wy + wz * wz)
    theta = math.atan2(s, c)
    if theta < 1e-6:
        f = 1.0 + theta * theta / 6.0  # θ / sin θ
    elif theta < math.pi - 1e-3:
        f = theta / s
    else:  # near π: the axis from the diagonal, its signs from the largest component's column
        d = 1.0 - c
        a = np.empty(3)
        for i in range(3):
            a[i] = math.sqrt(max(0.0, (R[i, i] - c) / d))
        k = 0
        if a[1] > a[k]:
            k = 1
        if a[2] > a[k]:
            k = 2
        for i in range(3):
            if i != k and (R[i, k] + R[k, i]) < 0.0:
                a[i] = -a[i]
        w = (wx, wy, wz)
        if w[k] < 0.0:  # the sign of the axis follows the antisymmetric part (sin θ a)
            a = -a
        out[0], out[1], out[2] = theta * a[0], theta * a[1], theta * a[2]
        return
    out[0], out[1], out[2] = f * wx, f * wy, f * wz


@_jit
def jr_inv(w: np.ndarray, out: np.ndarray) -> None:
    """out ← Jr⁻¹(θ) = I + ½[θ]ₓ + c(θ)[θ]ₓ², c = 1/θ² − (1 + cos θ)/(2θ sin θ) (Barfoot, State Estimation for
    Robotics, §7.1.5), the inverse right Jacobian of SO(3) at the rotation vector ``w`` [rad]; c → 1/12 as θ → 0 and
    1/π² as θ → π, written with sin θ / (1 − cos θ) so that it stays finite at π."""
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    t = math.sqrt(t2)
    if t < 1e-4:
        c = 1.0 / 12.0 + t2 / 720.0
    else:
        c = 1.0 / t2 - math.sin(t) / (2.0 * t * (1.0 - math.cos(t)))
    x, y, z = w[0], w[1], w[2]
    out[0, 0] = 1.0 - c * (y * y + z * z)
    out[1, 1] = 1.0 - c * (x * x + z * z)
    out[2, 2] = 1.0 - c * (x * x + y * y)
    out[0, 1] = -0.5 * z + c * x * y
    out[1, 0] = 0.5 * z + c * x * y
    out[0, 2] = 0.5 * y + c * x * z
    out[2, 0] = -0.5 * y + c * x * z
    out[1, 2] = -0.5 * x + c * y * z
    out[2, 1] = 0.5 * x + c * y * z


@_jit
def residual(
    J6: np.ndarray, M: np.ndarray, T: np.ndarray, mode: np.ndarray, Jr: np.ndarray, r: np.ndarray, err: np.ndarray
) -> float:
    """Stack the frames' residual rows r and Jacobian rows Jr (see the module docstring); ``err[k]`` ← (position
    error [m], orientation error [rad], 0 for a position frame). Returns the cost ½‖r‖²."""
    row = 0
    Rd = np.empty((3, 3))
    Ji = np.empty((3, 3))
    w = np.empty(3)
    nv = J6.shape[2]
    for k in range(M.shape[0]):
        ep = 0.0
        for i in range(3):
            d = T[k, i, 3] - M[k, i, 3]
            r[row + i] = d
            ep += d * d
            for j in range(nv):
                Jr[row + i, j] = J6[k, i, j]
        err[k, 0] = math.sqrt(ep)
        row += 3
        if mode[k] == 0:
            for i in range(3):
                for j in range(3):
                    Rd[i, j] = T[k, i, 0] * M[k, j, 0] + T[k, i, 1] * M[k, j, 1] + T[k, i, 2] * M[k, j, 2]
            log3(Rd, w)
            jr_inv(w, Ji)
            for i in range(3):
                r[row + i] = w[i]
                for j in range(nv):
                    Jr[row + i, j] = Ji[i, 0] * J6[k, 3, j] + Ji[i, 1] * J6[k, 4, j] + Ji[i, 2] * J6[k, 5, j]
            err[k, 1] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
            row += 3
        else:
            err[k, 1] = 0.0
    cost = 0.0
    for i in range(row):
        cost += r[i] * r[i]
    return 0.5 * cost


@_jit
def _solve_free(Jr: np.ndarray, r: np.ndarray, lam: float, free: np.ndarray, dq: np.ndarray) -> bool:
    """dq ← (JᵀJ + λI)⁻¹ Jᵀr on the free joints (0 elsewhere), by Cholesky; False if not positive definite."""
    nv = Jr.shape[1]
    m = r.shape[0]
    idx = np.flatnonzero(free)
    n = idx.shape[0]
    A = np.empty((n, n))
    b = np.empty(n)
    for a in range(n):
        ja = idx[a]
        s = 0.0
        for i in range(m):
            s += Jr[i, ja] * r[i]
        b[a] = s
        for c in range(a + 1):
            jc = idx[c]
            s = 0.0
            for i in range(m):
                s += Jr[i, ja] * Jr[i, jc]
            A[a, c] = s
        A[a, a] += lam
    for a in range(n):  # Cholesky, lower triangle in place
        for c in range(a + 1):
            s = A[a, c]
            for k in range(c):
                s -= A[a, k] * A[c, k]
            if a == c:
                if not s > 0.0:
                    return False
                A[a, a] = math.sqrt(s)
            else:
                A[a, c] = s / A[c, c]
    for a in range(n):
        s = b[a]
        for k in range(a):
            s -= A[a, k] * b[k]
        b[a] = s / A[a, a]
    for a in range(n - 1, -1, -1):
        s = b[a]
        for k in range(a + 1, n):
            s -= A[k, a] * b[k]
        b[a] = s / A[a, a]
    for j in range(nv):
        dq[j] = 0.0
    for a in range(n):
        dq[idx[a]] = b[a]
    return True


@_jit
def box_step(
    Jr: np.ndarray, r: np.ndarray, lam: float, qv: np.ndarray, lo: np.ndarray, hi: np.ndarray, dq: np.ndarray
) -> bool:
    """The damped step dq within [lo − qv, hi − qv] (projected LM, active set on the bounds; module docstring).

    ``qv`` holds each velocity coordinate's position (NaN where it has none: no bound applies). Returns False
    when the normal equations are not positive definite (λ too small for them).
    """
    nv = Jr.shape[1]
    free = np.ones(nv, dtype=np.bool_)
    for _ in range(nv + 1):
        if not _solve_free(Jr, r, lam, free, dq):
            return False
        fixed = False
        for j in range(nv):
            if not free[j] or math.isnan(qv[j]):
                continue
            low, high = lo[j] - qv[j], hi[j] - qv[j]
            if (dq[j] < low and low > -1e-12) or (dq[j] > high and high < 1e-12):
                free[j] = False  # on its bound and pushed outwards: fixed, solve again without it
                fixed = True
        if not fixed:
            break
    for j in range(nv):
        if not free[j]:
            dq[j] = 0.0
        elif not math.isnan(qv[j]):
            dq[j] = min(max(dq[j], lo[j] - qv[j]), hi[j] - qv[j])
    return True


@_jit
def lm_update(
    first: bool,
    J6: np.ndarray,
    M: np.ndarray,
    T: np.ndarray,
    mode: np.ndarray,
    qt: np.ndarray,
    tol: np.ndarray,
    qmap: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    st: np.ndarray,
    ist: np.ndarray,
    work: tuple[np.ndarray, np.ndarray, np.ndarray],
    cur: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    out: tuple[np.ndarray, np.ndarray],
) -> int:
    """One LM iteration: judge the trial configuration ``qt`` (its frames' Jacobians ``J6`` (k, 6, nv) and poses
    ``M`` (k, 4, 4)), then propose the next trial.

    Args:
        first: ``qt`` is an attempt's start (always accepted; the state is reset).
        T: Targets (k, 4, 4); ``mode`` (k,) 0 pose, 1 position.
        tol: (position tolerance [m], orientation tolerance [rad], stall window [iterations], stall ratio [1]).
        qmap: Per velocity coordinate, its index in q (−1: no bound applies); ``lo``/``hi`` its bounds (nv,).
        st: Float state (cost, λ, cost at the window's start); ``ist`` int state (iteration, window start).
        work: Scratch (Jr (m, nv), r (m,), err (k, 2)) for the trial.
        cur: The current iterate (Jr, r, err, q), updated when the trial is accepted.
        out: (dq (nv,), q_next (nq,)): the next step and, for models whose q adds up (nq = nv), the next trial.

    Returns:
        :data:`CONVERGED` (the current iterate meets both tolerances), :data:`STALLED` (λ beyond its cap, the cost
        fell by less than the stall ratio over the window, or no step is left) or :data:`CONTINUE`.
    """
    Jr, r, err = work
    Jc, rc, errc, qc = cur
    dq, qn = out
    cost = residual(J6, M, T, mode, Jr, r, err)
    conv = True
    for k in range(err.shape[0]):
        if err[k, 0] > tol[0] or err[k, 1] > tol[1]:
            conv = False
    if first:
        st[1] = 1e-3
        ist[0] = 0
        ist[1] = 0
        st[2] = cost
    else:
        ist[0] += 1
    if first or conv or cost < st[0]:
        Jc[:, :] = Jr
        rc[:] = r
        errc[:, :] = err
        qc[:] = qt
        st[0] = cost
        if not first:
            st[1] = max(st[1] / 3.0, LAM_MIN)
        if conv:
            return CONVERGED
    else:
        st[1] *= 4.0
        if st[1] > LAM_MAX:
            return STALLED
    if ist[0] - ist[1] >= tol[2]:
        if st[0] > tol[3] * st[2]:
            return STALLED
        ist[1] = ist[0]
        st[2] = st[0]
    nv = dq.shape[0]
    qv = np.empty(nv)
    for j in range(nv):
        qv[j] = qc[qmap[j]] if qmap[j] >= 0 else np.nan
    while not box_step(Jc, rc, st[1], qv, lo, hi, dq):
        st[1] = max(10.0 * st[1], 1e-9)
        if st[1] > LAM_MAX:
            return STALLED
    big = 0.0
    for j in range(nv):
        big = max(big, abs(dq[j]))
    if big < 1e-14:
        return STALLED
    qn[:] = qc
    for j in range(nv):
        if qmap[j] >= 0:
            qn[qmap[j]] += dq[j]
    return CONTINUE
