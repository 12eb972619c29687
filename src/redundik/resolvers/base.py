"""What every resolver shares: the step result record and the abstract interface."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.tasks.base import TaskStack, TaskTerm


@dataclass
class StepResult:
    """One resolved control step.

    Attributes:
        dq: Joint velocity q̇, shape (nv,), always finite.
        terms: The main-task terms the step was computed from.
        dq_rank: The rank (main-task) part J⁺V when the resolver separates it, else ``None``.
        dq_null: The null-space part when the resolver separates it, else ``None``.
        gains: Subtask gains k actually used (state-feedback law), or ``None``.
        damped: True when the pseudo-inverse was damped near a singularity.
        damping: λ used.
        fallback: Why the resolver fell back to a simpler method, or ``None``.
        info: Resolver-specific diagnostics (active constraints, level residuals, ...).
        build_time: Seconds spent building the problem.
        solve_time: Seconds spent solving it.
    """

    dq: np.ndarray
    terms: list[TaskTerm]
    dq_rank: np.ndarray | None = None
    dq_null: np.ndarray | None = None
    gains: np.ndarray | None = None
    damped: bool = False
    damping: float = 0.0
    fallback: str | None = None
    info: dict[str, object] = field(default_factory=dict)
    build_time: float = 0.0
    solve_time: float = 0.0

    @property
    def task_error(self) -> float:
        """Norm of the stacked main-task error."""
        if not self.terms:
            return 0.0
        return float(np.sqrt(sum(float(t.error @ t.error) for t in self.terms)))


class Resolver(ABC):
    """Turns a task stack into a joint velocity, one control tick at a time.

    Subclasses implement :meth:`solve`, which reads a robot already updated at the current configuration.
    :meth:`step` is the call for a control loop: update kinematics at q, then solve.
    """

    name: str = "resolver"

    def check(self, robot: RobotModel, stack: TaskStack) -> None:  # noqa: B027 - optional hook
        """Refuse a stack this resolver cannot handle (raise :class:`~redundik.errors.ResolverError`)."""

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget any state kept between steps (warm starts, previous q̇)."""

    @abstractmethod
    def solve(self, robot: RobotModel, stack: TaskStack, t: float, dt: float) -> StepResult:
        """Resolve the stack at the robot's current state, time t [s], for a step dt [s]."""

    def step(self, robot: RobotModel, stack: TaskStack, q: np.ndarray, t: float, dt: float) -> StepResult:
        """Update the kinematics at ``q`` and resolve one step; the call to make once per control tick."""
        robot.update(q)
        return self.solve(robot, stack, t, dt)

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def finite_or_zero(dq: np.ndarray) -> tuple[np.ndarray, bool]:
    """Return ``dq`` unchanged if finite, else zeros and ``False`` (a resolver must never output NaN)."""
    if np.isfinite(dq).all():
        return dq, True
    return np.zeros_like(dq), False
