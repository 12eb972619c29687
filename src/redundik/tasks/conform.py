"""The one check of what a user's Python code returns to a step — a task's term, a potential's value, a barrier's
rows: float64 arrays of the right shapes pass as they are; what NumPy reads as real numbers (lists, integers,
booleans, float32, objects holding floats) is converted; anything else (complex numbers, strings, misshapen rows, not
a term at all) is a :class:`~redundik.errors.TaskError` naming the task or subtask. Without it NumPy would drop an
imaginary part with a mere warning, or a numba kernel would fail on a list."""

from __future__ import annotations

import math
import sys

import numpy as np

from redundik._coldstart import HOT as _HOT
from redundik._coldstart import twins_of
from redundik._kernel_cache import KernelNamespace
from redundik.errors import TaskError, short_repr
from redundik.tasks.base import BarrierTerm, TaskTerm, check_term

#: The target writers' checks (``reference_status``), imported on first use; their twins during a cold start.
_TK = KernelNamespace("redundik.tasks.target_kernels")
#: ``target_kernels.NOT_RIGID`` (read here without importing numba).
_NOT_RIGID = 3
#: Largest |coordinate| [length unit of the model] of a target or a reference's position (the task files' bound on
#: numbers too): beyond it is a unit or sign mistake, whose error would only make every step fall back.
MAX_COORDINATE = 1e6
#: Largest |RRᵀ − I| entry of a target's or a reference's rotation.
RIGID_TOLERANCE = 1e-6
#: Largest weight a term may give (the largest float: an integer beyond it does not convert).
WEIGHT_MAX = sys.float_info.max

_F64 = np.dtype(np.float64)


def conform_term(term: TaskTerm, nv: int, task: object = None) -> TaskTerm:
    """``term`` with J (m, nv), v (m,) and error (m,) as float64 arrays: itself when they are, else a copy whose
    arrays are converted (a list, integers, float32: what NumPy reads as real numbers). The one check of a term a
    Python ``evaluate`` returned, on every path.

    Raises:
        TaskError: naming the task: not a ``TaskTerm``, complex or non-numeric entries, shapes that do not fit, or a
            weight that is not a finite number > 0 (as ``Task.weight``).
    """
    if type(term) is not TaskTerm and not isinstance(term, TaskTerm):
        who = f"task '{getattr(task, 'name', '?')}': " if task is not None else ""
        raise TaskError(f"{who}evaluate must return a TaskTerm (name, J, v, error, weight), got {short_repr(term)}")
    J, v, e, w = term.J, term.v, term.error, term.weight
    if (
        type(J) is np.ndarray and type(v) is np.ndarray and type(e) is np.ndarray
        and J.dtype is _F64 and v.dtype is _F64 and e.dtype is _F64
        and J.ndim == 2 and J.shape[1] == nv and v.shape == e.shape == (J.shape[0],)
        and (type(w) is float or type(w) is int) and 0.0 < w <= WEIGHT_MAX
    ):  # fmt: skip
        return term
    check_term(term, nv)  # (the shapes first: a message that names them)
    weight = term_weight(term)
    arrays = []
    for what, x in (("J", J), ("v", v), ("error", e)):
        try:
            arrays.append(real_array(x))
        except (TypeError, ValueError) as exc:
            raise TaskError(
                f"task '{term.name}': evaluate returned a {what} that is not real numbers ({exc}): "
                f"{short_repr(x)}; expected float arrays"
            ) from None
    return TaskTerm(term.name, arrays[0], arrays[1], arrays[2], weight)


def term_weight(term: TaskTerm) -> float:
    """A term's weight as a float when it is a finite number > 0 (what ``Task.weight`` accepts).

    Raises:
        TaskError: naming the task and the weight it gave.
    """
    try:
        w = real_value(term.weight)
    except (TypeError, ValueError, OverflowError):
        w = math.nan
    if not 0.0 < w <= WEIGHT_MAX:
        raise TaskError(
            f"task '{term.name}': evaluate returned the weight {short_repr(term.weight)}; expected a finite number > 0 "
            "(the weight of its rows among its level's, as Task.weight)"
        )
    return w


def real_array(x: object) -> np.ndarray:
    """``x`` as a float64 array when NumPy reads it as real numbers (floats, integers, booleans, a list of them,
    objects holding them); its own object when it already is one.

    Raises:
        TypeError, ValueError: complex numbers, strings, ragged lists: not real numbers (NumPy would drop an
            imaginary part with a mere warning).
    """
    if type(x) is np.ndarray and x.dtype is _F64:
        return x
    a = np.asarray(x)
    if a.dtype.kind not in "biufO":
        raise TypeError(f"dtype {a.dtype}")
    return a.astype(np.float64)  # (objects: each must convert; a complex or a string does not)


def real_value(x: object) -> float:
    """A scalar (or a one-entry array) as a float; NaN passes (the resolvers' fallback names where it came from).

    Raises:
        TypeError, ValueError: not one real number.
    """
    if type(x) is float:
        return x
    a = real_array(x)
    if a.size != 1:
        raise ValueError(f"{a.size} values, shape {a.shape}")
    return float(a.reshape(-1)[0])


