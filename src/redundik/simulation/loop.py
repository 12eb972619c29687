"""Closed-loop kinematic simulation: resolve, integrate, log.

The default integrator is the chapter's first-order update q ← q ⊕ q̇·dt; ``rk4`` and ``rk45`` integrate the same
velocity law accurately (see :mod:`redundik.simulation.integrators`). A run whose q̇, q, task errors or potential
values stop being finite raises :class:`~redundik.errors.SimulationError` instead of logging inf/NaN.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from redundik.errors import SimulationError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult
from redundik.simulation.integrators import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    INTEGRATORS,
    StateGuard,
    check_finite,
    check_tolerances,
    rk4_step,
    rk45_step,
)
from redundik.simulation.plant import Plant
from redundik.tasks.stack import TaskStack


@dataclass
class SimulationLog:
    """Everything recorded during a simulated run, one row per sample (steps + 1 samples, t = 0 … T).

    Attributes:
        t: Times [s], shape (N,).
        q: Configurations, shape (N, nq).
        dq: Joint velocities applied after each sample, shape (N, nv) (last row zero).
        task_errors: Per main task, the error norm at each sample, shape (N,).
        potentials: Per subtask potential, its value at each sample, shape (N,).
        step_time: Wall time of each resolver step (kinematics update + solve) [s], shape (N−1,).
        damped: Whether the step was damped, shape (N−1,).
        fallbacks: (step index, reason) for each step that fell back (``StepResult.fallback``: the answer is not
            what the stack asked beyond its documented relaxations — an alarm).
        relaxed: (step index, member names) for each step that made a documented relaxation
            (``StepResult.relaxed``: an ``hqp`` level contradicted by those above, a ``wqp`` bound subtask dropped
            from an infeasible QP — not an alarm).
        extras: Per-step scalar diagnostics by name (e.g. ``"sigma_min"``), shape (N−1,).
        frame_positions: Logged frame origins by frame name, shape (N, 3).
        main_tasks: Names of the main tasks (regularisation tasks such as a posture are logged but not counted in
            :attr:`stacked_error`); ``None``: every task.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    task_errors: dict[str, np.ndarray]
    potentials: dict[str, np.ndarray]
    step_time: np.ndarray
    damped: np.ndarray
    fallbacks: list[tuple[int, str]] = field(default_factory=list)
    relaxed: list[tuple[int, tuple[str, ...]]] = field(default_factory=list)
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    frame_positions: dict[str, np.ndarray] = field(default_factory=dict)
    main_tasks: list[str] | None = None

    @property
    def max_task_error(self) -> float:
        """Largest norm of the stacked task error over the run."""
        return float(np.max(self.stacked_error)) if self.stacked_error.size else 0.0

    @property
    def stacked_error(self) -> np.ndarray:
        """Norm of all task errors together at each sample, shape (N,)."""
        names = list(self.task_errors) if self.main_tasks is None else self.main_tasks
        if not names:
            return np.zeros_like(self.t)
        return np.sqrt(sum(self.task_errors[k] ** 2 for k in names))


#: Largest memory the logs of one :func:`simulate` call may take [bytes] (a typo in ``steps`` fails at once).
MAX_LOG_BYTES = 4 * 1024**3


