"""Named layouts of the packed arrays the compiled steps share with the resolvers (no numba: the resolvers import
these names without loading the kernels).

* A joint-limit record ``lim`` (``LIM_ROWS``, nv; ``LIM_JERK_ROWS`` with the jerk limits) and a box's options
  ``opts`` (``joint_box``, ``limit_box``, ``jerk_box``, ``wqp_free_step``); the rows of ``jerk_box``'s ``out``;
* a ``wqp`` resolver's QP record ``qp`` (``QP_P`` + nv, nv): the joint-limit record, g and P of its fused step;
* a ``wqp`` step's ``out`` (``OUT_ROWS``, nv): the box, the unconstrained optimum, q̇ and the copy kept;
* the closed form's ``out`` (``CF_ROWS``, nv) (``kernels.closed_form_into``, ``pinv``'s step);
* the ``feedback`` law's ``out`` (``FB_ROWS``, nv), ``settings`` and ``report`` (``feedback_kernels.feedback_law``);
* the resolver's tail of a fused step's coefficients ``coef`` (``wqp``: ``WQP_TAIL`` entries; ``pinv``:
  ``PINV_TAIL``), after the plan's own coefficients;
* the header slots of a fused plan's ``ints`` that the ``wqp`` and ``pinv`` steps read (the plan,
  ``FusedPlan``, writes them: its ``HEADER`` comment is the reference).
"""

from __future__ import annotations

from redundik.tasks.layouts import REF as REF  # a reference row (p_d, R_d row-major, twist): the tasks' layout

#: Rows of a joint-limit record ``lim`` (4, nv): lower and upper position limits [rad or m] (±inf where none), the
#: velocity limits [rad/s or m/s] and the rate (acceleration) limits [rad/s² or m/s²] (inf where none).
LIM_LO, LIM_HI, LIM_VMAX, LIM_AMAX = 0, 1, 2, 3
LIM_ROWS = 4
#: A record with jerk limits (``JointLimits``' own, ``LIM_JERK_ROWS``, nv) adds the jerk limits [rad/s³ or m/s³]
#: (inf where none) as row ``LIM_JMAX`` (readers of the first ``LIM_ROWS`` rows take it as it is).
LIM_JMAX = 4
LIM_JERK_ROWS = 5

#: Rows of ``jerk_box``'s ``out`` (``JERK_ROWS``, nv): the box (lb, ub), the braking (viability) bounds and the
#: jerk window's ends [rad/s or m/s].
JERK_LB, JERK_UB, JERK_BRAKE_LO, JERK_BRAKE_HI, JERK_WINDOW_LO, JERK_WINDOW_HI = 0, 1, 2, 3, 4, 5
JERK_ROWS = 6

#: Entries of a box's options ``opts``: position limits apply (1.0/0.0), rate limits apply (1.0/0.0), the position
#: gain g [-] and dt [s] (``joint_box``); then, for ``wqp_free_step``, the diagonal shift of P and the scale of the
#: null-space objective z.
OPT_POSITION, OPT_RATE, OPT_GAIN, OPT_DT = 0, 1, 2, 3
BOX_OPTS = 4
OPT_SHIFT, OPT_Z_SCALE = 4, 5
WQP_OPTS = 6

#: Rows of a ``wqp`` step's ``out`` (``OUT_ROWS``, nv): the box (lb, ub, and the position parts of its bounds),
#: the unconstrained optimum, q̇, and the copy of q̇ the resolver keeps (its warm start and rate-window reference).
OUT_LB, OUT_UB, OUT_POS_LO, OUT_POS_HI, OUT_FREE, OUT_DQ, OUT_KEPT = 0, 1, 2, 3, 4, 5, 6
#: Rows of the box part of ``out`` (lb, ub, pos_lo, pos_hi).
OUT_BOX = 4
OUT_ROWS = 7

#: Rows of a ``wqp`` resolver's QP record ``qp`` (``QP_P`` + nv, nv), the fused step's: the joint-limit record
#: (``LIM_ROWS`` rows from ``QP_LIM``), the QP's linear term g (row ``QP_G``), the joints' 1 / speed cap [s/rad]
#: for the step's cap test (row ``QP_CAPS``; a negative first entry: no test in the step, ``SpeedLimiter.folded_caps``),
#: then its Hessian P (nv rows from ``QP_P``; the resolver's ``_P`` and ``_q`` are views on these rows).
QP_LIM = 0
QP_G = LIM_ROWS
QP_CAPS = LIM_ROWS + 1
QP_P = LIM_ROWS + 2

#: Rows of the closed form's ``out`` (``CF_ROWS``, nv): J⁺V, (I − J⁺J) z and q̇ (eq. 5.8).
CF_RANK, CF_NULL, CF_DQ = 0, 1, 2
CF_ROWS = 3

