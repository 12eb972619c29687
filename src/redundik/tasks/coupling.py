"""Joint coupling as an equality task: q_i − q_j = c (e.g. the dual-arm's θ3r = θ3l + β, section 5.3)."""

from __future__ import annotations

import numpy as np

from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledRows, check_number, default_name
from redundik.tasks.layouts import CPL_FLOATS, CPL_INTS, CPL_IQ_I, CPL_IQ_J, CPL_IV_I, CPL_IV_J, CPL_OFFSET
from redundik.tasks.rows import CompiledTask

#: the compiled writers of the built-in tasks (loaded at first use)
_RK = KernelNamespace("redundik.tasks.row_kernels")


class JointCoupling(CompiledTask):
    """Keep two 1-dof joints coupled: q_i − q_j = c, as the 1-row task (e_i − e_j)ᵀq̇ = K(c − (q_i − q_j)).

    With ``offset=None`` the offset c is captured at :meth:`reset` (the coupling holds what the start pose has).
    In a QP hierarchy place it at level 0 (hard) or lower; in ``wqp`` its weight sets how hard it is held.

    Args:
        joint_i: Name of the first joint.
        joint_j: Name of the second joint.
        offset: c [rad or m]; captured at reset when ``None``.
        gain: K [1/s] ≥ 0 on the coupling error.
        weight: Weight in a weighted QP (> 0).
        priority: Level (0 = highest); ``None``: the main tasks' level 0.
        name: Task name (default ``"coupling_<i>_<j>"``).

    Raises:
        TaskError: same joint twice, non-finite offset, negative gain or weight.
    """

    def __init__(
        self,
        joint_i: str,
        joint_j: str,
        offset: float | None = None,
        *,
        gain: float = 1.0,
        weight: float = 1.0,
        priority: int | None = None,
        name: str | None = None,
    ) -> None:
        for key, joint in (("joint_i", joint_i), ("joint_j", joint_j)):
            if not isinstance(joint, str) or not joint:
                raise TaskError(f"JointCoupling: {key} must be a joint name (a str), got {joint!r:.60}")
        self.name = default_name(name, f"coupling_{joint_i}_{joint_j}", "JointCoupling")
        if joint_i == joint_j:
            raise TaskError(f"task '{self.name}': joint_i and joint_j must differ, got '{joint_i}' twice")
        self.joint_i, self.joint_j = joint_i, joint_j
        self.offset = None if offset is None else check_number(offset, f"task '{self.name}': offset [rad or m]")
        self.gain, self.weight, self.priority = gain, weight, priority  # (Task's setters: check_number)
        self._idx: tuple[int, int, int, int] | None = None
        self._c: float | None = self.offset
        self._ints = np.zeros(CPL_INTS, dtype=np.int64)  # the compiled writer's data, rewritten in place
        self._floats = np.zeros(CPL_FLOATS)

    def reset(self, robot: RobotModel) -> None:
        idx = []
        for jn in (self.joint_i, self.joint_j):
            try:
                info = robot.joint(jn)
            except Exception as exc:
                raise TaskError(f"task '{self.name}': {exc}") from exc
            if info.idx_q < 0:
                raise TaskError(f"task '{self.name}': joint '{jn}' is not a 1-dof joint")
            idx += [info.idx_q, info.idx_v]
        self._idx = (idx[0], idx[1], idx[2], idx[3])
        q = robot.q
        self._c = self.offset if self.offset is not None else float(q[idx[0]] - q[idx[2]])
        ints = self._ints  # (the same rows on other joints: data, not a new form)
        ints[CPL_IQ_I], ints[CPL_IV_I], ints[CPL_IQ_J], ints[CPL_IV_J] = self._idx
        self._floats[CPL_OFFSET] = self._c

    def compiled_rows(self, robot: RobotModel) -> CompiledRows:
        """One row: J = (e_i − e_j)ᵀ, e = c − (q_i − q_j), v = K e (``row_kernels.coupling_rows``)."""
        if self._idx is None or self._c is None:
            self.reset(robot)
        return CompiledRows(_RK.coupling_rows, 1, self._ints, self._floats)

    def __repr__(self) -> str:
        return f"JointCoupling({self.joint_i!r}, {self.joint_j!r}, offset={self.offset}, gain={self.gain})"
