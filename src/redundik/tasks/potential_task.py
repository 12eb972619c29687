"""A potential driven to a value as a 1-row task: ηᵀq̇ = ṗ_d + K(p_d − p) (the QP form of a "target" subtask)."""

from __future__ import annotations

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Potential, Task, TaskTerm


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
        self.name = name or potential.name
        for key, val in (("target", target), ("rate", rate), ("target_rate", target_rate), ("weight", weight)):
            if not np.isfinite(val):
                raise TaskError(f"task '{self.name}': {key} must be finite, got {val}")
        if rate < 0:
            raise TaskError(f"task '{self.name}': rate (K) must be ≥ 0, got {rate}")
        if weight <= 0:
            raise TaskError(f"task '{self.name}': weight must be > 0, got {weight}")
        self.potential = potential
        self.target, self.rate, self.target_rate = float(target), float(rate), float(target_rate)
        self.weight, self.priority = float(weight), priority

    def reset(self, robot: RobotModel) -> None:
        self.potential.check(robot)

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        eta = self.potential.gradient(robot)
        e = np.array([self.target - self.potential.value(robot)])
        v = self.target_rate + self.rate * e
        return TaskTerm(self.name, eta.reshape(1, -1), v, e, self.weight)

    def __repr__(self) -> str:
        return f"PotentialTask({self.potential!r}, target={self.target}, rate={self.rate})"
