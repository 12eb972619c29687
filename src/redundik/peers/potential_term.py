"""A redundik potential p(q) as a one-row peer task: Jacobian ηᵀ and an error that drives p (peer-agnostic part).

mink and pink use the first-order task dynamics J Δq = −α e (Δq the step's displacement, α ∈ [0, 1] the task
gain) with J = ∂e/∂q. A potential p becomes the 1-row task J = ηᵀ (η = ∂p/∂q in the peer's tangent coordinates)
with one of these errors:

* ``mode="target"``: e = (p − p_d) − ṗ_d·dt/α, so the task asks ηᵀΔq = α(p_d − p) + ṗ_d·dt. Given a feedback
  rate K [1/s] (``rate``) and the step dt, α = K·dt and this is the chapter's state-feedback law for the subtask
  values, ẏ = ẏ_d + K(y_d − y) (section 5.2, after eq. 5.15), one Euler step at a time.
* ``mode="increase"`` / ``"decrease"``: e = ∓ s·dt with s [p-units/s] the ``speed``, so the task asks
  ηᵀΔq = ±α s dt: p rises (falls) at s per second to first order — the task-space twin of the null-space
  gradient term kη of eq. (5.8), e.g. manipulability up, tr(JWJᵀ) or the virtual-point distance down.

The gradient comes from a redundik :class:`~redundik.tasks.base.Potential` (exact: analytic or from Pinocchio's
kinematic Hessians) evaluated on a redundik :class:`RobotModel` of the same robot, with the configuration mapped
from the peer by joint name (:class:`~redundik.peers.joint_map.JointMap`).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.peers.joint_map import JointMap
from redundik.tasks.base import Potential

PotentialMode = Literal["target", "increase", "decrease"]


class PotentialTerm:
    """Evaluates a potential for a peer configuration: p, η in peer coordinates, and the task error.

    Args:
        potential: The redundik potential.
        robot: A redundik model of the same robot (its kinematic state is overwritten on every evaluation).
        mode: ``"target"``, ``"increase"`` or ``"decrease"`` (module docstring).
        target: p_d for mode ``"target"``.
        rate: K [1/s] of the state-feedback law; sets the peer gain α = K·dt (needs ``dt``).
        target_rate: ṗ_d [p-units/s] for mode ``"target"`` (needs ``dt``).
        speed: s [p-units/s] > 0 for modes ``"increase"`` / ``"decrease"`` (needs ``dt``).
        dt: The IK step [s] the peer's solve_ik is called with.
        gain: Peer task gain α ∈ [0, 1] when ``rate`` is not given.

    Raises:
        TaskError: inconsistent arguments (the message names them).
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
        gain: float = 1.0,
    ) -> None:
        name = getattr(potential, "name", type(potential).__name__)
        where = f"peer task '{name}'"
        if mode not in ("target", "increase", "decrease"):
            raise TaskError(f"{where}: mode must be target, increase or decrease, got {mode!r}")
        if dt is not None and not (math.isfinite(dt) and dt > 0):
            raise TaskError(f"{where}: dt must be a positive number of seconds, got {dt}")
        if rate is not None:
            if not (math.isfinite(rate) and rate > 0):
                raise TaskError(f"{where}: rate (K) must be > 0 [1/s], got {rate}")
            if dt is None:
                raise TaskError(f"{where}: rate (K) needs dt, the IK step [s] (the peer gain is α = K·dt)")
            gain = rate * dt
            if gain > 1.0:
                raise TaskError(f"{where}: rate·dt = {gain:g} > 1; the peers need α = K·dt ≤ 1 (lower K or dt)")
        if not (math.isfinite(gain) and 0.0 <= gain <= 1.0):
            raise TaskError(f"{where}: gain α must be in [0, 1], got {gain}")
        if mode == "target":
            if target is None or not math.isfinite(target):
                raise TaskError(f"{where}: mode 'target' needs a finite target value p_d")
            if not math.isfinite(target_rate):
                raise TaskError(f"{where}: target_rate must be finite, got {target_rate}")
            if target_rate != 0.0 and (dt is None or gain == 0.0):
                raise TaskError(f"{where}: a target_rate needs dt and a gain α > 0")
        else:
            if not (math.isfinite(speed) and speed > 0):
                raise TaskError(f"{where}: speed must be > 0 [units of p per second], got {speed}")
            if dt is None:
                raise TaskError(f"{where}: mode '{mode}' needs dt, the IK step [s]")
        self.potential = potential
        self.robot = robot
        self.mode: PotentialMode = mode
        self.target = None if target is None else float(target)
        self.target_rate = float(target_rate)
        self.rate = rate
        self.speed = float(speed)
        self.dt = dt
        self.gain = float(gain)
        self.name = name
        self.joint_map: JointMap | None = None
        self._key: bytes | None = None
        self._value = 0.0
        self._eta = np.zeros(0)
        self._checked = False

    def set_target(self, target: float, target_rate: float = 0.0) -> None:
        """Move the target p_d (and its rate ṗ_d) of mode ``"target"``, e.g. along a reference."""
        if self.mode != "target":
            raise TaskError(f"peer task '{self.name}': set_target needs mode 'target', not '{self.mode}'")
        if not (math.isfinite(target) and math.isfinite(target_rate)):
            raise TaskError(f"peer task '{self.name}': target and target_rate must be finite")
        if target_rate != 0.0 and (self.dt is None or self.gain == 0.0):
            raise TaskError(f"peer task '{self.name}': a target_rate needs dt and a gain α > 0")
        self.target, self.target_rate = float(target), float(target_rate)

    def evaluate(self, q_peer: np.ndarray) -> tuple[float, np.ndarray]:
        """p and η (peer tangent coordinates, shape (nv_peer,)) at a peer configuration; cached per q."""
        if self.joint_map is None:
            raise TaskError(f"peer task '{self.name}': no joint map (bind the task to a peer model first)")
        key = q_peer.tobytes()
        if key != self._key:
            q = self.joint_map.to_robot_q(q_peer)
            self.robot.update(q)
            if not self._checked:
                self.potential.check(self.robot)
                self._checked = True
            self._value = float(self.potential.value(self.robot))
            self._eta = self.joint_map.gradient_to_peer(self.potential.gradient(self.robot), q)
            self._key = key
        return self._value, self._eta

    def error(self, value: float) -> np.ndarray:
        """The 1-row task error e for a potential value p (module docstring), shape (1,)."""
        dt = self.dt if self.dt is not None else 0.0  # validated: set whenever it is used
        if self.mode == "target":
            e = value - (self.target if self.target is not None else value)
            if self.target_rate != 0.0:
                e -= self.target_rate * dt / self.gain
        else:
            e = (-1.0 if self.mode == "increase" else 1.0) * self.speed * dt
        return np.array([e])

    def describe(self) -> str:
        """Short description for the peers' ``__repr__``."""
        if self.mode == "target":
            return f"{self.name}: target={self.target}, target_rate={self.target_rate}, gain={self.gain:g}"
        return f"{self.name}: {self.mode} at {self.speed:g}/s, gain={self.gain:g}"
