"""Pydantic models of sweep files (``sweeps/*.yaml``): shape only, strict, unknown keys refused.

A sweep file names a robot (as task files do), a task template (one frame task to a target, a posture in the null
space), the problems (targets × start configurations, from grids, lists or seeded random samples), a resolver
(``pinv`` or ``wqp``, through the batch API) and a convergence rule; ``method`` chooses how each problem is solved
(``differential``, the default: iterated resolver steps; ``solve_ik``: :func:`redundik.solve_ik` from the start,
options under ``ik``). Everything that needs the robot (frame names,
configuration lengths, resolver options) is checked by :mod:`redundik.sweep.plan`; every error is a one-line
:class:`~redundik.errors.ConfigError` with its YAML key path.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from redundik.config.schema import (
    DT_MAX,
    DT_MIN,
    AngleUnit,
    Axis,
    Bounded,
    Name,
    SafeName,
    StrictModel,
    Vec3,
    robot_reference,
)

#: Largest number of problems (targets × starts) of one sweep.
MAX_PROBLEMS = 1_000_000
#: Largest number of iterations of one problem.
MAX_ITERATIONS = 10_000
#: Largest number of problem-steps of one sweep (problems × max_iterations): at the batch's ~1e5 problem-steps/s,
#: about a quarter of an hour; a larger sweep is refused at validation rather than left to run for hours.
MAX_WORK = 100_000_000
#: Largest chunk (problems resolved in one batch call).
MAX_CHUNK = 100_000


class RangeSpec(StrictModel):
    """``num`` evenly spaced values from ``start`` to ``stop`` (both included) [m]."""

    start: Bounded
    stop: Bounded
    num: int = Field(ge=1, le=MAX_PROBLEMS)


#: One grid axis: a single value [m] or a range.
GridAxis = Annotated[float, Field(ge=-1e6, le=1e6)] | RangeSpec


class GridSpec(StrictModel):
    """Targets on a grid: every combination of the x, y and z values (x varies slowest)."""

    x: GridAxis
    y: GridAxis
    z: GridAxis


class RandomPointsSpec(StrictModel):
    """``count`` target positions drawn uniformly in the box [low, high] [m] (NumPy PCG64 seeded by ``seed``)."""

    count: int = Field(ge=1, le=MAX_PROBLEMS)
    seed: int = Field(ge=0, le=2**63 - 1)
    low: Vec3
    high: Vec3

    @model_validator(mode="after")
    def _box(self) -> RandomPointsSpec:
        if any(lo > hi for lo, hi in zip(self.low, self.high, strict=True)):
            raise ValueError(f"low must be ≤ high in every axis, got low={self.low}, high={self.high}")
        if any(abs(v) > 1e6 for v in (*self.low, *self.high)):
            raise ValueError("low and high must be at most 1e6 in magnitude")
        return self


class TargetsSpec(StrictModel):
    """Target positions of the frame: exactly one of ``grid``, ``random`` or ``points``.

    ``orientation``: the target orientation as roll, pitch, yaw in the file's angle unit (pose tasks); default: the
    frame's orientation at the robot's home configuration.
    """

    grid: GridSpec | None = None
    random: RandomPointsSpec | None = None
    points: Annotated[list[Vec3], Field(min_length=1, max_length=MAX_PROBLEMS)] | None = None
    orientation: Vec3 | None = None

    @model_validator(mode="after")
    def _one(self) -> TargetsSpec:
        given = [k for k in ("grid", "random", "points") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of 'grid', 'random' or 'points', got {given or 'none'}")
        return self


class RandomStartsSpec(StrictModel):
    """``count`` start configurations drawn uniformly within the joint limits, shrunk by ``margin`` of each range."""

    count: int = Field(ge=1, le=MAX_PROBLEMS)
    seed: int = Field(ge=0, le=2**63 - 1)
    margin: float = Field(default=0.0, ge=0.0, lt=0.5)


class StartsSpec(StrictModel):
    """Start configurations, in this order: the robot's home (``home: true``), the listed ones, the random ones."""

    home: bool = True
    configurations: Annotated[list[list[float]], Field(max_length=MAX_PROBLEMS)] = Field(default_factory=list)
    random: RandomStartsSpec | None = None


class PostureSpec(StrictModel):
    """The null-space posture: gain [1/s] towards ``target`` (``home`` or a configuration in the angle unit)."""

    gain: float = Field(default=0.1, ge=0.0, le=1e6)
    target: Literal["home"] | list[float] = "home"


