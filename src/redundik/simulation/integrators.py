"""Time integration of the velocity law q̇ = f(t, q) that a resolver and a task stack define.

* ``euler`` — the chapter's first-order update q ← q ⊕ q̇·dt (the default, what the book plots);
* ``rk4`` — classical Runge-Kutta, four evaluations of the law per step;
* ``rk45`` — adaptive Dormand-Prince (:func:`scipy.integrate.solve_ivp`) between consecutive samples, with
  ``rtol`` / ``atol`` (defaults 1e-10 / 1e-12: the integration error is far below anything plotted).

With ``rk4`` / ``rk45`` the resolver is called at every intermediate (stage) state, so a run shows the controller's
own continuous-time behaviour rather than the Euler drift. **Stateful pieces** — a QP resolver's previous q̇ (the
acceleration / rate limit reference), backend warm starts, a waypoint potential's active waypoint — are saved
before the stages and restored after them: their state advances only at the samples (the accepted steps), where
the simulation evaluates the law once more for the log. Stage evaluations therefore all see the state of the last
sample. (A rate limit is then a limit between samples, as with ``euler``.)

The Runge-Kutta integrators need a robot whose configuration is a vector space (nq = nv: D-H chains and URDF
robots without a free-flyer base or continuous joints); the loader refuses them otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from redundik.errors import SimulationError

Integrator = Literal["euler", "rk4", "rk45"]
INTEGRATORS: tuple[str, ...] = ("euler", "rk4", "rk45")
#: Default relative / absolute tolerances of ``rk45``.
DEFAULT_RTOL, DEFAULT_ATOL = 1e-10, 1e-12
#: A configuration coordinate beyond this magnitude [rad or length unit] means the run has diverged.
MAX_COORDINATE = 1e9

#: The velocity law: f(t [s], q) → q̇.
Law = Callable[[float, np.ndarray], np.ndarray]


def check_finite(values: np.ndarray, what: str, t: float) -> None:
    """Stop a run whose ``values`` are not finite (or beyond :data:`MAX_COORDINATE`).

    Raises:
        SimulationError: one line naming the quantity and the time.
    """
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise SimulationError(
            f"the run diverged at t = {t:.6g} s: {what} is not finite (overflow: a gain or dt too large?)"
        )
    if arr.size and float(np.max(np.abs(arr))) > MAX_COORDINATE:
        raise SimulationError(
            f"the run diverged at t = {t:.6g} s: {what} exceeds {MAX_COORDINATE:g} (a gain or dt too large?)"
        )


class StateGuard:
    """Shallow snapshot of the attributes of stateful objects (resolver, tasks, potentials), to undo stage calls."""

    def __init__(self, objects: list[Any]) -> None:
        self._objects = [o for o in objects if hasattr(o, "__dict__")]
        self._saved: list[dict[str, Any]] = []

    def save(self) -> None:
        """Remember every object's attributes (a shallow copy of ``vars``)."""
        self._saved = [dict(vars(o)) for o in self._objects]

    def restore(self) -> None:
        """Put back the attributes saved by :meth:`save`."""
        for o, saved in zip(self._objects, self._saved, strict=True):
            vars(o).update(saved)


def rk4_step(law: Law, t: float, q: np.ndarray, k1: np.ndarray, dt: float) -> np.ndarray:
    """One classical RK4 step [s] from (t, q) with the slope k1 = f(t, q) already known."""
    k2 = law(t + dt / 2, q + k1 * (dt / 2))
    k3 = law(t + dt / 2, q + k2 * (dt / 2))
    k4 = law(t + dt, q + k3 * dt)
    return q + (k1 + 2 * k2 + 2 * k3 + k4) * (dt / 6)


def rk45_step(law: Law, t: float, q: np.ndarray, dt: float, rtol: float, atol: float) -> np.ndarray:
    """Adaptive Dormand-Prince from t to t + dt [s] (:func:`scipy.integrate.solve_ivp`, method ``RK45``).

    Raises:
        SimulationError: the solver failed (step size underflow, ...).
    """
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda s, y: law(float(s), y), (t, t + dt), q, method="RK45", rtol=rtol, atol=atol)
    if not sol.success:
        raise SimulationError(f"rk45 failed between t = {t:.6g} s and {t + dt:.6g} s: {sol.message}")
    return np.asarray(sol.y[:, -1], dtype=float)


#: Smallest ``rtol`` of ``rk45``: SciPy raises smaller ones to 100 ε ≈ 2.2e-14 behind a warning.
RTOL_MIN = 1e-13


def check_tolerances(rtol: float, atol: float) -> None:
    """Raise ValueError unless RTOL_MIN ≤ rtol < 1 and atol > 0, both finite."""
    if not (math.isfinite(rtol) and RTOL_MIN <= rtol < 1):
        raise ValueError(f"rtol must be in [{RTOL_MIN:g}, 1), got {rtol}")
    if not (math.isfinite(atol) and atol > 0):
        raise ValueError(f"atol must be > 0, got {atol}")
