"""The task contract every resolver reads.

* A **task** (main task, or a QP level) gives, at the current kinematic state, a :class:`TaskTerm`:
  a Jacobian J (m×n), a desired velocity V (m,) and an error e (m,), so that J q̇ = V is what it asks for (eq. 5.6).
* A **potential** is a scalar p(q) with its exact gradient η = ∂p/∂q (n,) — the subtasks of section 5.2.
* A :class:`Subtask` says how a resolver should use a potential: with a gain k in the null space (eq. 5.8),
  driven to a target value (the state-feedback law, or a 1-row QP task), or kept within bounds (QP inequality).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel


@dataclass
class TaskTerm:
    """A task evaluated at one instant: ask for J q̇ = v.

    Attributes:
        name: Task name.
        J: Jacobian, shape (m, nv).
        v: Desired velocity (feed-forward plus feedback on the error), shape (m,).
        error: Task error (desired minus actual), shape (m,).
        weight: Weight of the term in a weighted QP.
    """

    name: str
    J: np.ndarray
    v: np.ndarray
    error: np.ndarray
    weight: float = 1.0

    @property
    def error_norm(self) -> float:
        """Euclidean norm of the error."""
        return float(np.linalg.norm(self.error))


class Task(ABC):
    """A velocity-level task J q̇ = v (a main task of the chapter, or one level of a QP stack)."""

    name: str

    def reset(self, robot: RobotModel) -> None:  # noqa: B027 - optional hook
        """Capture what the task needs at t = 0 (e.g. the start pose of a trajectory); ``robot`` is updated."""

    @abstractmethod
    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        """The task at time ``t`` [s]; ``robot`` has been :meth:`~RobotModel.update`-d at the current q."""

    @abstractmethod
    def __repr__(self) -> str: ...


class Potential(ABC):
    """A scalar subtask potential p(q) with exact gradient η = ∂p/∂q (section 5.2)."""

    name: str

    def check(self, robot: RobotModel) -> None:  # noqa: B027 - optional hook
        """Validate against a robot (frames and joints exist, sizes match); raise :class:`TaskError` if not."""

    @abstractmethod
    def value(self, robot: RobotModel) -> float:
        """p(q) at the robot's current (updated) state."""

    @abstractmethod
    def gradient(self, robot: RobotModel) -> np.ndarray:
        """η = ∂p/∂q, shape (nv,), exact (analytic or from Pinocchio's kinematic derivatives)."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"


SubtaskMode = Literal["gradient", "target", "bounds"]


@dataclass
class Subtask:
    """How a resolver uses a potential.

    Attributes:
        potential: The potential p(q).
        mode: ``"gradient"``: z = kη in the null space (eq. 5.8; QP: the linear objective −k ηᵀq̇);
            ``"target"``: drive p to ``target`` (state-feedback law, or the 1-row QP task ηᵀq̇ = ṗ_d + K(p_d − p));
            ``"bounds"``: keep ``lower ≤ p ≤ upper`` (QP inequality ηᵀq̇·dt ≥ lower − p, ...).
        gain: k of eq. (5.8): > 0 increases p, < 0 decreases it.
        target: Desired value p_d (mode ``"target"``).
        rate: Feedback gain K [1/s] towards the target, or the bound-approach gain in mode ``"bounds"``.
        target_rate: Desired rate ṗ_d (mode ``"target"``).
        lower: Lower bound (mode ``"bounds"``), or ``None``.
        upper: Upper bound (mode ``"bounds"``), or ``None``.
        weight: Weight in a weighted QP.
        priority: Level in a strict hierarchy (0 is the main task's level; larger is lower priority).
    """

    potential: Potential
    mode: SubtaskMode = "gradient"
    gain: float = 0.0
    target: float | None = None
    rate: float = 1.0
    target_rate: float = 0.0
    lower: float | None = None
    upper: float | None = None
    weight: float = 1.0
    priority: int = 1

    def __post_init__(self) -> None:
        name = getattr(self.potential, "name", "?")
        for key in ("gain", "rate", "target_rate", "weight"):
            val = getattr(self, key)
            if not math.isfinite(val):
                raise TaskError(f"subtask '{name}': {key} must be a finite number, got {val}")
        if self.mode not in ("gradient", "target", "bounds"):
            raise TaskError(f"subtask '{name}': mode must be gradient, target or bounds, got {self.mode!r}")
        if self.mode == "target" and (self.target is None or not math.isfinite(self.target)):
            raise TaskError(f"subtask '{name}': mode 'target' needs a finite target value")
        if self.mode == "bounds":
            if self.lower is None and self.upper is None:
                raise TaskError(f"subtask '{name}': mode 'bounds' needs lower and/or upper")
            if self.lower is not None and self.upper is not None and self.lower > self.upper:
                raise TaskError(f"subtask '{name}': lower ({self.lower}) > upper ({self.upper})")
        if self.rate < 0:
            raise TaskError(f"subtask '{name}': rate (K) must be ≥ 0, got {self.rate}")
        if self.weight < 0:
            raise TaskError(f"subtask '{name}': weight must be ≥ 0, got {self.weight}")

    @property
    def name(self) -> str:
        """The potential's name."""
        return self.potential.name


@dataclass
class TaskStack:
    """What a resolver resolves: main tasks (stacked, highest priority) and subtasks.

    Attributes:
        tasks: Main tasks; their terms are stacked into one J and V (eq. 5.6).
        subtasks: Subtasks (potentials and how to use them).
    """

    tasks: list[Task] = field(default_factory=list)
    subtasks: list[Subtask] = field(default_factory=list)

    def reset(self, robot: RobotModel) -> None:
        """Reset every task at the robot's current state (call after ``robot.update(q0)``)."""
        for s in self.subtasks:
            s.potential.check(robot)
        for task in self.tasks:
            task.reset(robot)

    def evaluate(self, robot: RobotModel, t: float) -> list[TaskTerm]:
        """Every main task's term at time ``t``."""
        return [task.evaluate(robot, t) for task in self.tasks]


def stack_terms(terms: list[TaskTerm], nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Stack task terms into one Jacobian (Σm, nv) and one velocity (Σm,)."""
    if not terms:
        return np.zeros((0, nv)), np.zeros(0)
    if len(terms) == 1:
        return terms[0].J, terms[0].v
    return np.vstack([t.J for t in terms]), np.concatenate([t.v for t in terms])
