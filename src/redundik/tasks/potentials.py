"""The chapter's subtask potentials p(q) with exact gradients η = ∂p/∂q (section 5.2).

Every gradient here is analytic or comes from Pinocchio's kinematic Jacobians and kinematic Hessians
(∂J/∂q); none uses finite differences at run time. ``tests/test_potentials.py`` checks each against central
finite differences.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError
from redundik.kinematics.layouts import POSE_P
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import ClearanceForm, CompiledGradient, Edits, Potential, check_number, default_name
from redundik.tasks.frame import axes_rows
from redundik.tasks.joint_potentials import JointSine2 as JointSine2
from redundik.tasks.joint_potentials import JointValue as JointValue
from redundik.tasks.layouts import FP_POINT, FP_RADIUS
from redundik.tasks.potential_rows import (
    CompiledPotential,
    frame_point_ints,
    jacobian_product_ints,
    supporting_columns,
)


def _finite_vec(value: Sequence[float] | np.ndarray, what: str, size: int | None = None) -> np.ndarray:
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "fiu":  # bool, complex, strings: refused, never cast
            raise TypeError(f"dtype {raw.dtype}")
        arr = np.asarray(raw, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise TaskError(f"{what}: expected real numbers, got {type(value).__name__} ({exc})") from None
    if size is not None and arr.shape[0] != size:
        raise TaskError(f"{what}: expected {size} numbers, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise TaskError(f"{what}: contains NaN or infinite values")
    return arr


#: The compiled potential kernels, imported on first use (a namespace: a cold start puts their twins here).
_PK = KernelNamespace("redundik.tasks.potential_kernels")


class JointCentering(Potential):
    """Joint-range centering (5.9): p = ½‖q − q_c‖², η = q − q_c (5.10); minimise it (k < 0).

    Args:
        center: q_c (size nq); the middle of each joint's range if ``None`` (joints without finite limits are
            left out, i.e. get zero weight).
        weights: Optional per-joint weights w ≥ 0 (size nv): p = ½ Σ w_i (q_i − q_c,i)².
    """

    def __init__(
        self,
        center: Sequence[float] | np.ndarray | None = None,
        weights: Sequence[float] | np.ndarray | None = None,
        name: str = "joint_centering",
    ) -> None:
        self.name = name
        self._c: np.ndarray | None = None
        self._w: np.ndarray | None = None
        self.center = center
        self.weights = weights

    @property
    def center(self) -> np.ndarray | None:
        """q_c as given (read-only), or ``None`` for the middle of the joint ranges.

        Assigning it is validated and takes effect at the next step: the (w, q_c) a fused step packs are computed
        again from it. The array is read-only because an edit in place would reach the per-task path (which read a
        view of it) but not the fused step's packed copy."""
        return self._center

    @center.setter
    def center(self, value: Sequence[float] | np.ndarray | None) -> None:
        arr = None if value is None else _finite_vec(value, f"subtask '{self.name}': center").copy()
        if arr is not None:
            arr.setflags(write=False)
        self._center = arr
        self._c = self._w = None  # computed again against the robot at the next evaluation
        self.form_revision += 1  # (a compiled step's writer holds (w, q_c): planned again)

    @property
    def weights(self) -> np.ndarray | None:
        """Per-joint weights w ≥ 0 (read-only), or ``None``; assigning them is validated, as :attr:`center`."""
        return self._weights

    @weights.setter
    def weights(self, value: Sequence[float] | np.ndarray | None) -> None:
        arr = None if value is None else _finite_vec(value, f"subtask '{self.name}': weights").copy()
        if arr is not None:
            if np.any(arr < 0):
                k = int(np.flatnonzero(arr < 0)[0])
                raise TaskError(
                    f"subtask '{self.name}': weights must be ≥ 0 (a negative weight pushes joint {k} away from the "
                    f"centre), got weights[{k}] = {arr[k]:g}"
                )
            arr.setflags(write=False)
        self._weights = arr
        self._c = self._w = None
        self.form_revision += 1

    def check(self, robot: RobotModel) -> None:
        if self.center is None:
            lo, hi = robot.lower_limits, robot.upper_limits
            finite = np.isfinite(lo) & np.isfinite(hi) & (hi - lo < 1e9)
            c = robot.neutral()
            w = np.zeros(robot.nv)
            for k, j in enumerate(robot.joints):
                if finite[k] and j.idx_q >= 0:
                    c[j.idx_q] = 0.5 * (lo[k] + hi[k])
                    w[k] = 1.0
        else:
            c = np.array(robot.check_configuration(self.center, f"subtask '{self.name}': center"))
            w = np.ones(robot.nv)
        if self.weights is not None:
            if self.weights.shape[0] != robot.nv:
                raise TaskError(f"subtask '{self.name}': weights: expected {robot.nv} numbers")
            w = w * self.weights
        old_c, old_w = self._c, self._w
        if old_c is not None and old_w is not None and np.array_equal(old_c, c) and np.array_equal(old_w, w):
            return  # the same data: keep the arrays a fused step packed (another resolver checking the stack)
        c.setflags(write=False)  # (the arrays linear_gradient hands to a fused step, which packs them)
        w.setflags(write=False)
        self._c, self._w = c, w

    def _delta(self, robot: RobotModel) -> np.ndarray:
        if self._c is None:
            self.check(robot)
        c = self._c
        if c is None:  # check() sets it; a robot without finite limits leaves nothing to centre on
            raise TaskError(f"subtask '{self.name}': no centre configuration")
        return robot.difference(c, robot.q)

    def value(self, robot: RobotModel) -> float:
        d = self._delta(robot)
        return float(0.5 * np.sum(self._w * d * d))

    def linear_gradient(self, robot: RobotModel) -> tuple[np.ndarray, np.ndarray] | None:
        if self._c is None or self._w is None:
            self.check(robot)
        if self._c is None or self._w is None:
            return None
        return self._w, self._c

    def gradient(self, robot: RobotModel) -> np.ndarray:
        # exact for vector-space joints (q_c ⊖ q is linear in q); the chart's first-order value on SO(3) bases
        d = self._delta(robot)  # (first: it computes _w when a new centre or weights were set)
        return self._w * d

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient | None:
        """``potential_kernels.centering_gradient`` (a target subtask's row on a compiled step; a gradient subtask
        uses :meth:`linear_gradient`); ``None`` when a weighted coordinate is not a subtraction (a free-flyer's
        orientation: Pinocchio's difference)."""
        lin = self.linear_gradient(robot)
        if lin is None:
            return None
        w, c = lin
        iq = np.array([j.idx_q for j in robot.joints], dtype=np.int64)
        if w.shape[0] != iq.shape[0] or bool(((iq < 0) & (w != 0.0)).any()):
            return None
        floats = np.concatenate([w, np.where(iq >= 0, c[np.maximum(iq, 0)], 0.0)])
        return CompiledGradient(_PK.centering_gradient, np.where(w != 0.0, iq, -1), floats)

    def __repr__(self) -> str:
        return f"JointCentering(name={self.name!r})"


