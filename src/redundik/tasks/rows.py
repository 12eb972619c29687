"""The row protocol's compiled form: a task whose rows a compiled writer gives (``CompiledRows``).

A task gives its rows one way — J (m, nv), e (m,) and v = v_d + K e (m,), eq. (5.6) — and a step takes them either
from its Python :meth:`~redundik.tasks.base.Task.evaluate` or, when the task declares
:meth:`~redundik.tasks.base.Task.compiled_rows`, from its compiled writer, called inside the resolver's compiled step
with Pinocchio's poses and joint Jacobians. :class:`CompiledTask` derives ``evaluate`` from the writer, so the
per-task path and the compiled step run the same formula.

A task of your own in one file (the tutorial "A task of your own"): subclass :class:`CompiledTask`, write the kernel
with ``numba.njit``, and return it with its data from ``compiled_rows``.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.memory import jacobian_view, se3_vector_view
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledRows, Task, TaskTerm

__all__ = ["CompiledRows", "CompiledTask", "kinematic_views", "write_rows", "writer_problems"]


def kinematic_views(robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """(poses (nframes, 12), jw (6, nv)) of ``robot`` at its last update, in the layout of :class:`CompiledRows`:
    views on Pinocchio's memory (verified once per ``robot.data``), or copies when the layout could not be
    verified."""
    data = robot.data
    cached = robot.__dict__.get("_redundik_views")
    if cached is not None and cached[0] is data:
        return cached[1], cached[2]
    poses, jw = se3_vector_view(data.oMf), jacobian_view(data)
    if poses is None or jw is None:  # not laid out as checked: copies, every call
        poses = np.array(
            [np.concatenate([np.asarray(M.rotation).reshape(-1, order="F"), M.translation]) for M in data.oMf]
        )
        jw = np.array(data.J, dtype=float).reshape(6, robot.nv)
        return poses, jw
    robot.__dict__["_redundik_views"] = (data, poses, jw)
    return poses, jw


def write_rows(
    form: CompiledRows, robot: RobotModel, t: float, gain: float, J: np.ndarray, e: np.ndarray, v: np.ndarray
) -> None:
    """Call ``form``'s writer at the robot's current (updated) state: J (rows, nv) zeros on entry, e and v (rows,)."""
    poses, jw = kinematic_views(robot)
    form.kernel(robot.q, float(t), poses, jw, form.ints, form.floats, float(gain), J, e, v)


class CompiledTask(Task):
    """A task whose rows its compiled writer gives (:meth:`compiled_rows`); :meth:`evaluate` calls the same writer.

    A subclass implements :meth:`compiled_rows` (and ``__repr__``); a resolver's compiled step calls the writer itself
    (``result.info["path"] == "compiled"``), the per-task path through :meth:`evaluate`.
    """

    @abstractmethod
    def compiled_rows(self, robot: RobotModel) -> CompiledRows | None:
        """The writer and its data on ``robot`` (:class:`CompiledRows`)."""

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        """The rows the compiled writer gives at ``t`` [s] (``robot`` updated)."""
        form = check_form(self, self.compiled_rows(robot))
        rows = int(form.rows)
        J = np.zeros((rows, robot.nv))
        e, v = np.zeros(rows), np.zeros(rows)
        write_rows(form, robot, t, self.gain, J, e, v)
        return TaskTerm(self.name, J, v, e, self.weight)


def writer_problems(form: Any) -> list[str]:
    """What is wrong with a compiled writer's ``kernel``, ``ints`` and ``floats`` (a callable, 1-D int64 and float64
    arrays): the checks :func:`check_form` and ``potential_rows.check_gradient_form`` share."""
    problems = [] if callable(form.kernel) else ["kernel is not callable"]
    for field, dtype in (("ints", np.int64), ("floats", np.float64)):
        arr = getattr(form, field)
        if not (isinstance(arr, np.ndarray) and arr.dtype == dtype and arr.ndim == 1):
            problems.append(f"{field} must be a 1-D {np.dtype(dtype).name} array")
    return problems


def check_form(task: Any, form: Any) -> CompiledRows:
    """``form`` if it is a well-made :class:`CompiledRows` (a callable kernel, rows ≥ 0, 1-D int64 and float64
    arrays); a :class:`TaskError` naming the task and what was wrong otherwise."""
    name = getattr(task, "name", type(task).__name__)
    if form is None:
        raise TaskError(f"task '{name}': compiled_rows returned None; a CompiledTask must give its writer")
    if not isinstance(form, CompiledRows):
        raise TaskError(f"task '{name}': compiled_rows must return a CompiledRows or None, got {type(form).__name__}")
    problems = writer_problems(form)
    if isinstance(form.rows, bool) or not isinstance(form.rows, (int, np.integer)) or int(form.rows) < 0:
        problems.append(f"rows must be an integer ≥ 0, got {form.rows!r}")
    if problems:
        raise TaskError(f"task '{name}': compiled_rows: " + "; ".join(problems))
    return form
