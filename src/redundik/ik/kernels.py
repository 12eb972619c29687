"""Compiled kernels (numba) of :func:`redundik.solve_ik`: pose residuals and one box-constrained Levenberg–Marquardt
iteration, one call per iteration.

Why compiled: through NumPy, the rest of an iteration after Pinocchio's pose and Jacobian (residual, normal
equations, a solve, the box) would be a dozen small-array calls, whose overhead, not their arithmetic, dominates at
these sizes; so it is one compiled call, and an iteration costs little more than Pinocchio's part.

Residual of frame k (rows selected by ``mode[k]``: 0 pose, 1 position):

    r_k = (w_p (p_d − p), log3(R_d Rᵀ))   [rad],    ∂r_k/∂q ≈ −(w_p J_k,v ; Jr⁻¹ J_k,ω)

(J_k: the frame's LOCAL_WORLD_ALIGNED Jacobian; w_p [rad/m] weighs a metre against a radian, 2 by default.) With
E = R_d Rᵀ and a world angular velocity ω, Ė = −E[ω]ₓ (a right perturbation of E), so θ = log3(E) moves by
−Jr⁻¹(θ) ω: the rotation rows are Jr⁻¹(θ) J_ω (``jr_inv``), the exact Jacobian of the residual.

Step: (JᵀJ + (λ + c·E) I) Δ = Jᵀ r on the free joints, E = ½‖r‖² the cost: the damping grows with the error
(Sugihara, "Solvability-unconcerned inverse kinematics by the Levenberg–Marquardt method", IEEE T-RO 27(5), 2011:
far from the target the step is short and gradient-like, near it Gauss–Newton), c = 0.1 by default, λ adaptive.
Δ is clipped into the box [lo − q, hi − q]; a joint whose step leaves the box while it already sits on that bound
is fixed and the system solved again without it (projected LM with an active set on the bounds, at most nv
passes). Accepted when the cost decreases (λ ← λ/3), else rejected (λ ← 4λ).

Measured on 300 reachable poses (attempts from mid-range then uniform restarts, 1e-5 m / 1e-4 rad): the error-
proportional damping and w_p = 2 raise the share of attempts that converge from 0.40 to 0.70 on the UR5 and from
0.64 to 0.78 on the Panda, and lower the iterations per solved pose from 43 to 18 and from 26 to 16.

Every kernel takes at most 7 parameters. ``lm_update``'s are plain arrays: Pinocchio's output, the targets,
the problem's constants packed in one float and one int array, and one workspace (``workspace``: the trial's
and the current iterate's residual, errors and q, the step, the state), because numba types a tuple's elements in
Python at every call, which costs several times what a few packed arrays do. Their layouts are named in
:mod:`redundik.ik.layouts`.
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.ik.layouts import (
    CURRENT,
    ERR_POS,
    ERR_ROT,
    IK_MODES,
    IK_NQ,
    N_ERR,
    N_ITERATES,
    N_PARAMS,
    N_STATE,
    P_COST_DAMPING,
    P_RATIO,
    P_TOL_POS,
    P_TOL_ROT,
    P_WINDOW,
    P_WPOS,
    S_COST,
    S_ITER,
    S_LAM,
    S_WINDOW_COST,
    S_WINDOW_START,
    TRIAL,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Codes returned by ``lm_update``.
CONTINUE, CONVERGED, STALLED = 0, 1, 2
LAM_START, LAM_MIN, LAM_MAX = 1e-3, 1e-12, 1e8


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
    frames: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    w_pos: float,
    Jr: np.ndarray,
    r: np.ndarray,
    err: np.ndarray,
) -> float:
    """Stack the frames' residual rows r and Jacobian rows Jr (see the module docstring; six rows per frame, the
    rotation rows of a position target zero), the position rows weighted by ``w_pos`` [rad/m]; ``frames`` = (J6
    (6k, nv), M (4k, 4), T (4k, 4), mode (k,)). ``err[k]`` ← (position error [m], orientation error [rad], 0 for a
    position frame), unweighted. Returns the cost ½‖r‖²."""
    J6, M, T, mode = frames
    row = 0
    Rd = np.empty((3, 3))
    Ji = np.empty((3, 3))
    w = np.empty(3)
    nv = J6.shape[1]
    for k in range(mode.shape[0]):
        a, b = 4 * k, 6 * k
        ep = 0.0
        for i in range(3):
            d = T[a + i, 3] - M[a + i, 3]
            r[row + i] = w_pos * d
            ep += d * d
            for j in range(nv):
                Jr[row + i, j] = w_pos * J6[b + i, j]
        err[k, ERR_POS] = math.sqrt(ep)
        row += 3
        if mode[k] == 0:
            for i in range(3):
                for j in range(3):
                    Rd[i, j] = T[a + i, 0] * M[a + j, 0] + T[a + i, 1] * M[a + j, 1] + T[a + i, 2] * M[a + j, 2]
            log3(Rd, w)
            jr_inv(w, Ji)
            for i in range(3):
                r[row + i] = w[i]
                for j in range(nv):
                    Jr[row + i, j] = Ji[i, 0] * J6[b + 3, j] + Ji[i, 1] * J6[b + 4, j] + Ji[i, 2] * J6[b + 5, j]
            err[k, ERR_ROT] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        else:  # a position target: its rotation rows are zero (the buffers are reused over targets)
            for i in range(3):
                r[row + i] = 0.0
                for j in range(nv):
                    Jr[row + i, j] = 0.0
            err[k, ERR_ROT] = 0.0
        row += 3
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
    Jr: np.ndarray, r: np.ndarray, lam: float, qv: np.ndarray, bounds: tuple[np.ndarray, np.ndarray], dq: np.ndarray
) -> bool:
    """The damped step dq within [lo − qv, hi − qv], ``bounds`` = (lo, hi) (projected LM, active set on the bounds;
    module docstring).

    ``qv`` holds each velocity coordinate's position (NaN where it has none: no bound applies). Returns False
    when the normal equations are not positive definite (λ too small for them).
    """
    lo, hi = bounds
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
def offsets(k: int, nv: int, nq: int) -> tuple[int, int, int, int, int, int, int]:
    """Where the workspace's parts start (``workspace``), and its length: (Jr, r, err, q, dq, state, total)
    for k frames, nv velocity and nq position coordinates."""
    m = 6 * k
    o_r = N_ITERATES * m * nv
    o_err = o_r + N_ITERATES * m
    o_q = o_err + N_ITERATES * k * N_ERR
    o_dq = o_q + N_ITERATES * nq
    o_st = o_dq + nv
    return 0, o_r, o_err, o_q, o_dq, o_st, o_st + N_STATE


@_jit
def workspace(ws: np.ndarray, k: int, nv: int, nq: int) -> tuple[np.ndarray, ...]:
    """Views of the workspace ``ws`` (one float array, :func:`offsets`): (Jr (2, m, nv), r (2, m), err (2, k, 2),
    q (2, nq), dq (nv,), st (:data:`N_STATE`,)); index ``TRIAL`` the trial, ``CURRENT`` the current iterate (m = 6k
    rows; the layouts of :mod:`redundik.ik.layouts`)."""
    o_J, o_r, o_err, o_q, o_dq, o_st, end = offsets(k, nv, nq)
    m = 6 * k
    return (
        ws[o_J:o_r].reshape((N_ITERATES, m, nv)),
        ws[o_r:o_err].reshape((N_ITERATES, m)),
        ws[o_err:o_q].reshape((N_ITERATES, k, N_ERR)),
        ws[o_q:o_dq].reshape((N_ITERATES, nq)),
        ws[o_dq:o_st],
        ws[o_st:end],
    )


@_jit
def lm_update(
    first: bool, J6: np.ndarray, M: np.ndarray, T: np.ndarray, consts: np.ndarray, ints: np.ndarray, ws: np.ndarray
) -> int:
    """One LM iteration: judge the trial configuration (the workspace's q[0]), then write the next trial there.

    Args:
        first: The trial is an attempt's start (always accepted; the state is reset).
        J6: (6k, nv) the frames' LOCAL_WORLD_ALIGNED Jacobians at the trial, frame after frame (Pinocchio's).
        M: (4k, 4) the frames' poses at the trial.
        T: (4k, 4) their targets.
        consts: the parameters (:data:`redundik.ik.layouts.PARAMS`) then lo (nv,) and hi (nv,), each velocity
            coordinate's bounds.
        ints: nq, then mode (k,) (0 pose, 1 position), then qmap (nv,) (each velocity coordinate's index in q; −1:
            no bound applies) (slots ``IK_NQ``, ``IK_MODES``).
        ws: The workspace (``workspace``): the trial's and the current iterate's residual rows, errors and q,
            the step dq (nv,) from the current iterate to the next trial (that trial's q is written for models whose
            q adds up; others compose q ⊕ dq themselves) and the state (:data:`S_COST` …).

    Why packed: numba types every argument at each call, a tuple element by element in Python, so the call's cost
    grows with its parameters; 7 parameters of plain arrays cost a few times less than the same data as 15
    parameters and tuples.

    Returns:
        :data:`CONVERGED` (the current iterate meets both tolerances), :data:`STALLED` (λ beyond its cap, the cost
        fell by less than the stall ratio over the window, or no step is left) or :data:`CONTINUE`.
    """
    k, nv, nq = T.shape[0] // 4, J6.shape[1], ints[IK_NQ]
    mode, qmap = ints[IK_MODES : IK_MODES + k], ints[IK_MODES + k : IK_MODES + k + nv]
    params, lo, hi = consts[:N_PARAMS], consts[N_PARAMS : N_PARAMS + nv], consts[N_PARAMS + nv : N_PARAMS + 2 * nv]
    Jr, r, err, q, dq, st = workspace(ws, k, nv, nq)
    cost = residual((J6, M, T, mode), params[P_WPOS], Jr[TRIAL], r[TRIAL], err[TRIAL])
    conv = True
    for f in range(k):
        if err[TRIAL, f, ERR_POS] > params[P_TOL_POS] or err[TRIAL, f, ERR_ROT] > params[P_TOL_ROT]:
            conv = False
    if first:
        st[S_LAM] = LAM_START
        st[S_ITER] = 0.0
        st[S_WINDOW_START] = 0.0
        st[S_WINDOW_COST] = cost
    else:
        st[S_ITER] += 1.0
    if first or conv or cost < st[S_COST]:
        Jr[CURRENT, :, :] = Jr[TRIAL, :, :]
        r[CURRENT, :] = r[TRIAL, :]
        err[CURRENT, :, :] = err[TRIAL, :, :]
        q[CURRENT, :] = q[TRIAL, :]
        st[S_COST] = cost
        if not first:
            st[S_LAM] = max(st[S_LAM] / 3.0, LAM_MIN)
        if conv:
            return CONVERGED
    else:
        st[S_LAM] *= 4.0
        if st[S_LAM] > LAM_MAX:
            return STALLED
    if st[S_ITER] - st[S_WINDOW_START] >= params[P_WINDOW]:
        if st[S_COST] > params[P_RATIO] * st[S_WINDOW_COST]:
            return STALLED
        st[S_WINDOW_START] = st[S_ITER]
        st[S_WINDOW_COST] = st[S_COST]
    qv = np.empty(nv)
    for j in range(nv):
        qv[j] = q[CURRENT, qmap[j]] if qmap[j] >= 0 else np.nan
    damping = st[S_LAM] + params[P_COST_DAMPING] * st[S_COST]
    while not box_step(Jr[CURRENT], r[CURRENT], damping, qv, (lo, hi), dq):
        st[S_LAM] = max(10.0 * st[S_LAM], 1e-9)
        if st[S_LAM] > LAM_MAX:
            return STALLED
        damping = st[S_LAM] + params[P_COST_DAMPING] * st[S_COST]
    big = 0.0
    for j in range(nv):
        big = max(big, abs(dq[j]))
    if big < 1e-14:
        return STALLED
    q[TRIAL, :] = q[CURRENT, :]
    for j in range(nv):
        if qmap[j] >= 0:
            q[TRIAL, qmap[j]] += dq[j]
    return CONTINUE


@_jit
def rigid_transform(H: np.ndarray, max_coordinate: float) -> bool:
    """Whether the 4×4 matrix H is, well within the frame task's own rules (``tasks.frame._as_pose``), a rigid
    transform: finite, R Rᵀ = I to 1e-6, det R > 0, last row (0, 0, 0, 1), |position| ≤ ``max_coordinate`` [m].
    False sends the target through those rules (which name what is wrong)."""
    for i in range(4):
        for j in range(4):
            if not math.isfinite(H[i, j]):
                return False
    for i in range(3):
        if abs(H[i, 3]) > max_coordinate or H[3, i] != 0.0:
            return False
        for j in range(3):
            s = H[i, 0] * H[j, 0] + H[i, 1] * H[j, 1] + H[i, 2] * H[j, 2]
            if abs(s - (1.0 if i == j else 0.0)) > 1e-6:
                return False
    det = (
        H[0, 0] * (H[1, 1] * H[2, 2] - H[1, 2] * H[2, 1])
        - H[0, 1] * (H[1, 0] * H[2, 2] - H[1, 2] * H[2, 0])
        + H[0, 2] * (H[1, 0] * H[2, 1] - H[1, 1] * H[2, 0])
    )
    return det > 0.0 and H[3, 3] == 1.0