class _FramePotential(Potential):
    """A potential of one frame's motion: ``frame``, ``axes`` (and the twist ``rows`` they select) are validated on
    assignment, and an assigned frame is looked up again at the next step (it used to keep the first frame's id:
    the potential silently measured the old frame)."""

    #: Only position axes (x, y, z) make sense for this potential.
    _position_only: ClassVar[bool] = False

    def __init__(self, frame: str, axes: str | Sequence[str], name: str) -> None:
        self.name = name
        self._fid = -1
        self.frame = frame
        self.axes = axes  # (the setter takes a name or a list, keeps a tuple)

    @property
    def frame(self) -> str:
        """The frame's name; an assignment takes effect at the next step (its id looked up again)."""
        return self._frame

    @frame.setter
    def frame(self, value: str) -> None:
        if not isinstance(value, str) or not value:
            raise TaskError(f"subtask '{self.name}': frame must be a frame name (a string), got {value!r:.80}")
        self._frame = value
        self._fid = -1
        self.form_revision += 1  # (a compiled step's writer reads the frame's id: planned again)
        Edits.count += 1

    @property
    def axes(self) -> tuple[str, ...]:
        """The axes that count (a name of ``AXIS_SETS`` or a list of axes on assignment)."""
        return self._axes

    @axes.setter
    def axes(self, value: str | Sequence[str]) -> None:
        axes, rows = axes_rows(value, f"subtask '{self.name}'")
        if self._position_only and any(a not in ("x", "y", "z") for a in axes):
            raise TaskError(f"subtask '{self.name}': axes must be among x, y, z, got {list(axes)}")
        self._axes, self._rows = axes, rows
        self.form_revision += 1
        Edits.count += 1

    @property
    def rows(self) -> np.ndarray:
        """The twist rows :attr:`axes` select (read-only: assign ``axes``)."""
        return self._rows

    def check(self, robot: RobotModel) -> None:
        """Look the frame up on ``robot``.

        Raises:
            TaskError: an unknown frame, or one fixed to the world (no joint moves it: the potential would be a
                constant, its gradient zero — a subtask that silently does nothing, which ``FrameTask`` refuses too).
        """
        try:
            fid = robot.frame_id(self.frame)
        except Exception as exc:
            raise TaskError(f"subtask '{self.name}': {exc}") from exc
        if robot.model.frames[fid].parentJoint == 0:
            raise TaskError(
                f"subtask '{self.name}': frame '{self.frame}' is fixed to the world (no joint moves it): its "
                "potential is a constant and its gradient zero; choose a frame on the robot's chain"
            )
        self._fid = fid

    def _id(self, robot: RobotModel) -> int:
        if self._fid < 0:
            self.check(robot)
        return self._fid

    def _writer(self, robot: RobotModel, kernel: str, floats: np.ndarray) -> CompiledGradient:
        """The compiled writer ``kernel`` of ``potential_kernels`` in the frame-point layout on ``robot``."""
        fid = self._id(robot)
        if fid >= robot.model.nframes:  # (an id of another robot's model)
            self.check(robot)
            fid = self._fid
        return CompiledGradient(getattr(_PK, kernel), frame_point_ints(robot, fid, self.rows), floats)


