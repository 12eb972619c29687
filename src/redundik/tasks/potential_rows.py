"""The row protocol's compiled form for potentials: p(q) and η = ∂p/∂q from a compiled writer (``CompiledGradient``).

A potential gives p and η one way. When it declares :meth:`~redundik.tasks.base.Potential.compiled_gradient`, a
resolver's compiled step calls that writer for a gradient subtask's z = k η (eq. 5.8) instead of the Python
``gradient``; :class:`CompiledPotential` derives ``value`` and ``gradient`` from the same writer, so the per-task
path and the compiled step run one formula. A potential of your own: subclass :class:`CompiledPotential`, write the
kernel with ``numba.njit`` (``(q, poses, jw, ints, floats, eta) → p``), return it with its data from
``compiled_gradient``.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledGradient, Potential
from redundik.tasks.layouts import FP_AXES, FP_AXES_N, FP_FRAME, JP_FRAMES, JP_ROWS, JP_ROWS_N
from redundik.tasks.rows import kinematic_views, writer_problems

__all__ = [
    "CompiledGradient",
    "CompiledPotential",
    "compiled_writer",
    "frame_point_ints",
    "jacobian_product_ints",
    "supporting_columns",
]

#: The methods through which a potential gives p or η: a subclass that overrides one of them below the class that
#: defines its ``compiled_gradient`` has values of its own; the inherited writer is not used (:func:`compiled_writer`).
_FORMULA = ("value", "gradient", "value_and_gradient")


def supporting_columns(robot: RobotModel, fid: int) -> np.ndarray:
    """(nv,) int64: 1 on the velocity columns of the joints that support frame ``fid`` (the columns its Jacobian may
    have nonzero), 0 elsewhere."""
    model = robot.model
    columns = np.zeros(robot.nv, dtype=np.int64)
    for j in model.supports[model.frames[fid].parentJoint]:
        if j > 0:
            jm = model.joints[j]
            columns[jm.idx_v : jm.idx_v + jm.nv] = 1
    return columns


def frame_point_ints(robot: RobotModel, fid: int, rows: np.ndarray) -> np.ndarray:
    """The ``ints`` of a frame-point potential's writer (``tasks.layouts``' ``FP_*``): the frame id, the number of
    axes, the axes, then :func:`supporting_columns`."""
    head = np.zeros(FP_AXES, dtype=np.int64)
    head[FP_FRAME], head[FP_AXES_N] = fid, rows.shape[0]
    return np.concatenate([head, np.asarray(rows, dtype=np.int64), supporting_columns(robot, fid)])


def jacobian_product_ints(robot: RobotModel, fids: list[int], rows: np.ndarray) -> np.ndarray:
    """The ``ints`` of a potential of frame Jacobians and their derivatives (``tasks.layouts``' ``JP_*``): the
    number of frames and of rows, the rows, the frame ids, each frame's :func:`supporting_columns`, then
    ``RobotModel.support_mask`` (nv × nv, row-major)."""
    head = np.zeros(JP_ROWS, dtype=np.int64)
    head[JP_FRAMES], head[JP_ROWS_N] = len(fids), rows.shape[0]
    parts = [head, np.asarray(rows, dtype=np.int64), np.asarray(fids, dtype=np.int64)]
    parts += [supporting_columns(robot, fid) for fid in fids]
    parts.append(robot.support_mask().astype(np.int64).reshape(-1))
    return np.concatenate(parts)


def _definer(kind: type, name: str) -> type:
    """The class of ``kind``'s MRO whose body defines ``name``."""
    for klass in kind.__mro__:
        if name in vars(klass):
            return klass
    return object


def compiled_writer(potential: Any, robot: RobotModel) -> CompiledGradient | None:
    """``potential``'s compiled writer on ``robot``, checked (:func:`check_gradient_form`); ``None`` when it has none,
    or when a subclass overrides ``value``, ``gradient`` or ``value_and_gradient`` below the class that defines
    the writer (its numbers are its own: the writer it inherits would silently replace them)."""
    if not isinstance(potential, Potential):
        return None
    kind = type(potential)
    owner = _definer(kind, "compiled_gradient")
    if owner is Potential or any(not issubclass(owner, _definer(kind, m)) for m in _FORMULA):
        return None
    form = potential.compiled_gradient(robot)
    return None if form is None else check_gradient_form(potential, form)


def check_gradient_form(potential: Any, form: Any) -> CompiledGradient:
    """``form`` if it is a well-made :class:`CompiledGradient` (a callable kernel, 1-D int64 and float64 arrays); a
    :class:`TaskError` naming the potential and what was wrong otherwise."""
    name = getattr(potential, "name", type(potential).__name__)
    if not isinstance(form, CompiledGradient):
        raise TaskError(
            f"potential '{name}': compiled_gradient must return a CompiledGradient or None, got {type(form).__name__}"
        )
    problems = writer_problems(form)
    if problems:
        raise TaskError(f"potential '{name}': compiled_gradient: " + "; ".join(problems))
    return form


class CompiledPotential(Potential):
    """A potential whose p and η its compiled writer gives (:meth:`compiled_gradient`); :meth:`value`,
    :meth:`gradient` and :meth:`value_and_gradient` call the same writer."""

    @abstractmethod
    def compiled_gradient(self, robot: RobotModel) -> CompiledGradient | None:
        """The writer and its data on ``robot`` (:class:`CompiledGradient`)."""

    def value_and_gradient(self, robot: RobotModel) -> tuple[float, np.ndarray]:
        """(p, η) from the compiled writer at the robot's current (updated) state."""
        form = self.compiled_gradient(robot)
        if form is None:
            raise TaskError(f"potential '{self.name}': compiled_gradient returned None on this robot")
        form = check_gradient_form(self, form)
        eta = np.zeros(robot.nv)
        poses, jw = kinematic_views(robot)
        value = float(form.kernel(robot.q, poses, jw, form.ints, form.floats, eta))
        return value, eta

    def value(self, robot: RobotModel) -> float:
        return self.value_and_gradient(robot)[0]

    def gradient(self, robot: RobotModel) -> np.ndarray:
        return self.value_and_gradient(robot)[1]
