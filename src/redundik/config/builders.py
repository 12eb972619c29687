"""Typed YAML entries (``type: ...``) → core objects: main tasks, trajectories, potentials, monitors.

The registries (:data:`TASKS`, :data:`TRAJECTORIES`, :data:`POTENTIALS`, :data:`MONITORS`) map a ``type`` name
to a model and a builder; the checks here (frame and joint names, axes, vector lengths) raise
:class:`~redundik.errors.ConfigError` with the key path. Types are registered from the library's constructors by
:func:`redundik.config.registry.register` (the library's own in :mod:`redundik.config.types`); a hand-written model
and builder can still be added with :func:`register_potential`, :func:`register_task` or
:func:`register_trajectory`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np
from pydantic import BaseModel

from redundik.config.robot import angle_scale
from redundik.config.yamlio import join_path, validate
from redundik.errors import ConfigError, RedundikError, short_repr
from redundik.kinematics import RobotModel
from redundik.tasks import (
    Potential,
    Task,
)
from redundik.tasks.frame import resolve_axes
from redundik.tasks.trajectory import Trajectory

T = TypeVar("T")


@dataclass(frozen=True)
class Context:
    """What builders need: the robot and the angle unit of the file being read."""

    robot: RobotModel
    angle_unit: str = "rad"
    world: Any = None  # the task file's collision world (redundik.collision.CollisionWorld), if it has one

    @property
    def scale(self) -> float:
        """Factor from the file's angle unit to radians."""
        return angle_scale(self.angle_unit)


@dataclass(frozen=True)
class Kind(Generic[T]):
    """One ``type:`` of a registry: its model and the builder ``(spec, name, context, path) -> object``."""

    model: type[BaseModel]
    build: Callable[[Any, str, Context, str], T]


# ---------------------------------------------------------------------------------------------------- checks
def check_frame(ctx: Context, name: str, path: str) -> str:
    """Return ``name`` if the robot has such a frame.

    Raises:
        ConfigError: at ``path``, listing the available frames.
    """
    if not ctx.robot.model.existFrame(name):
        names = [n for n in ctx.robot.frame_names if n != "universe"]
        shown = ", ".join(names) if len(names) <= 40 else ", ".join(names[:40]) + f", ... ({len(names)} in all)"
        raise ConfigError(f"frame '{name}' does not exist; available: {shown}", path)
    return name


def check_joint(ctx: Context, name: str, path: str) -> str:
    """Return ``name`` if the robot has such a 1-dof joint.

    Raises:
        ConfigError: at ``path``, listing the joints.
    """
    names = [j.name for j in ctx.robot.joints if j.idx_q >= 0]
    if name not in names:
        raise ConfigError(f"joint '{name}' does not exist; available: {', '.join(names)}", path)
    return name


def check_axes(axes: Any, path: str, position_only: bool = False) -> tuple[str, ...]:
    """Axis names from ``pose``/``position``/``orientation``/``planar`` or a list of x, y, z, rx, ry, rz."""
    if not isinstance(axes, (str, list)) or (isinstance(axes, list) and not all(isinstance(a, str) for a in axes)):
        raise ConfigError(f"expected an axis-set name or a list of axis names, got {short_repr(axes)}", path)
    try:
        out = resolve_axes(axes)
    except RedundikError as exc:
        raise ConfigError(str(exc), path) from None
    if position_only and any(a not in ("x", "y", "z") for a in out):
        raise ConfigError(f"expected position axes among x, y, z, got {list(out)}", path)
    return out


def check_length(values: Sequence[float], n: int, path: str, what: str = "") -> np.ndarray:
    """``values`` as an array of length ``n``.

    Raises:
        ConfigError: wrong length.
    """
    if len(values) != n:
        raise ConfigError(f"expected {n} values{what}, got {len(values)}", path)
    return np.asarray(values, dtype=float)


def frame_list(value: Any, ctx: Context, path: str) -> list[str]:
    """One frame name or a list of them, each checked."""
    frames = [value] if isinstance(value, str) else list(value)
    if not frames:
        raise ConfigError("expected at least one frame", path)
    if isinstance(value, str):
        return [check_frame(ctx, value, path)]
    return [check_frame(ctx, f, join_path(path, i)) for i, f in enumerate(frames)]


