"""Whole-body balance: a centre-of-mass task, contact tasks, and the support-polygon barrier.

* :class:`CoMTask` — J_c q̇ = ċ_d + K (c_d − c) on the selected axes of the CoM c (Pinocchio's
  ``jacobianCenterOfMass``: J_c = Σ m_i J_i / M, 3×nv, world frame, the floating base included).
* :class:`ContactTask` — a frame held at its start pose (a foot on the ground, a hand on a wall): a
  :class:`~redundik.tasks.frame.FrameTask` with no trajectory (it holds the pose it has at reset) that declares
  itself a contact, so a run reports its drift ‖p − p₀‖ [m].
* :class:`SupportPolygon` — a vector barrier keeping the ground projection of the CoM inside the convex polygon of
  the feet's sole corners with a margin m: for each edge i of the polygon (outward unit normal a_i, aᵢᵀx ≤ b_i
  inside), h_i = b_i − a_iᵀ S c − m ≥ 0 and H_i = −a_iᵀ S J_c, with S the x–y selection. The polygon is captured
  when the barrier is checked at the start of a run (the feet are held by contact tasks), so H is exact.
  As a potential its value is the signed margin min_i (b_i − a_iᵀ S c) [m] (positive inside), with the gradient of
  its active edge.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import (
    Barrier,
    BarrierTerm,
    CompiledBarrier,
    CompiledRows,
    Potential,
    Task,
    TaskTerm,
    check_name,
    check_number,
)
from redundik.tasks.frame import DEFAULT_HOLD_GAIN, FrameTask
from redundik.tasks.layouts import (
    COM_BODIES,
    COM_BODY,
    COM_LEVER,
    COM_MASS,
    COM_NBODIES,
    COM_NROWS,
    COM_ROWS,
    COM_TARGET,
    SUP_AX,
    SUP_AY,
    SUP_B,
    SUP_EDGE,
    SUP_EDGES,
    SUP_MARGIN,
)

_COM_AXES = {"x": 0, "y": 1, "z": 2}
#: the compiled writers of the built-in tasks (loaded at first use)
_RK = KernelNamespace("redundik.tasks.row_kernels")


def com_layout(robot: RobotModel, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(ints, floats) of ``row_kernels.com_rows`` for ``robot`` (the target slots zero), or ``None`` when the robot
    has no mass or a body's joint carries no frame (its pose is not among the frames' placements). A body is read
    through the frame at its joint (a URDF's joint frame) or, without one, through the first frame on its joint (a
    DH chain's), its lever then expressed in that frame."""
    model, nv = robot.model, robot.nv
    total = sum(model.inertias[j].mass for j in range(1, model.njoints))
    if not total > 0.0:
        return None
    joint_frame: dict[int, int] = {}
    any_frame: dict[int, int] = {}
    for f, frame in enumerate(model.frames):
        any_frame.setdefault(frame.parentJoint, f)
        if frame.type == pin.FrameType.JOINT and frame.placement.isIdentity():
            joint_frame.setdefault(frame.parentJoint, f)
    fids, columns, floats = [], [], [0.0] * COM_BODIES  # (the target c_d from COM_TARGET: written by the task)
    for j in range(1, model.njoints):
        fid = joint_frame.get(j, any_frame.get(j))
        if fid is None:
            return None
        fids.append(fid)
        col = np.zeros(nv, dtype=np.int64)
        for s in model.supports[j]:
            if s > 0:
                col[model.joints[s].idx_v : model.joints[s].idx_v + model.joints[s].nv] = 1
        columns.append(col)
        inertia = model.inertias[j]
        body = [0.0] * COM_BODY
        body[COM_MASS] = inertia.mass / total
        lever = np.asarray(inertia.lever, dtype=float)
        if fid != joint_frame.get(j):  # (the lever in the frame's coordinates: x_f = M_f⁻¹ x_joint)
            lever = np.asarray(model.frames[fid].placement.actInv(lever), dtype=float)
        body[COM_LEVER : COM_LEVER + 3] = lever.tolist()
        floats += body
    head = [0] * COM_ROWS
    head[COM_NBODIES], head[COM_NROWS] = len(fids), len(rows)
    ints = np.concatenate([head, rows, fids, *columns]).astype(np.int64)
    return ints, np.array(floats, dtype=float)


