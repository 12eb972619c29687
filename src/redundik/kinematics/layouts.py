"""Named layouts of the kinematic arrays that compiled writers read (no numba, no Pinocchio: every layer may import
these names).

* A frame placement row of ``poses`` (nframes, ``POSE_SIZE``), Pinocchio's ``SE3`` as it lies in memory
  (``memory.se3_vector_view`` of ``data.oMf``): the rotation column-major from ``POSE_R``
  (R[i, j] = ``poses[f, POSE_R + 3 j + i]``), then the origin [m] from ``POSE_P`` (``poses[f, POSE_P : POSE_P + 3]``).
* The rows of a twist or of a 6-row Jacobian (``jw``, ``data.J``): linear from ``LIN`` (3), angular from ``ANG`` (3).
"""

from __future__ import annotations

#: A placement row: rotation (column-major, 9 entries) then origin (3) [m].
POSE_R, POSE_P = 0, 9
POSE_SIZE = 12

#: A twist's (or a 6-row Jacobian's) linear rows [m/s] then angular rows [rad/s].
LIN, ANG = 0, 3