def _wrap(path: str, make: Callable[[], T]) -> T:
    """Call a core constructor; its :class:`RedundikError` becomes a :class:`ConfigError` at ``path``."""
    try:
        return make()
    except ConfigError:
        raise
    except RedundikError as exc:
        raise ConfigError(str(exc), path) from None


def build_typed(registry: dict[str, Kind[T]], raw: Any, name: str, ctx: Context, path: str, what: str) -> T:
    """Validate a ``type:``-tagged mapping against its registry entry and build it.

    Raises:
        ConfigError: not a mapping, missing or unknown ``type`` (lists the known ones), or any invalid field.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"expected a mapping with a 'type' key, got {short_repr(raw)}", path)
    kind = raw.get("type")
    if kind is None:
        raise ConfigError(f"missing 'type'; {what} types: {', '.join(registry)}", path)
    if not isinstance(kind, str) or kind not in registry:
        got = short_repr(kind)
        raise ConfigError(f"unknown {what} type {got}; available: {', '.join(registry)}", join_path(path, "type"))
    entry = registry[kind]
    spec = validate(entry.model, raw, path)
    return entry.build(spec, name, ctx, path)


# ---------------------------------------------------------------------------------------------------- registries
#: ``type:`` name → entry (a :class:`redundik.config.registry.YamlType`, or a hand-written :class:`Kind`), per section.
#: Filled by :mod:`redundik.config.types` (imported at the end of this module) through
#: :func:`redundik.config.registry.register`.
TRAJECTORIES: dict[str, Kind[Trajectory]] = {}
TASKS: dict[str, Kind[Task]] = {}
POTENTIALS: dict[str, Kind[Potential]] = {}
#: Monitor-only types (everything in :data:`POTENTIALS` can also be a monitor).
MONITORS: dict[str, Kind[Any]] = {}


def task_name(raw: Any, index: int) -> str:
    """The name a main-task entry will have: its ``name``, else its ``frame``, else its type."""
    if isinstance(raw, dict):
        for key in ("name", "frame"):
            val = raw.get(key)
            if isinstance(val, (str, int)) and not isinstance(val, bool):
                return str(val)
        if isinstance(raw.get("type"), str):
            return str(raw["type"])
    return f"task{index}"


# ---------------------------------------------------------------------------------------------------- monitors
@dataclass
class TorqueMonitor:
    """Logs τ = JᵀF (the chapter's statics) for a Cartesian load F on the stacked frame Jacobians.

    Attributes:
        name: Monitor name.
        frames: Frames whose Jacobians are stacked.
        rows: Jacobian rows used (from ``axes``).
        force: F, shape (len(frames)·len(rows),).
    """

    name: str
    frames: list[str]
    rows: np.ndarray
    force: np.ndarray

    def torques(self, robot: RobotModel) -> np.ndarray:
        """τ = JᵀF at the robot's current (updated) state, shape (nv,)."""
        J = np.vstack([robot.frame_jacobian(f)[self.rows] for f in self.frames])
        return J.T @ self.force


#: Hand-written registrations (a pydantic model and a builder), for types whose YAML form cannot be derived from a
#: constructor; :func:`redundik.config.registry.register` is the usual way.
def register_potential(type_name: str, model: type[BaseModel], build: Callable[..., Potential]) -> None:
    """Make ``type: type_name`` available under ``potentials:`` and ``monitors:``."""
    POTENTIALS[type_name] = Kind(model, build)


def register_task(type_name: str, model: type[BaseModel], build: Callable[..., Task]) -> None:
    """Make ``type: type_name`` available under ``main:``."""
    TASKS[type_name] = Kind(model, build)


def register_trajectory(type_name: str, model: type[BaseModel], build: Callable[..., Trajectory]) -> None:
    """Make ``type: type_name`` available as a frame task's ``trajectory``."""
    TRAJECTORIES[type_name] = Kind(model, build)


# the library's own types (at the end: redundik.config.types uses the checks above)
from redundik.config import types as _types  # noqa: E402, F401