def center_of_mass(robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """(c (3,) [m], J_c (3, nv)) at the robot's current (updated) state, cached until the next update."""
    q = robot.q
    cache = robot.__dict__.get("_redundik_com")
    if cache is not None and cache[0] is q:
        return cache[1], cache[2]
    Jc = np.array(pin.jacobianCenterOfMass(robot.model, robot.data, q))
    c = np.array(robot.data.com[0])
    robot.__dict__["_redundik_com"] = (q, c, Jc)
    return c, Jc


class CoMTask(Task):
    """Move or hold the centre of mass: J_c[S] q̇ = ċ_d + K (c_d − c)[S] (module docstring).

    Args:
        target: c_d (3,) [m] in the world frame, or ``None`` to hold the CoM at reset; settable (:meth:`set_target`).
        axes: CoM axes controlled, among ``x, y, z`` (``["x", "y"]``: its ground projection).
        gain: K [1/s] ≥ 0.
        weight: > 0, among the rows of its level.
        priority: Level (``None``: the main tasks' level 0).
        name: Task name.

    Raises:
        TaskError: bad axes or target.
    """

    def __init__(
        self,
        target: Sequence[float] | np.ndarray | None = None,
        *,
        axes: Sequence[str] = ("x", "y", "z"),
        gain: float = DEFAULT_HOLD_GAIN,
        weight: float = 1.0,
        priority: int | None = None,
        name: str = "com",
    ) -> None:
        self._init_task(name, weight=weight, gain=gain, priority=priority)
        self._layout: tuple[object, np.ndarray, np.ndarray] | None = None  # (robot data, ints, floats) of the writer
        self.axes = axes  # (the setter takes any sequence of names)
        self._given = None if target is None else self._vec(target)
        self._target: np.ndarray | None = self._given

    @property
    def axes(self) -> tuple[str, ...]:
        """The CoM axes controlled, among ``x, y, z``; an assignment takes effect at the next step."""
        return self._axes

    @axes.setter
    def axes(self, value: Sequence[str]) -> None:
        axes = [value] if isinstance(value, str) else list(value)
        if not axes or any(a not in _COM_AXES for a in axes) or len(set(axes)) != len(axes):
            raise TaskError(f"task '{self.name}': axes must be distinct names among x, y, z, got {axes}")
        rows = np.array([_COM_AXES[a] for a in axes])
        rows.setflags(write=False)
        self._axes, self._rows = tuple(axes), rows
        self._layout = None  # (the compiled writer's rows are packed again)
        self._form_revision += 1

    @property
    def rows(self) -> np.ndarray:
        """The indices of :attr:`axes` in (x, y, z) (read-only; assign :attr:`axes` to change them)."""
        return self._rows

    def _vec(self, target: Sequence[float] | np.ndarray) -> np.ndarray:
        arr = np.array(target, dtype=float).reshape(-1)  # (a copy, read-only: an edit is an assignment)
        if arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise TaskError(f"task '{self.name}': target must be 3 finite numbers [m], got {arr.tolist()}")
        arr.setflags(write=False)
        return arr

    @property
    def target(self) -> np.ndarray | None:
        """c_d (3,) [m] (read-only), or ``None`` before the first reset when none was given. ``None`` assigned: the
        next step takes the target again as a reset does (the one given, else the CoM then)."""
        return self._target

    @target.setter
    def target(self, value: Sequence[float] | np.ndarray | None) -> None:
        self._target = None if value is None else self._vec(value)
        if self._target is None:
            self._form_revision += 1  # (a compiled step plans again, and its writer takes the CoM then)
        elif self._layout is not None:
            self._layout[2][COM_TARGET : COM_TARGET + 3] = self._target  # (the compiled writer's data: in place)

    def set_target(self, target: Sequence[float] | np.ndarray) -> None:
        """A new CoM target c_d (3,) [m]; kept across resets."""
        self._given = self._vec(target)
        self.target = self._given

    def reset(self, robot: RobotModel) -> None:
        self.target = self._given if self._given is not None else center_of_mass(robot)[0].copy()

    def compiled_rows(self, robot: RobotModel) -> CompiledRows | None:
        """The rows of ``row_kernels.com_rows`` (the bodies' masses and levers packed once per robot); ``None`` when
        a joint has no frame at the joint (then :meth:`evaluate`, Pinocchio's ``jacobianCenterOfMass``)."""
        if self._target is None:
            self.reset(robot)
        layout = self._layout
        if layout is None or layout[0] is not robot.data:
            packed = com_layout(robot, self.rows)
            if packed is None:
                return None
            layout = self._layout = (robot.data, packed[0], packed[1])
            self._form_revision += 1
            assert self._target is not None
            layout[2][COM_TARGET : COM_TARGET + 3] = self._target
        return CompiledRows(_RK.com_rows, len(self.rows), layout[1], layout[2])

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        if self.target is None:
            self.reset(robot)
        assert self.target is not None
        c, Jc = center_of_mass(robot)
        e = (self.target - c)[self.rows]
        return TaskTerm(self.name, Jc[self.rows], self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return f"CoMTask(axes={list(self.axes)}, gain={self.gain})"


class ContactTask(FrameTask):
    """A frame held at its start pose (a contact); reports its drift from that pose (module docstring).

    Args:
        frame: The contact frame (e.g. a sole).
        axes: Rows held (default the full pose).
        gain: K [1/s] on the drift (default 10 /s).
        weight: > 0.
        priority: Level (``None``: 0).
        name: Defaults to the frame name.
    """

    contact = True

    def __init__(
        self,
        frame: str,
        *,
        axes: str | Sequence[str] = "pose",
        gain: float | None = None,
        weight: float = 1.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        super().__init__(frame, None, axes=axes, gain=gain, weight=weight, priority=priority, name=name)
        self.start: np.ndarray | None = None

    def reset(self, robot: RobotModel) -> None:
        super().reset(robot)
        self.start = np.array(robot.frame_pose(self._frame_id(robot)).translation)

    def drift(self, robot: RobotModel) -> float:
        """‖p − p₀‖ [m] of the frame origin from its pose at reset."""
        if self.start is None:
            self.reset(robot)
        assert self.start is not None
        return float(np.linalg.norm(robot.frame_position(self._frame_id(robot)) - self.start))

    def __repr__(self) -> str:
        return f"ContactTask(frame={self.frame!r}, axes={list(self.axes)}, gain={self.gain})"


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (Andrew's monotone chain) of 2-D points (k, 2), without repeated vertices."""
    pts = sorted({(float(x), float(y)) for x, y in np.asarray(points, dtype=float)})
    if len(pts) < 3:
        return np.array(pts)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


class SupportPolygon(Barrier, Potential):
    """The CoM's ground projection inside the feet's support polygon with a margin (module docstring).

    Args:
        feet: Sole frames in contact.
        size: Sole rectangle (length along the frame's x, width along its y) [m], centred on the frame origin.
        margin: m [m] ≥ 0 kept from every edge.
        rate: Per-row damper gain γ [1/s] > 0 (``None``: the bound subtask's rate).
        name: Subtask name.

    Raises:
        TaskError: no feet, non-positive size, negative margin.
    """

    def __init__(
        self,
        feet: Sequence[str],
        size: Sequence[float] = (0.2, 0.13),
        *,
        margin: float = 0.01,
        rate: float | None = None,
        name: str = "support",
    ) -> None:
        self.name = check_name(name, "support polygon")
        self.feet = [str(f) for f in feet]
        if not self.feet:
            raise TaskError(f"subtask '{self.name}': give at least one foot frame")
        if len(size) != 2:
            raise TaskError(f"subtask '{self.name}': size needs (length, width) [m]")
        self.size = tuple(check_number(s, f"subtask '{self.name}': size [m]", low=0.0, strict=True) for s in size)
        self.margin = check_number(margin, f"subtask '{self.name}': margin [m]", low=0.0)
        self.rate = None if rate is None else check_number(rate, f"subtask '{self.name}': rate", low=0.0, strict=True)
        self.A: np.ndarray | None = None  # (k, 2) outward edge normals
        self.b: np.ndarray | None = None  # (k,)
        self.vertices: np.ndarray | None = None
        #: The compiled writer's (robot data, ints, floats, row names, where its margin is in floats) for the polygon
        #: captured last
        self._packed: tuple[object, np.ndarray, np.ndarray, list[str], int] | None = None

    def check(self, robot: RobotModel) -> None:
        """Check the foot frames and capture the polygon at the robot's current state."""
        for f in self.feet:
            if not robot.model.existFrame(f):
                raise TaskError(f"subtask '{self.name}': frame '{f}' does not exist in robot '{robot.name}'")
        self.capture(robot)

    def capture(self, robot: RobotModel) -> None:
        """Compute the support polygon (sole corners of every foot, convex hull in x–y) at the current state."""
        lx, ly = self.size[0] / 2, self.size[1] / 2
        corners = np.array([[lx, ly, 0], [lx, -ly, 0], [-lx, -ly, 0], [-lx, ly, 0]])
        pts = []
        for f in self.feet:
            M = robot.frame_pose(f)
            pts.append(corners @ np.asarray(M.rotation).T + np.asarray(M.translation))
        hull = convex_hull_2d(np.vstack(pts)[:, :2])
        if len(hull) < 3:
            raise TaskError(f"subtask '{self.name}': the feet's support polygon is degenerate")
        nxt = np.roll(hull, -1, axis=0)
        edge = nxt - hull
        normal = np.column_stack([edge[:, 1], -edge[:, 0]])  # outward for a counter-clockwise polygon
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        self.A, self.b, self.vertices = normal, np.einsum("ij,ij->i", normal, hull), hull
        self._packed = None  # (the compiled writer's edges: packed again)

    def _edges(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.A is None or self.b is None:
            self.check(robot)
        assert self.A is not None and self.b is not None
        c, Jc = center_of_mass(robot)
        return self.b - self.A @ c[:2], -self.A @ Jc[:2], c

    def evaluate(self, robot: RobotModel) -> BarrierTerm:
        """h_i = b_i − a_iᵀ S c − m, H_i = −a_iᵀ S J_c (one row per edge)."""
        s, H, _ = self._edges(robot)
        gamma = None if self.rate is None else np.full(len(s), self.rate)
        return BarrierTerm(s - self.margin, H, [f"edge{i}" for i in range(len(s))], gamma)

    def compiled_barrier(self, robot: RobotModel) -> CompiledBarrier | None:
        """The rows of :meth:`evaluate` from ``row_kernels.support_rows``: the CoM of ``com_rows``' packed bodies
        (once per robot) and the captured polygon's edges; ``None`` when a body's joint has no frame at the joint
        (then :meth:`evaluate`, Pinocchio's ``jacobianCenterOfMass``)."""
        if self.A is None or self.b is None:
            self.check(robot)
        assert self.A is not None and self.b is not None
        packed = self._packed
        if packed is None or packed[0] is not robot.data:
            com = com_layout(robot, np.array([0, 1]))
            if com is None:
                return None
            edges = np.column_stack([self.A, self.b])  # (a_x, a_y, b) per edge: SUP_AX, SUP_AY, SUP_B
            assert edges.shape[1] == SUP_EDGE and (SUP_AX, SUP_AY, SUP_B) == (0, 1, 2)
            floats = np.concatenate([com[1], np.zeros(SUP_EDGES), edges.reshape(-1)])  # (after the bodies)
            names = [f"edge{i}" for i in range(len(self.b))]
            packed = self._packed = (robot.data, com[0], floats, names, com[1].shape[0] + SUP_MARGIN)
        floats = packed[2]
        floats[packed[4]] = self.margin  # (an attribute: read at every call)
        return CompiledBarrier(_RK.support_rows, len(packed[3]), packed[1], floats, packed[3], self.rate or 0.0)

    def value(self, robot: RobotModel) -> float:
        """Signed distance [m] of the CoM projection to the nearest edge line, positive inside (no margin)."""
        return float(np.min(self._edges(robot)[0]))

    def gradient(self, robot: RobotModel) -> np.ndarray:
        """The gradient of the active edge's distance (a subgradient where two edges tie), shape (nv,)."""
        s, H, _ = self._edges(robot)
        return np.asarray(H[int(np.argmin(s))])

    def __repr__(self) -> str:
        return f"SupportPolygon(name={self.name!r}, feet={self.feet}, size={self.size}, margin={self.margin})"
