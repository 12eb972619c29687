"""Plants: what a control loop drives instead of the perfect integrator q ← q ⊕ q̇·dt.

A :class:`Plant` receives the resolver's q̇ once per control tick, advances its own simulation (at its own rate)
for one control period and returns the *measured* configuration the next tick starts from. The only plant here is
MuJoCo (:mod:`redundik.simulation.mujoco_plant`, optional extra ``sim``), imported when one is made.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from redundik.errors import ConfigError

if TYPE_CHECKING:
    from redundik.config.loader import RunPlan, TaskPlan
    from redundik.config.schema import PlantSpec
    from redundik.simulation.loop import SimulationLog


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


def make_plant(spec: PlantSpec, plan: TaskPlan, where: str = "plant") -> Plant:
    """The plant a ``plant:`` entry describes, for the task file's robot.

    Raises:
        ConfigError: a robot MuJoCo cannot load from a URDF (D-H tables), or inconsistent rates.
        PlantImportError: the ``sim`` extra is not installed.
    """
    if spec.type == "mujoco":
        from redundik.simulation.mujoco_plant import MujocoPlant

        if plan.robot.urdf is None:
            raise ConfigError("a MuJoCo plant needs a URDF robot (this one is a D-H table)", where)
        return MujocoPlant(plan.robot.model, plan.robot.urdf, spec, control_dt=plan.dt, where=where)
    raise ConfigError(f"unknown plant type '{spec.type}'", where)  # pragma: no cover - schema restricts it


def plant_summary(plan: TaskPlan, run: RunPlan, plant: Plant, log: SimulationLog) -> dict[str, Any]:
    """The plant's entries of a run's ``summary.json``: ``plant``, the error under the plant and, when
    ``kinematic_reference`` is on, the same run's error with the perfect integrator (``kinematic_max_task_error``)."""
    from redundik.simulation.loop import simulate

    out: dict[str, Any] = {"plant": plant.name, **plant.summary()}
    out["plant_max_task_error"] = log.max_task_error
    spec = run.plant
    if spec is not None and spec.kinematic_reference:
        ref = simulate(plan.robot.model, run.stack, run.resolver, run.q0, dt=plan.dt, steps=plan.steps)
        out["kinematic_max_task_error"] = ref.max_task_error
        out["error_ratio_plant_vs_kinematic"] = log.max_task_error / max(ref.max_task_error, 1e-15)
        out["max_q_deviation_from_kinematic"] = float(np.max(np.abs(log.q - ref.q)))
    return out
