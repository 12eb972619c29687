"""Frame tracking tasks: pose, position or a subset of axes (e.g. the planar x–y tip task of the 3R arm)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from redundik.errors import TaskError
from redundik.kinematics.model import AXES, RobotModel
from redundik.tasks.base import Task, TaskTerm
from redundik.tasks.trajectory import Hold, Trajectory

#: Named axis sets.
AXIS_SETS: dict[str, tuple[str, ...]] = {
    "pose": ("x", "y", "z", "rx", "ry", "rz"),
    "position": ("x", "y", "z"),
    "orientation": ("rx", "ry", "rz"),
    "planar": ("x", "y"),
}


def resolve_axes(axes: str | Sequence[str]) -> tuple[str, ...]:
    """Turn ``"pose"``/``"position"``/``"orientation"``/``"planar"`` or a list of axis names into axis names.

    Raises:
        TaskError: on an unknown name; lists the valid ones.
    """
    if isinstance(axes, str):
        if axes not in AXIS_SETS:
            raise TaskError(f"unknown axes '{axes}'; expected one of {sorted(AXIS_SETS)} or a list of {list(AXES)}")
        return AXIS_SETS[axes]
    out = tuple(axes)
    bad = [a for a in out if a not in AXES]
    if bad or not out or len(set(out)) != len(out):
        raise TaskError(f"axes {list(out)}: expected distinct names among {list(AXES)}")
    return out


class FrameTask(Task):
    """Track a trajectory with a frame: J q̇ = V_d + K·e on the selected rows of the base-aligned Jacobian.

    The error is e = (p_d − p, log3(R_d Rᵀ)) in the world frame, restricted to ``axes``. With ``gain`` = 0 the task is
    the chapter's open-loop feed-forward V = ṗ_d (its 3R and (6+1) simulations); a positive gain closes the loop on
    the tracking error (first-order convergence e ~ exp(−K t)).

    Args:
        frame: Frame name.
        trajectory: Reference; :class:`Hold` if ``None``.
        axes: Rows to control (see :data:`AXIS_SETS`).
        gain: K [1/s] ≥ 0 on the error.
        weight: Weight in a weighted QP.
        name: Task name (defaults to the frame name).
    """

    def __init__(
        self,
        frame: str,
        trajectory: Trajectory | None = None,
        *,
        axes: str | Sequence[str] = "pose",
        gain: float = 0.0,
        weight: float = 1.0,
        name: str | None = None,
    ) -> None:
        if not (np.isfinite(gain) and gain >= 0):
            raise TaskError(f"frame task '{name or frame}': gain must be a finite number ≥ 0, got {gain}")
        if not (np.isfinite(weight) and weight > 0):
            raise TaskError(f"frame task '{name or frame}': weight must be > 0, got {weight}")
        self.frame = frame
        self.trajectory = trajectory if trajectory is not None else Hold()
        self.axes = resolve_axes(axes)
        self.rows = np.array([AXES[a] for a in self.axes], dtype=int)
        self._all_rows = self.rows.tolist() == list(range(6))
        self._rotation_rows = bool(np.any(self.rows >= 3))
        self.gain = float(gain)
        self.weight = float(weight)
        self.name = name or frame
        self._fid: int | None = None

    @property
    def dim(self) -> int:
        """Number of task rows m."""
        return len(self.rows)

    def reset(self, robot: RobotModel) -> None:
        try:
            self._fid = robot.frame_id(self.frame)
        except Exception as exc:
            raise TaskError(f"task '{self.name}': {exc}") from exc
        self.trajectory.start(robot.frame_pose(self._fid))

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        if self._fid is None:
            self.reset(robot)
        fid = self._fid
        assert fid is not None  # for the type checker; set by reset()
        pose = robot.frame_pose(fid)
        p_d, R_d, twist_d = self.trajectory.reference(t)
        J = robot.frame_jacobian(fid)
        if self._all_rows:
            e = np.empty(6)
            e[:3] = p_d - pose.translation
            e[3:] = pin.log3(R_d @ pose.rotation.T)
            return TaskTerm(self.name, J, twist_d + self.gain * e if self.gain else twist_d, e, self.weight)
        err6 = np.zeros(6)
        err6[:3] = p_d - pose.translation
        if self._rotation_rows:
            err6[3:] = pin.log3(R_d @ pose.rotation.T)
        e = err6[self.rows]
        v = twist_d[self.rows] + self.gain * e
        return TaskTerm(self.name, J[self.rows], v, e, self.weight)

    def __repr__(self) -> str:
        return (
            f"FrameTask(frame={self.frame!r}, axes={list(self.axes)}, trajectory={self.trajectory!r}, gain={self.gain})"
        )


class PostureTask(Task):
    """Joint-space posture: q̇ = K (q_ref ⊖ q) on every joint (the usual lowest-priority regulariser).

    Args:
        target: Reference configuration q_ref (size nq); the configuration at reset if ``None``.
        gain: K [1/s] > 0.
        weight: Weight in a weighted QP.
    """

    def __init__(
        self,
        target: Sequence[float] | None = None,
        *,
        gain: float = 1.0,
        weight: float = 1.0,
        name: str = "posture",
    ) -> None:
        if not (np.isfinite(gain) and gain >= 0):
            raise TaskError(f"posture task '{name}': gain must be ≥ 0, got {gain}")
        self.target = None if target is None else np.asarray(target, dtype=float)
        self.gain, self.weight, self.name = float(gain), float(weight), name

    def reset(self, robot: RobotModel) -> None:
        if self.target is None:
            self.target = robot.q.copy()
        else:
            self.target = robot.check_configuration(self.target, f"task '{self.name}': target")

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        if self.target is None:
            self.reset(robot)
        e = robot.difference(robot.q, self.target)
        return TaskTerm(self.name, np.eye(robot.nv), self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"PostureTask(gain={self.gain})"
