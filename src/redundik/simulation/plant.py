"""Plants: what a control loop drives instead of the perfect integrator q ← q ⊕ q̇·dt.

A :class:`Plant` receives the resolver's q̇ once per control tick, advances its own simulation (at its own rate)
for one control period and returns the *measured* configuration the next tick starts from. The only plant here is
MuJoCo (:mod:`redundik.simulation.mujoco_plant`, optional extra ``sim``), imported when one is made.

A plant's options are one plain record, :class:`PlantOptions`; a task file's ``plant:`` entry is validated by the
YAML layer (``redundik.config.schema.PlantSpec``) and turned into this record.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from redundik.errors import ConfigError

if TYPE_CHECKING:
    from redundik.kinematics.model import RobotModel

#: Plant types and their actuator modes.
PLANT_TYPES = ("mujoco",)
ACTUATORS = ("position", "velocity")


@runtime_checkable
class Plant(Protocol):
    """A simulated robot under joint-level control."""

    name: str

    def reset(self, q0: np.ndarray) -> np.ndarray:
        """Put the plant at rest at ``q0`` (size nq); returns the measured configuration."""
        ...

    def step(self, dq: np.ndarray, dt: float) -> np.ndarray:
        """Apply the command q̇ (size nv) [rad/s, length/s] for one control period ``dt`` [s]; returns measured q."""
        ...

    def series(self) -> dict[str, np.ndarray]:
        """Per-sample logs (``u.<joint>``: actuator torque [N·m or N] at each sample), shape (N,) each."""
        ...

    def summary(self) -> dict[str, Any]:
        """Scalars for ``summary.json`` (actuator effort ...)."""
        ...


@dataclass(frozen=True)
class PlantOptions:
    """How a plant is built and driven (the ``plant:`` entry of a task file, see ``docs/task-files.md``).

    Attributes:
        type: Plant type (:data:`PLANT_TYPES`: ``"mujoco"``).
        actuator: ``"position"`` (τ = kp·(q_ref − q) − kv·q̇) or ``"velocity"`` (τ = kv·(q̇_cmd − q̇)).
        kp: Position gain, one number for every joint or joint name → value [N·m/rad or N/m].
        kv: Damping (position actuators) or velocity gain (velocity actuators), likewise [N·m·s/rad or N·s/m].
        sim_dt: Physics step [s] > 0; it must divide the control period.
        gravity: Gravity on.
        gravity_compensation: Gravity compensated through the actuators (counts in the effort and the limits).
        effort_limits: The URDF effort limits as actuator force limits.
        armature: Reflected rotor inertia added to every joint [kg·m²] ≥ 0.
        kinematic_reference: Also run the perfect integrator, to report the error under the plant against it.

    Raises:
        ConfigError: an unknown type or actuator, a non-finite or non-positive ``sim_dt``, a negative armature.
    """

    type: str = "mujoco"
    actuator: str = "position"
    kp: float | Mapping[str, float] = 2000.0
    kv: float | Mapping[str, float] = 100.0
    sim_dt: float = 0.001
    gravity: bool = True
    gravity_compensation: bool = True
    effort_limits: bool = True
    armature: float = 0.1
    kinematic_reference: bool = True

    def __post_init__(self) -> None:
        if self.type not in PLANT_TYPES:
            raise ConfigError(f"unknown plant type {self.type!r}; available: {', '.join(PLANT_TYPES)}", "type")
        if self.actuator not in ACTUATORS:
            raise ConfigError(f"actuator must be one of {', '.join(ACTUATORS)}, got {self.actuator!r}", "actuator")
        if not (math.isfinite(self.sim_dt) and self.sim_dt > 0):
            raise ConfigError(f"sim_dt must be a finite number > 0 [s], got {self.sim_dt}", "sim_dt")
        if not (math.isfinite(self.armature) and self.armature >= 0):
            raise ConfigError(f"armature must be a finite number ≥ 0 [kg·m²], got {self.armature}", "armature")


def make_plant(
    options: PlantOptions,
    robot: RobotModel,
    urdf: str | os.PathLike[str] | None,
    *,
    control_dt: float,
    where: str = "plant",
) -> Plant:
    """The plant ``options`` describe, for ``robot`` loaded from ``urdf``.

    Args:
        options: The plant's options.
        robot: The redundik model (joints matched by name).
        urdf: The robot's URDF file; ``None`` for a D-H robot (refused by MuJoCo).
        control_dt: The control period [s].
        where: Key path for errors.

    Raises:
        ConfigError: a robot MuJoCo cannot load from a URDF (D-H tables), or inconsistent rates.
        ExtraImportError: the ``sim`` extra is not installed.
    """
    if options.type == "mujoco":
        from redundik.simulation.mujoco_plant import MujocoPlant

        if urdf is None:
            raise ConfigError("a MuJoCo plant needs a URDF robot (this one is a D-H table)", where)
        return MujocoPlant(robot, urdf, options, control_dt=control_dt, where=where)
    raise ConfigError(f"unknown plant type '{options.type}'", where)  # pragma: no cover - PlantOptions checks it
