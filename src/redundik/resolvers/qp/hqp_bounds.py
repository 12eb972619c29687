"""The bound subtasks of ``hqp``'s fused step (:mod:`redundik.resolvers.qp.hqp_plan`): their packing for the
compiled damper rows (``hqp_fused.clearance_rows``), and the records through which a step's result reads the rows
that call wrote into the plan's inequality buffers C, d (the velocity damper, Faverjon & Tournassoud 1987, as
``BoundSubtask.rows_into`` writes it).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from redundik.kinematics.model import RobotModel
from redundik.resolvers.layouts import (
    B_AXES,
    B_CENTER,
    B_FID,
    B_LO,
    B_LOWER,
    B_NAXES,
    B_RADIUS,
    B_RATE,
    B_ROW,
    B_UP,
    B_UPPER,
)


class WrittenRows:
    """The damper rows one step wrote into the plan's buffers, for ``_Plan.step_rows``: their copies, taken when
    first asked or before those buffers are next written while this record is still held (the step's lazy
    diagnostics hold it), never otherwise. ``src``: (C, d, rows) — the buffers written and how many rows."""

    __slots__ = ("C", "__weakref__", "d", "src")

    def __init__(self) -> None:
        self.C: np.ndarray | None = None
        self.d: np.ndarray | None = None
        self.src: tuple[np.ndarray, np.ndarray, int] | None = None

    def keep(self) -> None:
        """Copy the rows out of the buffers they were written into (once)."""
        if self.C is None and self.src is not None:
            C, d, rows = self.src
            self.C, self.d = C[:rows].copy(), d[:rows].copy()


class PackedBounds(NamedTuple):
    """Bound subtasks packed for ``hqp_fused.clearance_rows`` (``_Plan.packed_bounds``)."""

    bint: np.ndarray  # (B, B_AXES + 3) integers per bound (``layouts.B_FID`` …)
    bcols: np.ndarray  # (B, nv) the columns of the joints supporting each frame
    bfl: np.ndarray  # (B, B_RATE + 1) numbers per bound (``layouts.B_CENTER`` …)
    offsets: list[tuple[int, int]]  # the offsets table (least-squares row, inequality row) per level
    slices: list[tuple[slice, list[str]]]  # per bound its rows of C, d and their names
    rows: int  # the rows of C, d written


#: No packed bounds (``hqp_fused.fused_hqp_call``'s arguments when ``_Plan.fused_bounds`` wrote the rows).
NO_BOUNDS = (np.zeros((0, B_AXES + 3), dtype=np.int64), np.zeros((0, 0), dtype=np.int64), np.zeros((0, B_RATE + 1)))


def _refs_of_unheld() -> int:
    """What ``sys.getrefcount`` reports for a list held only by the tuple it is read from, in the expression
    ``_Plan.written_bounds`` uses (measured, not assumed: interpreters differ by the argument's own reference)."""
    last: tuple[None, list[Any]] = (None, [])
    return sys.getrefcount(last[1])


#: ``sys.getrefcount`` of a records list that only the plan holds (``_Plan.written_bounds`` reuses it then).
UNHELD = _refs_of_unheld()


def pack_bounds(
    robot: RobotModel, levels: Sequence[Sequence[Any]], ls_offsets: list[int], n: int
) -> PackedBounds | None:
    """The bound subtasks of ``levels`` (per level, its bound subtasks: ``hqp``'s ``_Plan.members``, or ``wqp``'s
    one list with ``ls_offsets`` ``[0]``) packed for the compiled damper rows, when every one gives its
    ``clearance_form`` (a bound on a clearance, read through verified views of Pinocchio's memory); their rows C, d
    one after another, level by level (the offsets ``_Plan.fused_bounds`` gives them). ``None``: another source, rows
    of its own, unverified views (their rows are written from Python)."""
    bsubs = [bsub for bs in levels for bsub in bs]
    forms = [bsub.clearance_form(robot) for bsub in bsubs]
    if any(form is None for form in forms):
        return None
    bint = np.zeros((len(bsubs), B_AXES + 3), dtype=np.int64)
    bcols = np.zeros((len(bsubs), n), dtype=np.int64)
    bfl = np.zeros((len(bsubs), B_RATE + 1))
    slices: list[tuple[slice, list[str]]] = []
    offsets = []
    cs = k = 0
    for bs, ls_row in zip(levels, ls_offsets, strict=False):
        offsets.append((ls_row, cs))
        for bsub in bs:
            form = forms[k]
            assert form is not None  # (checked above)
            rows = form.rows
            lower, upper = bsub.lower, bsub.upper
            bint[k, [B_FID, B_ROW, B_LOWER, B_UPPER, B_NAXES]] = (
                form.fid,
                cs,
                lower is not None,
                upper is not None,
                rows.shape[0],
            )
            bint[k, B_AXES : B_AXES + rows.shape[0]] = rows
            bcols[k] = form.columns
            bfl[k, B_CENTER : B_CENTER + 3] = form.center
            bfl[k, [B_RADIUS, B_LO, B_UP, B_RATE]] = (
                form.radius,
                0.0 if lower is None else lower,
                0.0 if upper is None else upper,
                bsub.rate,
            )
            e = cs + (lower is not None) + (upper is not None)
            slices.append((slice(cs, e), bsub.row_names))
            cs, k = e, k + 1
    offsets.append((ls_offsets[-1], cs))
    return PackedBounds(bint, bcols, bfl, offsets, slices, cs)


__all__ = ["NO_BOUNDS", "UNHELD", "PackedBounds", "WrittenRows", "pack_bounds"]
