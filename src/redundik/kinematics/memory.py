"""Views on Pinocchio's own memory, for compiled kernels that read what Pinocchio computed without a Python call
per element (each such call costs about a microsecond on a busy control tick).

Every view is returned only once its layout has been verified against what the bindings report (addresses,
strides, values); otherwise ``None`` and the caller takes the per-element route. A view is valid while the object it
was taken from lives and is not resized (Pinocchio sizes ``Data``'s and ``GeometryData``'s vectors and matrices once,
at construction).
"""

from __future__ import annotations

from typing import Any

import numpy as np


class _Memory:
    """Read-only float64 memory at an address, for ``np.asarray`` (the array interface protocol)."""

    def __init__(self, address: int, shape: tuple[int, ...]) -> None:
        self.__array_interface__ = {"data": (address, True), "shape": shape, "typestr": "<f8", "version": 3}


def se3_vector_view(placements: Any) -> np.ndarray | None:
    """A read-only (G, 12) view on a std::vector of SE3 (``data.oMf``, ``data.oMi``, ``geometry_data.oMg``): per
    element the rotation (column-major, 9), then the translation (3); ``None`` unless that layout is verified (SE3s
    of 96 bytes back to back, each element's rotation and translation at their offsets, the values equal)."""
    G = len(placements)
    if not G:
        return None
    base = int(placements[0].rotation.__array_interface__["data"][0])
    for g in range(G):
        M = placements[g]
        R, t = M.rotation, M.translation
        if (
            R.__array_interface__["data"][0] != base + 96 * g
            or t.__array_interface__["data"][0] != base + 96 * g + 72
            or R.dtype != np.float64
            or R.strides != (8, 24)
            or t.strides != (8,)
        ):
            return None
    view = np.asarray(_Memory(base, (G, 12)))  # (no ctypes array type: each is a new class in a reference cycle)
    view.flags.writeable = False
    for g in range(G):
        M = placements[g]
        if not (
            np.array_equal(view[g, :9].reshape(3, 3, order="F"), M.rotation)
            and np.array_equal(view[g, 9:], M.translation)
        ):
            return None
    return view


def jacobian_view(data: Any) -> np.ndarray | None:
    """``data.J`` (6, nv), the joint Jacobians in the world frame that ``computeJointJacobians`` writes, as the
    array the bindings return — verified to be a view on Data's memory (not a copy), float64, column-major."""
    J = data.J
    again = data.J
    if isinstance(J, np.ndarray) and J.ndim == 1 and J.shape == (6,):  # nv = 1: the bindings drop the unit axis
        J = J.reshape(6, 1)  # (a view still: a contiguous vector reshaped)
    if not (
        isinstance(J, np.ndarray)
        and not J.flags.owndata
        and J.dtype == np.float64
        and J.ndim == 2
        and J.shape[0] == 6
        and J.flags.f_contiguous
        and J.__array_interface__["data"][0] == again.__array_interface__["data"][0]
    ):
        return None
    return J
