"""Frame tracking tasks: pose, position or a subset of axes (e.g. the planar x–y tip task of the 3R arm)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from redundik._coldstart import HOT as _HOT
from redundik._coldstart import twins_of
from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError, short_repr
from redundik.kinematics.model import AXES, LWA, RobotModel
from redundik.tasks.base import NOT_READY, FrameForm, Task, TaskTerm, default_name
from redundik.tasks.conform import MAX_COORDINATE, RIGID_TOLERANCE, conform_reference
from redundik.tasks.joint_selection import check_joint_selection, selected_coordinates
from redundik.tasks.layouts import P0, REF_R
from redundik.tasks.trajectory import Hold, Trajectory

#: Named axis sets.
AXIS_SETS: dict[str, tuple[str, ...]] = {
    "pose": ("x", "y", "z", "rx", "ry", "rz"),
    "position": ("x", "y", "z"),
    "orientation": ("rx", "ry", "rz"),
    "planar": ("x", "y"),
}


def resolve_axes(axes: str | Sequence[str]) -> tuple[str, ...]:
    """Turn ``"pose"``/``"position"``/``"orientation"``/``"planar"`` or a list (a tuple, a 1-D array) of axis names
    into axis names, in the order given (the order of the task's rows).

    Raises:
        TaskError: an unknown name (lists the valid ones), a repeated or empty list, an unordered set, or anything
            else than a name or a sequence of names.
    """
    if isinstance(axes, str):
        if axes not in AXIS_SETS:
            raise TaskError(f"unknown axes '{axes}'; expected one of {sorted(AXIS_SETS)} or a list of {list(AXES)}")
        return AXIS_SETS[axes]
    if isinstance(axes, (set, frozenset)):  # (its order, the rows' order, would change from run to run)
        raise TaskError(f"axes {short_repr(axes)}: a set has no order; give a list or a tuple of {list(AXES)}")
    if not isinstance(axes, (list, tuple, np.ndarray)):
        raise TaskError(
            f"axes must be one of {sorted(AXIS_SETS)} or a list of names among {list(AXES)}, got "
            f"{type(axes).__name__} {short_repr(axes)}"
        )
    out = tuple(str(a) if isinstance(a, str) else a for a in (axes.tolist() if isinstance(axes, np.ndarray) else axes))
    if not out or any(not isinstance(a, str) or a not in AXES for a in out) or len(set(out)) != len(out):
        raise TaskError(f"axes {short_repr(list(out))}: expected distinct names among {list(AXES)}")
    return out


def axes_rows(axes: str | Sequence[str], owner: str) -> tuple[tuple[str, ...], np.ndarray]:
    """:func:`resolve_axes` and the axes' row indices in (x, y, z, rx, ry, rz), read-only (a compiled step's writer
    packs them: an edit is an assignment of the axes); a bad value is a TaskError prefixed with ``owner``."""
    try:
        names = resolve_axes(axes)
    except TaskError as exc:
        raise TaskError(f"{owner}: {exc}") from None
    rows = np.array([AXES[a] for a in names], dtype=np.int64)
    rows.setflags(write=False)
    return names, rows


#: The compiled Lie kernels and target writers, imported on first use (numba loads then, not when redundik is
#: imported); namespaces, so that a cold start puts their interpreted twins here while they compile.
_K = KernelNamespace("redundik.kinematics.lie_kernels")
_TK = KernelNamespace("redundik.tasks.target_kernels")
#: ``target_kernels.OK``, the writers' status of a target written (read here without importing numba).
_STATUS_OK = 0
_SE3 = pin.SE3


#: Gain [1/s] of a frame task built without a trajectory (hold the start pose, or track targets set at run time).
DEFAULT_HOLD_GAIN = 10.0


#: (``MAX_COORDINATE``, ``RIGID_TOLERANCE``: :mod:`redundik.tasks.conform`'s, the bounds of a target and of a
#: reference; the 4×4 check of ``_as_pose`` is looser on the diagonal: a target refused by the compiled check is
#: checked again there, and taken if it passes.)
_MAX_COORDINATE2 = MAX_COORDINATE * MAX_COORDINATE


def _numbers(value: object, what: str, expected: str) -> np.ndarray:
    """``value`` as a float array when it holds real numbers (ints, floats), else a :class:`TaskError`: booleans,
    complex numbers and strings are refused rather than cast."""
    raw = np.asarray(value)
    if raw.dtype.kind not in "iuf":
        raise TaskError(f"{what}: expected {expected} of real numbers, got {raw.dtype.name} values {value!r:.80}")
    return np.asarray(raw, dtype=float)


def _bounded_configuration(q: np.ndarray, what: str) -> np.ndarray:
    """A copy of ``q`` when every finite coordinate is within ±:data:`MAX_COORDINATE` [rad or length unit], else a
    :class:`TaskError` (a posture 1e308 rad away asks for an absurd velocity: refused where it is set)."""
    finite = q[np.isfinite(q)]
    if finite.size and float(np.max(np.abs(finite))) > MAX_COORDINATE:
        k = int(np.flatnonzero(np.isfinite(q) & (np.abs(q) > MAX_COORDINATE))[0])
        raise TaskError(
            f"{what}: coordinate {k} = {q.reshape(-1)[k]:g} is beyond ±{MAX_COORDINATE:g} (a unit mistake?)"
        )
    return np.array(q, dtype=float)


def _as_pose(target: object, what: str) -> pin.SE3 | np.ndarray:
    """An SE3 from an SE3 or a 4×4 homogeneous matrix, or a position (3,) array; validated."""
    if isinstance(target, pin.SE3):
        T = target.homogeneous
    else:
        try:
            T = _numbers(target, what, "an SE3, a 4×4 matrix or a position (3,)")
        except (TypeError, ValueError) as exc:
            raise TaskError(f"{what}: expected an SE3, a 4×4 matrix or a position (3,), got {target!r:.80}") from exc
    position = T if T.shape == (3,) else T[:3, 3] if T.shape == (4, 4) else np.zeros(3)
    if np.all(np.isfinite(position)) and float(np.max(np.abs(position))) > MAX_COORDINATE:
        raise TaskError(f"{what}: a position coordinate beyond ±{MAX_COORDINATE:g} (a unit or sign mistake?)")
    if T.shape == (3,):
        if not np.all(np.isfinite(T)):
            raise TaskError(f"{what}: position contains NaN or infinite values")
        return T.copy()
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise TaskError(f"{what}: expected an SE3, a finite 4×4 matrix or a position (3,), got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0 or not np.allclose(T[3], [0, 0, 0, 1]):
        raise TaskError(f"{what}: the 4×4 matrix is not a rigid transform (rotation not orthonormal, or bad last row)")
    return pin.SE3(R.copy(), T[:3, 3].copy())


class FrameTask(Task):
    """Track a trajectory with a frame: J q̇ = V_d + K·e on the selected rows of the base-aligned Jacobian.

    The error is e = (p_d − p, log3(R_d Rᵀ)) in the world frame, restricted to ``axes``. With ``gain`` = 0 the task is
    the chapter's open-loop feed-forward V = ṗ_d (its 3R and (6+1) simulations); a positive gain closes the loop on
    the tracking error (first-order convergence e ~ exp(−K t)).

    Defaults: with a trajectory, ``gain`` = 0 (the chapter's open loop); without one the task holds the pose it
    has at reset, or the target set with :meth:`set_target`, with ``gain`` = :data:`DEFAULT_HOLD_GAIN` (10 /s).
    A target set at run time survives :meth:`reset`.

    Args:
        frame: Frame name.
        trajectory: Reference; :class:`Hold` if ``None``.
        axes: Rows to control (see :data:`AXIS_SETS`).
        gain: K [1/s] ≥ 0 on the error (default above).
        weight: Weight among the rows of its level in a weighted QP (> 0).
        priority: Level (0 = highest; ``None``: the main tasks' level 0).
        name: Task name (defaults to the frame name).
    """

    def __init__(
        self,
        frame: str,
        trajectory: Trajectory | None = None,
        *,
        axes: str | Sequence[str] = "pose",
        gain: float | None = None,
        weight: float = 1.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        if gain is None:
            gain = 0.0 if trajectory is not None else DEFAULT_HOLD_GAIN
        self._init_task(default_name(name, frame, "FrameTask"), weight=weight, gain=gain, priority=priority)
        self._frame = ""
        self.frame = frame
        self.trajectory = trajectory if trajectory is not None else Hold()
        # the hold this task made itself (its targets are written into it in place); a hold given by the caller
        # may be shared, so a first set_target replaces it with one of the task's own
        self._held: Trajectory | None = self.trajectory if trajectory is None else None
        self.axes = axes  # (the setter takes a name or a list of axes, sets the rows)
        self._fid: int | None = None
        self._pending_position: np.ndarray | None = None
        # the target orientation at the last evaluation (or a fused step's reference row, R_d in entries 3:12)
        self._last_R: np.ndarray | None = None
        self._data: Any = None  # the robot data the task was reset on, and its live view of the frame's pose
        self._pose: Any = None

    @property
    def trajectory(self) -> Trajectory:
        """The reference the frame follows. Assigning another trajectory takes effect at the next step (it is
        anchored at the frame's pose then, unless already started)."""
        return self._trajectory

    @trajectory.setter
    def trajectory(self, value: Trajectory) -> None:
        if not isinstance(value, Trajectory):
            raise TaskError(f"frame task '{self.name}': trajectory must be a Trajectory, got {type(value).__name__}")
        self._trajectory = value
        self._form_revision += 1

    @property
    def frame(self) -> str:
        """The tracked frame's name. Assigning another frame takes effect at the next step: its id is looked up
        again and the task is reset there (the trajectory anchored at the new frame's pose, a set target kept)."""
        return self._frame

    @frame.setter
    def frame(self, value: str) -> None:
        if not isinstance(value, str) or not value:
            raise TaskError(f"frame task '{self.name}': frame must be a frame name (a string), got {value!r:.80}")
        self._frame = value
        self._fid = None
        self._form_revision += 1  # (a fused step plans the stack again)

    @property
    def axes(self) -> tuple[str, ...]:
        """The controlled axes; assigning a name of :data:`AXIS_SETS` or a list of axes sets :attr:`rows` too."""
        return self._axes

    @axes.setter
    def axes(self, value: str | Sequence[str]) -> None:
        axes = resolve_axes(value)
        rows = np.array([AXES[a] for a in axes], dtype=int)
        rows.setflags(write=False)
        self._axes = axes
        self._m = int(rows.shape[0])
        self._all_rows = rows.tolist() == list(range(6))
        self._rotation_rows = bool(np.any(rows >= 3))
        self._rows = rows
        self._form_revision += 1

    @property
    def rows(self) -> np.ndarray:
        """The rows of the twist this task controls (read-only: a fused step packs them; a new :attr:`axes` gives a
        new array, which it sees)."""
        return self._rows

    @property
    def dim(self) -> int:
        """Number of task rows m."""
        return len(self.rows)

    def set_target(self, target: pin.SE3 | np.ndarray | Sequence[float]) -> None:
        """Hold a new target from now on (teleoperation): an SE3, a 4×4 homogeneous matrix, or a position (3,).

        A position keeps the current target orientation (or the frame's own at the next evaluation if the task has
        not run yet). The reference twist becomes zero; the gain closes the error, so it must be > 0 to move.

        Call it as often as every control tick: once the task holds a target of its own, a new one is checked and
        written in place into the hold's parameter row (:mod:`redundik.tasks.target_kernels`), which a fused step
        reads as data — no re-planning, no allocation for an SE3 or a float64 array.

        Raises:
            TaskError: malformed target.
        """
        traj = self._trajectory
        row = traj._kparams if traj is self._held else None
        if row is not None:  # our own started hold: the target is data, written in place
            tk = _TK if _HOT else twins_of(_TK)  # (their twins until a resolver's kernels are loaded: no compile here)
            status = -1
            if type(target) is _SE3:  # (first, with its own return: the common form)
                if tk.pose_into(target.homogeneous, row, RIGID_TOLERANCE, MAX_COORDINATE) == _STATUS_OK:  # type: ignore[union-attr]
                    traj._revision += 1
                    traj._given = True  # type: ignore[attr-defined]  # (traj is self._held, a Hold): kept by a reset
                    self._pending_position = None
                    return
            elif type(target) is np.ndarray and target.dtype == np.float64:
                if target.shape == (4, 4):
                    status = tk.pose_into(target, row, RIGID_TOLERANCE, MAX_COORDINATE)
                elif target.shape == (3,):
                    status = tk.position_into(target, row, MAX_COORDINATE)
            if status == _STATUS_OK:
                traj._revision += 1
                traj._given = True  # type: ignore[attr-defined]  # (traj is self._held, a Hold): kept by a reset
                self._pending_position = None
                return
        pose = _as_pose(target, f"frame task '{self.name}': set_target")  # the checks, and their messages
        if row is not None:
            if isinstance(pose, np.ndarray):
                row[P0 : P0 + 3] = pose
                traj._revision += 1
                traj._given = True  # type: ignore[attr-defined]
            else:
                traj._write(pose)  # type: ignore[attr-defined]  # (traj is self._held, a Hold)
            self._pending_position = None
            return
        if isinstance(pose, np.ndarray):
            last = self._last_R if traj._kparams is None else traj._R0  # (a compiled reference holds R0)
            if last is not None:
                if last.shape != (3, 3):  # a fused step's reference row (p_d, R_d row-major, twist)
                    last = last[REF_R : REF_R + 9].reshape(3, 3)
                self._hold(pin.SE3(np.array(last), pose))
            else:
                self._pending_position = pose
                self._form_revision += 1
            return
        self._pending_position = None
        self._hold(pose)

    def set_target_from_configuration(self, robot: RobotModel) -> None:
        """Hold the frame's pose at the robot's current (updated) configuration."""
        self._pending_position = None
        self._hold(robot.frame_pose(self._frame_id(robot)))

    @property
    def target(self) -> pin.SE3 | None:
        """The held target pose, or ``None`` while following a trajectory / before the first evaluation."""
        traj = self.trajectory
        return traj.pose if isinstance(traj, Hold) else None

    def _hold(self, pose: pin.SE3) -> None:
        """Hold ``pose`` with a hold of the task's own (later targets are written into it in place)."""
        hold = Hold(pose)
        hold.start(pose)
        self.trajectory = self._held = hold

    def _frame_id(self, robot: RobotModel) -> int:
        if self._fid is None:
            try:
                self._fid = robot.frame_id(self.frame)
            except Exception as exc:
                raise TaskError(f"task '{self.name}': {exc}") from exc
        return self._fid

    def reset(self, robot: RobotModel) -> None:
        """Anchor the trajectory at the frame's current pose (a target set at run time is kept).

        Raises:
            TaskError: unknown frame, or a frame that no joint moves (its parent joint is the world: the task
                could never be met).
        """
        before = (self._fid, self._data)
        self._fid = None
        fid = self._frame_id(robot)
        if before[0] != fid or before[1] is not robot.data:
            self._form_revision += 1
        if robot.model.frames[fid].parentJoint == 0:
            raise TaskError(
                f"task '{self.name}': frame '{self.frame}' is fixed to the world (no joint moves it): a task on it can "
                "never be met; choose a frame on a moving link"
            )
        pose = robot.frame_pose_view(fid)
        self._data, self._pose = robot.data, pose  # the frame's placement, updated in place by every robot.update
        self.trajectory.start(pose)  # a Hold(pose) keeps its pose
        if self._pending_position is not None:
            self._hold(pin.SE3(np.array(pose.rotation), self._pending_position))
            self._pending_position = None

    def reference_sampled(self, R_d: np.ndarray) -> None:
        """The desired orientation R_d (3, 3) a fused step sampled for this task: kept, as ``evaluate`` keeps
        it, for a later position-only ``set_target``."""
        self._last_R = R_d

    def frame_form(self, robot: RobotModel) -> FrameForm | str | None:
        """This task's ``FrameForm`` (a fused step computes its rows itself), or
        ``NOT_READY`` until it has been evaluated (or reset) on ``robot``. A subclass that overrides
        :meth:`evaluate` has rows of its own: ``None``, unless it overrides this method too."""
        if type(self).evaluate is not FrameTask.evaluate:
            return None
        fid = self._fid
        if fid is None or not self._trajectory.has_start or self._data is not robot.data:
            return NOT_READY
        if self._pending_position is not None:
            return NOT_READY
        return FrameForm(
            self, fid, self._rows, self._rotation_rows, self._all_rows, self._trajectory, self._form_revision
        )

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        fid = self._fid
        data = robot.data
        if fid is None or not self.trajectory.has_start:
            self.reset(robot)  # checks the frame, and that the robot was updated (robot.frame_pose)
            fid = self._fid
            assert fid is not None  # for the type checker; set by reset()
        elif data is not self._data:  # evaluated on another robot object than at reset: its own pose view, and
            self._fid = None  # its own id of the frame (another model numbers its frames its own way: the id of the
            fid = self._frame_id(robot)  # first robot's frame named some other frame of this one, silently)
            self._data, self._pose = data, robot.frame_pose_view(fid)
            self._form_revision += 1
        pose = self._pose  # a live view on data.oMf[fid] (robot.frame_pose_view without its checks, done at reset)
        if self._pending_position is not None:
            self._hold(pin.SE3(np.array(pose.rotation), self._pending_position))
            self._pending_position = None
        p_d, R_d, twist_d = conform_reference(self.trajectory.reference(t), f"task '{self.name}'")
        self._last_R = R_d
        J = pin.getFrameJacobian(robot.model, data, fid, LWA)  # robot.frame_jacobian without its checks
        J = J if J.ndim == 2 else J.reshape(6, -1)  # a 1-joint robot: the bindings return its 6×1 as shape (6,)
        m = self._m
        e, v = np.empty(m), np.empty(m)
        # one compiled call for e = (p_d − p, log3(R_d Rᵀ))[rows] and v = V_d[rows] + K e (rotations under 0.45 rad)
        if _K.frame_error(p_d, R_d, pose.homogeneous, twist_d, self._gain, self.rows, self._rotation_rows, e, v):
            return TaskTerm(self._name, J if self._all_rows else J[self.rows], v, e, self._weight)
        if self._all_rows:  # a large rotation error: Pinocchio's log3, robust up to π
            e = np.concatenate((p_d - pose.translation, pin.log3(R_d @ pose.rotation.T)))
            gain = self._gain
            return TaskTerm(self._name, J, twist_d + gain * e if gain else twist_d, e, self._weight)
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


_IDENTITY: dict[int, np.ndarray] = {}


def _identity(n: int) -> np.ndarray:
    """The n×n identity, shared and read-only (a posture term's Jacobian, built once per size)."""
    eye = _IDENTITY.get(n)
    if eye is None:
        eye = np.eye(n)
        eye.setflags(write=False)
        _IDENTITY[n] = eye
    return eye


def _read_only(arr: np.ndarray) -> np.ndarray:
    """``arr`` with its write flag off (an array a task hands to a fused plan, which packs it once)."""
    arr.setflags(write=False)
    return arr


class PostureTask(Task):
    """Joint-space posture: q̇ = K (q_ref ⊖ q) on every joint (or on the ``joints`` given) — a regularisation task.

    It declares ``regularization`` (and ``identity_jacobian`` when it covers every coordinate): in every resolver it
    lies below the main tasks and the subtasks, as one term of the null-space objective z (see
    :mod:`redundik.tasks.stack`): it is the gradient of −½K‖S(q ⊖ q_ref)‖², S the rows of the identity it covers
    (J = S; z += Sᵀ K S(q_ref ⊖ q)). As in pink and mink, a posture never pulls the main tasks off their targets; its
    strength in the null space is its gain (its weight only matters if it is given an explicit ``priority``, where
    its rows J = S are weighted as any task's).

    ``joints="actuated"`` leaves a floating base out (a free flyer or a planar root joint), as pink's and mink's
    posture tasks do: the base then moves as the other tasks need, not back towards q_ref's base pose.

    Args:
        target: Reference configuration q_ref (size nq); the configuration at reset if ``None``. Settable at run
            time with :meth:`set_target` or by assigning :attr:`target` (kept across resets); the array in use is
            read-only, since a fused step packs it when it plans the stack (an edit in place would be missed).
        joints: ``None`` (every velocity coordinate), ``"actuated"`` (all but a floating root joint's), or a list of
            joint names (a multi-dof joint by its name, or one of its coordinates as ``"name.k"``), checked against
            the robot at reset.
        gain: K [1/s] ≥ 0.
        weight: Weight (> 0), used only when the task is given an explicit level.
        priority: ``None`` (the null-space objective) or an explicit level.
    """

    identity_jacobian = True
    regularization = True

    def __init__(
        self,
        target: Sequence[float] | np.ndarray | None = None,
        *,
        joints: Sequence[str] | str | None = None,
        gain: float = 1.0,
        weight: float = 1.0,
        priority: int | None = None,
        name: str = "posture",
    ) -> None:
        self._init_task(name, weight=weight, gain=gain, priority=priority)
        self._joints = check_joint_selection(joints, f"posture task '{name}'")
        if self._joints is not None:  # (rows of the identity, not all of them: J = S)
            self.identity_jacobian = False  # type: ignore[misc]  # (a per-instance declaration)
        what = f"posture task '{name}': target"
        given = None if target is None else _numbers(target, what, "a configuration")
        if given is not None and not np.all(np.isfinite(given)):
            raise TaskError(f"{what}: contains NaN or infinite values")  # as set_target says: refused where set
        self._given = None if given is None else _read_only(_bounded_configuration(given, what).copy())
        self._target: np.ndarray | None = self._given
        self._sel: np.ndarray | None = None
        self._sel_model: Any = None
        self._sel_nv = -1
        self._rows = _identity(0)

    @property
    def joints(self) -> str | tuple[str, ...] | None:
        """The coordinates covered: ``None`` (all), ``"actuated"`` or the joint names given (fixed at construction)."""
        return self._joints

    def _selection(self, robot: RobotModel) -> np.ndarray:
        """The velocity coordinates covered on ``robot`` (sorted indices, read-only; made once per robot model)."""
        sel = self._sel
        if sel is None or self._sel_model is not robot.model or self._sel_nv != robot.nv:
            sel = _read_only(selected_coordinates(robot, self._joints, f"posture task '{self.name}'"))
            self._sel, self._sel_model, self._sel_nv = sel, robot.model, robot.nv
            self._rows = _read_only(np.eye(robot.nv)[sel])  # J = S, the rows of the identity covered
        return sel

    @property
    def target(self) -> np.ndarray | None:
        """The reference configuration q_ref (nq,), read-only: the one in use, or the one set and not yet checked
        against the robot (at the next evaluation); ``None`` until the first evaluation or reset when none was
        given. Assigning it is :meth:`set_target`."""
        return self._target if self._target is not None else self._given

    @target.setter
    def target(self, q: Sequence[float] | np.ndarray) -> None:
        self.set_target(q)

    def set_target(self, q: Sequence[float] | np.ndarray) -> None:
        """A new reference configuration q_ref (size nq), checked against the robot at the next evaluation.

        Call it as often as every control tick: a fused step writes the new q_ref into its plan as data (no new
        plan). A float64 vector is checked in a few operations (finite, within ±``MAX_COORDINATE``) and copied."""
        if type(q) is np.ndarray and q.dtype == np.float64 and q.ndim == 1 and q.dot(q) <= _MAX_COORDINATE2:
            arr = q.copy()  # (every entry finite and within ±MAX_COORDINATE; else the checks below, and their words)
            arr.flags.writeable = False
            self._given = arr
            self._target = None
            return
        what = f"posture task '{self.name}': set_target"
        arr = _numbers(q, what, "a configuration").reshape(-1)
        if not np.all(np.isfinite(arr)):
            raise TaskError(f"{what}: contains NaN or infinite values")
        _bounded_configuration(arr, what)
        self._given = _read_only(arr.copy())
        self._target = None

    def reset(self, robot: RobotModel) -> None:
        """Capture q_ref (the configuration now, unless one was given: checked against the robot here) and the
        coordinates covered.

        Raises:
            TaskError: a given target that is not one of this robot's configurations; ``joints`` naming a joint the
                robot does not have, or covering none of its coordinates.
        """
        self._selection(robot)
        given = self._given
        if given is None:
            self._target = _read_only(robot.q.copy())
        elif given.shape == (robot.nq,) and not robot.has_quaternions:  # (finite and bounded: checked where set)
            self._target = given
        else:
            self._target = _read_only(robot.check_configuration(given, f"task '{self.name}': target"))

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        target = self._target
        if target is None or target.shape[0] != robot.nq:  # (a stack stepped on a robot of another size: the
            self.reset(robot)  # target it captured is not one of this robot's; a given one is checked against it)
        assert self._target is not None  # set by reset()
        e = robot.difference(robot.q, self._target)
        if self._joints is None:
            return TaskTerm(self._name, _identity(robot.nv), self._gain * e, e, self._weight)
        e = e[self._selection(robot)]
        return TaskTerm(self._name, self._rows, self._gain * e, e, self._weight)

    def joint_form(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray] | None:
        """(every velocity coordinate, q_ref) once the target is known: after the first evaluation or reset, or
        given (``set_target``: checked against the robot here, as :meth:`evaluate` would, so a fused step takes the
        new target as data).

        Raises:
            TaskError: a given target that is not one of this robot's configurations.
        """
        target = self._target
        if target is not None and self._sel_model is robot.model:  # (both captured on this model at reset)
            return self._sel, target  # type: ignore[return-value]  # (set with _sel_model)
        if target is None and self._given is not None:
            self.reset(robot)
            target = self._target
        if target is None or target.shape[0] != robot.nq:
            return None
        return self._selection(robot), target

    def __repr__(self) -> str:
        joints = "" if self._joints is None else f"joints={self._joints!r}, "
        return f"PostureTask({joints}gain={self.gain})"
