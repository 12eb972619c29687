"""Potentials of one 1-dof joint (section 5.2): sin²θ_j (singularity avoidance) and (q_j − c)², each given by its
compiled writer (``potential_kernels.sine2_gradient``, ``joint_value_gradient``): the per-task path and the
resolvers' compiled steps run the same formula."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError, short_repr
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledGradient, default_name
from redundik.tasks.layouts import J_INTS, J_IQ, J_IV, JV_CENTER
from redundik.tasks.potential_rows import CompiledPotential

#: The compiled potential kernels, imported on first use (a namespace: a cold start puts their twins here).
_PK = KernelNamespace("redundik.tasks.potential_kernels")


def one_dof_joint(robot: RobotModel, joint: str, name: str) -> tuple[int, int]:
    """(idx_q, idx_v) of the 1-dof ``joint`` of ``robot``; a :class:`TaskError` naming subtask ``name`` otherwise."""
    try:
        info = robot.joint(joint)
    except Exception as exc:
        raise TaskError(f"subtask '{name}': {exc}") from exc
    if info.idx_q < 0:
        raise TaskError(f"subtask '{name}': joint '{joint}' is not a 1-dof joint")
    return info.idx_q, info.idx_v


class _JointPotential(CompiledPotential):
    """Base for potentials of a single 1-dof joint; its writer's ``ints`` are (idx_q, idx_v), rewritten in place
    when it is checked against a robot."""

    def __init__(self, joint: str, name: str | None) -> None:
        if not isinstance(joint, str) or not joint:
            raise TaskError(f"{type(self).__name__}: joint must be a joint name (a string), got {joint!r}")
        self.joint = joint
        self.name = default_name(name, f"{type(self).__name__.lower()}_{joint}", type(self).__name__)
        self._iq = -1
        self._iv = -1
        self._ints = np.zeros(J_INTS, dtype=np.int64)
        self._floats = np.zeros(JV_CENTER + 1)

    def check(self, robot: RobotModel) -> None:
        self._iq, self._iv = self._ints[J_IQ], self._ints[J_IV] = one_dof_joint(robot, self.joint, self.name)

    def _writer(self, robot: RobotModel, kernel: Any) -> CompiledGradient:
        """``kernel`` with this potential's data on ``robot`` (the joint looked up when it was not yet, or
        ``robot`` is another model)."""
        if self._iq < 0 or self._iq >= robot.nq:
            self.check(robot)
        return CompiledGradient(kernel, self._ints, self._floats)


class JointSine2(_JointPotential):
    """Singularity avoidance through one joint: p = sin²θ_j, η_j = sin 2θ_j (the chapter's p = sin²θ6, sin²θ3).

    Maximised (k > 0) it drives θ_j towards ±90°, away from the wrist/elbow singularity at 0.
    """

    def __init__(self, joint: str, name: str | None = None) -> None:
        super().__init__(joint, f"sin2_{joint}" if name is None else name)

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """``potential_kernels.sine2_gradient``."""
        return self._writer(robot, _PK.sine2_gradient)


class JointValue(_JointPotential):
    """A single joint towards a value: p = (q_j − c)², η_j = 2(q_j − c) (the (6+1) robot's p = (d1 − c)²).

    ``c`` may be assigned between steps (a finite number): it is the writer's data, used from the next step."""

    def __init__(self, joint: str, value: float, name: str | None = None) -> None:
        super().__init__(joint, f"value_{joint}" if name is None else name)
        self.c = value

    @property
    def c(self) -> float:
        """The joint value c [rad or length unit]."""
        return float(self._floats[JV_CENTER])

    @c.setter
    def c(self, value: float) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            what = f"joint value potential on '{self.joint}'"
            raise TaskError(f"{what}: value must be a number, got {type(value).__name__}")
        try:
            c = float(value)
        except OverflowError:  # an int beyond the float range (10**400)
            c = math.inf
        if not math.isfinite(c):
            raise TaskError(
                f"joint value potential on '{self.joint}': value must be finite (within the float range), got "
                f"{short_repr(value)}"
            )
        self._floats[JV_CENTER] = c

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """``potential_kernels.joint_value_gradient``."""
        return self._writer(robot, _PK.joint_value_gradient)
