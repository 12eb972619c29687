"""What a task stack means, under every resolver — decided here, once (the page ``docs/stack.md`` explains it).

A stack holds **tasks** (main tasks and regularisation tasks such as a posture) and **subtasks** (gradient,
target, bound; :mod:`redundik.tasks.subtasks`). Its levels, highest first:

1. **main tasks**: level ``task.priority`` (default 0). ``pinv`` and ``feedback`` stack every main task into one
   J q̇ = V (eq. 5.6); ``hqp`` keeps their levels; ``wqp`` weights them (below).
2. **target and bound subtasks**: level ``priority``, default one below the lowest main level.
3. **the null-space objective**, always the lowest level: ½‖q̇ − z‖² with
   z = Σ k_i η_i (every gradient subtask, eqs. 5.8/5.15) + Σ_r J_r⁺ v_r (every regularisation task without a level
   of its own: for a posture, J = I and J⁺v = K (q_r ⊖ q), the gradient of −½K‖q ⊖ q_r‖²; for a posture on some
   joints, J = S, rows of the identity, and J⁺ = Sᵀ). Restricted to the null space N of the levels above, its
   optimum is P_N z: after a minimum-norm main task this is exactly the chapter's J⁺V + (I − J⁺J)z.

Resolver by resolver: ``pinv`` = J⁺V + (I − J⁺J)z (refuses target and bound subtasks); ``feedback`` = the same
plus the state-feedback gains for the target subtasks (refuses bound subtasks); ``hqp`` = the strict cascade over
these levels; ``wqp`` = one QP in which the rows of the k-th level (k = 0, 1, …, counted over the levels present)
are weighted by ρ^k (``level_ratio``, default 1e-4): with no constraint active its main-task velocity differs
from ``pinv``'s by O(ρ‖z‖/σ_min²), so it tracks as ``pinv`` does.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from redundik.errors import ResolverError, TaskError, short_repr
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Edits, Task, TaskTerm
from redundik.tasks.conform import conform_term
from redundik.tasks.subtasks import BoundSubtask, GradientSubtask, Subtask, TargetSubtask


@dataclass
class LevelPlan:
    """The members of one level of a stack (indices into ``stack.tasks`` and the subtask objects).

    Attributes:
        priority: The level's number (0 = highest).
        tasks: Indices of the tasks whose rows are at this level.
        targets: Target subtasks at this level.
        bounds: Bound subtasks at this level.
        null_objective: True for the level carrying ½‖q̇ − z‖² (gradient subtasks, identity regularisers).
    """

    priority: int
    tasks: list[int] = field(default_factory=list)
    targets: list[TargetSubtask] = field(default_factory=list)
    bounds: list[BoundSubtask] = field(default_factory=list)
    null_objective: bool = False

    @property
    def names(self) -> list[str]:
        """Members' names (tasks by index are resolved by the caller)."""
        return [s.name for s in (*self.targets, *self.bounds)]


@dataclass
class StackLayout:
    """The levels of a stack, highest priority first, and what the null-space objective gathers.

    Attributes:
        levels: Non-empty levels in decreasing priority.
        main: Indices of the main tasks (not regularisation tasks).
        null_tasks: Indices of the regularisation tasks without a level of their own, summed into z (J⁺v each).
        gradients: The gradient subtasks summed into z.
    """

    levels: list[LevelPlan]
    main: list[int]
    null_tasks: list[int]
    gradients: list[GradientSubtask]

    @property
    def has_null_objective(self) -> bool:
        """True when z has at least one contribution."""
        return bool(self.null_tasks or self.gradients)


