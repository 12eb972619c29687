"""The constrained cascade's entry from Python (``hqp_kernels.qp_cascade_call``): its work arrays and outputs as
parts of a few flat blocks, so that the call unboxes few arrays (each argument costs numba about 60 ns, an array
inside a tuple more), made into :func:`~redundik.resolvers.hqp_cascade.qp_cascade_run`'s records in compiled code.

* ``fwork`` (float): Z (n, n), N (n, n), the fixed rows F (cap, n), f (cap,) and the slacks (cap,);
* ``iwork`` (int64): the cascade's ``state`` (``hqp_layout.ST_*``), then ``sel`` (n,);
* ``out`` (float): q̇ (n,), the per-level ``stats`` (L, 7) and ``rfac`` (L, r²).

Python holds views of the same parts, sliced in Python (``_Plan.cascade_buffers``, ``_Plan.cascade_outputs``: a
compiled call returning them would box each array).
"""

from __future__ import annotations

import numpy as np

from redundik.resolvers.hqp_cascade import qp_cascade_run
from redundik.resolvers.hqp_layout import QS_COLUMNS, ST_NEQ
from redundik.resolvers.kernels import _jit

__all__ = ["cascade_out_views", "cascade_work_views", "qp_cascade_call"]

#: Entries of ``state`` (``ST_MODE`` … ``ST_NEQ``), the first part of ``iwork``.
STATE_SIZE = ST_NEQ + 1


def cascade_work_sizes(n: int, cap: int) -> tuple[int, int]:
    """Lengths of ``fwork`` and ``iwork`` for n joints and ``cap`` fixed (inequality) rows."""
    return 2 * n * n + cap * (n + 2), STATE_SIZE + n


@_jit
def cascade_work_views(
    fwork: np.ndarray, iwork: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Z, N, F, f, slack, state, sel): the parts of ``fwork`` and ``iwork`` (views; the row capacity is read from
    ``fwork``'s length)."""
    cap = (fwork.shape[0] - 2 * n * n) // (n + 2)
    a = n * n
    b = a + n * n
    c = b + cap * n
    return (
        fwork[0:a].reshape((n, n)),
        fwork[a:b].reshape((n, n)),
        fwork[b:c].reshape((cap, n)),
        fwork[c : c + cap],
        fwork[c + cap : c + 2 * cap],
        iwork[0:STATE_SIZE],
        iwork[STATE_SIZE : STATE_SIZE + n],
    )


@_jit
def cascade_out_views(out: np.ndarray, n: int, levels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x (n,), stats (levels, 7), rfac (levels, r²)): the parts of ``out`` (views)."""
    a = n + levels * QS_COLUMNS
    r_size = (out.shape[0] - a) // levels if levels > 0 else 0
    return out[0:n], out[n:a].reshape((levels, QS_COLUMNS)), out[a : a + levels * r_size].reshape((levels, r_size))


@_jit
def qp_cascade_call(
    A: np.ndarray, b: np.ndarray, w: np.ndarray, C: np.ndarray, d: np.ndarray, z: np.ndarray, meta: np.ndarray,
    mixed: np.ndarray, lb: np.ndarray, ub: np.ndarray, cfg: np.ndarray, fwork: np.ndarray, iwork: np.ndarray,
    free: np.ndarray, out: np.ndarray, qbuf: np.ndarray, k0: int, absorb: bool, u: np.ndarray, ctl: np.ndarray,
    nx: np.ndarray,
) -> tuple[int, int, int, int, float]:  # fmt: skip
    """:func:`qp_cascade_run` for a caller in Python (the loop calls it once per level QP the backend solves): the
    records made here from the blocks (module docstring) and the arrays given one by one."""
    n = A.shape[1]
    Z, N, F, f, slack, state, sel = cascade_work_views(fwork, iwork, n)
    x, stats, rfac = cascade_out_views(out, n, meta.shape[1] - 1)
    return qp_cascade_run(
        (A, b, w, C, d, z, meta), mixed, (lb, ub), cfg, (Z, N, F, f, slack, state, free, sel), (x, stats, rfac, qbuf),
        (k0, absorb, u), (ctl, nx),
    )  # fmt: skip
