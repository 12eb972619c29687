"""Closed-loop kinematic simulation: resolve, integrate q ⊕ q̇·dt, log — the chapter's first-order update."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver, StepResult
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
        fallbacks: (step index, reason) for each step that fell back.
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


def simulate(
    robot: RobotModel,
    stack: TaskStack,
    resolver: Resolver,
    q0: np.ndarray,
    *,
    dt: float,
    steps: int,
    log_frames: tuple[str, ...] = (),
    extra_potentials: tuple = (),
    progress: Callable[[int], None] | None = None,
    plant: Plant | None = None,
) -> SimulationLog:
    """Run ``steps`` control ticks from ``q0`` with the first-order update q ← q ⊕ q̇·dt.

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

    Returns:
        The :class:`SimulationLog`.
    """
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
    names_task = [t.name for t in stack.tasks]
    Q = np.empty((n, robot.nq))
    DQ = np.zeros((n, robot.nv))
    E = {name: np.empty(n) for name in names_task}
    P = {p.name: np.empty(n) for p in watched}
    F = {f: np.empty((n, 3)) for f in log_frames}
    step_time = np.empty(steps)
    damped = np.zeros(steps, dtype=bool)
    extras: dict[str, np.ndarray] = {}
    fallbacks: list[tuple[int, str]] = []
    times = np.arange(n) * dt
    for k in range(n):
        t = float(times[k])
        t0 = time.perf_counter()
        res: StepResult = resolver.step(robot, stack, q, t, dt)
        elapsed = time.perf_counter() - t0
        Q[k] = q
        for term in res.terms:
            E[term.name][k] = term.error_norm
        for p in watched:
            P[p.name][k] = p.value(robot)
        for f in log_frames:
            F[f][k] = robot.frame_position(f)
        if k == steps:
            break
        step_time[k] = elapsed
        damped[k] = res.damped
        for key, val in res.info.items():
            if isinstance(val, (int, float, np.floating, np.integer)) and not isinstance(val, bool):
                extras.setdefault(key, np.full(steps, np.nan))[k] = float(val)
        if res.fallback:
            fallbacks.append((k, res.fallback))
        DQ[k] = res.dq
        q = robot.integrate(q, res.dq, dt) if plant is None else plant.step(res.dq, dt)
        if progress is not None:
            progress(k + 1)
    return SimulationLog(
        t=times,
        q=Q,
        dq=DQ,
        task_errors=E,
        potentials=P,
        step_time=step_time,
        damped=damped,
        fallbacks=fallbacks,
        extras=extras,
        frame_positions=F,
        main_tasks=[t.name for t in stack.tasks if not t.regularization],
    )
