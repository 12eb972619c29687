"""A joint visiting values in turn: the potential of the (6+1) robot's round trip (section 5.2)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledGradient, default_name
from redundik.tasks.joint_potentials import one_dof_joint
from redundik.tasks.layouts import J_IQ, J_IV, WP_ACTIVE, WP_COUNT, WP_POINTS, WP_TOLERANCE
from redundik.tasks.potential_rows import CompiledPotential

#: The compiled potential kernels, imported on first use (a namespace: a cold start puts their twins here).
_PK = KernelNamespace("redundik.tasks.potential_kernels")


class JointWaypoints(CompiledPotential):
    """A joint visiting values in turn: p = (q_j − c_i)² with c_i the active waypoint, η_j = 2(q_j − c_i).

    The (6+1) robot's round trip (section 5.2, Figs. 5.2–5.5): with p = (d_1 − c)² and k < 0 the null-space motion
    slides the arm to c; the chapter then brings it back home. Here the waypoint switches to the next value once
    |q_j − c_i| < ``tolerance``, so one run does the whole trip: ``values = [c, d_1(0)]``. Between switches p is the
    chapter's (d_1 − c)² and its gradient is exact; the switch is the only discontinuity. The state (active index)
    is reset by :meth:`check`, which :meth:`TaskStack.reset` calls at the start of every run. p, η and the switch
    are one compiled writer (``potential_kernels.waypoints_gradient``; the active index is its data).

    Args:
        joint: Joint name (e.g. the track joint ``"1"``).
        values: Waypoints c_1, c_2, … [rad or length unit].
        tolerance: Distance to the active waypoint at which the next one becomes active (> 0).
        name: Potential name.

    Raises:
        TaskError: no waypoint, non-finite values, tolerance ≤ 0; unknown joint at :meth:`check`.
    """

    def __init__(self, joint: str, values: Sequence[float], tolerance: float = 0.05, name: str | None = None) -> None:
        self.name = default_name(name, f"waypoints_{joint}", "JointWaypoints")
        vals = np.asarray(values, dtype=float).reshape(-1)
        if vals.size == 0 or not np.all(np.isfinite(vals)):
            raise TaskError(f"subtask '{self.name}': values must be one or more finite numbers, got {list(values)}")
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise TaskError(f"subtask '{self.name}': tolerance must be > 0, got {tolerance}")
        self.joint, self.values, self.tolerance = joint, vals, float(tolerance)
        #: the writer's data: (idx_q, idx_v, active index, count) and (tolerance, c_1, c_2, …)
        self._ints = np.full(WP_COUNT + 1, -1, dtype=np.int64)
        self._ints[WP_ACTIVE], self._ints[WP_COUNT] = 0, vals.size
        self._floats = np.empty(WP_POINTS + vals.size)
        self._floats[WP_TOLERANCE], self._floats[WP_POINTS:] = self.tolerance, vals
        self._iq = self._iv = -1

    @property
    def active(self) -> int:
        """The index of the active waypoint."""
        return int(self._ints[WP_ACTIVE])

    @active.setter
    def active(self, value: int) -> None:
        self._ints[WP_ACTIVE] = int(value)

    def check(self, robot: RobotModel) -> None:
        self._iq, self._iv = self._ints[J_IQ], self._ints[J_IV] = one_dof_joint(robot, self.joint, self.name)
        self.active = 0

    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient:
        """``potential_kernels.waypoints_gradient`` (the joint looked up when it was not yet)."""
        if self._iq < 0 or self._iq >= robot.nq:
            self.check(robot)
        return CompiledGradient(_PK.waypoints_gradient, self._ints, self._floats)

    def reached(self, q_series: np.ndarray) -> int:
        """How many of the waypoints, in order, a run through the configurations ``q_series`` (samples, nq)
        reached — each within ``tolerance`` of the joint, after the ones before it (the switching rule of this
        potential, the last waypoint included). Requires :meth:`check` (the joint's index)."""
        if self._iq < 0:
            raise TaskError(f"subtask '{self.name}': reached() before check(robot)")
        k = 0
        for x in np.asarray(q_series, dtype=float)[:, self._iq]:
            while k < self.values.size and abs(x - self.values[k]) < self.tolerance:
                k += 1
            if k == self.values.size:
                break
        return k

    @property
    def target(self) -> float:
        """The active waypoint c_i."""
        return float(self.values[self.active])

    def __repr__(self) -> str:
        return f"JointWaypoints(joint={self.joint!r}, values={self.values.tolist()}, tolerance={self.tolerance})"
