"""Named layouts of the arrays ``hqp``'s kernels share with :mod:`redundik.resolvers.qp.hqp`: which row, column or
entry of a packed array holds what. Constants only (the kernels compile them in; no numba here).

The records the kernels take (tuples of arrays, unpacked inside the compiled code at no cost):

* the cascade's rows ``rows`` = (A, b, w, C, d, z, meta): the least-squares rows of every level stacked (A, b, the
  row weights w), the inequality rows C q̇ ≤ d, the null-space objective's target z and the ``meta`` table
  (``META_*`` rows: the levels' first rows in A and C, their kinds);
* the joint-limit arguments ``limits`` = (iq, lo, hi, vmax, amax, position, has_rate, gain) of ``kernels.limit_box``
  (``LimitBox.kernel_args``);
* the constrained cascade's work arrays ``work`` = (Z, N, F, f, slack, state, free, sel) (``_Plan.cascade_buffers``)
  and its outputs ``outs`` = (x, stats, rfac, qbuf); daqp's C call ``native`` = (ctl, nx).
"""

from __future__ import annotations

import numpy as np

#: Rows of the ``meta`` table (3, L + 1): per level its first least-squares row (entry L: the rows in all), its first
#: inequality row, and its kind (first L entries).
META_LS, META_INEQ, META_KIND = 0, 1, 2
#: Level kinds in row ``META_KIND`` of ``meta``.
SKIP, NULL_OBJECTIVE, LEAST_SQUARES = 0, 1, 2
#: Entries of the ``params`` array of ``closed_cascade``: ε, λ_max, rcond, the feasibility tolerance, and 1 to take
#: the SVD at every level (0: a certified QR where nothing is damped).
PARAM_EPSILON, PARAM_MAX_DAMPING, PARAM_RCOND, PARAM_TOL, PARAM_EXACT = range(5)
#: Columns of the per-level ``stats`` array of ``closed_cascade``.
SIGMA_MIN, DAMPING, RANK, FREE = 0, 1, 2, 3
#: Rows of ``closed_step``'s ``out`` (7, 1, n): the limit box (lb, ub, the position bounds), the cascade's q̇, q̇
#: clipped to the box (returned) and its copy (kept).
OUT_LB, OUT_UB, OUT_POS_LO, OUT_POS_HI, OUT_CASCADE, OUT_DQ, OUT_KEPT = range(7)
OUT_ROWS = 7

#: Slots of the header of a fused plan's ``ints`` (the layout of ``fused.HEADER``, written by ``FusedPlan._pack``):
#: the counts K (frame tasks), J (level joint tasks), N (null-space terms), m (rows of e), nv, nq; the offsets in
#: ``ints`` of the frame rows, their starts (K + 1), the joint rows, their starts (J + 1), the joint flags (J), the q
#: index per velocity coordinate (nv); the offset in ``floats`` of the joint targets (J × nq).
H_K, H_J, H_N, H_M, H_NV, H_NQ = range(6)
H_FRAME_ROWS, H_FRAME_STARTS, H_JOINT_ROWS, H_JOINT_STARTS, H_JOINT_FLAGS, H_IQ = 7, 8, 10, 11, 12, 13
H_JOINT_TARGETS = 17

#: Words (int64) of the ``native`` array of ``native_quadprog``: the address of daqp's ``daqp_quadprog`` (0: no
#: native call), of its settings, the smallest n of a bounds-only QP the backend splits (never solved here), the
#: level QPs solved and their iterations (counted by ``qp_cascade_run``), the last level so solved; then daqp's
#: ``DAQPProblem`` (10 words) and ``DAQPResult`` (8 words) structs, then the constraints' ``sense`` (int32).
NAT_FN, NAT_SETTINGS, NAT_SPLIT_MIN, NAT_SOLVED, NAT_ITERS, NAT_LAST = range(6)
NAT_PROBLEM, NAT_RESULT, NAT_SENSE = 8, 18, 26

