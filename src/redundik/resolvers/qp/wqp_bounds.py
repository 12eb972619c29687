"""The bound subtasks' rows G q̇ ≤ h of a ``wqp`` step: the velocity damper ḣ ≥ −γh of each bound subtask
(Faverjon & Tournassoud 1987; ``BoundSubtask.rows``), as inequality rows beside the weighted QP.

When every bound subtask of the plan is on a clearance (its ``clearance_form``), the fused step writes their rows in
one compiled call, ``hqp_fused.clearance_rows`` — the packing and kernel of ``hqp``'s fused step
(``hqp_bounds.pack_bounds``), the same operations as ``BoundSubtask.rows_into`` — into
buffers of the plan: no Python per subtask, no allocation a step. Otherwise (a barrier's rows, coal's distances, a
potential without a clearance form) each subtask's ``rows`` is called from Python, as the per-task path does.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.resolvers.linalg import _Kernels
from redundik.resolvers.qp.hqp_bounds import PackedBounds, pack_bounds
from redundik.tasks.base import Edits

#: ``hqp_fused``'s kernels (``clearance_rows``), imported on first use.
_HFK = _Kernels("hqp_fused")

#: The rows of a step's bound subtasks: G (rows, nv), h (rows,), the row names, which rows are safety rows
#: (``None``: no bound subtask).
BoundRows = tuple[np.ndarray, np.ndarray, list[str], np.ndarray | None]


def python_bound_rows(bounds: list[Any], robot: RobotModel, dt: float) -> BoundRows:
    """Each bound subtask's ``rows`` (C, d, names) stacked: G, h, the names and the safety flags (its ``critical``)."""
    Cs, ds, critical, names = [], [], [], []
    for bsub in bounds:
        C, d, rn = bsub.rows(robot, dt)
        Cs.append(C)
        ds.append(d)
        names += rn
        critical += [bsub.critical] * len(rn)
    G, h = (Cs[0], ds[0]) if len(Cs) == 1 else (np.vstack(Cs), np.concatenate(ds))
    return G, h, names, np.array(critical, dtype=bool)


class PackedBoundRows:
    """A ``wqp`` plan's bound subtasks packed for the compiled damper rows, and the buffers that call writes.

    Packed again when ``Edits`` moved (an assigned centre, radius, frame, axes, bound, rate, name or source) or for
    another robot's data; a plan is made anew when the stack's membership or layout changes."""

    __slots__ = ("G", "h", "key", "names", "packed", "safe")

    def __init__(self) -> None:
        self.key: tuple[int, int, Any] | None = None
        self.packed: PackedBounds | None = None
        self.G = np.zeros((0, 0))
        self.h = np.zeros(0)
        self.names: list[str] = []
        self.safe = np.zeros(0, dtype=bool)

    def rows(self, bounds: list[Any], robot: RobotModel, jw: np.ndarray, poses: np.ndarray, dt: float) -> BoundRows:
        """The rows of ``bounds`` at the robot's current state for a step dt [s]: written by the compiled call into
        this object's buffers (:meth:`kept` copies them for a result), or from Python when they are not packed.
        ``jw``, ``poses``: the fused plan's views of Pinocchio's joint Jacobians and frame placements."""
        key = self.key
        if key is None or key[0] != Edits.count or key[1] != Edits.layout or key[2] is not robot.data:
            self._pack(bounds, robot)
        packed = self.packed
        if packed is None:
            return python_bound_rows(bounds, robot, dt)
        _HFK.clearance_rows(jw, poses, dt, packed.bint, packed.bcols, packed.bfl, self.G, self.h)
        return self.G, self.h, self.names, self.safe

    def kept(self, rows: BoundRows) -> BoundRows:
        """``rows`` for a QP and a result to keep: copies when they are this object's buffers (the next step writes
        them again)."""
        G, h, names, safe = rows
        if G is self.G:
            return G.copy(), h.copy(), list(names), None if safe is None else safe.copy()
        return rows

    def _pack(self, bounds: list[Any], robot: RobotModel) -> None:
        n = robot.nv
        packed = self.packed = pack_bounds(robot, [bounds], [0], n)
        self.key = (Edits.count, Edits.layout, robot.data)
        if packed is None:
            return
        self.G = np.zeros((packed.rows, n))
        self.h = np.zeros(packed.rows)
        names: list[str] = []
        critical: list[bool] = []
        for bsub, (_, row_names) in zip(bounds, packed.slices, strict=True):
            names += row_names
            critical += [bsub.critical] * len(row_names)
        self.names = names
        self.safe = np.array(critical, dtype=bool)


__all__ = ["BoundRows", "PackedBoundRows", "python_bound_rows"]
