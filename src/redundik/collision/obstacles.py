"""Environment obstacles of a collision world: coal shapes made from a kind and sizes, a pose, and an optional
translational motion (:class:`Motion`) whose rate enters the collision damper as ∂d/∂t."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from redundik.errors import ModelError


@dataclass(frozen=True)
class Motion:
    """A translational obstacle motion: offset(t) = v t + A ⊙ sin(2π f t + φ) [m] added to the obstacle's pose.

    Attributes:
        velocity: v [m/s], shape (3,).
        amplitude: A [m], shape (3,).
        frequency: f [Hz] ≥ 0.
        phase: φ [rad].
    """

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frequency: float = 0.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        vals = [*self.velocity, *self.amplitude, self.frequency, self.phase]
        if len(self.velocity) != 3 or len(self.amplitude) != 3 or not all(math.isfinite(float(v)) for v in vals):
            raise ModelError("obstacle motion: velocity and amplitude need 3 finite numbers, frequency/phase finite")
        if self.frequency < 0:
            raise ModelError(f"obstacle motion: frequency must be ≥ 0 [Hz], got {self.frequency}")

    def offset(self, t: float) -> np.ndarray:
        """Displacement at time t [s], shape (3,) [m]."""
        w = 2 * math.pi * self.frequency
        return np.asarray(self.velocity) * t + np.asarray(self.amplitude) * math.sin(w * t + self.phase)

    def rate(self, t: float) -> np.ndarray:
        """Velocity at time t [s], shape (3,) [m/s]."""
        w = 2 * math.pi * self.frequency
        return np.asarray(self.velocity) + np.asarray(self.amplitude) * w * math.cos(w * t + self.phase)


#: Obstacle kinds and their size parameters.
OBSTACLE_KINDS: dict[str, tuple[str, ...]] = {
    "sphere": ("radius",),
    "box": ("size",),
    "capsule": ("radius", "length"),
    "cylinder": ("radius", "length"),
    "plane": (),
    "mesh": ("path",),
}


def _positive(value: float, what: str, allow_zero: bool = False) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ModelError(f"{what} must be a finite number {'≥' if allow_zero else '>'} 0 [m], got {value}")
    return v


def make_shape(
    kind: str,
    *,
    radius: float | None = None,
    length: float | None = None,
    size: Sequence[float] | None = None,
    path: str | Path | None = None,
    scale: Sequence[float] = (1.0, 1.0, 1.0),
) -> object:
    """A coal shape for an obstacle of ``kind`` (see :data:`OBSTACLE_KINDS`); sizes in [m].

    ``box`` takes full side lengths ``size`` (3,); ``capsule``/``cylinder`` a ``radius`` and the ``length`` of the
    axis (along local z); ``plane`` is the half-space z ≤ 0 of its frame (solid below); ``mesh`` is a mesh file
    (STL, OBJ, DAE) used through its convex hull.

    Raises:
        ModelError: unknown kind (lists them), a missing or non-positive size, a missing or unreadable mesh file.
    """
    if kind == "sphere":
        return coal.Sphere(_positive(radius if radius is not None else -1, "sphere radius"))
    if kind == "box":
        if size is None or len(size) != 3:
            raise ModelError("box: 'size' needs 3 side lengths [m]")
        return coal.Box(*[_positive(s, "box size") for s in size])
    if kind in ("capsule", "cylinder"):
        r = _positive(radius if radius is not None else -1, f"{kind} radius")
        ln = _positive(length if length is not None else -1, f"{kind} length", allow_zero=True)
        return coal.Capsule(r, ln) if kind == "capsule" else coal.Cylinder(r, ln)
    if kind == "plane":
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if kind == "mesh":
        if path is None:
            raise ModelError("mesh: 'path' (a mesh file) is required")
        p = Path(path)
        if not p.is_file():
            raise ModelError(f"mesh file '{p}' does not exist")
        sc = np.array([_positive(s, "mesh scale") for s in scale], dtype=float)
        try:
            bvh = coal.MeshLoader().load(str(p), sc)
            if bvh.num_vertices < 4:
                raise ValueError("fewer than 4 vertices")
            bvh.buildConvexHull(True, "Qt")
            return bvh.convex
        except Exception as exc:
            raise ModelError(f"mesh file '{p}' could not be read: {_loader_message(exc)}") from exc
    raise ModelError(f"unknown obstacle type '{kind}'; available: {', '.join(OBSTACLE_KINDS)}")


def _loader_message(exc: Exception) -> str:
    """The reason in a coal loader error, without its C++ source location (one line, ≤ 160 characters)."""
    text = str(exc).strip()
    if "message:" in text:
        text = text.split("message:", 1)[1]
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("Hint:")]
    return " ".join(lines)[:160] or type(exc).__name__


@dataclass
class Obstacle:
    """An environment obstacle fixed to the world, optionally moving (translation only).

    Attributes:
        name: Unique name (also the pair names of diagnostics).
        shape: A coal shape (:func:`make_shape`).
        placement: Pose in the world at t = 0.
        motion: A :class:`Motion`, or ``None`` (static).
    """

    name: str
    shape: object
    placement: pin.SE3 = field(default_factory=pin.SE3.Identity)
    motion: Motion | None = None

    def __post_init__(self) -> None:
        M = self.placement.homogeneous
        if not np.all(np.isfinite(M)):
            raise ModelError(f"obstacle '{self.name}': the pose contains NaN or infinite values")

    def placement_at(self, t: float) -> pin.SE3:
        """Pose at time t [s]."""
        if self.motion is None:
            return self.placement
        return pin.SE3(self.placement.rotation, self.placement.translation + self.motion.offset(t))
