"""Tasks and subtasks as QP rows, grouped by priority level — every task of the task API, without rewriting it.

* a main task's :class:`~redundik.tasks.base.TaskTerm` → least-squares rows ‖J q̇ − v‖² with its weight;
* a ``"target"`` subtask → the 1-row task ηᵀq̇ = ṗ_d + K(p_d − p);
* ``"gradient"`` subtasks → the objective ½ω‖q̇ − z‖² with z = Σ k_i η_i (the z of eqs. 5.8 / 5.15) and ω the
  mean of their weights (rows √ω·I q̇ = √ω·z). Its linear part −ω zᵀq̇ is the QP twin of the null-space term kη,
  its quadratic part ½ω‖q̇‖² the regulariser that keeps the optimum bounded. Restricted to the null space of the
  levels above (hqp) it gives exactly P_n z, i.e. the chapter's J⁺V + (I − J⁺J)kη after a minimum-norm level 0;
* a ``"bounds"`` subtask → inequality rows from lower ≤ p + ηᵀq̇·dt ≤ upper with a velocity-damper approach
  gain: ηᵀq̇ ≥ γ(lower − p) and ηᵀq̇ ≤ γ(upper − p), γ = min(K, 1/dt) (γ = 1/dt when K = 0). With γ = 1/dt it is the
  first-order prediction itself; with γ < 1/dt the distance to the bound can shrink at most like exp(−γt)
  (Faverjon & Tournassoud 1987), so the bound is approached smoothly and never crossed to first order.

Levels: a main task's level is ``levels[name]`` if given, else its ``priority`` attribute, else 0; a subtask's is
``levels[name]`` if given, else ``Subtask.priority``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from redundik.errors import ResolverError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Subtask, TaskStack, TaskTerm
from redundik.tasks.frame import PostureTask


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
        z: Target z = Σ k_i η_i of the gradient objective ½ω‖q̇ − z‖² (n,), or ``None`` without gradient subtasks.
        z_weight: ω, the mean weight of the gradient subtasks.
        gradient_names: Names of the gradient subtasks.
        identity: True when the task rows are exactly one identity block (a posture task): J = I.
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
    z_weight: float = 0.0
    gradient_names: list[str] = field(default_factory=list)
    identity: bool = False

    @property
    def m(self) -> int:
        """Number of least-squares rows."""
        return int(self.J.shape[0])

    @property
    def p(self) -> int:
        """Number of inequality rows."""
        return int(self.C.shape[0])

    def ls_rows(self, weighted: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """All least-squares rows of the level, gradient objective included, as (A, b): minimise ‖A q̇ − b‖².

        Rows are scaled by √w when ``weighted``; the gradient block is √ω·I, √ω·z (I, z when not weighted).
        """
        A, b = self.J, self.v
        if weighted and self.m and not np.all(self.w == 1.0):
            s = np.sqrt(self.w)
            A, b = A * s[:, None], b * s
        if self.z is not None:
            n = self.z.shape[0]
            s = np.sqrt(self.z_weight) if weighted else 1.0
            Iz, z = (np.eye(n), self.z) if s == 1.0 else (s * np.eye(n), s * self.z)
            A = np.vstack([A, Iz]) if self.m else Iz
            b = np.concatenate([b, z]) if self.m else z
        return A, b

    def inequality_residual(self, dq: np.ndarray) -> np.ndarray:
        """max(C q̇ − d, 0) per row."""
        if not self.p:
            return np.zeros(0)
        return np.maximum(self.C @ dq - self.d, 0.0)


def bound_rows(
    sub: Subtask, value: float, eta: np.ndarray, dt: float
) -> tuple[list[np.ndarray], list[float], list[str]]:
    """Inequality rows (C, d, names) of a ``"bounds"`` subtask at p = ``value``, η = ``eta`` (module docstring)."""
    gamma = 1.0 / dt if sub.rate == 0 else min(sub.rate, 1.0 / dt)
    rows, rhs, names = [], [], []
    if sub.lower is not None:
        rows.append(-eta)
        rhs.append(-gamma * (sub.lower - value))
        names.append(f"{sub.name}:lower")
    if sub.upper is not None:
        rows.append(eta)
        rhs.append(gamma * (sub.upper - value))
        names.append(f"{sub.name}:upper")
    return rows, rhs, names


def level_of_task(task: object, levels: Mapping[str, int]) -> int:
    """A main task's level: ``levels[name]``, else its ``priority`` attribute, else 0."""
    name = getattr(task, "name", "")
    if name in levels:
        return int(levels[name])
    return int(getattr(task, "priority", 0))


