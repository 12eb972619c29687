"""A potential driven to a value as a 1-row task: ηᵀq̇ = ṗ_d + K(p_d − p) (the QP form of a "target" subtask)."""

from __future__ import annotations

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Potential, Task, TaskTerm
from redundik.tasks.subtasks import TargetSubtask


class PotentialTask(Task):
    """Drive a potential p(q) to p_d: the 1-row task ηᵀq̇ = ṗ_d + K(p_d − p), with η = ∂p/∂q.

    Since ṗ = ηᵀq̇, an exact solution makes e = p_d − p obey ė = −K e (for constant p_d), the same closed loop as the
    chapter's state-feedback law on the subtask gains (section 5.2), but as a task a QP can place at any level.

    Args:
        potential: The potential p(q).
        target: p_d.
        rate: K [1/s] ≥ 0.
        target_rate: ṗ_d [1/s · unit of p].
        weight: Weight in a weighted QP (> 0).
        priority: Level (0 = highest); ``None``: the main tasks' level 0.
        name: Task name (default: the potential's name).

    Raises:
        TaskError: non-finite target, negative rate or weight.
    """

    def __init__(
        self,
        potential: Potential,
        target: float,
        *,
        rate: float = 1.0,
        target_rate: float = 0.0,
        weight: float = 1.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        # the one formula of "drive p to p_d" (and its validation) is the target subtask's; this task places it
        # among the tasks, at any level
        self._row = TargetSubtask(potential, target, rate=rate, target_rate=target_rate, weight=weight, name=name)
        self._init_task(self._row.name, weight=weight, gain=0.0, priority=priority)
        self.potential = potential

    @property
    def target(self) -> float:
        """p_d [unit of p]."""
        return self._row.target

    @property
    def rate(self) -> float:
        """K [1/s]."""
        return self._row.rate

    @property
    def target_rate(self) -> float:
        """ṗ_d [unit of p / s]."""
        return self._row.target_rate

    def set_target(self, target: float, target_rate: float = 0.0) -> None:
        """Move p_d (and ṗ_d) at run time, between ticks."""
        self._row.set_target(target, target_rate)

    def reset(self, robot: RobotModel) -> None:
        self.potential.check(robot)

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        eta, v, e = self._row.row(robot)
        return TaskTerm(self.name, eta.reshape(1, -1), np.array([v]), np.array([e]), self.weight)

    def __repr__(self) -> str:
        return f"PotentialTask({self.potential!r}, target={self.target}, rate={self.rate})"
