"""Named layouts of the tasks' packed rows, which their compiled writers and the fused steps read (no numba: the
resolvers import these names without loading the kernels).

* A compiled trajectory's parameter row (``PARAMS``,) (``Trajectory.kernel_params``): the start or held
  position p0 [m] at ``P0`` and rotation R0 (row-major) at ``R0``; then per kind, a ``Line``'s velocity [m/s] at
  ``LINE_V``, a ``Circle``'s centre [m] at ``CIRCLE_C``, its two in-plane axes scaled by the radius [m] at
  ``CIRCLE_E1`` and ``CIRCLE_E2``, its angular rate [rad/s] at ``CIRCLE_W`` and phase [rad] at ``CIRCLE_PHASE``.
* A sampled reference row (``REF``,) (``target_kernels.reference_into``): p_d [m] at ``REF_P``, R_d (row-major) at
  ``REF_R``, the reference twist (linear [m/s], angular [rad/s]) at ``REF_TWIST``.
* The records (``ints``, ``floats``) of the built-in tasks' compiled writers (``row_kernels``), beside their names.
"""

from __future__ import annotations

#: A trajectory's parameter row: p0 (3), R0 row-major (9), then its kind's own entries.
P0, R0 = 0, 3
#: Where a kind's own entries start (``Trajectory._params_row``'s ``extra``).
EXTRA = 12
LINE_V = 12
CIRCLE_C, CIRCLE_E1, CIRCLE_E2, CIRCLE_W, CIRCLE_PHASE = 12, 15, 18, 21, 22
PARAMS = 23

#: A sampled reference row: p_d (3), R_d row-major (9), the twist (6).
REF_P, REF_R, REF_TWIST = 0, 3, 12
REF = 18

#: ``JointCoupling`` (``row_kernels.coupling_rows``): ``ints`` = (idx_q of i, idx_v of i, idx_q of j, idx_v of j);
#: ``floats`` = (c,) [rad or m].
CPL_IQ_I, CPL_IV_I, CPL_IQ_J, CPL_IV_J = 0, 1, 2, 3
CPL_INTS = 4
CPL_OFFSET = 0
CPL_FLOATS = 1

#: ``RelativePoseTask`` (``row_kernels.relative_rows``): ``ints`` = (frame A, frame B, r, the r task rows from
#: ``REL_ROWS``, then A's supporting velocity columns (nv), then B's (nv)); ``floats`` = (p_d [m] at ``REL_P``, R_d
#: row-major at ``REL_R``).
REL_FRAME_A, REL_FRAME_B, REL_NROWS, REL_ROWS = 0, 1, 2, 3
REL_P, REL_R = 0, 3
REL_FLOATS = 12

#: ``CoMTask`` (``row_kernels.com_rows``): ``ints`` = (bodies b, r, the r task rows from ``COM_ROWS``, then per body
#: its joint's frame id (b), then per body its supporting velocity columns (b × nv)); ``floats`` = (c_d [m] at
#: ``COM_TARGET``, then from ``COM_BODIES`` per body (``COM_BODY`` entries): its mass over the total at ``COM_MASS``
#: and its lever l [m] (3, in its joint's frame) at ``COM_LEVER``).
COM_NBODIES, COM_NROWS, COM_ROWS = 0, 1, 2
COM_TARGET, COM_BODIES = 0, 3
COM_MASS, COM_LEVER = 0, 1
COM_BODY = 4
#: ``SupportPolygon`` (``row_kernels.support_rows``): ``ints`` those of ``com_rows``; ``floats`` those of
#: ``com_rows`` (the target unused), then from the end of the bodies (``COM_BODIES`` + ``COM_BODY`` b) the margin m
#: [m] at ``SUP_MARGIN`` and, from ``SUP_EDGES``, per edge (``SUP_EDGE`` entries) its outward unit normal a (x, y)
#: at ``SUP_AX``, ``SUP_AY`` and its offset b [m] at ``SUP_B`` (aᵀx ≤ b inside).
SUP_MARGIN, SUP_EDGES = 0, 1
SUP_AX, SUP_AY, SUP_B = 0, 1, 2
SUP_EDGE = 3

#: ``ints`` of a joint potential's writer: the joint's index in q, then in q̇.
J_IQ, J_IV = 0, 1
J_INTS = 2
#: ``floats`` of ``JointValue``: its centre c [rad or m].
JV_CENTER = 0
#: ``JointWaypoints``: ``ints`` = (idx_q, idx_v, the active waypoint's index (rewritten in place), the count);
#: ``floats`` = (tolerance [rad or m], then the waypoints from ``WP_POINTS``).
WP_ACTIVE, WP_COUNT = 2, 3
WP_TOLERANCE, WP_POINTS = 0, 1
#: ``ints`` of a frame-point potential's writer (``Clearance``, ``VirtualPoint``): the frame's id, the number k of
#: axes that count, then those k axes (indices into x, y, z), then nv flags: nonzero on the velocity columns of the
#: joints that support the frame (``frame_jacobian_lwa``).
FP_FRAME, FP_AXES_N, FP_AXES = 0, 1, 2
#: ``floats`` of a clearance: the obstacle's centre p_o (3) [m], then its radius r [m]; of a virtual point: p_v (3).
FP_POINT, FP_RADIUS = 0, 3
#: ``ints`` of a potential of frame Jacobians and their derivatives (``BestPosture``, ``Manipulability``): the number
#: F of frames, the number k of twist rows that count, those k rows, the F frame ids, F × nv flags (the columns of the
#: joints that support each frame), then nv × nv flags M[j, k]: the joint of velocity k is the joint of velocity j
#: or one of its ancestors (``RobotModel.support_mask``). ``floats`` of ``BestPosture``: the joint weights w (nv).
JP_FRAMES, JP_ROWS_N, JP_ROWS = 0, 1, 2