#: Entries of the ``cfg`` array of ``qp_cascade_run``.
(CFG_EPSILON, CFG_MAX_DAMPING, CFG_RCOND, CFG_REGULARIZATION, CFG_SLACK_TOL, CFG_FEASIBLE, CFG_IDENTITY, CFG_SHORTCUT,
 CFG_CONTRADICTION, CFG_COMPLEMENT_MIN_N, CFG_COMPLEMENT_FRACTION, CFG_CERTIFIED_QR) = range(12)  # fmt: skip
#: Entries of the ``state`` array of ``qp_cascade_run``: the basis mode (0: Z = I, 1: I on the free joints,
#: 2: the basis Z), r (its columns), the fixed rows so far, the pending level's null-basis columns, whether the
#: pending level solved a least squares (its basis then shrinks to Z·N), the number of free joints (``sel``),
#: whether a level's slack exceeded the contradiction tolerance, the variables of the level QP's step and its
#: equality rows.
ST_MODE, ST_R, ST_NF, ST_NCOLS, ST_LSQ, ST_NSEL, ST_CONTRADICTED, ST_NU, ST_NEQ = range(9)
#: Basis modes (``state[ST_MODE]``): Z = I, I on the free joints, the basis Z (n, r), or its complement W (n − r, n)
#: (orthonormal rows, kept in the rows of the ``Z`` buffer: the free directions are null(W)). A level of least
#: squares goes over to the complement mode when n ≥ ``cfg[CFG_COMPLEMENT_MIN_N]`` and the complement it leaves —
#: the directions fixed so far plus its rows — times ``cfg[CFG_COMPLEMENT_FRACTION]`` is at most n (a fraction of 0:
#: whenever it has fewer rows than n).
IDENTITY_BASIS, SELECTION_BASIS, GENERAL_BASIS, COMPLEMENT_BASIS = 0, 1, 2, 3
#: Columns of the ``stats`` array of ``qp_cascade_run``, per level: σ_min, damping λ, rank of A_k Z, free
#: directions r before the level, projected (1: the basis was a general Z), solved (1: a least squares was solved:
#: the record of ``HierarchicalQPResolver._record``), the worst slack w_k* of its inequality rows.
QS_SIGMA, QS_DAMPING, QS_RANK, QS_FREE, QS_PROJECTED, QS_SOLVED, QS_WORST = range(7)
QS_COLUMNS = 7
#: Values ``qp_cascade_run`` returns first: the cascade is done, or a level QP waits in ``qbuf`` for the backend.
CASCADE_DONE, CASCADE_LEVEL_QP = 0, 1

#: The records' types (for the annotations): two rows arrays (C, d) or (F, f); the box (lb, ub, free); a level's
#: least squares (M, rhs, ε) and, posed in joint space, (M, rhs, ε, diagonal); a basis (Z, mode, sel).
Rows = tuple[np.ndarray, np.ndarray]
Box = tuple[np.ndarray, np.ndarray, np.ndarray]
LeastSquares = tuple[np.ndarray, np.ndarray, float]
JointLeastSquares = tuple[np.ndarray, np.ndarray, float, float]
Basis = tuple[np.ndarray, int, np.ndarray]
#: The cascade's rows (A, b, w, C, d, z, meta); the constrained cascade's work arrays (Z, N, F, f, slack, state,
#: free, sel), its outputs (x, stats, rfac, qbuf), where it resumes (k0, absorb, u), daqp's C call (ctl, nx).
CascadeRows = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Work = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Outs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
Resume = tuple[int, bool, np.ndarray]
Native = tuple[np.ndarray, np.ndarray]
#: The joint limits as ``JointLimits.kernel_args`` gives them: (iq, lo, hi, vmax, amax, position, has_rate, gain)
#: (``closed_step`` passes the four rows to ``box_kernels.limit_box`` as its ``lim`` record).
LimitArgs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool, bool, float]
