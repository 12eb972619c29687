"""A stack's levels as QP rows — every task and subtask of the task API, laid out by :mod:`redundik.tasks.stack`.

* a task's :class:`~redundik.tasks.base.TaskTerm` → least-squares rows ‖J q̇ − v‖² with its weight;
* a target subtask → the 1-row task ηᵀq̇ = ṗ_d + K(p_d − p) with its weight;
* a bound subtask → the damper rows C q̇ ≤ d of :meth:`~redundik.tasks.subtasks.BoundSubtask.rows`;
* the null-space objective → ½‖q̇ − z‖², z = Σ k_i η_i + Σ_r K_r e_r. Restricted to the null space of the levels
  above (hqp) its optimum is exactly P_n z, i.e. the chapter's J⁺V + (I − J⁺J)z after a minimum-norm level 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack
from redundik.tasks.subtasks import BoundSubtask


@dataclass
class Level:
    """The rows of one priority level.

    Attributes:
        priority: The level number (0 = highest).
        names: Names of the tasks and subtasks at this level.
        J: Least-squares rows (m, n): minimise Σ w_i ‖J_i q̇ − v_i‖².
        v: Their targets (m,).
        w: Row weights (m,).
        C: Inequality rows (p, n): C q̇ ≤ d.
        d: Their bounds (p,).
        c_names: A name per inequality row (``"clearance:lower"``).
        z: Target of the null-space objective ½‖q̇ − z‖² (n,), or ``None`` when the level does not carry it.
    """

    priority: int
    names: list[str] = field(default_factory=list)
    J: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    v: np.ndarray = field(default_factory=lambda: np.zeros(0))
    w: np.ndarray = field(default_factory=lambda: np.zeros(0))
    C: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    d: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c_names: list[str] = field(default_factory=list)
    z: np.ndarray | None = None

    @property
    def m(self) -> int:
        """Number of least-squares rows."""
        return int(self.J.shape[0])

    @property
    def p(self) -> int:
        """Number of inequality rows."""
        return int(self.C.shape[0])

    @property
    def pure_null_objective(self) -> bool:
        """True when the level is only the null-space objective (identity rows: solved in closed form)."""
        return self.z is not None and not self.m

    @property
    def scale(self) -> float:
        """√ of the largest weight of the level's least-squares rows (the null-space objective's identity rows weigh
        1; 1 without rows): the damping rule's ε and λ_max, and the regulariser, are taken relative to it, so that a
        level's rows count by their weights *relative to each other* and a level of one task of any weight is solved
        as one of weight 1 (scaling every row of a level leaves its optimum unchanged)."""
        wmax = float(self.w.max()) if self.m else 0.0
        if self.z is not None:
            wmax = max(wmax, 1.0)
        return math.sqrt(wmax) if wmax > 0.0 else 1.0

    def ls_rows(self, weighted: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """All least-squares rows of the level, null-space objective included, as (A, b): minimise ‖A q̇ − b‖²."""
        A, b = self.J, self.v
        if weighted and self.m and not (self.w == 1.0).all():
            s = np.sqrt(self.w)
            A, b = A * s[:, None], b * s
        if self.z is not None:
            n = self.z.shape[0]
            A = np.vstack([A, np.eye(n)]) if self.m else np.eye(n)
            b = np.concatenate([b, self.z]) if self.m else self.z
        return A, b

    def residual(self, dq: np.ndarray) -> float:
        """‖J q̇ − v‖ of the task rows (‖q̇ − z‖ for a pure null-space objective) with the inequality violations."""
        res = 0.0
        if self.m:
            res = float(np.sum((self.J @ dq - self.v) ** 2))
        elif self.z is not None:
            res = float(np.sum((dq - self.z) ** 2))
        if self.p:
            res += float(np.sum(self.inequality_residual(dq) ** 2))
        return float(np.sqrt(res))

    def inequality_residual(self, dq: np.ndarray) -> np.ndarray:
        """max(C q̇ − d, 0) per row."""
        if not self.p:
            return np.zeros(0)
        return np.maximum(self.C @ dq - self.d, 0.0)


class StepRows:
    """One step's rows of every level of a layout, as evaluated (no copy); the :class:`Level` records are built on
    first use (:attr:`levels`).

    Attributes:
        ls: Per level, its least-squares blocks (J_i (m_i, n), v_i (m_i,), weight w_i): tasks, then target subtasks.
        ineq: Per level, its bound subtasks' rows (C_i (p_i, n), d_i (p_i,), row names), with the subtask.
        z: The null-space objective's target (n,) (``None`` without one); carried by the level with ``null_objective``.
        n: Number of velocity coordinates.
    """

    __slots__ = ("_levels", "ineq", "layout", "ls", "n", "terms", "z")

    def __init__(
        self,
        layout: StackLayout,
        terms: list[TaskTerm],
        ls: list[list[tuple[np.ndarray, np.ndarray, float]]],
        ineq: list[list[tuple[np.ndarray, np.ndarray, list[str], BoundSubtask]]],
        z: np.ndarray | None,
        n: int,
    ) -> None:
        self.layout, self.terms, self.ls, self.ineq, self.z, self.n = layout, terms, ls, ineq, z, n
        self._levels: list[Level] | None = None

    @property
    def levels(self) -> list[Level]:
        """The levels as :class:`Level` records (stacked rows), built once on first access."""
        if self._levels is None:
            self._levels = [self._level(k) for k in range(len(self.ls))]
        return self._levels

    def _level(self, k: int) -> Level:
        n = self.n
        plan = self.layout.levels[k]
        blocks, rows = self.ls[k], self.ineq[k]
        if blocks:
            J = blocks[0][0] if len(blocks) == 1 else np.vstack([bl[0] for bl in blocks])
            v = blocks[0][1] if len(blocks) == 1 else np.concatenate([bl[1] for bl in blocks])
            w = np.concatenate([np.full(bl[1].shape[0], bl[2]) for bl in blocks])
        else:
            J, v, w = np.zeros((0, n)), np.zeros(0), np.zeros(0)
        if rows:
            C = rows[0][0] if len(rows) == 1 else np.vstack([r[0] for r in rows])
            d = rows[0][1] if len(rows) == 1 else np.concatenate([r[1] for r in rows])
        else:
            C, d = np.zeros((0, n)), np.zeros(0)
        c_names = [name for r in rows for name in r[2]]
        z = self.z if plan.null_objective else None
        terms, layout = self.terms, self.layout
        names = [terms[i].name for i in plan.tasks] + [s.name for s in plan.targets] + [b.name for b in plan.bounds]
        if plan.null_objective:
            names += [terms[i].name for i in layout.null_tasks] + [s.name for s in layout.gradients]
        return Level(plan.priority, names, J, v, w, C, d, c_names, z)


def gather_rows(robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], layout: StackLayout, dt: float) -> StepRows:
    """Every level's rows of ``layout`` at the robot's state, in decreasing priority, without stacking them.

    Args:
        robot: Updated robot.
        stack: The stack whose ``terms`` (one per task, in order) were just evaluated.
        terms: ``stack.evaluate(robot, t)``.
        layout: ``stack.layout(...)``.
        dt: Step [s] (for the bound rows).
    """
    n = robot.nv
    ls: list[list[tuple[np.ndarray, np.ndarray, float]]] = []
    ineq: list[list[tuple[np.ndarray, np.ndarray, list[str], BoundSubtask]]] = []
    z = None
    for plan in layout.levels:
        blocks = [(terms[i].J, terms[i].v, terms[i].weight) for i in plan.tasks]
        for sub in plan.targets:
            eta, vt, _ = sub.row(robot)
            blocks.append((eta.reshape(1, n), np.array([vt]), sub.weight))
        rows = []
        for bsub in plan.bounds:
            C, d, rn = bsub.rows(robot, dt)
            rows.append((C, d, rn, bsub))
        if plan.null_objective:
            z = stack.null_target(robot, terms, layout)
        ls.append(blocks)
        ineq.append(rows)
    return StepRows(layout, terms, ls, ineq, z, n)


def build_levels(
    robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], layout: StackLayout, dt: float
) -> list[Level]:
    """The levels of ``layout`` as rows, in decreasing priority (``gather_rows``, stacked per level).

    Args:
        robot: Updated robot.
        stack: The stack whose ``terms`` (one per task, in order) were just evaluated.
        terms: ``stack.evaluate(robot, t)``.
        layout: ``stack.layout(...)``.
        dt: Step [s] (for the bound rows).
    """
    return gather_rows(robot, stack, terms, layout, dt).levels