def _point(value: Sequence[float] | np.ndarray, what: str) -> np.ndarray:
    """A read-only copy of a finite point (3,) [m]."""
    arr = _finite_vec(value, what, 3).copy()
    arr.setflags(write=False)
    return arr


class VirtualPoint(_FramePotential, CompiledPotential):
    """A frame point to a virtual point: p = ½‖S(p_f(q) − p_v)‖², η = J_vᵀ S (p_f − p_v).

    This is the chapter's elbow-to-virtual-safe-point potential p = ½(μ_x² + μ_z²) of the (6+1) robot with
    ``axes = ("x", "z")`` in frame 0. The chapter's printed 7×1 gradient is wrong (chapter notes); this is the
    exact one, checked against finite differences. Minimise it (k < 0).

    Args:
        frame: The frame whose origin moves (e.g. the elbow, D-H frame ``"3"``).
        point: p_v in world coordinates, shape (3,).
        axes: Position axes that count (subset of x, y, z); S selects them.
    """

    def __init__(
        self,
        frame: str,
        point: Sequence[float],
        axes: str | Sequence[str] = "position",
        name: str | None = None,
    ) -> None:
        self._floats = np.zeros(FP_POINT + 3)  # p_v: the compiled writer's data, rewritten in place
        super().__init__(frame, axes, default_name(name, f"virtual_point_{frame}", "VirtualPoint"))
        self.point = point

    _position_only = True

    @property
    def point(self) -> np.ndarray:
        """p_v [m] (3,), read-only; an assigned point (3 finite numbers) is used from the next step."""
        return self._point

    @point.setter
    def point(self, value: Sequence[float] | np.ndarray) -> None:
        self._point = _point(value, f"subtask '{self.name}': point")
        self._floats[FP_POINT : FP_POINT + 3] = self._point

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """p and η from one compiled call (``potential_kernels.virtual_point_gradient``)."""
        return self._writer(robot, "virtual_point_gradient", self._floats)


