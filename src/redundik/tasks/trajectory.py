"""Reference trajectories for frame tasks: desired pose and twist as functions of time.

Every trajectory starts from the frame's pose at t = 0 (captured by :meth:`Trajectory.start`) unless it is given an
explicit start, so a task run can begin wherever the robot is, as in the chapter's examples. Twists are
base-aligned (v of the frame origin, ω), both in the world frame, like the Jacobians of
:class:`~redundik.kinematics.RobotModel`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError, short_repr
from redundik.kinematics.model import AXES
from redundik.tasks.layouts import EXTRA, P0, PARAMS, R0, REF, REF_P, REF_TWIST

#: Largest magnitude of a trajectory parameter (a length, a speed, a rate): beyond it the task rows overflow.
MAX_MAGNITUDE = 1e12


def _vec(value: Sequence[float] | np.ndarray, size: int, what: str) -> np.ndarray:
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "fiu":
            raise TypeError(f"dtype {raw.dtype}")
        arr = np.asarray(raw, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise TaskError(f"{what}: expected {size} numbers, got {type(value).__name__} ({exc})") from None
    if arr.shape[0] != size:
        raise TaskError(f"{what}: expected {size} numbers, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise TaskError(f"{what}: contains NaN or infinite values")
    if np.any(np.abs(arr) > MAX_MAGNITUDE):
        raise TaskError(f"{what}: values must be at most {MAX_MAGNITUDE:g} in magnitude, got {arr.tolist()}")
    return arr


def _float(value: object, what: str) -> float:
    """``value`` as a float when it is a real number (not a bool); an int beyond the float range gives ``inf`` (the
    caller's range check refuses it, rather than an ``OverflowError``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TaskError(f"{what} must be a number, got {type(value).__name__} {short_repr(value)}")
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _time(t: object, trajectory: object) -> float:
    """A reference's ``t`` [s] as a float, checked: the slow branch of the references' one-test fast path.

    Raises:
        TaskError: not a real number, or NaN / infinite / beyond the float range; names the trajectory's class.
    """
    what = f"{type(trajectory).__name__}.reference(t)"
    x = _float(t, f"{what}: t [s]")
    if not math.isfinite(x):
        raise TaskError(f"{what}: t must be a finite time [s], got {short_repr(t)}")
    return x


def _number(value: object, what: str, *, positive: bool = False) -> float:
    """``value`` as a float: a real number (not a bool), finite, at most :data:`MAX_MAGNITUDE` in magnitude."""
    x = _float(value, what)
    if not math.isfinite(x) or abs(x) > MAX_MAGNITUDE or (positive and x <= 0):
        rule = "a positive number" if positive else "a finite number"
        raise TaskError(f"{what} must be {rule}, at most {MAX_MAGNITUDE:g} in magnitude, got {short_repr(value)}")
    return x


def _rigid(pose: object, what: str) -> pin.SE3:
    """``pose`` (an SE3 or a 4×4 homogeneous matrix) as an SE3 copy, finite and bounded; a matrix must be rigid too
    (an SE3's rotation is taken as given: this is on the path of ``FrameTask.set_target``, which checked it). Raises
    :class:`TaskError`."""
    if isinstance(pose, pin.SE3):
        if not float(np.abs(pose.homogeneous).sum()) <= 4 + 3 * MAX_MAGNITUDE:  # one cheap check, NaN included
            raise TaskError(f"{what}: contains NaN, infinite or values over {MAX_MAGNITUDE:g}")
        return pose.copy()
    if not (isinstance(pose, np.ndarray) and pose.shape == (4, 4) and pose.dtype.kind in "fiu"):
        raise TaskError(f"{what}: expected an SE3 or a 4×4 homogeneous matrix, got {type(pose).__name__}")
    M = np.asarray(pose, dtype=float)
    if not np.all(np.isfinite(M)) or np.any(np.abs(M[:3, 3]) > MAX_MAGNITUDE):
        raise TaskError(f"{what}: contains NaN, infinite or values over {MAX_MAGNITUDE:g}")
    R = M[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0 or not np.allclose(M[3], (0, 0, 0, 1)):
        raise TaskError(f"{what}: not a rigid transform (rotation not orthonormal, or bad last row)")
    return pin.SE3(M)


#: Kinds of compiled reference (``target_kernels.reference_into``); ``GIVEN``: none, the
#: trajectory's :meth:`Trajectory.reference` is sampled in Python.
GIVEN, HOLD, LINE, CIRCLE = 0, 1, 2, 3

#: The compiled trajectory references (:mod:`redundik.tasks.target_kernels`), imported at first use; a cold start
#: puts their interpreted twins here while they compile.
_TK = KernelNamespace("redundik.tasks.target_kernels")


class Trajectory(ABC):
    """A desired frame pose and twist over time.

    A trajectory whose reference is compiled declares ``_kind`` (a kind of
    ``target_kernels.reference_into``, 0 = none) and, once started, ``_kparams`` (its parameter
    row): a fused step then samples it inside its compiled call, with the same kernel as :meth:`reference`.
    """

    _start: pin.SE3 | None = None
    _prepared_for: pin.SE3 | None = None  # (Circle: the start its centre was found for)
    _kind: int = 0
    _kparams: np.ndarray | None = None
    _revision: int = 0
    _p0: np.ndarray  # the start position [length] (a view of ``_kparams`` once it exists)
    _R0: np.ndarray  # the start rotation (a view of ``_kparams`` once it exists)

    def __getstate__(self) -> dict[str, object]:
        """The state for a copy or a pickle, without the views of the parameter row (``_p0``, ``_R0``): a copied view
        is a frozen array, which the per-task path would read while a new target went into the row."""
        state = dict(self.__dict__)
        if state.get("_kparams") is not None:
            state.pop("_p0", None)
            state.pop("_R0", None)
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        """Restore a copy: ``_p0`` and ``_R0`` views of its own parameter row again."""
        self.__dict__.update(state)
        row = self._kparams
        if row is not None:
            self._p0 = row[P0 : P0 + 3]
            self._R0 = row[R0 : R0 + 9].reshape(3, 3)

    @property
    def revision(self) -> int:
        """A counter that moves whenever the parameter row's values are rewritten in place (a new target of a
        :class:`Hold`): a fused step copies the row again when it moved, without planning the stack again."""
        return self._revision

    @property
    def kind(self) -> int:
        """The kind of compiled reference (``HOLD``, ``LINE``, ``CIRCLE``), or ``GIVEN`` (sampled in Python)."""
        return self._kind

    @property
    def parameters(self) -> np.ndarray | None:
        """The compiled reference's parameter row (``PARAMS``,) once started, else ``None``: the data a fused step
        packs (read it, do not write it: a new target goes through the task or the trajectory's setters)."""
        return self._kparams

    def share_parameters(self, row: np.ndarray) -> bool:
        """Keep the parameter row in ``row`` from now on (a float64 view of a fused plan's packed data, of the row's
        size): its values copied there, ``_p0`` and ``_R0`` views of it, so that a target written in place reaches
        the plan without a copy at the next step. False: no parameter row yet, or ``row`` of another size."""
        own = self._kparams
        if own is None or row.shape != own.shape or row.dtype != np.float64:
            return False
        if own is not row:
            row[:] = own
            self._kparams, self._p0, self._R0 = row, row[P0 : P0 + 3], row[R0 : R0 + 9].reshape(3, 3)
        return True

    def _params_row(self, kind: int, extra: Sequence[float] = ()) -> None:
        """Set ``_kind`` and ``_kparams`` = (p0, R0 row-major, extra...) for the compiled reference; ``_p0`` and
        ``_R0`` become views of the row (one copy of the data, which in-place target writes update)."""
        row = np.zeros(PARAMS)
        row[P0 : P0 + 3] = self._p0
        row[R0 : R0 + 9] = np.asarray(self._R0).reshape(-1)
        row[EXTRA : EXTRA + len(extra)] = extra
        self._kparams = row
        self._kind = kind
        self._revision += 1
        self._p0 = row[P0 : P0 + 3]
        self._R0 = row[R0 : R0 + 9].reshape(3, 3)

    def start(self, pose: pin.SE3) -> None:
        """Anchor the trajectory at the frame pose at t = 0."""
        self._start = pose.copy()
        self._p0 = np.array(pose.translation)
        self._R0 = np.array(pose.rotation)
        self._prepare()

    def _prepare(self) -> None:  # noqa: B027 - optional hook
        """Precompute what :meth:`reference` needs once the start pose is known."""

    @property
    def has_start(self) -> bool:
        """True once :meth:`start` has anchored the trajectory."""
        return self._start is not None

    @property
    def start_pose(self) -> pin.SE3:
        """The pose captured by :meth:`start`.

        Raises:
            TaskError: if :meth:`start` was never called.
        """
        if self._start is None:
            raise TaskError(f"{type(self).__name__}: start(pose) must be called before sampling")
        return self._start

    def sample(self, t: float) -> tuple[pin.SE3, np.ndarray]:
        """Desired pose (world) and twist (v, ω) [m/s, rad/s], shape (6,), at time t [s]."""
        p, R, twist = self.reference(t)
        return pin.SE3(R, p), twist

    @abstractmethod
    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired position (3,), rotation (3, 3) and twist (6,) at time t [s] as plain arrays (the hot path).

        A t that is not a finite real number is a :class:`TaskError` (the built-in trajectories test it in one
        operation on the fast path: a float that is finite)."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class Hold(Trajectory):
    """Hold a pose (zero twist): the start pose — the (6+1) robot's 'end-effector held still' — or a given one.

    A started hold keeps its pose in its parameter row (p0, R0): a new pose (:attr:`pose`, or a frame task's
    ``set_target``) is written there in place and moves ``revision``, so a fused step takes it as data.

    Args:
        pose: A fixed pose to hold (a target set at run time); ``None`` holds the pose captured at start.
    """

    def __init__(self, pose: pin.SE3 | np.ndarray | None = None) -> None:
        self._pose = None if pose is None else _rigid(pose, "hold pose")
        self._given = pose is not None

    @property
    def pose(self) -> pin.SE3 | None:
        """The given pose held (a copy; ``None``: the pose captured at start). Assigning a pose (an SE3 or a rigid
        4×4 matrix) to a started hold takes effect at the next step; assigning ``None`` keeps holding the current
        pose."""
        if not self._given:
            return None
        if self._kparams is not None:
            return pin.SE3(np.array(self._R0), np.array(self._p0))
        return self._pose

    @pose.setter
    def pose(self, value: pin.SE3 | np.ndarray | None) -> None:
        if value is None:
            self._pose, self._given = None, False
            return
        pose = _rigid(value, "hold pose")
        self._pose, self._given = pose, True
        if self._kparams is not None:
            self._write(pose)

    def _write(self, pose: pin.SE3) -> None:
        """Hold ``pose`` (checked) from now on: written into the started hold's parameter row in place."""
        row = self._kparams
        assert row is not None  # (started)
        row[P0 : P0 + 3] = pose.translation
        row[R0 : R0 + 9] = np.asarray(pose.rotation).reshape(-1)
        self._given = True
        self._revision += 1

    def start(self, pose: pin.SE3) -> None:
        """Anchor at ``pose``, or keep holding the given pose (a started hold keeps its row: a target written in
        place survives a reset)."""
        if self._given and self._kparams is not None:
            return
        super().start(self._pose if self._pose is not None else pose)

    def _prepare(self) -> None:
        self._zero = np.zeros(6)
        self._params_row(HOLD)

    def __repr__(self) -> str:
        pose = self.pose
        return "Hold()" if pose is None else f"Hold(pose at {np.round(pose.translation, 6).tolist()})"

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if type(t) is not float or not math.isfinite(t):
            _time(t, self)  # (raises: a held pose does not depend on t, but a NaN time is a caller's bug)
        self.start_pose  # noqa: B018 - raises if start() was never called
        return self._p0, self._R0, self._zero


class Line(Trajectory):
    """Straight line at constant velocity from the start position, orientation held.

    Args:
        velocity: Linear velocity [length/s], shape (3,) (or (2,) for a planar x–y line).
    """

    def __init__(self, velocity: Sequence[float]) -> None:
        v = _vec(velocity, int(np.size(velocity)), "line velocity")  # bounded by MAX_MAGNITUDE where it is made
        if v.shape[0] == 2:
            v = np.append(v, 0.0)
        self.velocity = _vec(v, 3, "line velocity")  # (the setter keeps a read-only copy)

    @property
    def velocity(self) -> np.ndarray:
        """The line's velocity (3,), read-only: its compiled reference packs it when the line starts, so an edit in
        place would be missed. Assigning a new one (2 or 3 finite numbers) takes effect at the next step
        (p_d = p0 + v t from the same start)."""
        return self._velocity

    @velocity.setter
    def velocity(self, value: Sequence[float] | np.ndarray) -> None:
        # (not bounded by MAX_MAGNITUDE here: a trajectory of one's own may ask for more, as the contract tests do)
        try:
            raw = np.asarray(value)
            if raw.dtype.kind not in "fiu":
                raise TypeError(f"dtype {raw.dtype}")
            v = np.array(raw, dtype=float).reshape(-1)  # a copy: the caller's array stays its own
        except (TypeError, ValueError) as exc:
            raise TaskError(f"line velocity: expected 2 or 3 numbers, got {type(value).__name__} ({exc})") from None
        if v.shape[0] == 2:
            v = np.append(v, 0.0)
        if v.shape[0] != 3 or not np.all(np.isfinite(v)):
            raise TaskError(f"line velocity: expected 2 or 3 finite numbers, got {v.tolist()}")
        v.setflags(write=False)
        self._velocity = v
        if self._start is not None:
            self._prepare()  # a new parameter row: the fused step, which compares it by identity, plans again

    def _prepare(self) -> None:
        self._params_row(LINE, self.velocity.tolist())

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if type(t) is not float or not math.isfinite(t):
            t = _time(t, self)
        self.start_pose  # noqa: B018 - raises if start() was never called
        out = np.empty(REF)
        _TK.reference_into(LINE, self._kparams, t, out)  # p0 + v t, (v, 0)
        return out[REF_P : REF_P + 3], self._R0, out[REF_TWIST : REF_TWIST + 6]

    def __repr__(self) -> str:
        return f"Line(velocity={self.velocity.tolist()})"


class Circle(Trajectory):
    """Circle in a coordinate plane at constant angular rate, orientation held.

    Position: c + r(cos(ωt + φ) e1 + sin(ωt + φ) e2), as in the chapter's y_b–z_b circle of the (6+1) robot.

    Args:
        radius: r [length].
        omega: ω [rad/s].
        plane: The two world axes spanning the plane, e.g. ``("y", "z")``.
        center: Centre; if ``None`` it is placed so that the circle passes through the start at phase φ.
        phase: φ [rad].
    """

    def __init__(
        self,
        radius: float,
        omega: float,
        plane: tuple[str, str] = ("x", "y"),
        center: Sequence[float] | None = None,
        phase: float = 0.0,
    ) -> None:
        radius = _number(radius, "circle radius", positive=True)
        omega = _number(omega, "circle omega")
        phase = _number(phase, "circle phase")
        if abs(radius * omega) > MAX_MAGNITUDE:
            raise TaskError(f"circle speed radius × omega = {radius * omega:g} exceeds {MAX_MAGNITUDE:g}")
        self._radius, self._omega, self._phase = float(radius), float(omega), float(phase)
        self._set_plane(plane)
        self._set_center(center)

    def _set_plane(self, plane: object) -> None:
        if (
            not isinstance(plane, (tuple, list))
            or len(plane) != 2
            or any(not isinstance(a, str) or a not in ("x", "y", "z") for a in plane)
            or plane[0] == plane[1]
        ):
            raise TaskError(f"circle plane must be two different axes among x, y, z, got {plane!r:.80}")
        e1, e2 = np.eye(3)[AXES[plane[0]]], np.eye(3)[AXES[plane[1]]]
        e1.setflags(write=False)
        e2.setflags(write=False)
        self._e1, self._e2, self._plane = e1, e2, (str(plane[0]), str(plane[1]))

    def _set_center(self, center: Sequence[float] | np.ndarray | None) -> None:
        c = None if center is None else _vec(center, 3, "circle center").copy()
        if c is not None:
            c.setflags(write=False)
        self._center = c
        self._prepared_for = None  # the centre is found again for the start (``_prepare``)

    # radius, omega, phase: validated on assignment, and a started circle's compiled parameter row is made again
    # (a fused step compares it by identity), so that a new value is used from the next step on, not ignored
    def _set(self, radius: float, omega: float, phase: float) -> None:
        if abs(radius * omega) > MAX_MAGNITUDE:
            raise TaskError(f"circle speed radius × omega = {radius * omega:g} exceeds {MAX_MAGNITUDE:g}")
        self._radius, self._omega, self._phase = radius, omega, phase
        if self._start is not None:
            self._prepare()

    @property
    def radius(self) -> float:
        """r [length] (> 0); an assignment takes effect at the next step (the centre found at the start is kept)."""
        return self._radius

    @radius.setter
    def radius(self, value: float) -> None:
        self._set(_number(value, "circle radius", positive=True), self._omega, self._phase)

    @property
    def omega(self) -> float:
        """ω [rad/s]; an assignment takes effect at the next step."""
        return self._omega

    @omega.setter
    def omega(self, value: float) -> None:
        self._set(self._radius, _number(value, "circle omega"), self._phase)

    @property
    def phase(self) -> float:
        """φ [rad]; an assignment takes effect at the next step (the centre found at the start is kept)."""
        return self._phase

    @phase.setter
    def phase(self, value: float) -> None:
        self._set(self._radius, self._omega, _number(value, "circle phase"))

    @property
    def plane(self) -> tuple[str, str]:
        """The two world axes spanning the circle's plane (e1, e2). Assigning two other axes takes effect at the
        next step, about the same centre."""
        return self._plane

    @plane.setter
    def plane(self, value: tuple[str, str]) -> None:
        self._set_plane(value)
        if self._start is not None:
            self._prepare()

    @property
    def e1(self) -> np.ndarray:
        """The unit vector of the plane's first axis (read-only; set :attr:`plane`)."""
        return self._e1

    @property
    def e2(self) -> np.ndarray:
        """The unit vector of the plane's second axis (read-only; set :attr:`plane`)."""
        return self._e2

    @property
    def center(self) -> np.ndarray:
        """The circle's centre in the world frame: the given one, or the one that puts the start on the circle at
        phase φ. Assigning a centre (3 finite numbers) takes effect at the next step; assigning ``None`` places it
        again from the start pose with the current radius, plane and phase."""
        if self._center is not None:
            return self._center
        p0 = self.start_pose.translation
        return p0 - self.radius * (np.cos(self.phase) * self.e1 + np.sin(self.phase) * self.e2)

    @center.setter
    def center(self, value: Sequence[float] | np.ndarray | None) -> None:
        self._set_center(value)
        if self._start is not None:
            self._prepare()

    def _prepare(self) -> None:
        if self._prepared_for is not self._start:  # the centre of this start (kept on a new r, φ)
            self._c = self.center
            self._prepared_for = self._start
        self._re1 = self.radius * self.e1
        self._re2 = self.radius * self.e2
        extra = [*self._c.tolist(), *self._re1.tolist(), *self._re2.tolist(), self.omega, self.phase]
        self._params_row(CIRCLE, extra)

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if type(t) is not float or not math.isfinite(t):
            t = _time(t, self)
        if self._start is None:
            self.start_pose  # noqa: B018 - raises: start() was never called
        out = np.empty(REF)
        _TK.reference_into(CIRCLE, self._kparams, t, out)  # one implementation
        return out[REF_P : REF_P + 3], self._R0, out[REF_TWIST : REF_TWIST + 6]

    def __repr__(self) -> str:
        return f"Circle(radius={self.radius}, omega={self.omega}, plane={self.plane})"


class PoseInterpolation(Trajectory):
    """Linear interpolation from the start pose to a goal pose over ``duration``, then hold.

    Position moves on a straight line at constant speed; orientation along the geodesic
    R(s) = R0 exp(s log(R0ᵀ R1)), whose world angular velocity R0 log(R0ᵀR1)/T is constant.

    Args:
        position: Goal position [length], shape (3,).
        rotation: Goal rotation (3×3); the start orientation if ``None``.
        duration: T [s] > 0.
    """

    def __init__(self, position: Sequence[float], duration: float, rotation: np.ndarray | None = None) -> None:
        self._duration = self._checked_duration(duration)
        self._goal_position = self._checked_position(position)
        self._goal_rotation = self._checked_rotation(rotation)

    # goal and duration: validated on assignment; a started interpolation is prepared again from the same start, so
    # that a new value is used from the next step on, not ignored
    @staticmethod
    def _checked_duration(duration: object) -> float:
        value = _float(duration, "pose interpolation duration")
        if not (math.isfinite(value) and value > 0):
            raise TaskError(f"pose interpolation duration must be > 0 [s] and finite, got {short_repr(duration)}")
        return value

    @staticmethod
    def _checked_position(position: Sequence[float] | np.ndarray) -> np.ndarray:
        p = _vec(position, 3, "goal position").copy()
        p.setflags(write=False)
        return p

    @staticmethod
    def _checked_rotation(rotation: np.ndarray | None) -> np.ndarray | None:
        if rotation is None:
            return None
        if np.asarray(rotation).dtype.kind not in "fiu":
            raise TaskError(f"goal rotation must be a 3×3 matrix of numbers, got {type(rotation).__name__}")
        r = np.array(rotation, dtype=float)
        if (
            r.shape != (3, 3)
            or not np.all(np.isfinite(r))
            or not np.allclose(r @ r.T, np.eye(3), atol=1e-6)
            or np.linalg.det(r) < 0
        ):
            raise TaskError("goal rotation must be a proper 3×3 rotation matrix")
        r.setflags(write=False)
        return r

    def _changed(self) -> None:
        if self._start is not None:
            self._prepare()

    @property
    def duration(self) -> float:
        """T [s] > 0; an assignment takes effect at the next step (from the same start, at the same t)."""
        return self._duration

    @duration.setter
    def duration(self, value: float) -> None:
        self._duration = self._checked_duration(value)
        self._changed()

    @property
    def goal_position(self) -> np.ndarray:
        """Goal position [length] (3,), read-only; assigning a new one takes effect at the next step."""
        return self._goal_position

    @goal_position.setter
    def goal_position(self, value: Sequence[float] | np.ndarray) -> None:
        self._goal_position = self._checked_position(value)
        self._changed()

    @property
    def goal_rotation(self) -> np.ndarray | None:
        """Goal rotation (3×3, read-only), or ``None`` for the start orientation; an assignment takes effect at the
        next step."""
        return self._goal_rotation

    @goal_rotation.setter
    def goal_rotation(self, value: np.ndarray | None) -> None:
        self._goal_rotation = self._checked_rotation(value)
        self._changed()

    def _prepare(self) -> None:
        r1 = self._R0 if self.goal_rotation is None else self.goal_rotation
        self._w = pin.log3(self._R0.T @ r1)
        self._dp = self.goal_position - self._p0
        self._moving = np.concatenate([self._dp / self.duration, self._R0 @ self._w / self.duration])
        if not np.all(np.abs(self._moving) <= MAX_MAGNITUDE):  # also NaN
            raise TaskError(
                f"pose interpolation: moving {np.linalg.norm(self._dp):g} in {self.duration:g} s needs a speed over "
                f"{MAX_MAGNITUDE:g}; give a longer duration"
            )

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if type(t) is not float or not math.isfinite(t):
            t = _time(t, self)
        self.start_pose  # noqa: B018 - raises if start() was never called
        s = min(max(t / self.duration, 0.0), 1.0)
        pos = self._p0 + s * self._dp
        rot = self._R0 @ pin.exp3(s * self._w)
        if t < 0 or t >= self.duration:
            return pos, rot, np.zeros(6)
        return pos, rot, self._moving

    def __repr__(self) -> str:
        return f"PoseInterpolation(position={self.goal_position.tolist()}, duration={self.duration})"
