"""Sweeps: thousands of independent IK problems from one YAML file, in-process or on Dask (``redundik sweep``).

A sweep file (``sweeps/*.yaml``, format in :mod:`redundik.sweep.schema`) names a robot, a task template (a frame
position/pose task to a target, a posture in the null space), targets (grid, list or seeded random box) × start
configurations (home, listed, seeded random), a resolver (``pinv`` or ``wqp``) and a convergence rule. Each problem
iterates the differential IK from its start at a fixed dt until ‖e‖ < tol, a stall or ``max_iterations``; chunks
of problems go through :class:`redundik.resolvers.batch.BatchResolver` (one step of all active problems at once).

``method: solve_ik`` in the file solves each problem with :func:`redundik.solve_ik` instead (Levenberg–Marquardt
within the joint limits, random restarts): ``convergence.tol`` is its position tolerance [m], ``max_iterations``
the iterations of one attempt, and the ``ik`` block holds ``orientation_tolerance`` [rad] (pose axes; default
``tol``), ``max_restarts`` (default 20), ``timeout`` [s] per problem (default none: the table then depends only on
the file) and ``seed`` (problem p's restarts seeded with (seed, p)); ``dt``, the gains, the posture, ``stall`` and
the resolver are not used, the axes must be ``position`` or ``pose``. The default, ``method: differential``, is the
iteration above. Same columns either way (``qp_steps`` 0 under ``solve_ik``), plus ``restarts`` under ``solve_ik``.

Result columns (one row per problem, problem order): ``problem``, ``target_index``, ``start_index``,
``target_x/y/z`` [m], ``status`` (``converged``, ``stalled``, ``max_iterations``, ``failed``; under ``solve_ik``
``converged``, ``max_restarts``, ``timeout``), ``converged``,
``iterations`` (steps taken), ``qp_steps`` (steps that needed the QP backend), ``final_error`` [m, rad],
``manipulability`` √det(J Jᵀ) of the task rows at the end, ``limit_margin`` [fraction of the joint range, 0.5 =
mid-range], ``reached_x/y/z`` [m], ``start_q*`` and ``final_q*`` [rad, length unit].

>>> from redundik.sweep import load_sweep, run_sweep            # doctest: +SKIP
>>> result = run_sweep(load_sweep("sweeps/panda_reach.yaml"), dask="local:2")  # doctest: +SKIP
"""

from __future__ import annotations

from redundik.sweep.engine import SweepError, SweepResult, chunk_bounds, run_sweep
from redundik.sweep.plan import SweepPlan, load_sweep
from redundik.sweep.schema import MAX_PROBLEMS, SweepFileSpec
from redundik.sweep.solve import STATUSES, run_chunk

__all__ = [
    "MAX_PROBLEMS",
    "STATUSES",
    "SweepError",
    "SweepFileSpec",
    "SweepPlan",
    "SweepResult",
    "chunk_bounds",
    "load_sweep",
    "run_chunk",
    "run_sweep",
]
