"""A stack's levels as QP rows — every task and subtask of the task API, laid out by :mod:`redundik.tasks.stack`.

* a task's :class:`~redundik.tasks.base.TaskTerm` → least-squares rows ‖J q̇ − v‖² with its weight;
* a target subtask → the 1-row task ηᵀq̇ = ṗ_d + K(p_d − p) with its weight;
* a bound subtask → the damper rows C q̇ ≤ d of :meth:`~redundik.tasks.subtasks.BoundSubtask.rows`;
* the null-space objective → ½‖q̇ − z‖², z = Σ k_i η_i + Σ_r K_r e_r. Restricted to the null space of the levels
  above (hqp) its optimum is exactly P_n z, i.e. the chapter's J⁺V + (I − J⁺J)z after a minimum-norm level 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.tasks.base import TaskTerm
from redundik.tasks.stack import StackLayout, TaskStack


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


def build_levels(
    robot: RobotModel, stack: TaskStack, terms: list[TaskTerm], layout: StackLayout, dt: float
) -> list[Level]:
    """The levels of ``layout`` as rows, in decreasing priority.

    Args:
        robot: Updated robot.
        stack: The stack whose ``terms`` (one per task, in order) were just evaluated.
        terms: ``stack.evaluate(robot, t)``.
        layout: ``stack.layout(...)``.
        dt: Step [s] (for the bound rows).
    """
    n = robot.nv
    no_rows, no_rhs = np.zeros((0, n)), np.zeros(0)
    out = []
    for plan in layout.levels:
        names: list[str] = []
        Js: list[np.ndarray] = []
        vs: list[np.ndarray] = []
        ws: list[np.ndarray] = []
        for i in plan.tasks:
            term = terms[i]
            names.append(term.name)
            Js.append(term.J)
            vs.append(term.v)
            ws.append(np.full(term.v.shape[0], term.weight))
        for sub in plan.targets:
            eta, vt, _ = sub.row(robot)
            names.append(sub.name)
            Js.append(eta.reshape(1, n))
            vs.append(np.array([vt]))
            ws.append(np.array([sub.weight]))
        Cs, ds, cn = [], [], []
        for bsub in plan.bounds:
            C, d, rn = bsub.rows(robot, dt)
            names.append(bsub.name)
            Cs.append(C)
            ds.append(d)
            cn.extend(rn)
        z = None
        if plan.null_objective:
            z = stack.null_target(robot, terms, layout)
            names += [terms[i].name for i in layout.null_tasks] + [s.name for s in layout.gradients]
        if Js:
            J = Js[0] if len(Js) == 1 else np.vstack(Js)
            v = vs[0] if len(vs) == 1 else np.concatenate(vs)
            w = ws[0] if len(ws) == 1 else np.concatenate(ws)
        else:
            J, v, w = no_rows, no_rhs, no_rhs
        if Cs:
            C, d = (Cs[0], ds[0]) if len(Cs) == 1 else (np.vstack(Cs), np.concatenate(ds))
        else:
            C, d = no_rows, no_rhs
        out.append(Level(plan.priority, names, J, v, w, C, d, cn, z))
    return out
