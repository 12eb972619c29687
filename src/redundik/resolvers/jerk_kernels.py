"""Compiled kernels of jerk-limited joint-limit boxes (the rules of :mod:`redundik.resolvers.qp.limits`).

Per joint, in the discrete time of the control loop (one q̇ per step of length dt, q ← q + q̇·dt):

* velocity increments d_k = q̇_k − q̇_(k−1) are bounded by α = a_max·dt (the acceleration limit) and their
  changes |d_k − d_(k−1)| by β = j_max·dt² (the jerk limit);
* the state a step starts from is (q, q̇_(k−1), d_(k−1)); the candidates of this step form the window
  q̇_(k−1) + [max(d_(k−1) − β, −α), min(d_(k−1) + β, α)].

Viability (the joint can still stop inside its position limits, below its velocity limit, with bounded
acceleration and jerk) is tested by a roll-out of the *hardest braking* policy d ← max(d − β, −α) from the state
a candidate leads to: that policy decreases every later q, q̇ and d as much as the limits allow, and the closed
loop (q, q̇, d) → (q + q̇·dt, q̇ + d', d') is monotone (every output is non-decreasing in every input), so

* the candidate is viable for the upper limits exactly when this roll-out keeps q̇·dt ≤ g·(q_hi − q) and
  q̇ ≤ v_max at every step until q̇ ≤ 0 and d ≤ 0 (after which q never rises again) — one-sided viability is
  *exact*, not a sufficient condition;
* the set of viable candidates is an interval of the window (the roll-out's peaks grow with the candidate), found
  by bisection; the lower limits are the mirror image.

The first step of the roll-out from a viable state is itself in the window and viable (the roll-out from there is
the rest of the same roll-out), so a box computed from a viable state is never empty: recursive feasibility, as in
Del Prete (2018), "Joint position and velocity bounds in discrete-time acceleration/torque control of robot
manipulators" (IEEE RA-L 3(1)), whose acceleration-level argument this extends by one derivative. The braking
profiles are those of jerk-limited time-optimal stops (Berscheid & Kröger (2021), "Jerk-limited real-time
trajectory generation with arbitrary target states", RSS — Ruckig), here simulated step by step in discrete time
rather than solved in closed form, so that no continuous-time approximation enters the bound.

The two one-sided sets together are the joint's viability set as long as a reversal does not need more room than
the joint has (a range wider than about a_max³/j_max² and velocity limits wider than a_max²/j_max, true of every
robot we ship); otherwise the box may be empty and the caller relaxes the jerk limit (the limits module's order).
"""

from __future__ import annotations

import math

import numpy as np

from redundik import _kernel_cache
from redundik.resolvers.layouts import (
    JERK_BRAKE_HI,
    JERK_BRAKE_LO,
    JERK_LB,
    JERK_UB,
    JERK_WINDOW_HI,
    JERK_WINDOW_LO,
    LIM_AMAX,
    LIM_HI,
    LIM_JMAX,
    LIM_LO,
    LIM_VMAX,
)

_jit = _kernel_cache.jit  # numba.njit, cached in the user's cache folder (redundik._kernel_cache)

#: Longest braking roll-out simulated [steps]; a longer one counts as a breach (conservative).
MAX_ROLLOUT = 2_000_000
#: Relative margin [-] the bisection keeps from a breach (the rounding of the next step's roll-out stays inside).
MARGIN = 1e-11
#: Status codes of :func:`jerk_box`, per joint.
OK, EMPTY = 0, 1


@_jit
def breach_up(
    q: float, v: float, d: float, hi: float, vm: float, alpha: float, beta: float, dt: float, gain: float, slack: float
) -> bool:
    """True when hardest braking from (q, q̇ = v applied this step, d = v − q̇_prev) breaks an upper limit: some
    step's q̇·dt > g·(hi − q) + slack·max(1, |hi|), or q̇ > v_max·(1 + slack) (slack < 0: a margin)."""
    if hi == math.inf and vm == math.inf:
        return False
    sx = slack * max(1.0, abs(hi)) if hi < math.inf else 0.0
    sv = slack * max(1.0, vm) if vm < math.inf else 0.0
    # a cheap sufficient test first: the peak speed, the steps to stop and the distance they can cover
    vpk = max(v, 0.0) + (d + d * d / (2.0 * beta) if d > 0.0 else 0.0)
    if vpk <= vm + sv or vm == math.inf:
        n1 = (max(d, 0.0) / beta) + 2.0
        if alpha == math.inf or vpk <= alpha * alpha / (2.0 * beta):
            n2 = math.sqrt(2.0 * vpk / beta) + 2.0
        else:
            n2 = vpk / alpha + alpha / beta + 2.0
        dist = (n1 + n2) * vpk * dt
        if vpk * dt <= gain * (hi - q - dist) + sx:
            return False
    x = q
    for _ in range(MAX_ROLLOUT):
        if v > vm + sv or v * dt > gain * (hi - x) + sx:
            return True
        if v <= 0.0 and d <= 0.0:
            return False
        x += v * dt
        d = max(d - beta, -alpha)
        v += d
    return True


