"""Checks of the numbers given to a robot's methods (a configuration, a velocity, a step): what was wrong, named,
as a :class:`~redundik.errors.ModelError`, never NumPy's or Pinocchio's own exception."""

from __future__ import annotations

import math

import numpy as np

from redundik.errors import ModelError, short_repr


def finite_real(value: object, what: str, low: float | None = None) -> float:
    """``value`` as a float when it is a finite real number (not a bool) ≥ ``low``, else a :class:`ModelError`
    naming ``what`` (an int beyond the float range too: out of range, not an ``OverflowError``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"{what} must be a real number, got {type(value).__name__} {short_repr(value)}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the float range
        x = math.inf
    if not math.isfinite(x) or (low is not None and x < low):
        rule = "a finite number" if low is None else f"a finite number ≥ {low:g}"
        raise ModelError(f"{what} must be {rule} (within the float range), got {short_repr(value)}")
    return x


def reals(value: object, what: str) -> np.ndarray:
    """``value`` as a 1-D float array of real numbers (no bool, complex or text: never cast; a vector, or a matrix of
    one row or one column), else a ModelError."""
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "fiuO" or value is None:
            raise TypeError(f"dtype {raw.dtype}")
        if raw.ndim > 1 and max(raw.shape) != raw.size:  # (nq,), (1, nq) or (nq, 1); never a (3, 3) for nq = 9
            raise ValueError(f"shape {raw.shape}")
        return np.asarray(raw, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{what}, got {type(value).__name__} ({exc})") from None
