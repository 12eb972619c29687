"""What keeps the figures readable: a marker per run (placed at a different phase on each run, so curves that
coincide all stay visible), a note on runs whose curve equals an earlier run's, potential units, and text placed
outside the data.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: One marker per run (cycled): with the run's colour they tell runs apart even where their curves coincide.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")

#: Markers drawn per curve.
MARKS_PER_CURVE = 12


def marker(i: int) -> str:
    """Run i's marker."""
    return MARKERS[i % len(MARKERS)]


def mark_every(i: int, n_runs: int, n_points: int) -> tuple[int, int]:
    """``markevery`` of run i of ``n_runs`` on a curve of ``n_points``: every ``step`` samples from an offset that
    differs per run, so coinciding curves show every run's markers side by side."""
    step = max(1, n_points // MARKS_PER_CURVE)
    return (i * step) // max(n_runs, 1) % step, step


def run_style(i: int, n_runs: int, n_points: int) -> dict[str, Any]:
    """Matplotlib keywords giving run i its marker (hollow, phase-shifted)."""
    return {
        "marker": marker(i),
        "markevery": mark_every(i, n_runs, n_points),
        "markersize": 5,
        "markerfacecolor": "none",
    }


def same_as(curves: Sequence[tuple[str, np.ndarray, np.ndarray]], rtol: float = 1e-9) -> dict[str, str]:
    """For each curve (name, t, y) equal to an earlier one (same t, y within ``rtol`` of its scale): that one's name."""
    out: dict[str, str] = {}
    for k, (name, t, y) in enumerate(curves):
        for other, t0, y0 in curves[:k]:
            if other in out or np.shape(t0) != np.shape(t) or np.shape(y0) != np.shape(y):
                continue
            a, b = np.asarray(y, dtype=float), np.asarray(y0, dtype=float)
            scale = float(np.nanmax(np.abs(b), initial=0.0)) or 1.0
            if np.array_equal(np.isnan(a), np.isnan(b)) and np.allclose(
                a, b, rtol=0.0, atol=rtol * scale, equal_nan=True
            ):
                out[name] = other
                break
    return out


def with_note(label: str, name: str, same: dict[str, str]) -> str:
    """``label`` with "= other run" when run ``name``'s curve equals an earlier run's."""
    return f"{label} (= {same[name]})" if name in same else label


# ---------------------------------------------------------------------------------------------------- units
def _joint_unit(robot: Any, joint: str, unit: str, power: str = "") -> str:
    info = robot.joint(joint)
    base = "rad" if info.kind == "revolute" else unit
    return f"{base}{power}"


def potential_unit(potential: Any, robot: Any | None) -> str:
    """The unit of a potential's value p (the robot's length unit for lengths), e.g. ``"m"``, ``"rad²"``, ``"1"``.

    Returns ``"?"`` for a potential whose unit is not known here.
    """
    from redundik.collision import CollisionAvoidance
    from redundik.tasks import potentials as P
    from redundik.tasks.balance import SupportPolygon
    from redundik.tasks.waypoints import JointWaypoints

    unit = robot.length_unit if robot is not None else "m"
    if isinstance(potential, (P.Clearance, SupportPolygon)):
        return unit  # a distance
    if isinstance(potential, P.VirtualPoint):
        return f"{unit}²"  # ½‖S(p_f − p_v)‖²
    if isinstance(potential, (P.JointSine2, CollisionAvoidance)):
        return "1"  # sin²θ; ½Σ((d_i − d)/(d_i − d_s))²
    if isinstance(potential, (P.JointValue, JointWaypoints)):
        return _joint_unit(robot, potential.joint, unit, "²") if robot is not None else "rad² or m²"
    if isinstance(potential, P.JointCentering):  # ½Σ w (q − q_c)²
        kinds = {j.kind for j in robot.joints if j.idx_q >= 0} if robot is not None else {"revolute", "prismatic"}
        if kinds == {"revolute"}:
            return "rad²"
        if kinds == {"prismatic"}:
            return f"{unit}²"
        return f"rad², {unit}² for prismatic joints"
    if isinstance(potential, (P.Manipulability, P.BestPosture)):
        linear = sum(1 for a in potential.axes if not a.startswith("r"))
        if isinstance(potential, P.BestPosture):  # tr(JWJᵀ): Σ of squared rows
            return f"{unit}²" if linear == len(potential.axes) else "1" if linear == 0 else f"{unit}² + 1 (mixed rows)"
        return "1" if linear == 0 else unit if linear == 1 else f"{unit}^{linear}"  # √det(JJᵀ), revolute joints
    return "?"


def outside_right(ax: Any, y: float, text: str, color: str = "grey") -> Any:
    """Label the horizontal line at data height ``y`` just right of the axes (outside the data)."""
    return ax.annotate(
        text,
        xy=(1.0, y),
        xycoords=("axes fraction", "data"),
        xytext=(4, 0),
        textcoords="offset points",
        ha="left",
        va="center",
        fontsize=7,
        color=color,
        annotation_clip=False,
    )
