"""Coordination of two end-effectors: hold the pose of frame A relative to frame B (section 5.3).

Two hands carrying one rigid object (the dual arm of Table 5.1, or two cooperating robots, Fig. 5.17) must keep
their relative pose: T_B^A = (T_0^B)⁻¹ T_0^A = const. Written in frame B,

    p_rel = R_Bᵀ (p_A − p_B),    R_rel = R_Bᵀ R_A,

and differentiating (v, ω base-aligned, as in :meth:`RobotModel.frame_jacobian`):

    ṗ_rel = R_Bᵀ [(v_A − v_B) + [p_A − p_B]× ω_B],    ω_rel = R_Bᵀ (ω_A − ω_B)

(ω_rel in frame B, Ṙ_rel = [ω_rel]× R_rel)

so the task Jacobian is J_rel = diag(R_Bᵀ, R_Bᵀ) [[J_A^v − J_B^v + [p_A − p_B]× J_B^ω], [J_A^ω − J_B^ω]] (6×n). With a
block-diagonal Jacobian (two robots, no shared joint) this is the coordination constraint that gives the 12-joint
pair its 6 degrees of redundancy; on a shared torso the torso columns of J_A and J_B partly cancel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from redundik.errors import TaskError
from redundik.kinematics.model import AXES, RobotModel
from redundik.tasks.base import Task, TaskTerm
from redundik.tasks.frame import resolve_axes


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class RelativePoseTask(Task):
    """Hold (or drive to) the pose of frame A expressed in frame B: J_rel q̇ = K e, e in frame B.

    The error is e = (p_d − p_rel, log3(R_d R_relᵀ)) with (p_d, R_d) the relative pose captured at :meth:`reset`
    (``target=None``) or given. Rows are selected by ``axes`` (names refer to frame B's axes here).

    Args:
        frame_a: The frame that is held relative to ``frame_b`` (e.g. the right hand).
        frame_b: The reference frame (e.g. the left hand).
        axes: Rows to control (see :data:`redundik.tasks.frame.AXIS_SETS`).
        gain: K [1/s] ≥ 0 on the error.
        weight: Weight in a weighted QP (> 0).
        target: Optional relative pose as a 4×4 homogeneous matrix T_B^A [length unit]; captured at reset if ``None``.
        name: Task name (default ``"<a>_in_<b>"``).

    Raises:
        TaskError: same frame twice, bad gain or weight, target not a proper homogeneous transform; unknown
            frames at :meth:`reset`.
    """

    def __init__(
        self,
        frame_a: str,
        frame_b: str,
        *,
        axes: str | Sequence[str] = "pose",
        gain: float = 1.0,
        weight: float = 1.0,
        target: np.ndarray | Sequence[Sequence[float]] | None = None,
        name: str | None = None,
    ) -> None:
        self.name = name or f"{frame_a}_in_{frame_b}"
        if frame_a == frame_b:
            raise TaskError(f"task '{self.name}': frame_a and frame_b must differ, got '{frame_a}' twice")
        if not (np.isfinite(gain) and gain >= 0):
            raise TaskError(f"task '{self.name}': gain must be a finite number ≥ 0, got {gain}")
        if not (np.isfinite(weight) and weight > 0):
            raise TaskError(f"task '{self.name}': weight must be > 0, got {weight}")
        self.frame_a, self.frame_b = frame_a, frame_b
        self.axes = resolve_axes(axes)
        self.rows = np.array([AXES[a] for a in self.axes], dtype=int)
        self.gain, self.weight = float(gain), float(weight)
        self._target: pin.SE3 | None = None
        self._given: pin.SE3 | None = None
        if target is not None:
            m = np.asarray(target, dtype=float)
            rot = m[:3, :3] if m.shape == (4, 4) else None
            if (
                rot is None
                or not np.all(np.isfinite(m))
                or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6)
                or np.linalg.det(rot) < 0
            ):
                raise TaskError(f"task '{self.name}': target must be a finite 4×4 homogeneous transform")
            self._given = pin.SE3(rot, m[:3, 3])
        self._ids: tuple[int, int] | None = None

    @property
    def dim(self) -> int:
        """Number of task rows m."""
        return len(self.rows)

    def reset(self, robot: RobotModel) -> None:
        try:
            self._ids = (robot.frame_id(self.frame_a), robot.frame_id(self.frame_b))
        except Exception as exc:
            raise TaskError(f"task '{self.name}': {exc}") from exc
        self._target = self._given.copy() if self._given is not None else self.relative_pose(robot)

    def relative_pose(self, robot: RobotModel) -> pin.SE3:
        """T_B^A = (T_0^B)⁻¹ T_0^A at the robot's current state."""
        if self._ids is None:
            self.reset(robot)
        assert self._ids is not None  # set by reset()
        return robot.frame_pose_view(self._ids[1]).actInv(robot.frame_pose_view(self._ids[0]))

    def jacobian(self, robot: RobotModel) -> np.ndarray:
        """The full 6×nv relative Jacobian J_rel (rows v, ω of A relative to B, in frame B)."""
        if self._ids is None:
            self.reset(robot)
        assert self._ids is not None
        ia, ib = self._ids
        pose_a, pose_b = robot.frame_pose_view(ia), robot.frame_pose_view(ib)
        ja, jb = robot.frame_jacobian(ia), robot.frame_jacobian(ib)  # (6, nv) each
        rbt = pose_b.rotation.T
        d = pose_a.translation - pose_b.translation
        jv = ja[:3] - jb[:3] + _skew(d) @ jb[3:]
        jw = ja[3:] - jb[3:]
        return np.vstack([rbt @ jv, rbt @ jw])

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        if self._ids is None or self._target is None:
            self.reset(robot)
        assert self._target is not None
        rel = self.relative_pose(robot)
        err6 = np.empty(6)
        err6[:3] = self._target.translation - rel.translation
        err6[3:] = pin.log3(self._target.rotation @ rel.rotation.T)
        e = err6[self.rows]
        J = self.jacobian(robot)[self.rows]
        return TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"RelativePoseTask({self.frame_a!r} in {self.frame_b!r}, axes={list(self.axes)}, gain={self.gain})"
