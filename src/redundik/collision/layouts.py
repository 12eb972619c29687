"""Named layouts of the collision world's packed records, written by :mod:`redundik.collision.world` and read by the
compiled kernels (:mod:`redundik.collision.kernels`) and the interpreted reference
(:mod:`redundik.collision.distances`); no numba, no NumPy: the world imports these names without loading the kernels.

* A geometry's kind code (``CAPSULE``, ``BOX``, ``HALFSPACE``, ``OTHER``) and its row of numbers ``prm[g]``
  (``SHAPE_PRM`` entries, unused ones 0):

  * ``CAPSULE`` (a sphere is a capsule of half length 0, axis local z): the radius [m] at ``CAP_RADIUS``, the half
    length [m] at ``CAP_HALF``;
  * ``BOX``: the half sides along local x, y, z [m] at ``BOX_HX``, ``BOX_HY``, ``BOX_HZ`` (``BOX_HALVES``);
  * ``HALFSPACE``, the solid {x : nᵀx ≤ d} of the geometry's frame: the unit normal n [-] at ``HS_NX``, ``HS_NY``,
    ``HS_NZ`` (``HS_NORMAL``), the offset d [m] at ``HS_D``;
  * ``OTHER`` (meshes, convex hulls): none (coal computes their distances).

* A ``BranchTable`` ``(br, sign)`` (slots ``TABLE_BR``, ``TABLE_SIGN``): per end-sphere branch r, ``br[r]``
  (``BR_COLS`` ints: the pair at ``BR_PAIR``, the capsule geometry at ``BR_CAPSULE``, the pair's other geometry at
  ``BR_OTHER``, 1 when the capsule is body 1 of the pair at ``BR_FIRST``) and ``sign[r]`` = ±1 [-], the end along
  the capsule's local z.
* The pairs' joints ``pj`` (P, ``PJ_COLS``) (a ``Joints`` record's second array): the joint of body 1 at
  ``PJ_BODY1``, of body 2 at ``PJ_BODY2``.
* A ``PairData`` tuple (slots ``PAIR_D`` … ``PAIR_NEAR``, ``PAIR_DATA`` of them): per pair the signed distance [m]
  (P,), the witness points on body 1 and body 2 [m] and the unit normal from body 1 to body 2 [-] (P, 3), ∂d/∂t
  [m/s] (P,), and the indices of the pairs that get rows (k₀,).
* A ``Gains`` tuple (slots ``GAIN_REACH`` … ``GAIN_QP_CAP``, ``GAINS`` of them): the rows' reach [m], the influence
  distance d_i [m], the safety distance d_s [m], the damper's gain γ [1/s], the gain outside d_i [1/s], whether the
  end spheres get rows (bool), the QP rate cap [1/s] (0: the rows as h, ∂h/∂q).
* The placements record ``poses`` of ``capsule_damper`` (slots ``POSES_SRC``, ``POSES_LIVE``): the (G, 12)
  placements of Pinocchio's ``GeometryData.oMg`` and the geometries to load (int).
* ``capsule_damper``'s float output ``F``, in blocks of P (pairs) then of R (rows): the pairs' distances [m] at
  block ``F_DIST``, then from block ``F_POINTS`` their witness points p₁, p₂ [m] and normals n [-] stacked
  (``PTS``, P, 3) (p₁ at ``PTS_P1``, p₂ at ``PTS_P2``, n at ``PTS_N``), ``F_PAIR`` floats per pair in all; then from
  ``F_PAIR`` P, the rows' h [m] at block ``F_H``, their γ [1/s] at block ``F_GAMMA`` and their Jacobian rows ∂h/∂q
  (R, nv) [m per unit of q̇'s coordinates] from block ``F_JAC``.
"""

from __future__ import annotations

#: Kind codes of the geometries.
CAPSULE, BOX, HALFSPACE, OTHER = 0, 1, 2, 3

#: Entries of a geometry's numbers ``prm[g]``.
SHAPE_PRM = 4
#: A capsule's (or sphere's) radius [m] and half length [m].
CAP_RADIUS, CAP_HALF = 0, 1
#: A box's half sides along its local x, y, z [m].
BOX_HX, BOX_HY, BOX_HZ = 0, 1, 2
BOX_HALVES = (BOX_HX, BOX_HY, BOX_HZ)
#: A half space's unit normal (local frame) [-] and offset d [m].
HS_NX, HS_NY, HS_NZ, HS_D = 0, 1, 2, 3
HS_NORMAL = (HS_NX, HS_NY, HS_NZ)

#: Slots of a ``BranchTable``: the int table ``br`` (branches, ``BR_COLS``) and the ends' signs ``sign``.
TABLE_BR, TABLE_SIGN = 0, 1
#: Columns of a ``BranchTable``'s ``br``: the pair, the capsule, the pair's other body, the capsule is body 1.
BR_PAIR, BR_CAPSULE, BR_OTHER, BR_FIRST = 0, 1, 2, 3
BR_COLS = 4

#: Columns of the pairs' joints ``pj`` (P, ``PJ_COLS``): the joint of body 1, of body 2.
PJ_BODY1, PJ_BODY2 = 0, 1
PJ_COLS = 2

#: Slots of a ``PairData``: d [m], p1, p2 [m], n, ∂d/∂t [m/s], the pairs that get rows.
PAIR_D, PAIR_P1, PAIR_P2, PAIR_N, PAIR_RATE, PAIR_NEAR = 0, 1, 2, 3, 4, 5
PAIR_DATA = 6

#: Slots of a ``Gains``: reach [m], d_i [m], d_s [m], γ [1/s], the gain outside d_i [1/s], end spheres (bool), the
#: QP rate cap [1/s].
GAIN_REACH, GAIN_INFLUENCE, GAIN_SAFETY, GAIN_GAMMA, GAIN_NO_CAP, GAIN_ENDS, GAIN_QP_CAP = 0, 1, 2, 3, 4, 5, 6
GAINS = 7

#: Slots of ``capsule_damper``'s ``poses``: the placements (G, 12), the geometries to load.
POSES_SRC, POSES_LIVE = 0, 1

#: ``capsule_damper``'s ``F``: blocks of P floats (the distances, then p₁, p₂, n: 9 per pair), ``F_PAIR`` per pair.
F_DIST, F_POINTS = 0, 1
F_PAIR = 10
#: The stacked points of the ``F_POINTS`` blocks (``PTS``, P, 3): p₁ [m], p₂ [m], n [-].
PTS_P1, PTS_P2, PTS_N = 0, 1, 2
PTS = 3
#: Then blocks of R floats (h, γ, then the Jacobian rows: nv per row).
F_H, F_GAMMA, F_JAC = 0, 1, 2
