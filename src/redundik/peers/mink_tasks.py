"""redundik's subtasks as mink tasks: manipulability, best posture, virtual point, any potential.

Importing this module imports mink and MuJoCo (the ``peers`` extra). Each task is a 1-row ``mink.Task`` with
Jacobian ηᵀ (in MuJoCo's tangent coordinates) and the error of :mod:`redundik.peers.potential_term`; the gradient
is exact, computed on a redundik :class:`RobotModel` of the same robot, joints matched by name.

Example::

    robot = rk.load_example_robot("panda")
    mj_model = mujoco_from_urdf(urdf_path, robot, ["panda_hand"])
    configuration = Any(mj_model)
    up = MinkManipulabilityTask(robot, "panda_hand", dt=0.01, speed=0.05, cost=0.1)
    mink.solve_ik(configuration, [frame_task, posture_task, up], 0.01, "daqp")
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

mink = require("mink")
require("mujoco")


class MinkPotentialTask(mink.Task):  # type: ignore[misc,name-defined]  # mink is untyped
    """Any redundik potential p(q) as a 1-row mink task (J = ηᵀ, error per ``mode``).

    Args:
        potential: The potential.
        robot: A redundik model of the same robot as the mink configuration.
        mode: ``"target"`` (drive p to ``target``, optionally with the state-feedback ``rate`` K and
            ``target_rate``), ``"increase"`` or ``"decrease"`` (at ``speed`` per second).
        target: p_d.
        rate: K [1/s]; sets mink's gain α = K·dt.
        target_rate: ṗ_d [p-units/s].
        speed: [p-units/s] for increase/decrease.
        dt: The IK step [s] given to ``mink.solve_ik``.
        cost: Weight of the row [cost]/[p-unit].
        gain: mink's α ∈ [0, 1] when ``rate`` is not given.
        lm_damping: mink's Levenberg–Marquardt damping.
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
            self.term.joint_map = JointMap.from_mujoco(self.term.robot, configuration.model)
        return self.term.evaluate(configuration.data.qpos)

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
        """ηᵀ in MuJoCo's tangent coordinates, shape (1, nv)."""
        return self._bind(configuration)[1][None, :].copy()

    def __repr__(self) -> str:
        return f"MinkPotentialTask({self.term.describe()}, cost={self.cost[0]:g})"


class MinkManipulabilityTask(MinkPotentialTask):
    """Raise Yoshikawa's manipulability √det(JJᵀ) of a frame (exact gradient); see :class:`Manipulability`."""

    def __init__(self, robot: RobotModel, frame: str, axes: str | Sequence[str] = "pose", **kwargs: object) -> None:
        kwargs.setdefault("mode", "increase")
        super().__init__(Manipulability(frame, axes), robot, **kwargs)  # type: ignore[arg-type]


class MinkBestPostureTask(MinkPotentialTask):
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


class MinkVirtualPointTask(MinkPotentialTask):
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