@_jit
def _edge(
    q: float, v1: float, lo_c: float, hi_c: float, hi: float, vm: float, alpha: float, beta: float, dt: float,
    gain: float,
) -> float:  # fmt: skip
    """The largest candidate of [lo_c, hi_c] whose hardest braking keeps the upper limits with the margin
    (``lo_c`` itself when only it passes; the caller checked that it passes without the margin)."""
    if not breach_up(q, hi_c, hi_c - v1, hi, vm, alpha, beta, dt, gain, -MARGIN):
        return hi_c
    if breach_up(q, lo_c, lo_c - v1, hi, vm, alpha, beta, dt, gain, -MARGIN):
        return lo_c
    a, b = lo_c, hi_c  # a passes, b breaches
    for _ in range(80):
        if b - a <= 1e-14 * max(1.0, abs(a), abs(b)):
            break
        m = 0.5 * (a + b)
        if breach_up(q, m, m - v1, hi, vm, alpha, beta, dt, gain, -MARGIN):
            b = m
        else:
            a = m
    return a


@_jit
def jerk_box(
    q: np.ndarray,
    iq: np.ndarray,
    lim: np.ndarray,
    position: bool,
    gain: float,
    dt: float,
    v1: np.ndarray,
    v2: np.ndarray,
    out: np.ndarray,
    status: np.ndarray,
) -> None:
    """The jerk-limited box of every joint with a finite jerk limit (the module docstring's rules).

    ``q`` (nq,) is the configuration and ``iq`` (nv,) each q̇ coordinate's q index; ``lim`` the joint-limit record
    (``LIM_JERK_ROWS``, nv: ``layouts.LIM_LO``/``LIM_HI`` the position limits, ±inf where none; ``LIM_VMAX``,
    ``LIM_AMAX``, ``LIM_JMAX`` the velocity [rad/s], acceleration [rad/s²] and jerk [rad/s³] limits, inf where
    none); ``position``: the position limits apply (else each joint is taken at 0 between ±inf); ``gain`` g,
    ``dt`` [s], ``v1``/``v2`` the last two q̇ [rad/s]. Writes, for those joints, the rows ``JERK_LB``,
    ``JERK_UB``, ``JERK_BRAKE_LO``, ``JERK_BRAKE_HI``, ``JERK_WINDOW_LO``, ``JERK_WINDOW_HI`` of ``out``
    (``JERK_ROWS``, nv) and ``status`` (nv,) ``OK`` or ``EMPTY`` (no candidate meets jerk, acceleration and
    viability together; the row is then left to the caller's relaxation). Joints with an infinite jerk limit are
    not touched.
    """
    for i in range(iq.shape[0]):
        j = lim[LIM_JMAX, i]
        if not j < math.inf:
            continue
        if position:
            q_i, lo_i, hi_i = q[iq[i]], lim[LIM_LO, i], lim[LIM_HI, i]
        else:
            q_i, lo_i, hi_i = 0.0, -math.inf, math.inf
        alpha = lim[LIM_AMAX, i] * dt
        beta = j * dt * dt
        d1 = v1[i] - v2[i]
        wl = v1[i] + max(d1 - beta, -alpha)
        wu = v1[i] + min(d1 + beta, alpha)
        vm = lim[LIM_VMAX, i]
        mhi = -lo_i  # the lower side, mirrored (q → −q): its limit as an upper one
        status[i] = EMPTY
        out[JERK_WINDOW_LO, i], out[JERK_WINDOW_HI, i] = wl, wu
        if not wl <= wu:
            continue
        if breach_up(q_i, wl, wl - v1[i], hi_i, vm, alpha, beta, dt, gain, 0.0):
            continue
        if breach_up(-q_i, -wu, v1[i] - wu, mhi, vm, alpha, beta, dt, gain, 0.0):
            continue
        ub = _edge(q_i, v1[i], wl, wu, hi_i, vm, alpha, beta, dt, gain)
        lb = -_edge(-q_i, -v1[i], -wu, -wl, mhi, vm, alpha, beta, dt, gain)
        if lb > ub:
            continue
        out[JERK_LB, i], out[JERK_UB, i], out[JERK_BRAKE_LO, i], out[JERK_BRAKE_HI, i] = lb, ub, lb, ub
        status[i] = OK