class Clearance(_FramePotential):
    """Distance from a frame point to a round obstacle, minus its radius: p = ‖S(p_f − p_o)‖ − r [m].

    Negative means penetration. With ``axes = ("x", "z")`` the obstacle is an infinite vertical post (the
    (6+1) robot's post of radius 0.3 dm). η = J_vᵀ Sᵀ u with u the unit vector from the obstacle to the point.
    Use it as a QP inequality (p ≥ margin) or maximise it (k > 0), like the chapter's collision potential
    ‖p_el − p_ob‖² (same gradient direction).

    p and η come from one compiled call (``potential_kernels.clearance_into``, the one implementation), reading the
    frame's origin and the joint Jacobians on Pinocchio's memory (``data.oMf``, ``data.J``: views verified when first
    used with a robot's data; if they cannot be verified, the origin and the Jacobian are copied through the
    bindings).
    """

    def __init__(
        self,
        frame: str,
        center: Sequence[float],
        radius: float = 0.0,
        axes: str | Sequence[str] = "position",
        name: str | None = None,
    ) -> None:
        #: What the kernel reads for one robot's data: (data, frame id, p_f, data.J, supporting columns, J6 scratch,
        #: the kernel),
        #: p_f and data.J views on Pinocchio's memory, or ``None`` when those could not be verified.
        self._views: tuple[Any, ...] | None = None
        self._floats = np.zeros(FP_RADIUS + 1)  # (p_o, r): the compiled writer's data, rewritten in place
        super().__init__(frame, axes, default_name(name, f"clearance_{frame}", "Clearance"))
        self.center = center
        self.radius = radius

    _position_only = True

    # centre and radius: validated on assignment (a NaN centre or a negative radius used to reach the rows); each
    # assignment moves ``Edits``, which a fused step's packed copy of them compares
    @property
    def center(self) -> np.ndarray:
        """p_o [m] (3,), read-only; an assigned centre (3 finite numbers) is used from the next step."""
        return self._center

    @center.setter
    def center(self, value: Sequence[float] | np.ndarray) -> None:
        self._center = _point(value, f"subtask '{self.name}': center")
        self._floats[FP_POINT : FP_POINT + 3] = self._center
        Edits.count += 1

    @property
    def radius(self) -> float:
        """r [m] ≥ 0; an assignment is used from the next step."""
        return self._radius

    @radius.setter
    def radius(self, value: float) -> None:
        self._radius = check_number(value, f"subtask '{self.name}': radius", low=0.0)
        self._floats[FP_RADIUS] = self._radius
        Edits.count += 1

    def __getstate__(self) -> dict[str, Any]:
        """Pickled and copied without the views (they belong to one robot's data; rebuilt on first use)."""
        state = dict(self.__dict__)
        state["_views"] = None
        return state

    def _prepare(self, robot: RobotModel) -> tuple[Any, ...]:
        """The kernel's inputs for ``robot.data`` (built on first use with that data, and when the frame changed)."""
        from redundik.kinematics.memory import jacobian_view, se3_vector_view

        fid = self._id(robot)
        data = robot.data
        jw, poses = jacobian_view(data), se3_vector_view(data.oMf)
        columns = supporting_columns(robot, fid)
        p = None if jw is None or poses is None else poses[fid, POSE_P : POSE_P + 3]
        self._views = (data, fid, p, jw, columns, np.zeros((6, robot.nv)))
        return self._views

    def value_and_gradient_into(self, robot: RobotModel, out: np.ndarray, scale: float = 1.0) -> float:
        """p [m], with scale · η written into ``out`` (nv,); scale −1 gives a lower bound's damper row −η
        (:class:`~redundik.tasks.subtasks.BoundSubtask`)."""
        views = self._views
        if views is None or views[0] is not robot.data or views[1] != self._fid:
            views = self._prepare(robot)
        _, fid, p, jw, columns, J6 = views
        robot.q  # noqa: B018 - raises if update() was never called
        if p is None:  # Pinocchio's memory not as verified: the same kernel on copies through the bindings
            J6[:] = robot.frame_jacobian(fid)
            p, lwa = robot.frame_position(fid), False
        else:
            lwa = True
        value: float = _PK.clearance_into(
            jw if lwa else J6, p, columns, self.rows, self.center, self.radius, J6, lwa, out, scale
        )
        return value

    def clearance_form(self, robot: RobotModel) -> ClearanceForm | None:
        """This clearance's ``ClearanceForm`` on ``robot``; ``None`` when the views of
        Pinocchio's memory could not be verified (the kernel then reads copies), or for a subclass that overrides how
        p or η is computed (its values are its own)."""
        kind = type(self)
        if any(getattr(kind, m) is not getattr(Clearance, m) for m in _CLEARANCE_FORMULA):
            return None
        views = self._views
        if views is None or views[0] is not robot.data or views[1] != self._fid:
            views = self._prepare(robot)
        if views[2] is None:
            return None
        return ClearanceForm(views[1], self.rows, self.center, self.radius, views[4])

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient | None:
        """p and η as a compiled writer (``potential_kernels.clearance_gradient``: the same kernel); ``None`` when
        the views of Pinocchio's memory could not be verified."""
        if self.clearance_form(robot) is None:
            return None
        return self._writer(robot, "clearance_gradient", self._floats)

    def value_and_gradient(self, robot: RobotModel) -> tuple[float, np.ndarray]:
        """(p [m], η), from one frame position and one Jacobian."""
        g = np.empty(robot.nv)
        return self.value_and_gradient_into(robot, g), g

    def value(self, robot: RobotModel) -> float:
        return self.value_and_gradient(robot)[0]

    def gradient(self, robot: RobotModel) -> np.ndarray:
        return self.value_and_gradient(robot)[1]


