"""Smoothness of a run's joint motion: accelerations, jerks and chatter from the applied q̇ (``summary.json``, CSV).

Definitions (q̇_0 … q̇_(M−1): the q̇ the resolver returned at the M steps, each applied for dt [s]):

* acceleration q̈_k = (q̇_k − q̇_(k−1))/dt [rad/s² or m/s²], jerk j_k = (q̈_k − q̈_(k−1))/dt [rad/s³], per joint,
  for k = 0 … M−1; with ``from_rest`` (the default, and the runs' convention: a run starts at rest) q̇_(−1) =
  q̇_(−2) = 0, so the first step's jump from rest counts; without it they start at k = 1 and k = 2;
* ``max_abs_ddq`` / ``max_abs_jerk``: the largest |q̈_k,i| / |j_k,i| over steps and joints;
* chatter of joint i [1/s]: the number of sign changes of q̈_·,i divided by the run's duration M·dt, where the
  entries with |q̈_k,i| ≤ max(``atol``, ``rtol``·max_k |q̈_k,i|) count as zero and are skipped (a dead band:
  rounding noise around a constant velocity is not chatter; + 0 − is one change, + 0 + none). A joint that
  brakes and accelerates once has 1 change; one that alternates every step has about 1/dt per second.

Per-sample columns for the CSV (``columns``): ``max_abs_ddq`` and ``max_abs_jerk`` over the joints at each step, and
``ddq_sign_changes``, the number of joints whose q̈ changed sign at that step (their sum over the run divided by
M·dt is the sum of the joints' chatter); empty on the last sample, which has no step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: Dead band of the chatter count: absolute [rad/s²] and relative to the joint's largest |q̈| [-].
ATOL, RTOL = 1e-9, 1e-6


def _history(dq: np.ndarray, from_rest: bool, extra: int) -> np.ndarray:
    dq = np.asarray(dq, dtype=float)
    if dq.ndim != 2:
        raise ValueError(f"smoothness: q̇ must be an (M, nv) array, got shape {dq.shape}")
    if not from_rest:
        return dq
    return np.vstack([np.zeros((extra, dq.shape[1])), dq])


def accelerations(dq: np.ndarray, dt: float, from_rest: bool = True) -> np.ndarray:
    """q̈ [rad/s²] of the q̇ sequence ``dq`` (M, nv): (M, nv) from rest, else (M − 1, nv)."""
    return np.diff(_history(dq, from_rest, 1), axis=0) / dt


def jerks(dq: np.ndarray, dt: float, from_rest: bool = True) -> np.ndarray:
    """Jerk [rad/s³] of ``dq`` (M, nv): (M, nv) from rest, else (M − 2, nv)."""
    return np.diff(_history(dq, from_rest, 2), n=2, axis=0) / (dt * dt)


def _signs(ddq: np.ndarray, atol: float, rtol: float) -> np.ndarray:
    """−1, 0, +1 per entry of ``ddq`` (K, nv), 0 inside the dead band."""
    peak = np.max(np.abs(ddq), axis=0, initial=0.0)
    band = np.maximum(atol, rtol * peak)
    return np.where(ddq > band, 1, np.where(ddq < -band, -1, 0))


def sign_change_steps(ddq: np.ndarray, atol: float = ATOL, rtol: float = RTOL) -> np.ndarray:
    """(K, nv) booleans: q̈_k,i has the opposite sign of the last q̈_·,i outside the dead band before it."""
    s = _signs(np.asarray(ddq, dtype=float), atol, rtol)
    out = np.zeros(s.shape, dtype=bool)
    last = np.zeros(s.shape[1], dtype=int)
    for k in range(s.shape[0]):
        row = s[k]
        out[k] = (row != 0) & (last != 0) & (row != last)
        last = np.where(row != 0, row, last)
    return out


def chatter(dq: np.ndarray, dt: float, from_rest: bool = True, atol: float = ATOL, rtol: float = RTOL) -> np.ndarray:
    """Sign changes of q̈ per joint per second [1/s] (module docstring), shape (nv,); zeros for an empty run."""
    steps = np.asarray(dq).shape[0]
    if steps == 0:
        return np.zeros(np.asarray(dq).shape[1] if np.asarray(dq).ndim == 2 else 0)
    changes = sign_change_steps(accelerations(dq, dt, from_rest), atol, rtol).sum(axis=0)
    return changes / (steps * dt)


def summary(dq: np.ndarray, dt: float, joint_names: Sequence[str], from_rest: bool = True) -> dict[str, Any]:
    """The ``smoothness`` entry of a run's summary: ``max_abs_ddq``, ``max_abs_jerk``, ``chatter_per_s`` (max and
    mean over the joints, and the joint with the most), ``chatter_by_joint``, ``from_rest``."""
    dq = np.asarray(dq, dtype=float)
    acc = accelerations(dq, dt, from_rest)
    jrk = jerks(dq, dt, from_rest)
    rate = chatter(dq, dt, from_rest)
    worst = int(np.argmax(rate)) if rate.size else -1
    return {
        "max_abs_ddq": float(np.max(np.abs(acc), initial=0.0)),
        "max_abs_jerk": float(np.max(np.abs(jrk), initial=0.0)),
        "chatter_per_s": {
            "max": float(rate[worst]) if rate.size else 0.0,
            "mean": float(np.mean(rate)) if rate.size else 0.0,
            "joint": joint_names[worst] if rate.size else None,
        },
        "chatter_by_joint": {name: float(r) for name, r in zip(joint_names, rate, strict=True)},
        "from_rest": from_rest,
    }


def columns(dq: np.ndarray, dt: float, samples: int, from_rest: bool = True) -> list[tuple[str, np.ndarray]]:
    """The per-sample CSV columns (module docstring) for a run of ``samples`` samples (``dq``: its M = samples − 1
    applied q̇); NaN where a value is not defined."""
    dq = np.asarray(dq, dtype=float)
    out = []
    acc = accelerations(dq, dt, from_rest)
    jrk = jerks(dq, dt, from_rest)
    flips = sign_change_steps(acc).sum(axis=1).astype(float)
    for name, values in (
        ("max_abs_ddq", np.max(np.abs(acc), axis=1, initial=0.0)),
        ("max_abs_jerk", np.max(np.abs(jrk), axis=1, initial=0.0)),
        ("ddq_sign_changes", flips),
    ):
        col = np.full(samples, np.nan)
        col[dq.shape[0] - values.shape[0] : dq.shape[0]] = values  # aligned on the step that applied q̇_k
        out.append((name, col))
    return out