def build_levels(
    robot: RobotModel,
    stack: TaskStack,
    terms: list[TaskTerm],
    dt: float,
    levels: Mapping[str, int] | None = None,
    merge: bool = False,
) -> list[Level]:
    """Group every term and subtask into levels, sorted by priority.

    Args:
        robot: Updated robot.
        stack: The stack whose ``terms`` (one per main task, in order) were just evaluated.
        terms: ``stack.evaluate(robot, t)``.
        dt: Step [s] (for the bound rows).
        levels: Optional level overrides by task / subtask name.
        merge: Put everything in one level (``wqp``).

    Returns:
        Levels in decreasing priority (increasing number).

    Raises:
        ResolverError: a negative level.
    """
    levels = levels or {}
    n = robot.nv
    groups: dict[int, dict[str, list]] = {}

    def group(prio: int, name: str) -> dict[str, list]:
        if prio < 0:
            raise ResolverError(f"'{name}': priority level must be ≥ 0, got {prio}")
        key = 0 if merge else prio
        g = groups.setdefault(
            key, {"names": [], "J": [], "v": [], "w": [], "C": [], "d": [], "cn": [], "z": [], "zw": [], "zn": []}
        )
        g["names"].append(name)
        return g

    for task, term in zip(stack.tasks, terms, strict=True):
        g = group(level_of_task(task, levels), term.name)
        g["J"].append(term.J)
        g["v"].append(term.v)
        g["w"].append(np.full(term.v.shape[0], term.weight))
        g.setdefault("posture", []).append(isinstance(task, PostureTask))
    for sub in stack.subtasks:
        prio = int(levels.get(sub.name, sub.priority))
        if sub.mode == "gradient" and sub.gain == 0.0:
            continue
        g = group(prio, sub.name)
        pot = sub.potential
        eta = pot.gradient(robot)
        if sub.mode == "gradient":
            g["z"].append(sub.gain * eta)
            g["zw"].append(sub.weight)
            g["zn"].append(sub.name)
        elif sub.mode == "target":
            assert sub.target is not None  # validated by Subtask
            g["J"].append(eta.reshape(1, n))
            g["v"].append(np.array([sub.target_rate + sub.rate * (sub.target - pot.value(robot))]))
            g["w"].append(np.array([sub.weight]))
        else:
            rows, rhs, names = bound_rows(sub, pot.value(robot), eta, dt)
            g["C"].extend(rows)
            g["d"].extend(rhs)
            g["cn"].extend(names)
    out = []
    no_rows, no_rhs = np.zeros((0, n)), np.zeros(0)
    for prio in sorted(groups):
        g = groups[prio]
        Js, vs, ws = g["J"], g["v"], g["w"]
        if Js:
            J = Js[0] if len(Js) == 1 else np.vstack(Js)
            v = vs[0] if len(vs) == 1 else np.concatenate(vs)
            w = ws[0] if len(ws) == 1 else np.concatenate(ws)
        else:
            J, v, w = no_rows, no_rhs, no_rhs
        if g["C"]:
            C, d = np.vstack(g["C"]), np.array(g["d"], dtype=float)
        else:
            C, d = no_rows, no_rhs
        zs, zw = g["z"], g["zw"]
        z = (zs[0] if len(zs) == 1 else np.sum(zs, axis=0)) if zs else None
        out.append(
            Level(
                prio,
                g["names"],
                J,
                v,
                w,
                C,
                d,
                g["cn"],
                z,
                sum(zw) / len(zw) if zw else 0.0,
                g["zn"],
                len(Js) == 1 and g.get("posture", [False]) == [True],
            )
        )
    return out