class TaskSpec(StrictModel):
    """The task template: frame ``frame`` to each target (``axes``: ``position``, ``pose``, … as in task files)."""

    frame: Name
    axes: Any = "position"
    gain: float = Field(default=1.0, gt=0.0, le=1e6)
    posture: PostureSpec = Field(default_factory=PostureSpec)


class ResolverSpec(StrictModel):
    """The resolver of every step: ``pinv`` or ``wqp`` (the batch API's), with its options as in task files."""

    name: Literal["pinv", "wqp"] = "wqp"
    options: dict[Name, Any] = Field(default_factory=dict)


class StallSpec(StrictModel):
    """Stop a problem early when its error fell by less than ``min_decrease`` [m, rad] over ``window`` steps."""

    window: int = Field(ge=1, le=MAX_ITERATIONS)
    min_decrease: float = Field(gt=0.0, le=1e6)


class ConvergenceSpec(StrictModel):
    """Iterate q ← q ⊕ q̇·dt from the start until ‖e‖ < ``tol`` or ``max_iterations`` steps (or a stall).

    With ``method: solve_ik``: ``tol`` is the position tolerance [m], ``max_iterations`` the iterations of one
    attempt, and ``dt`` and ``stall`` are not used (``dt`` is required only by ``method: differential``).
    """

    dt: float | None = Field(default=None, ge=DT_MIN, le=DT_MAX)
    tol: float = Field(gt=0.0, le=1e3)
    max_iterations: int = Field(default=200, ge=1, le=MAX_ITERATIONS)
    stall: StallSpec | None = None

    @model_validator(mode="after")
    def _stall_can_fire(self) -> ConvergenceSpec:
        if self.stall is not None and self.stall.window >= self.max_iterations:
            raise ValueError(
                f"stall.window ({self.stall.window}) must be < max_iterations ({self.max_iterations}): the stall "
                "rule compares the error over that many steps, so it could never stop a problem"
            )
        return self


#: How each problem is solved: ``differential`` (iterated resolver steps at dt) or ``solve_ik``.
METHODS = ("differential", "solve_ik")


class IKSpec(StrictModel):
    """Options of ``method: solve_ik`` (:func:`redundik.solve_ik` per problem, from its start configuration).

    ``orientation_tolerance`` [rad] for pose axes (default: ``convergence.tol``); ``max_restarts`` random restarts
    after the first attempt; ``timeout`` [s] per problem (``null``: none; with a timeout the results depend on the
    machine's speed, without one only on the file); problem p's restarts are seeded with (``seed``, p).
    """

    orientation_tolerance: float | None = Field(default=None, gt=0.0, le=10.0)
    max_restarts: int | None = Field(default=20, ge=0, le=MAX_ITERATIONS)
    timeout: float | None = Field(default=None, gt=0.0, le=60.0)
    seed: int = Field(default=0, ge=0, le=2**63 - 1)


class FigureSpec(StrictModel):
    """The map figure: the world plane it is drawn in (default: the two axes the targets spread most along)."""

    plane: Annotated[list[Axis], Field(min_length=2, max_length=2)] | None = None
    enabled: bool = True

    @field_validator("plane")
    @classmethod
    def _two_axes(cls, plane: list[str] | None) -> list[str] | None:
        if plane is not None and plane[0] == plane[1]:
            raise ValueError(f"expected two different axes, got {plane}")
        return plane


class SweepFileSpec(StrictModel):
    """A sweep file (``sweeps/*.yaml``)."""

    name: SafeName
    description: str = ""
    robot: Any
    angle_unit: AngleUnit = "rad"
    #: The home configuration (start ``home`` and posture target ``home``); default: the robot config's ``q0``.
    q0: list[float] | None = None
    task: TaskSpec
    targets: TargetsSpec
    starts: StartsSpec = Field(default_factory=StartsSpec)
    resolver: ResolverSpec = Field(default_factory=ResolverSpec)
    method: Literal["differential", "solve_ik"] = "differential"
    ik: IKSpec | None = None
    convergence: ConvergenceSpec
    chunk_size: int = Field(default=256, ge=1, le=MAX_CHUNK)
    figure: FigureSpec = Field(default_factory=FigureSpec)

    @field_validator("robot")
    @classmethod
    def _robot(cls, robot: Any) -> Any:
        return robot_reference(robot)