def _check_time_grid(robot: RobotModel, stack: TaskStack, dt: object, steps: object, extra_columns: int) -> None:
    """Refuse a ``dt`` that is not a finite number > 0 and a ``steps`` that is not a whole number ≥ 0 whose logs fit.

    Raises:
        SimulationError: names the argument, its value and what was expected.
    """
    for what, value, kind in (("robot", robot, RobotModel), ("stack", stack, TaskStack)):
        if not isinstance(value, kind):
            raise SimulationError(f"simulate: {what} must be a {kind.__name__}, got {type(value).__name__}")
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
        raise SimulationError(f"simulate: dt must be a number [s], got {type(dt).__name__}")
    if not (math.isfinite(dt) and dt > 0):
        raise SimulationError(f"simulate: dt must be finite and > 0 [s], got {dt}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)):
        raise SimulationError(f"simulate: steps must be a whole number, got {type(steps).__name__} {steps!r}")
    if steps < 0:
        raise SimulationError(f"simulate: steps must be ≥ 0, got {steps}")
    columns = robot.nq + robot.nv + len(stack.tasks) + len(stack.subtasks) + 3 * extra_columns + 4
    need = (int(steps) + 1) * columns * 8
    if need > MAX_LOG_BYTES:
        raise SimulationError(
            f"simulate: the logs of {steps} steps would need {need / 1024**3:.3g} GiB (at most "
            f"{MAX_LOG_BYTES / 1024**3:g}); simulate fewer steps at a time"
        )


def _check_integrator(
    robot: RobotModel, resolver: object, plant: Plant | None, integrator: str, tolerances: tuple[float, float]
) -> None:
    """Refuse an unknown integrator, bad ``rk45`` tolerances (rtol, atol), Runge-Kutta with nq ≠ nv or with a plant,
    and a resolver that is not a :class:`Resolver`.

    Raises:
        ValueError: the integrator's problems.
        SimulationError: not a resolver.
    """
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    check_tolerances(*tolerances)
    if integrator != "euler" and robot.nq != robot.nv:
        raise ValueError(
            f"integrator {integrator} needs nq = nv (no free-flyer base), got nq={robot.nq}, nv={robot.nv}"
        )
    if plant is not None and integrator != "euler":
        raise ValueError(f"integrator {integrator}: a plant integrates its own dynamics; use integrator euler with it")
    if not isinstance(resolver, Resolver):
        raise SimulationError(f"simulate: resolver must be a Resolver (make_resolver(NAME)), got {resolver!r:.60}")


class _Recorder:
    """The logs of a run being simulated: one row per sample (``steps`` + 1), per-step records, then the
    :class:`SimulationLog`."""

    def __init__(
        self, robot: RobotModel, stack: TaskStack, watched: list[Any], log_frames: tuple[str, ...], steps: int
    ) -> None:
        n = steps + 1
        self.robot, self.watched, self.log_frames, self.steps = robot, watched, log_frames, steps
        self.Q = np.empty((n, robot.nq))
        self.DQ = np.zeros((n, robot.nv))
        self.E = {t.name: np.empty(n) for t in stack.tasks}
        self.P = {p.name: np.empty(n) for p in watched}
        self.F = {f: np.empty((n, 3)) for f in log_frames}
        self.step_time = np.empty(steps)
        self.damped = np.zeros(steps, dtype=bool)
        self.extras: dict[str, np.ndarray] = {}
        self.fallbacks: list[tuple[int, str]] = []
        self.relaxed: list[tuple[int, tuple[str, ...]]] = []

    def sample(self, k: int, t: float, q: np.ndarray, res: StepResult) -> None:
        """Record sample k at time t [s] (q, task errors, potentials, frame origins); stop at a non-finite one."""
        self.Q[k] = q
        for term in res.terms:
            self.E[term.name][k] = term.error_norm
        for p in self.watched:
            self.P[p.name][k] = p.value(self.robot)
        for f in self.log_frames:
            self.F[f][k] = self.robot.frame_position(f)
        _check_sample(k, t, res, self.E, self.P)

    def step(self, k: int, elapsed: float, res: StepResult) -> None:
        """Record step k: its wall time [s], damping, numeric diagnostics, fallback, relaxations and q̇."""
        self.step_time[k] = elapsed
        self.damped[k] = res.damped
        for key, val in res.info.items():
            if isinstance(val, (int, float, np.floating, np.integer)) and not isinstance(val, bool):
                self.extras.setdefault(key, np.full(self.steps, np.nan))[k] = float(val)
        if res.fallback:
            self.fallbacks.append((k, res.fallback))
        if res.relaxed:
            self.relaxed.append((k, tuple(res.relaxed)))
        self.DQ[k] = res.dq

    def log(self, times: np.ndarray, stack: TaskStack) -> SimulationLog:
        """The :class:`SimulationLog` of the samples at ``times`` [s]."""
        return SimulationLog(
            t=times,
            q=self.Q,
            dq=self.DQ,
            task_errors=self.E,
            potentials=self.P,
            step_time=self.step_time,
            damped=self.damped,
            fallbacks=self.fallbacks,
            relaxed=self.relaxed,
            extras=self.extras,
            frame_positions=self.F,
            main_tasks=[t.name for t in stack.tasks if not t.regularization],
        )


def simulate(
    robot: RobotModel,
    stack: TaskStack,
    resolver: Resolver,
    q0: np.ndarray,
    *,
    dt: float,
    steps: int,
    log_frames: tuple[str, ...] = (),
    extra_potentials: tuple[Any, ...] = (),
    progress: Callable[[int], None] | None = None,
    plant: Plant | None = None,
    integrator: str = "euler",
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
) -> SimulationLog:
    """Run ``steps`` control ticks from ``q0``: by default the first-order update q ← q ⊕ q̇·dt.

    Args:
        robot: The robot model.
        stack: Main tasks and subtasks (reset here at q0).
        resolver: Any resolver.
        q0: Initial configuration (size nq).
        dt: Time step [s] > 0.
        steps: Number of steps ≥ 1.
        log_frames: Frames whose origins are logged at each sample (for drawings).
        extra_potentials: Potentials logged but not controlled (e.g. tr(JWJᵀ) under a rank-only run).
        progress: Called with the number of steps done, for a progress bar.
        plant: Drive this plant with q̇ and read its measured q at every tick instead of integrating.
        integrator: ``euler`` (the chapter's update), ``rk4`` or ``rk45`` (:mod:`redundik.simulation.integrators`;
            the resolver is called at every stage, ``dq`` is logged at the samples). Runge-Kutta needs nq = nv.
        rtol: Relative tolerance of ``rk45``.
        atol: Absolute tolerance of ``rk45`` [rad or length unit].

    Returns:
        The :class:`SimulationLog`.

    Raises:
        ValueError: unknown integrator, bad tolerances, or Runge-Kutta on a robot with nq ≠ nv.
        SimulationError: q̇, q, a task error or a potential became non-finite (or diverged) during the run.
    """
    _check_integrator(robot, resolver, plant, integrator, (rtol, atol))
    _check_time_grid(robot, stack, dt, steps, len(log_frames) + len(extra_potentials))
    q = robot.check_configuration(q0, "q0").copy()
    if plant is not None:
        q = plant.reset(q)
    n = steps + 1
    robot.update(q)
    stack.reset(robot)
    resolver.reset()
    resolver.check(robot, stack)
    for p in extra_potentials:
        p.check(robot)
    watched = [p for p in (getattr(s, "potential", None) for s in stack.subtasks) if p is not None]
    watched += list(extra_potentials)
    rec = _Recorder(robot, stack, watched, log_frames, steps)
    times = np.arange(n) * dt
    dog = getattr(resolver, "watchdog", None)  # (the command watchdog's state too: redundik.resolvers.watchdog)
    guard = StateGuard([resolver, *stack.tasks, *stack.subtasks, *watched, *([dog] if dog is not None else [])])

    def law(t: float, q_stage: np.ndarray) -> np.ndarray:
        dq_stage = resolver.step(robot, stack, q_stage, t, dt).dq
        check_finite(dq_stage, "the joint velocity q̇ (at an integrator stage)", t)
        return np.asarray(dq_stage, dtype=float)

    with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported once, as a SimulationError
        for k in range(n):
            t = float(times[k])
            t0 = time.perf_counter()
            res: StepResult = resolver.step(robot, stack, q, t, dt)
            elapsed = time.perf_counter() - t0
            rec.sample(k, t, q, res)
            if k == steps:
                break
            if plant is None:
                q = _advance(robot, law, guard, integrator, t, q, res, dt, rtol, atol)
            else:  # the plant integrates its own dynamics at its own rate; q is what it measures
                q = plant.step(res.dq, dt)
            rec.step(k, elapsed, res)
            if progress is not None:
                progress(k + 1)
    return rec.log(times, stack)


def _check_sample(k: int, t: float, res: StepResult, E: dict[str, np.ndarray], P: dict[str, np.ndarray]) -> None:
    """Stop the run at the first non-finite q̇, task error or potential value of sample ``k``."""
    check_finite(res.dq, "the joint velocity q̇", t)
    for name, e in E.items():
        check_finite(e[k : k + 1], f"the error of task '{name}'", t)
    for name, p in P.items():
        if not np.isfinite(p[k]):
            raise SimulationError(f"the run diverged at t = {t:.6g} s: potential '{name}' is not finite")


def _advance(
    robot: RobotModel,
    law: Callable[[float, np.ndarray], np.ndarray],
    guard: StateGuard,
    integrator: str,
    t: float,
    q: np.ndarray,
    res: StepResult,
    dt: float,
    rtol: float,
    atol: float,
) -> np.ndarray:
    """The configuration at t + dt [s] from the sample (t, q) whose resolver answer is ``res``."""
    if integrator == "euler":
        q_next = robot.integrate(q, res.dq, dt)
    else:
        guard.save()  # stage calls must not advance the resolver's / potentials' state (see integrators.py)
        try:
            if integrator == "rk4":
                q_next = rk4_step(law, t, q, np.asarray(res.dq, dtype=float), dt)
            else:
                q_next = rk45_step(law, t, q, dt, rtol, atol)
        finally:
            guard.restore()
    check_finite(q_next, "the configuration q", t + dt)
    return q_next
