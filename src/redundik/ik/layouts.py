"""Named layouts of the packed arrays of :func:`redundik.solve_ik`'s iteration, written by
:mod:`redundik.ik.solve` and read by the compiled ``lm_update`` (:mod:`redundik.ik.kernels`); no numba, no NumPy.

* The problem's ints ``ints`` (``IK_MODES`` + k + nv,): nq at ``IK_NQ``, then from ``IK_MODES`` each frame's mode
  (k,) (0 pose, 1 position), then each velocity coordinate's index in q (nv,) (−1: no bound applies) from
  ``IK_MODES`` + k.
* The problem's floats ``consts`` (``N_PARAMS`` + 2 nv,): the parameters ``params`` (``N_PARAMS``,), then the
  velocity coordinates' lower bounds lo (nv,) [rad or m] from ``N_PARAMS`` and upper bounds hi (nv,) from
  ``N_PARAMS`` + nv. The parameters: the position tolerance [m] at ``P_TOL_POS``, the orientation tolerance [rad] at
  ``P_TOL_ROT``, the stall window [iterations] at ``P_WINDOW``, the stall ratio [-] at ``P_RATIO``, the position
  weight [rad/m] at ``P_WPOS``, the cost damping c [-] at ``P_COST_DAMPING`` (names in ``PARAMS``).
* The workspace's iterates: the residual rows, errors and q of the trial at ``TRIAL`` and of the current (best
  accepted) iterate at ``CURRENT`` (``N_ITERATES`` of them); a frame's errors ``err[i, k]`` (``N_ERR``,): the position
  error [m] at ``ERR_POS``, the orientation error [rad] at ``ERR_ROT`` (0 for a position target).
* The workspace's state ``st`` (``N_STATE``,): the cost ½‖r‖² [rad²] at ``S_COST``, the adaptive damping λ [-] at
  ``S_LAM``, the cost at the stall window's start [rad²] at ``S_WINDOW_COST``, the iteration at ``S_ITER`` and the
  window's first iteration at ``S_WINDOW_START`` (counts held as floats: one state array).
"""

from __future__ import annotations

#: Entries of ``ints``: nq, then the frames' modes from ``IK_MODES`` (then the q indices of the velocities).
IK_NQ, IK_MODES = 0, 1

#: Indices of the parameters ``params`` (:data:`PARAMS`): position tolerance [m], orientation tolerance [rad], stall
#: window [iterations], stall ratio [1], position weight [rad/m], cost damping [1].
P_TOL_POS, P_TOL_ROT, P_WINDOW, P_RATIO, P_WPOS, P_COST_DAMPING = 0, 1, 2, 3, 4, 5
#: The parameters' names, in order.
PARAMS = ("position_tolerance", "orientation_tolerance", "stall_window", "stall_ratio", "position_weight",
          "cost_damping")  # fmt: skip
N_PARAMS = 6

#: The workspace's two iterates: the trial, the current iterate.
TRIAL, CURRENT = 0, 1
N_ITERATES = 2
#: A frame's errors: position [m], orientation [rad].
ERR_POS, ERR_ROT = 0, 1
N_ERR = 2

#: Indices of the state ``st``: cost ½‖r‖², λ, the cost at the stall window's start, the iteration, the window's
#: first iteration (counts held as floats: one state array).
S_COST, S_LAM, S_WINDOW_COST, S_ITER, S_WINDOW_START = 0, 1, 2, 3, 4
#: Length of the state.
N_STATE = 5