def conform_barrier_term(term: BarrierTerm, nv: int, owner: str) -> BarrierTerm:
    """``term`` with h (k,), H (k, nv) and γ (k,) or ``None`` as float64 arrays and k row names: itself when it is
    so, else a converted copy. NaN in h or H passes (the step's fallback names the subtask).

    Raises:
        TaskError: naming the subtask ``owner``: not a ``BarrierTerm``, rows that are not real numbers, shapes or
            a count of names that do not fit, a γ that is negative or not finite.
    """
    if not isinstance(term, BarrierTerm):
        raise TaskError(
            f"subtask '{owner}': the barrier's evaluate must return a BarrierTerm (h, H, names, gamma), got "
            f"{short_repr(term)}"
        )
    h, H, names, gamma = term.h, term.H, term.names, term.gamma
    if (
        type(h) is np.ndarray and type(H) is np.ndarray and h.dtype is _F64 and H.dtype is _F64
        and h.ndim == 1 and H.shape == (h.shape[0], nv) and type(names) is list and len(names) == h.shape[0]
        and gamma is None
    ):  # fmt: skip
        return term
    try:
        h, H = real_array(h), real_array(H)
        gamma = None if gamma is None else real_array(gamma)
    except (TypeError, ValueError) as exc:
        raise TaskError(f"subtask '{owner}': the barrier's h, H or gamma are not real numbers ({exc})") from None
    k = h.shape[0] if h.ndim == 1 else -1
    if k < 0 or H.shape != (k, nv) or (gamma is not None and gamma.shape != (k,)):
        raise TaskError(
            f"subtask '{owner}': the barrier gave h of shape {h.shape}, H of shape {H.shape}"
            f"{'' if gamma is None else f' and gamma of shape {gamma.shape}'}; expected h (k,), H (k, {nv}), gamma (k,)"
        )
    if isinstance(names, str) or not hasattr(names, "__len__") or len(names) != k:
        raise TaskError(f"subtask '{owner}': the barrier gave {k} rows and names {short_repr(names)}: one name per row")
    if gamma is not None and not (np.isfinite(gamma).all() and (gamma >= 0.0).all()):
        raise TaskError(f"subtask '{owner}': the barrier's gamma must be finite and ≥ 0 [1/s], got {short_repr(gamma)}")
    return BarrierTerm(h, H, [str(n) for n in names], gamma)


def conform_reference(ref: object, owner: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A trajectory's ``reference(t)`` as (p (3,) [length], R (3, 3), twist (6,) [length/s, rad/s]) float64
    arrays: as they are when they are so, else converted. NaN passes (the step's fallback names the task).

    Raises:
        TaskError: naming ``owner`` (the task): not three arrays, not real numbers, other shapes, R not a
            rotation (|RRᵀ − I| > 1e-6 or det R < 0).
    """
    p: object
    R: object
    twist: object
    try:
        p, R, twist = ref  # type: ignore[misc]
    except (TypeError, ValueError):
        raise TaskError(
            f"{owner}: its trajectory's reference(t) must return (p (3,), R (3, 3), twist (6,)), got {short_repr(ref)}"
        ) from None
    if not (
        type(p) is np.ndarray and type(R) is np.ndarray and type(twist) is np.ndarray
        and p.dtype is _F64 and R.dtype is _F64 and twist.dtype is _F64
        and p.shape == (3,) and R.shape == (3, 3) and twist.shape == (6,)
    ):  # fmt: skip
        try:
            p, R, twist = real_array(p), real_array(R), real_array(twist)
        except (TypeError, ValueError) as exc:
            raise TaskError(f"{owner}: its trajectory's reference is not real numbers ({exc})") from None
        if p.shape != (3,) or R.shape != (3, 3) or twist.shape != (6,):
            raise TaskError(
                f"{owner}: its trajectory's reference gave p of shape {p.shape}, R of shape {R.shape} and twist of "
                f"shape {twist.shape}; expected (3,), (3, 3) and (6,)"
            )
    tk = _TK if _HOT else twins_of(_TK)  # (their twins until a resolver's kernels are loaded: no compile here)
    # (any finite position is resolved as asked, as a compiled Line's is: the joint-speed cap and the divergence
    # watch see to what a huge one asks)
    if tk.reference_status(p, R, RIGID_TOLERANCE, math.inf) == _NOT_RIGID:
        raise TaskError(f"{owner}: its trajectory's reference rotation is not a rotation: {short_repr(R)}")
    return p, R, twist


def check_linear_gradient(lin: object, nv: int, nq: int, owner: str) -> tuple[np.ndarray, np.ndarray] | None:
    """A potential's ``linear_gradient`` answer — ``None``, or (w (nv,), q_c (nq,)) float64 arrays — returned as it
    is (a compiled step keeps them and tests their identity at each step; a float64 dtype compared by value: an
    unpickled array's is not NumPy's own object).

    Raises:
        TaskError: naming the subtask ``owner``: not a pair of float64 1-D arrays of those sizes.
    """
    if lin is None:
        return None
    w: object = None
    c: object = None
    if isinstance(lin, tuple) and len(lin) == 2:
        w, c = lin
    if not (
        isinstance(w, np.ndarray) and isinstance(c, np.ndarray) and w.dtype == _F64 and c.dtype == _F64
        and w.shape == (nv,) and c.shape == (nq,)
    ):  # fmt: skip
        raise TaskError(
            f"subtask '{owner}': its potential's linear_gradient must return (w, q_c), float64 arrays of shapes "
            f"({nv},) and ({nq},) (or None), got {short_repr(lin)}"
        )
    return w, c
