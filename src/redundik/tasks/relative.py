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

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledRows, default_name
from redundik.tasks.frame import axes_rows
from redundik.tasks.layouts import REL_FLOATS, REL_FRAME_A, REL_FRAME_B, REL_NROWS, REL_P, REL_R, REL_ROWS
from redundik.tasks.rows import CompiledTask

#: the compiled writers of the built-in tasks (loaded at first use)
_RK = KernelNamespace("redundik.tasks.row_kernels")


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class RelativePoseTask(CompiledTask):
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
        for key, frame in (("frame_a", frame_a), ("frame_b", frame_b)):
            if not isinstance(frame, str) or not frame:
                raise TaskError(f"RelativePoseTask: {key} must be a frame name (a str), got {frame!r:.60}")
        self.name = default_name(name, f"{frame_a}_in_{frame_b}", "RelativePoseTask")
        if frame_a == frame_b:
            raise TaskError(f"task '{self.name}': frame_a and frame_b must differ, got '{frame_a}' twice")
        self._frames = (frame_a, frame_b)
        self._ids: tuple[int, int] | None = None
        self._data: object = None  # the robot data the writer's frame ids and columns are for
        self.axes = axes  # (the setter takes a name of AXIS_SETS or a list of axes)
        self.gain, self.weight = gain, weight  # (Task's setters: check_number)
        self._target: pin.SE3 | None = None
        self._given: pin.SE3 | None = None if target is None else self._pose(target)
        self._ints = np.zeros(0, dtype=np.int64)
        self._floats = np.zeros(REL_FLOATS)  # (p_d, R_d row-major): the target, rewritten in place

    @property
    def frame_a(self) -> str:
        """Frame A, whose pose in frame B is held; an assignment takes effect at the next step, which holds the
        target given (:meth:`set_target`), else the frames' relative pose then."""
        return self._frames[0]

    @frame_a.setter
    def frame_a(self, value: str) -> None:
        self._set_frames(value, self._frames[1])

    @property
    def frame_b(self) -> str:
        """Frame B, in which the pose of frame A is held (as :attr:`frame_a` on assignment)."""
        return self._frames[1]

    @frame_b.setter
    def frame_b(self, value: str) -> None:
        self._set_frames(self._frames[0], value)

    def _set_frames(self, frame_a: object, frame_b: object) -> None:
        for key, frame in (("frame_a", frame_a), ("frame_b", frame_b)):
            if not isinstance(frame, str) or not frame:
                raise TaskError(f"task '{self.name}': {key} must be a frame name (a str), got {frame!r:.60}")
        if frame_a == frame_b:
            raise TaskError(f"task '{self.name}': frame_a and frame_b must differ, got '{frame_a}' twice")
        assert isinstance(frame_a, str) and isinstance(frame_b, str)  # (checked above)
        if (frame_a, frame_b) != self._frames:
            self._frames = (frame_a, frame_b)
            self._ids, self._target = None, None  # (bound again at the next step, and the target taken then)
            self._form_revision += 1

    @property
    def axes(self) -> tuple[str, ...]:
        """The rows of the relative pose that count (a name of ``AXIS_SETS`` or a list of axes on assignment); an
        assignment takes effect at the next step, the target kept."""
        return self._axes

    @axes.setter
    def axes(self, value: str | Sequence[str]) -> None:
        self._axes, self._rows = axes_rows(value, f"task '{self.name}'")
        self._data = None  # (the writer's rows packed again at the next step: ``compiled_rows`` binds anew)
        self._form_revision += 1

    @property
    def rows(self) -> np.ndarray:
        """The indices of :attr:`axes` in (x, y, z, rx, ry, rz) (read-only; assign :attr:`axes` to change them)."""
        return self._rows

    def _pose(self, target: object) -> pin.SE3:
        """``target`` (an SE3 or a 4×4 homogeneous matrix) as an SE3, checked: finite, a rotation block."""
        try:
            raw = np.asarray(target.homogeneous if isinstance(target, pin.SE3) else target)
            m = np.asarray(raw, dtype=float) if raw.dtype.kind in "iuf" else np.zeros(0)  # (no bools, complex, text)
        except (TypeError, ValueError):
            m = np.zeros(0)
        rot = m[:3, :3] if m.shape == (4, 4) else None
        if (
            rot is None
            or not np.all(np.isfinite(m))
            or not np.allclose(m[3], (0.0, 0.0, 0.0, 1.0), atol=1e-9)
            or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6)
            or np.linalg.det(rot) < 0
        ):
            raise TaskError(
                f"task '{self.name}': target must be an SE3 or a finite 4×4 homogeneous transform, got {target!r:.80}"
            )
        return pin.SE3(rot, m[:3, 3])

    def set_target(self, target: pin.SE3 | np.ndarray | Sequence[Sequence[float]]) -> None:
        """A new relative pose T_B^A (an SE3 or a 4×4 homogeneous matrix), held from now on and kept across resets
        (a new grip of the carried object). Data: written in place into the compiled writer's target, so a fused
        step keeps its plan; call it as often as every tick.

        Raises:
            TaskError: not a finite homogeneous transform with a rotation block.
        """
        pose = self._pose(target)
        self._given = pose
        if self._target is not None:
            self._target = pose.copy()
            self._write_target()

    @property
    def target(self) -> pin.SE3 | None:
        """T_B^A held (a copy): the given one, or the one captured at :meth:`reset`; ``None`` before."""
        held = self._target if self._target is not None else self._given
        return None if held is None else held.copy()

    @property
    def dim(self) -> int:
        """Number of task rows m."""
        return len(self.rows)

    def reset(self, robot: RobotModel) -> None:
        """Bind to ``robot`` and hold the given target, or the frames' relative pose now."""
        self._bind(robot)
        self._target = self._given.copy() if self._given is not None else self.relative_pose(robot)
        self._write_target()

    def _write_target(self) -> None:
        """The held target into the compiled writer's ``floats`` (``tasks.layouts``' ``REL_P``, ``REL_R``)."""
        assert self._target is not None
        self._floats[REL_P : REL_P + 3] = self._target.translation
        self._floats[REL_R : REL_R + 9] = self._target.rotation.reshape(-1)

    def _bind(self, robot: RobotModel) -> None:
        """The frames' ids and velocity columns on ``robot`` (the compiled writer's ``ints``); the target is kept."""
        try:
            self._ids = (robot.frame_id(self.frame_a), robot.frame_id(self.frame_b))
        except Exception as exc:
            raise TaskError(f"task '{self.name}': {exc}") from exc
        model, nv = robot.model, robot.nv
        columns = []
        for fid in self._ids:  # the velocity columns of the joints that move each frame
            col = np.zeros(nv, dtype=np.int64)
            for j in model.supports[model.frames[fid].parentJoint]:
                if j > 0:
                    col[model.joints[j].idx_v : model.joints[j].idx_v + model.joints[j].nv] = 1
            columns.append(col)
        head = [0] * REL_ROWS
        head[REL_FRAME_A], head[REL_FRAME_B], head[REL_NROWS] = self._ids[0], self._ids[1], len(self.rows)
        ints = np.concatenate([head, self.rows, *columns]).astype(np.int64)
        if self._data is not robot.data or not np.array_equal(ints, self._ints):
            self._form_revision += 1
        self._ints, self._data = ints, robot.data

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

    def compiled_rows(self, robot: RobotModel) -> CompiledRows:
        """The rows of the module docstring (``row_kernels.relative_rows``)."""
        if self._ids is None or self._target is None:
            self.reset(robot)
        elif self._data is not robot.data:  # another robot object (or a copy of this one): bound again, target kept
            self._bind(robot)
        return CompiledRows(_RK.relative_rows, len(self.rows), self._ints, self._floats)

    def __repr__(self) -> str:
        return f"RelativePoseTask({self.frame_a!r} in {self.frame_b!r}, axes={list(self.axes)}, gain={self.gain})"