@dataclass
class TaskStack:
    """What a resolver resolves: tasks (main and regularisation) and typed subtasks; its meaning is this module's.

    Attributes:
        tasks: Tasks, each J q̇ = v.
        subtasks: Gradient, target and bound subtasks.
    """

    tasks: list[Task] = field(default_factory=list)
    subtasks: list[Subtask] = field(default_factory=list)

    def __post_init__(self) -> None:
        for key in ("tasks", "subtasks"):
            given = getattr(self, key)
            if given is None or isinstance(given, (str, bytes, Mapping)) or not isinstance(given, Iterable):
                raise ResolverError(f"stack.{key}: expected a list, got {type(given).__name__}")
        self.tasks = list(self.tasks)
        self.subtasks = list(self.subtasks)
        self._check_members()

    def _check_members(self) -> None:
        """Types and unique names (what needs no robot); raises :class:`ResolverError` naming the member."""
        for i, task in enumerate(self.tasks):
            if not isinstance(task, Task):
                hint = " (a subtask belongs in the second list, subtasks)" if isinstance(task, Subtask) else ""
                raise ResolverError(f"stack.tasks[{i}]: expected a Task, got {type(task).__name__}{hint}")
        for i, sub in enumerate(self.subtasks):
            if not isinstance(sub, Subtask):
                hint = (
                    " (a task belongs in the first list, tasks)"
                    if isinstance(sub, Task)
                    else " (a potential must be wrapped: GradientSubtask, TargetSubtask or BoundSubtask)"
                )
                raise ResolverError(f"stack.subtasks[{i}]: expected a Subtask, got {type(sub).__name__}{hint}")
        names = [t.name for t in self.tasks] + [s.name for s in self.subtasks]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ResolverError(f"task and subtask names must be unique in a stack; repeated: {dup}")

    # ------------------------------------------------------------------ checks
    def check(self, robot: RobotModel) -> None:
        """Check types, unique names and every subtask against the robot.

        Raises:
            ResolverError: a member that is not a Task / Subtask, or a repeated name.
            TaskError: ``robot`` is not a RobotModel, or a subtask does not fit the robot.
        """
        if not isinstance(robot, RobotModel):  # (each task's reset would fail on its first attribute of it)
            raise TaskError(
                f"task stack: expected a RobotModel (rk.load_example_robot, rk.from_urdf, rk.from_dh, ...), got "
                f"{type(robot).__name__} {short_repr(robot)}"
            )
        self._check_members()
        for sub in self.subtasks:
            sub.check(robot)

    def signature(self) -> tuple[int, ...]:
        """Identity of the stack's membership and levels: it changes when a task or subtask is added, removed or
        replaced, and when a member's ``priority`` or name changed (``Edits.layout``)."""
        return (id(self), *map(id, self.tasks), -1, *map(id, self.subtasks), -2, Edits.layout)

    def reset(self, robot: RobotModel) -> None:
        """Check the stack and reset every task at the robot's current state (call after ``robot.update(q0)``).

        Targets set explicitly (``FrameTask.set_target``, ``PostureTask.set_target``) are kept.
        """
        self.check(robot)
        for task in self.tasks:
            task.reset(robot)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, robot: RobotModel, t: float) -> list[TaskTerm]:
        """Every task's term at time ``t`` (main and regularisation tasks, in order), each conformed to float64
        arrays of its shapes (``conform_term``: a user's list or integers converted, complex or misshapen refused).

        Raises:
            TaskError: a term that is not a ``TaskTerm`` of real numbers and consistent shapes (naming its task).
        """
        nv = robot._nv
        return [conform_term(task.evaluate(robot, t), nv, task) for task in self.tasks]

    @property
    def gradient_subtasks(self) -> list[GradientSubtask]:
        """The gradient subtasks."""
        return [s for s in self.subtasks if isinstance(s, GradientSubtask)]

    @property
    def target_subtasks(self) -> list[TargetSubtask]:
        """The target subtasks."""
        return [s for s in self.subtasks if isinstance(s, TargetSubtask)]

    @property
    def bound_subtasks(self) -> list[BoundSubtask]:
        """The bound subtasks."""
        return [s for s in self.subtasks if isinstance(s, BoundSubtask)]

    def names(self) -> list[str]:
        """Every task and subtask name."""
        return [t.name for t in self.tasks] + [s.name for s in self.subtasks]

    def layout(self, overrides: Mapping[str, int] | None = None) -> StackLayout:
        """The levels of this stack (module docstring), with optional level overrides by name.

        Raises:
            ResolverError: an override names no task or subtask (lists the valid ones), names a gradient subtask
                (it belongs to the null-space objective), or is not an integer ≥ 0.
        """
        overrides = dict(overrides or {})
        valid = [t.name for t in self.tasks] + [s.name for s in self.subtasks if not isinstance(s, GradientSubtask)]
        for key, lv in overrides.items():
            if key not in valid:
                grads = [s.name for s in self.gradient_subtasks]
                why = (
                    "a gradient subtask belongs to the null-space objective, the lowest level"
                    if key in grads
                    else "no such task or subtask"
                )
                raise ResolverError(f"levels: '{key}': {why}; tasks and subtasks with a level: {valid}")
            if isinstance(lv, bool) or not isinstance(lv, (int, np.integer)) or lv < 0:
                raise ResolverError(f"levels: '{key}' must be an integer level ≥ 0, got {lv!r}")

        def level(obj: Task | TargetSubtask | BoundSubtask, default: int) -> int:
            if obj.name in overrides:
                return int(overrides[obj.name])
            return default if obj.priority is None else int(obj.priority)

        plans: dict[int, LevelPlan] = {}

        def plan(prio: int) -> LevelPlan:
            return plans.setdefault(prio, LevelPlan(prio))

        main, null_tasks = [], []
        for i, task in enumerate(self.tasks):
            if not task.regularization:
                main.append(i)
                plan(level(task, 0)).tasks.append(i)
            elif task.priority is not None or task.name in overrides:
                plan(level(task, 0)).tasks.append(i)
            else:
                null_tasks.append(i)
        below_main = max((p for p in plans), default=-1) + 1
        for sub in self.subtasks:
            if isinstance(sub, TargetSubtask):
                plan(level(sub, below_main)).targets.append(sub)
            elif isinstance(sub, BoundSubtask):
                plan(level(sub, below_main)).bounds.append(sub)
        gradients = self.gradient_subtasks
        lowest = max(plans, default=-1) + 1
        if null_tasks or gradients:
            plan(lowest).null_objective = True
        return StackLayout([plans[p] for p in sorted(plans)], main, null_tasks, gradients)

    def null_target(self, robot: RobotModel, terms: list[TaskTerm], layout: StackLayout) -> np.ndarray | None:
        """z of the null-space objective: Σ k_i η_i + Σ_r J_r⁺ v_r (module docstring), or ``None`` if nothing adds
        to it."""
        if not layout.has_null_objective:
            return None
        z = None  # a new array in every case (the first gradient's k η is one already)
        for sub in layout.gradients:
            if sub.gain != 0.0:
                d = sub.direction(robot)
                z = d if z is None else z + d
        for i in layout.null_tasks:
            v = null_velocity(self.tasks[i], terms[i], robot._nv)
            z = v.copy() if z is None else z + v
        return np.zeros(robot.nv) if z is None else z


def null_velocity(task: Task, term: TaskTerm, nv: int) -> np.ndarray:
    """J⁺v of a regularisation task's term in the null-space objective: v itself for an identity Jacobian; Sᵀv for
    rows of the identity S (a posture on some joints: v scattered to its coordinates); the minimum-norm solution
    of J q̇ = v otherwise."""
    J, v = term.J, term.v
    if task.identity_jacobian and v.shape[0] == nv:
        return v
    if not np.isfinite(J).all():  # (NaN rows: q̇ is then not finite, and the resolver says where from)
        return np.full(nv, np.nan)
    r = J.shape[0]
    cols = np.argmax(J, axis=1) if r else np.zeros(0, dtype=np.intp)
    if np.count_nonzero(J) == r and np.all(J[np.arange(r), cols] == 1.0) and np.unique(cols).shape[0] == r:
        out = np.zeros(nv)
        out[cols] = v
        return out
    return np.asarray(np.linalg.lstsq(J, v, rcond=None)[0], dtype=float)