_NONE = np.zeros(0)  # (a writer without float data)

#: The methods that compute a clearance: a subclass that overrides one has no ``clearance_form``.
_CLEARANCE_FORMULA = ("value_and_gradient_into", "value_and_gradient", "value", "gradient", "_prepare")


class Manipulability(_FramePotential, CompiledPotential):
    """Yoshikawa's manipulability p = √det(J Jᵀ) of a frame Jacobian (rows ``axes``), section 5.2.

    The chapter calls its gradient "unfeasible" symbolically; numerically it is exact and cheap. With the SVD
    J = Σ σ_i u_i v_iᵀ, p = Π σ_i and dσ_i = u_iᵀ dJ v_i, so ∂p/∂q_k = Σ_i (Π_{l≠i} σ_l) u_iᵀ (∂J/∂q_k) v_i, with
    ∂J/∂q_k exact from :meth:`RobotModel.frame_jacobian_derivatives`. This form needs no inverse of JJᵀ, so it
    stays finite at a singularity (where p is not differentiable). Maximise it (k > 0). p and η are one compiled
    writer (``potential_kernels.manipulability_gradient``).
    """

    def __init__(self, frame: str, axes: str | Sequence[str] = "pose", name: str | None = None) -> None:
        super().__init__(frame, axes, default_name(name, f"manipulability_{frame}", "Manipulability"))

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """p and η from one compiled call (``potential_kernels.manipulability_gradient``)."""
        fid = self._id(robot)
        if fid >= robot.model.nframes:  # (an id of another robot's model)
            self.check(robot)
            fid = self._fid
        return CompiledGradient(_PK.manipulability_gradient, jacobian_product_ints(robot, [fid], self.rows), _NONE)