#: Rows of the ``feedback`` law's ``out`` (``FB_ROWS``, nv): J⁺V, P(N k + z), q̇ (eq. 5.15 and the law after it).
FB_RANK, FB_NULL, FB_DQ = 0, 1, 2
FB_ROWS = 3
#: Entries of its ``settings``: ε and λ_max of J⁺, the rank threshold, d_ε of D (``FB_SETTINGS`` entries).
FB_EPSILON, FB_MAX_DAMPING, FB_RCOND, FB_D_EPSILON = 0, 1, 2, 3
FB_SETTINGS = 4
#: Entries of its ``report``: rank of J, σ_min (NaN: J well conditioned and undamped, to compute when read), λ of J⁺,
#: rank of D, λ of D (0: D undamped) (``FB_REPORT`` entries).
FB_J_RANK, FB_SIGMA_MIN, FB_DAMPING, FB_D_RANK, FB_D_DAMPING = 0, 1, 2, 3, 4
FB_REPORT = 5

#: A frame task's Jacobian rows (linear, angular).
FRAME_ROWS = 6

#: The ``wqp`` resolver's tail of a fused step's ``coef``: position limits apply (1.0/0.0), rate limits apply, the
#: position gain, λ (the Hessian's diagonal shift), dt [s] and the step's time t [s] (written at every step).
TAIL_POSITION, TAIL_RATE, TAIL_GAIN, TAIL_DAMPING, TAIL_DT, TAIL_T = 0, 1, 2, 3, 4, 5
WQP_TAIL = 6
#: The ``pinv`` resolver's tail of a fused step's ``coef``: ε, λ_max and rcond of the damping rule.
TAIL_EPSILON, TAIL_MAX_DAMPING, TAIL_RCOND = 0, 1, 2
PINV_TAIL = 3

#: Header slots of a fused plan's ``ints`` (``FusedPlan._pack`` writes them, the fused kernels read them): the counts
#: K (frame tasks), J (joint-space tasks of a level), N (null-space terms), m (rows of e), nv, nq; then the offsets
#: (in ``ints``) of the frame kinds (K), the frame rows, the frame row starts (K + 1), the frames' rotation flags (K),
#: the joint rows, the joint row starts (J + 1), the joint tasks' flags (J), the q index of each velocity coordinate
#: (nv) and the main-row flags (m); the offsets (in ``floats``) of the trajectory parameters (K × PARAMS), the joint
#: targets (J × nq), the null weights (N × nv) and the null centres (N × nq); the offsets (in ``ints``) of the frame
#: ids (K) and their supporting columns (K × nv); the rows Python writers add after the compiled rows (a mixed plan),
#: and 1 when Python writers add to the null-space objective z.
H_K, H_J, H_N, H_M, H_NV, H_NQ = 0, 1, 2, 3, 4, 5
H_FRAME_KINDS, H_FRAME_ROWS, H_FRAME_STARTS, H_FRAME_ROTATION = 6, 7, 8, 9
H_JOINT_ROWS, H_JOINT_STARTS, H_JOINT_FLAGS, H_IQ, H_MAIN = 10, 11, 12, 13, 14
H_FRAME_PARAMS, H_JOINT_TARGETS, H_NULL_WEIGHTS, H_NULL_CENTRES = 16, 17, 18, 19
H_FRAME_IDS, H_FRAME_COLUMNS = 20, 21
H_EXTERNAL_ROWS, H_EXTERNAL_Z = 22, 23
#: Entries of the header (slot 15 is unused).
HEADER = 24
#: The ``ints`` parts in the order ``FusedPlan._pack`` lays them out, and the ``floats`` parts.
INT_PARTS = (
    H_FRAME_KINDS, H_FRAME_ROWS, H_FRAME_STARTS, H_FRAME_ROTATION, H_JOINT_ROWS, H_JOINT_STARTS, H_JOINT_FLAGS, H_IQ,
    H_MAIN, H_FRAME_IDS, H_FRAME_COLUMNS,
)  # fmt: skip
FLOAT_PARTS = (H_FRAME_PARAMS, H_JOINT_TARGETS, H_NULL_WEIGHTS, H_NULL_CENTRES)
#: Bits of a level joint task's flag (the header's identity flags): an identity task (a diagonal shift), and an error
#: the caller writes before the compiled call (Lie-group coordinates: K (q_ref ⊖ q) from Pinocchio's difference).
IDENTITY, GIVEN_ERROR = 1, 2
#: Columns of a packed bound subtask's integer row (``fused_kernels.clearance_rows``): frame id, first row of C,
#: lower bound set, upper bound set, the number of axes, then the axes (indices into x, y, z).
B_FID, B_ROW, B_LOWER, B_UPPER, B_NAXES, B_AXES = 0, 1, 2, 3, 4, 5
#: Columns of a packed bound subtask's float row: the centre (3) [m], the radius [m], lower, upper [m], the rate K
#: [1/s].
B_CENTER, B_RADIUS, B_LO, B_UP, B_RATE = 0, 3, 4, 5, 6
