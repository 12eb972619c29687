"""A barrier's compiled form (``Barrier.compiled_barrier``, :class:`~redundik.tasks.base.CompiledBarrier`): found,
checked and called for a bound subtask's rows, in place of the barrier's Python ``evaluate``."""

from __future__ import annotations

import contextlib
import math
import weakref
from typing import Any

import numpy as np

from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import Barrier, CompiledBarrier
from redundik.tasks.potential_rows import _definer
from redundik.tasks.rows import kinematic_views, writer_problems

__all__ = ["barrier_values", "barrier_writer"]


#: Per barrier class: whether its compiled writer gives its rows (the class that defines ``compiled_barrier`` is
#: not above the one that defines ``evaluate``).
_WRITES: dict[type, bool] = {}
#: Per barrier: the last form found well made (a form of the same objects is not checked again); weak, so that it
#: lives as long as its barrier and is never copied or pickled with it.
_CHECKED: weakref.WeakKeyDictionary[Any, CompiledBarrier] = weakref.WeakKeyDictionary()


def barrier_writer(barrier: Any, robot: RobotModel) -> CompiledBarrier | None:
    """``barrier``'s compiled writer on ``robot``, checked; ``None`` when it has none, or when a subclass overrides
    ``evaluate`` below the class that defines the writer (its rows are its own: the writer it inherits would silently
    replace them).

    Raises:
        TaskError: a malformed form (not a ``CompiledBarrier``, a kernel that is not callable, data arrays of the
            wrong kind, a row count or names that do not agree, a negative or non-finite γ), naming the barrier.
    """
    kind = type(barrier)
    writes = _WRITES.get(kind)
    if writes is None:
        owner = _definer(kind, "compiled_barrier")
        writes = _WRITES[kind] = (
            issubclass(kind, Barrier) and owner is not Barrier and issubclass(owner, _definer(kind, "evaluate"))
        )
    if not writes:
        return None
    form = barrier.compiled_barrier(robot)
    if form is None:
        return None
    try:
        last = _CHECKED.get(barrier)
    except TypeError:  # (a barrier that cannot be a weak key: unhashable, or slots without a weak reference)
        last = None
    if (
        last is not None
        and type(form) is CompiledBarrier
        and form.kernel is last.kernel
        and form.ints is last.ints
        and form.floats is last.floats
        and form.names is last.names
        and form.rows == last.rows == len(form.names)
        and form.gamma == last.gamma
    ):
        return form
    name = getattr(barrier, "name", kind.__name__)
    if not isinstance(form, CompiledBarrier):
        raise TaskError(
            f"barrier '{name}': compiled_barrier must return a CompiledBarrier or None, got {type(form).__name__}"
        )
    problems = writer_problems(form)
    rows = form.rows
    if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or int(rows) < 0:
        problems.append(f"rows must be an integer ≥ 0, got {rows!r}")
    elif len(form.names) != int(rows):
        problems.append(f"names must give one name per row ({int(rows)}), got {len(form.names)}")
    gamma = form.gamma
    if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not (math.isfinite(gamma) and gamma >= 0):
        problems.append(f"gamma must be a finite number ≥ 0 [1/s] (0: the subtask's rate), got {gamma!r}")
    if problems:
        raise TaskError(f"barrier '{name}': compiled_barrier: " + "; ".join(problems))
    with contextlib.suppress(TypeError):
        _CHECKED[barrier] = form
    return form


def barrier_values(form: CompiledBarrier, robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """(h (rows,), H (rows, nv)) of ``form``'s writer at the robot's current (updated) state."""
    rows = int(form.rows)
    h, H = np.zeros(rows), np.zeros((rows, robot.nv))
    poses, jw = kinematic_views(robot)
    form.kernel(robot.q, poses, jw, form.ints, form.floats, h, H)
    return h, H