class BestPosture(CompiledPotential):
    """Best posture in the sense of uniform joint-torque distribution (5.12): p = tr(J W Jᵀ); minimise it.

    J stacks the frame Jacobians (rows ``axes``) of one or more end-effectors; W = diag(w) is the joint weight.
    ∂p/∂q_k = 2 tr((∂J/∂q_k) W Jᵀ), exact, from Pinocchio's kinematic Hessian. ``torques(F)`` gives τ = JᵀF, whose
    spread the chapter plots against p (Fig. 5.5). p and η are one compiled writer
    (``potential_kernels.best_posture_gradient``).

    Args:
        frames: One frame name or several.
        weights: Diagonal of W (size nv), identity if ``None``. The chapter's example prints six entries for seven
            joints; pass all nv explicitly.
        axes: Rows of each frame Jacobian.
    """

    def __init__(
        self,
        frames: str | Sequence[str],
        weights: Sequence[float] | None = None,
        axes: str | Sequence[str] = "pose",
        name: str = "best_posture",
    ) -> None:
        self.name = name
        self._fids: list[int] = []
        self.frames = frames
        self.axes = axes
        self.weights = weights

    @property
    def axes(self) -> tuple[str, ...]:
        """The rows of each frame Jacobian that count (a name of ``AXIS_SETS`` or a list of axes on assignment)."""
        return self._axes

    @axes.setter
    def axes(self, value: str | Sequence[str]) -> None:
        self._axes, self.rows = axes_rows(value, f"subtask '{self.name}'")
        self.form_revision += 1  # (a compiled step's writer reads them: planned again)

    @property
    def weights(self) -> np.ndarray | None:
        """The diagonal of W (nv, > 0), or ``None`` for the identity: a read-only copy of what was assigned; an
        assignment is used from the next step."""
        return self._weights

    @weights.setter
    def weights(self, value: Sequence[float] | None) -> None:
        arr = None if value is None else _finite_vec(value, f"subtask '{self.name}': weights").copy()
        if arr is not None and np.any(arr <= 0):
            raise TaskError(f"subtask '{self.name}': weights must be > 0 (W is positive definite)")
        if arr is not None:  # (a copy, read-only: a compiled step packs it; an edit is an assignment)
            arr.setflags(write=False)
        self._weights = arr
        self.form_revision += 1

    @property
    def frames(self) -> tuple[str, ...]:
        """The frames' names; an assignment (one name or several) takes effect at the next step (their ids looked
        up again)."""
        return self._frames

    @frames.setter
    def frames(self, value: str | Sequence[str]) -> None:
        # one name, or a list / tuple of names (not a set or a dict: the rows of J follow the frames' order)
        names = (value,) if isinstance(value, str) else tuple(value) if isinstance(value, (list, tuple)) else ()
        if not names or not all(isinstance(f, str) and f for f in names):
            raise TaskError(
                f"subtask '{self.name}': frames must be one frame name (a str) or a list / tuple of names, got "
                f"{type(value).__name__} {value!r:.80}"
            )
        self._frames = tuple(str(f) for f in names)
        self._fids = []
        self.form_revision += 1

    def check(self, robot: RobotModel) -> None:
        try:
            self._fids = [robot.frame_id(f) for f in self.frames]
        except Exception as exc:
            raise TaskError(f"subtask '{self.name}': {exc}") from exc
        if self.weights is not None and self.weights.shape[0] != robot.nv:
            raise TaskError(
                f"subtask '{self.name}': weights: expected {robot.nv} numbers (one per joint), "
                f"got {self.weights.shape[0]}"
            )

    def _w(self, robot: RobotModel) -> np.ndarray:
        return np.ones(robot.nv) if self.weights is None else self.weights

    def jacobian(self, robot: RobotModel) -> np.ndarray:
        """The stacked Jacobian J the measure is taken of, shape (len(frames)·m, nv)."""
        if not self._fids:
            self.check(robot)
        return np.vstack([robot.frame_jacobian(f)[self.rows] for f in self._fids])

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """p and η from one compiled call (``potential_kernels.best_posture_gradient``)."""
        if not self._fids or max(self._fids) >= robot.model.nframes:
            self.check(robot)
        ints = jacobian_product_ints(robot, self._fids, self.rows)
        return CompiledGradient(_PK.best_posture_gradient, ints, np.array(self._w(robot), dtype=float))

    def torques(self, robot: RobotModel, force: Sequence[float]) -> np.ndarray:
        """Joint torques τ = JᵀF for a Cartesian load F (size rows·frames), the chapter's statics."""
        J = self.jacobian(robot)
        F = _finite_vec(force, f"subtask '{self.name}': force", J.shape[0])
        return J.T @ F
