"""What ``wqp`` and ``hqp`` share: limits, the backend, the closed-form fallback and the step diagnostics."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from redundik.errors import ResolverError, SolverError
from redundik.kinematics.model import RobotModel
from redundik.resolvers.base import Resolver
from redundik.resolvers.linalg import pseudo_inverse
from redundik.resolvers.qp.backends import DEFAULT_BACKEND, Backend, make_backend
from redundik.resolvers.qp.limits import JointLimits, LimitBox
from redundik.resolvers.qp.problem import QPProblem, QPSolution
from redundik.resolvers.qp.terms import Level
from redundik.tasks.base import TaskStack

LimitsOption = JointLimits | Mapping[str, object] | bool | None
LevelsOption = Mapping[str, int] | Sequence[Sequence[str]] | None


def make_limits(limits: LimitsOption) -> JointLimits:
    """``JointLimits`` from an instance, a dict of its keyword arguments, ``None``/``True`` (model defaults) or
    ``False`` (no limits).

    Raises:
        ResolverError: unknown keys (lists the valid ones) or bad values.
    """
    if isinstance(limits, JointLimits):
        return limits
    if limits is None or limits is True:
        return JointLimits()
    if limits is False:
        return JointLimits(position=False, velocity=False)
    if isinstance(limits, Mapping):
        valid = ["position", "velocity", "lower", "upper", "velocity_limits", "acceleration", "position_gain"]
        bad = [k for k in limits if k not in valid]
        if bad:
            raise ResolverError(f"limits: unknown option(s) {bad}; valid: {valid}")
        return JointLimits(**limits)  # type: ignore[arg-type]
    raise ResolverError(f"limits: expected a mapping, true/false or JointLimits, got {limits!r}")


def make_levels(levels: LevelsOption) -> dict[str, int]:
    """Level overrides by name, from a mapping ``{name: level}`` or a list of levels ``[[names of level 0], ...]``.

    Raises:
        ResolverError: a negative or non-integer level, or a name given twice.
    """
    if levels is None:
        return {}
    out: dict[str, int] = {}
    if isinstance(levels, Mapping):
        for name, lv in levels.items():
            if isinstance(lv, bool) or not isinstance(lv, (int, np.integer)) or lv < 0:
                raise ResolverError(f"levels: '{name}' must be an integer level ≥ 0, got {lv!r}")
            out[str(name)] = int(lv)
        return out
    for k, names in enumerate(levels):
        if isinstance(names, str):
            names = [names]
        for name in names:
            if name in out:
                raise ResolverError(f"levels: '{name}' appears in level {out[name]} and level {k}")
            out[str(name)] = k
    return out


class QPResolverBase(Resolver):
    """Shared machinery of the QP resolvers (not registered itself).

    Args:
        backend: QP backend name (see :func:`~redundik.resolvers.qp.backends.make_backend`) or instance.
        limits: Joint limits (see :func:`make_limits`).
        levels: Level overrides by task / subtask name, or a list of levels of names.
        epsilon: Singular value under which the closed forms are damped (as :mod:`redundik.resolvers.linalg`).
        max_damping: λ_max of that damping rule.
    """

    def __init__(
        self,
        backend: str | Backend = DEFAULT_BACKEND,
        limits: LimitsOption = None,
        levels: LevelsOption = None,
        epsilon: float = 1e-2,
        max_damping: float = 5e-2,
    ) -> None:
        if not (np.isfinite(epsilon) and epsilon >= 0 and np.isfinite(max_damping) and max_damping >= 0):
            raise ResolverError(f"{self.name}: epsilon and max_damping must be finite numbers ≥ 0")
        self.backend = make_backend(backend)
        self.limits = make_limits(limits)
        self.levels = make_levels(levels)
        self.epsilon, self.max_damping = float(epsilon), float(max_damping)
        self._dq_prev: np.ndarray | None = None

    def check(self, robot: RobotModel, stack: TaskStack) -> None:
        self.limits.bind(robot)
        known = {getattr(t, "name", "") for t in stack.tasks} | {s.name for s in stack.subtasks}
        bad = sorted(set(self.levels) - known)
        if bad:
            raise ResolverError(f"{self.name}: levels name unknown task(s) {bad}; tasks and subtasks: {sorted(known)}")

    def reset(self) -> None:
        self._dq_prev = None
        self.backend.reset()

    def _solve_qp(self, problem: QPProblem, warm: np.ndarray | None = None) -> QPSolution:
        """The backend's answer; anything it raises (also a user backend's own exception) becomes SolverError."""
        try:
            sol = self.backend.solve(problem, warm)
        except SolverError:
            raise
        except Exception as exc:  # a failed QP must never crash a control loop
            raise SolverError(
                f"{self.backend.name} raised {type(exc).__name__} on {problem.label}: {exc}", problem
            ) from exc
        if sol.x.shape != (problem.n,) or not np.all(np.isfinite(sol.x)):
            raise SolverError(
                f"{self.backend.name}: no finite solution of size {problem.n} for {problem.label}", problem
            )
        return sol

    def _box(self, robot: RobotModel, dt: float) -> LimitBox:
        return self.limits.box(robot, robot.q, dt, self._dq_prev)

    def _closed_form(self, levels: list[Level], n: int) -> np.ndarray:
        """The damped closed form J⁺V + (I − J⁺J)z on the level-0 rows and every gradient target (the fallback)."""
        top = levels[0] if levels else None
        z = np.zeros(n)
        for lv in levels:
            if lv.z is not None:
                z += lv.z
        if top is None or not top.m:
            return z
        pi = pseudo_inverse(top.J, epsilon=self.epsilon, max_damping=max(self.max_damping, 1e-3))
        return pi.pinv @ top.v + pi.null_projector @ z

    def _finish(
        self, dq: np.ndarray, box: LimitBox, robot: RobotModel, info: dict[str, object]
    ) -> tuple[np.ndarray, bool]:
        """Clip to the limit box, refuse NaN, remember q̇ for the rate limit, add the active-limit diagnostics."""
        ok = bool(np.isfinite(dq).all())
        if not ok:
            dq = np.zeros_like(dq)
        dq = box.clip(dq)  # the limits hold whatever happened (solver tolerance, fallback); a new array
        active = box.active(dq, self.limits.joint_names)
        info["active_limits"] = active
        info["n_active"] = len(active)
        self._dq_prev = dq.copy()
        return dq, ok

    def __repr__(self) -> str:
        return f"{type(self).__name__}(backend={self.backend.name!r}, limits={self.limits!r})"
