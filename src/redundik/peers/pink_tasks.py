"""redundik's subtasks as pink tasks: manipulability, best posture, virtual point, any potential.

Importing this module imports pink (the ``peers`` extra). Each task is a 1-row ``pink.tasks.Task`` with Jacobian
ηᵀ (Pinocchio tangent coordinates of pink's model) and the error of :mod:`redundik.peers.potential_term`; the
gradient is exact, computed on a redundik :class:`RobotModel` of the same robot, joints matched by name. pink's own
``ManipulabilityTask`` covers manipulability; this one follows the chapter's √det(JJᵀ) on any axes subset.

Example::

    robot = rk.load_example_robot("panda")
    configuration = Any(model, data, q)      # model: the same URDF in Pinocchio
    low = PinkBestPostureTask(robot, "panda_hand", dt=0.01, speed=0.1, cost=0.1)
    pink.solve_ik(configuration, [frame_task, posture_task, low], 0.01, solver="daqp")
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.peers._deps import require
from redundik.peers.joint_map import JointMap
from redundik.peers.potential_term import PotentialMode, PotentialTerm
from redundik.tasks.base import Potential
from redundik.tasks.potentials import BestPosture, Manipulability, VirtualPoint

pink = require("pink")
from pink.tasks import Task as _PinkTask  # noqa: E402 - after the guarded import


class PinkPotentialTask(_PinkTask):  # type: ignore[misc]  # pink is untyped
    """Any redundik potential p(q) as a 1-row pink task (J = ηᵀ, error per ``mode``).

    Args:
        potential: The potential.
        robot: A redundik model of the same robot as pink's model.
        mode: ``"target"`` (drive p to ``target``, optionally with the state-feedback ``rate`` K and
            ``target_rate``), ``"increase"`` or ``"decrease"`` (at ``speed`` per second).
        target: p_d.
        rate: K [1/s]; sets pink's gain α = K·dt.
        target_rate: ṗ_d [p-units/s].
        speed: [p-units/s] for increase/decrease.
        dt: The IK step [s] given to ``pink.solve_ik``.
        cost: Weight of the row [cost]/[p-unit].
        gain: pink's α ∈ [0, 1] when ``rate`` is not given.
        lm_damping: pink's Levenberg–Marquardt damping.
        joint_map: The joint map; built from the first configuration's model if ``None``.

    Raises:
        TaskError: inconsistent arguments.
    """

    def __init__(
        self,
        potential: Potential,
        robot: RobotModel,
        *,
        mode: PotentialMode = "target",
        target: float | None = None,
        rate: float | None = None,
        target_rate: float = 0.0,
        speed: float = 1.0,
        dt: float | None = None,
        cost: float = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        joint_map: JointMap | None = None,
    ) -> None:
        self.term = PotentialTerm(
            potential,
            robot,
            mode=mode,
            target=target,
            rate=rate,
            target_rate=target_rate,
            speed=speed,
            dt=dt,
            gain=gain,
        )
        super().__init__(cost=np.array([float(cost)]), gain=self.term.gain, lm_damping=lm_damping)
        self.term.joint_map = joint_map

    def _bind(self, configuration: Any) -> tuple[float, np.ndarray]:
        if self.term.joint_map is None:
            self.term.joint_map = JointMap.from_pinocchio(self.term.robot, configuration.model)
        return self.term.evaluate(configuration.q)

    def set_target(self, target: float, target_rate: float = 0.0) -> None:
        """Move p_d (and ṗ_d) of mode ``"target"``."""
        self.term.set_target(target, target_rate)

    def value(self, configuration: Any) -> float:
        """p at the configuration."""
        return self._bind(configuration)[0]

    def compute_error(self, configuration: Any) -> np.ndarray:
        """e, shape (1,) (see :mod:`redundik.peers.potential_term`)."""
        return self.term.error(self._bind(configuration)[0])

    def compute_jacobian(self, configuration: Any) -> np.ndarray:
        """ηᵀ in pink's tangent coordinates, shape (1, nv)."""
        return self._bind(configuration)[1][None, :].copy()

    def __repr__(self) -> str:
        return f"PinkPotentialTask({self.term.describe()}, cost={float(np.atleast_1d(self.cost)[0]):g})"


class PinkManipulabilityTask(PinkPotentialTask):
    """Raise Yoshikawa's manipulability √det(JJᵀ) of a frame (exact gradient); see :class:`Manipulability`."""

    def __init__(self, robot: RobotModel, frame: str, axes: str | Sequence[str] = "pose", **kwargs: object) -> None:
        kwargs.setdefault("mode", "increase")
        super().__init__(Manipulability(frame, axes), robot, **kwargs)  # type: ignore[arg-type]


class PinkBestPostureTask(PinkPotentialTask):
    """Lower tr(J W Jᵀ) of one or more frames (eq. 5.12), the chapter's best posture; see :class:`BestPosture`."""

    def __init__(
        self,
        robot: RobotModel,
        frames: str | Sequence[str],
        weights: Sequence[float] | None = None,
        axes: str | Sequence[str] = "pose",
        **kwargs: object,
    ) -> None:
        kwargs.setdefault("mode", "decrease")
        super().__init__(BestPosture(frames, weights, axes), robot, **kwargs)  # type: ignore[arg-type]


class PinkVirtualPointTask(PinkPotentialTask):
    """Pull a frame towards a virtual point, p = ½‖S(p_f − p_v)‖² → 0; see :class:`VirtualPoint`."""

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        point: Sequence[float],
        axes: str | Sequence[str] = "position",
        **kw: object,
    ) -> None:
        kw.setdefault("mode", "target")
        kw.setdefault("target", 0.0)
        super().__init__(VirtualPoint(frame, point, axes), robot, **kw)  # type: ignore[arg-type]
