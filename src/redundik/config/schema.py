"""Pydantic models of the YAML files: robot configs (``configs/*.yaml``) and task runs (``tasks/*.yaml``).

The models only check *shape*: known keys (``extra="forbid"``), types (strict: a string is never a number, an
integer is accepted where a float is meant), finiteness (NaN and ±inf rejected). Everything that needs the robot
(frame and joint names, vector lengths, resolver names) is checked by :mod:`redundik.config.loader`, which also
turns every error into a one-line :class:`~redundik.errors.ConfigError` naming the YAML key path.

Typed entries (``main`` tasks, ``potentials``, ``monitors``, trajectories) are mappings with a ``type`` key; their
models are derived from the library's constructors by :mod:`redundik.config.registry` (registered in
:mod:`redundik.config.types`), so they are not written here.

The reference of the format is ``docs/task-files.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    WithJsonSchema,
    field_validator,
    model_validator,
)

from redundik.errors import short_repr
from redundik.reporting.paths import name_problem

if TYPE_CHECKING:
    from redundik.simulation.plant import PlantOptions


def _name(value: Any) -> Any:
    """YAML reads ``frame: 3`` as an integer; names are strings, so accept integers and turn them into text."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return value


#: A frame / joint / task name: a string (an integer in the YAML is taken as its decimal text).
Name = Annotated[str, BeforeValidator(_name), WithJsonSchema({"type": ["string", "integer"]})]


#: Pinocchio's name of the world frame and joint: a D-H row or frame of that name would shadow it.
RESERVED_NAMES = ("universe",)


def _model_name(value: str) -> str:
    """A name the robot model will carry (D-H rows, frame 0, extra frames, the robot): it ends up in CSV headers,
    figures, the HTML replay and terminal tables, so it must be printable text (no NUL, newline or escape)."""
    if not value.strip():
        raise ValueError("expected a non-empty name")
    if not value.isprintable():
        raise ValueError(f"{short_repr(value)}: a name must be printable text (no control characters)")
    if len(value) > 200:
        raise ValueError(f"{short_repr(value)}: a name must be at most 200 characters, got {len(value)}")
    return value


def _frame_name(value: str) -> str:
    _model_name(value)
    if value in RESERVED_NAMES:
        raise ValueError(f"{value!r} is the name of Pinocchio's world frame; choose another name")
    return value


#: The name of the robot (reports, summary.json, figures): printable text.
ModelName = Annotated[
    str, BeforeValidator(_name), AfterValidator(_model_name), WithJsonSchema({"type": ["string", "integer"]})
]
#: A frame or joint a robot config defines (a D-H row, frame 0, an extra frame): printable, not ``universe``.
FrameName = Annotated[
    str, BeforeValidator(_name), AfterValidator(_frame_name), WithJsonSchema({"type": ["string", "integer"]})
]


def _safe_name(value: str) -> str:
    problem = name_problem(value)
    if problem is not None:
        raise ValueError(problem)
    return value


def robot_reference(robot: Any) -> Any:
    """The ``robot:`` of a task or sweep file: a config path, ``example-robot-data:NAME`` or an inline mapping."""
    if robot is None or not isinstance(robot, (str, dict)):
        raise ValueError(
            f"expected a config path, 'example-robot-data:NAME' or an inline mapping, got {short_repr(robot)}"
        )
    return robot


#: A name that becomes a file name (task and run names): see :data:`redundik.reporting.paths.NAME_PATTERN`.
SafeName = Annotated[str, BeforeValidator(_name), AfterValidator(_safe_name)]
#: A 3-vector [length or angle unit].
Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
#: A geometric number of a robot file, |x| ≤ 1e6 (length unit or angle unit): larger ones overflow the kinematics.
Bounded = Annotated[float, Field(ge=-1e6, le=1e6)]
AngleUnit = Literal["deg", "rad"]
Axis = Literal["x", "y", "z"]


class StrictModel(BaseModel):
    """Base of every YAML model: unknown keys, wrong types and NaN/inf are errors."""

    model_config = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)


# ---------------------------------------------------------------------------------------------------- robot files
class BaseSpec(StrictModel):
    """Placement of frame 0 in the world (A_b^0 of eq. 5.13): ``xyz`` + ``rpy`` or a 4×4 ``matrix``."""

    xyz: Vec3 | None = None
    rpy: Vec3 | None = None
    matrix: list[Annotated[list[float], Field(min_length=4, max_length=4)]] | None = None

    @model_validator(mode="after")
    def _one_form(self) -> BaseSpec:
        if self.matrix is not None:
            if self.xyz is not None or self.rpy is not None:
                raise ValueError("give either matrix or xyz/rpy, not both")
            if len(self.matrix) != 4:
                raise ValueError(f"matrix: expected 4 rows of 4 numbers, got {len(self.matrix)} rows")
        return self


class DHRowSpec(StrictModel):
    """One standard D-H row (see :class:`redundik.kinematics.DHRow`); angles in the file's ``angle_unit``."""

    name: FrameName
    type: Literal["revolute", "prismatic", "fixed"] = "revolute"
    theta: Bounded = 0.0
    d: Bounded = 0.0
    a: Bounded = 0.0
    alpha: Bounded = 0.0
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = Field(default=None, gt=0)
    parent: Name | None = None
    joint: Name | None = None


class FrameSpec(StrictModel):
    """An extra operational frame fixed to an existing frame (a tool point, a marker)."""

    parent: Name
    xyz: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class JointLimitSpec(StrictModel):
    """Override of one joint's limits (angles in the file's ``angle_unit`` for revolute joints)."""

    lower: float | None = None
    upper: float | None = None
    velocity: float | None = Field(default=None, gt=0)


#: Most rows of a D-H table (Pinocchio's model data grows as n³: 200 rows take ~0.9 GB and 1.4 s to build, 400
#: rows ~6 GB and 13 s; the shipped snake has 40, the benchmark's largest 160).
MAX_DH_ROWS = 200


class RobotSpec(StrictModel):
    """A robot config file (``configs/*.yaml``), or the inline ``robot:`` mapping of a task file."""

    name: ModelName | None = None
    description: str = ""
    length_unit: str = "m"
    angle_unit: AngleUnit = "rad"
    base: BaseSpec | None = None
    base_frame: FrameName = "0"
    dh: list[DHRowSpec] | None = Field(default=None, min_length=1)
    urdf: str | None = None
    free_flyer: bool | None = None
    q0: list[float] | None = None
    frames: dict[FrameName, FrameSpec] = Field(default_factory=dict)
    joint_limits: dict[Name, JointLimitSpec] = Field(default_factory=dict)

    @field_validator("dh")
    @classmethod
    def _few_rows(cls, dh: list[DHRowSpec] | None) -> list[DHRowSpec] | None:
        if dh is not None and len(dh) > MAX_DH_ROWS:
            raise ValueError(
                f"at most {MAX_DH_ROWS} D-H rows, got {len(dh)}: the model's memory grows as n³ (400 rows need "
                "about 6 GB)"
            )
        return dh

    @model_validator(mode="after")
    def _one_source(self) -> RobotSpec:
        if (self.dh is None) == (self.urdf is None):
            raise ValueError(
                "give exactly one of 'dh' (a D-H table) or 'urdf' (a URDF path or example-robot-data:NAME)"
            )
        if self.dh is not None and self.free_flyer:
            raise ValueError("free_flyer applies to URDF robots only")
        return self


# ---------------------------------------------------------------------------------------------------- task files
class SubtaskSpec(StrictModel):
    """How one run uses a named potential: a typed subtask (:mod:`redundik.tasks.subtasks`).

    ``kind``: ``gradient`` (``gain``), ``target`` (``target``, ``rate``, ``target_rate``, ``weight``, ``priority``)
    or ``bound`` (``lower``/``upper``, ``rate``, ``priority``); inferred when omitted (``target`` → target,
    ``lower``/``upper`` → bound, else gradient). ``mode`` is the old spelling of ``kind`` (``bounds`` = ``bound``).
    """

    kind: Literal["gradient", "target", "bound"] | None = None
    mode: Literal["gradient", "target", "bounds"] | None = None
    gain: float | None = None
    target: float | None = None
    rate: float | None = Field(default=None, ge=0)
    target_rate: float | None = None
    lower: float | None = None
    upper: float | None = None
    weight: float | None = Field(default=None, gt=0)
    priority: int | None = Field(default=None, ge=0)


#: A servo gain of a plant: ≥ 0, at most 1e9 (larger ones make the simulation blow up).
Gain = Annotated[float, Field(ge=0, le=1e9)]


class PlantSpec(StrictModel):
    """``plant:`` (task file or run): drive a simulated robot instead of integrating q̇ (see ``docs/task-files.md``).

    Gains are per joint (a number for all, or a mapping joint → value): ``kp`` [N·m/rad or N/m], ``kv``
    [N·m·s/rad or N·s/m] (position actuators: damping; velocity actuators: the velocity gain). ``sim_dt`` [s] must
    divide the control ``dt``. ``armature`` [kg·m²] adds reflected rotor inertia to every joint.
    """

    type: Literal["mujoco"]
    actuator: Literal["position", "velocity"] = "position"
    kp: Gain | dict[Name, Gain] = 2000.0
    kv: Gain | dict[Name, Gain] = 100.0
    sim_dt: float = Field(default=0.001, gt=0, le=1.0)  # [s], at most DT_MAX (defined below)
    gravity: bool = True
    gravity_compensation: bool = True
    effort_limits: bool = True
    armature: float = Field(default=0.1, ge=0)
    kinematic_reference: bool = True

    def options(self) -> PlantOptions:
        """The plant's options record (:class:`redundik.simulation.plant.PlantOptions`)."""
        from redundik.simulation.plant import PlantOptions  # lazy: validation imports nothing numerical

        return PlantOptions(**self.model_dump())


#: Integrators of a run (:mod:`redundik.simulation.integrators`).
IntegratorName = Literal["euler", "rk4", "rk45"]
#: Bounds of a run's time grid: steps ≤ MAX_STEPS, DT_MIN ≤ dt ≤ DT_MAX [s] (see docs/task-files.md).
MAX_STEPS = 1_000_000
DT_MIN, DT_MAX = 1e-6, 1.0
#: Smallest ``rtol`` of ``rk45`` (the value of :data:`redundik.simulation.integrators.RTOL_MIN`, repeated here so that
#: the schema imports nothing numerical): SciPy raises smaller ones to 100 ε behind a warning.
RTOL_MIN = 1e-13
#: Longest ``duration`` [s] (duration / dt must also give at most MAX_STEPS steps).
MAX_DURATION = 1e6


class RunSpec(StrictModel):
    """One named run: a resolver, its options, the subtasks it controls and per-run overrides."""

    description: str = ""
    resolver: Name = "pinv"
    options: dict[str, Any] = Field(default_factory=dict)
    subtasks: dict[Name, SubtaskSpec | None] = Field(default_factory=dict)
    gains: dict[Name, float] = Field(default_factory=dict)
    weights: dict[Name, float] = Field(default_factory=dict)
    main: list[dict[str, Any]] | None = None
    extra_main: list[dict[str, Any]] = Field(default_factory=list)
    q0: list[float] | None = None
    plant: PlantSpec | None = None
    integrator: IntegratorName | None = None
    rtol: float | None = Field(default=None, ge=RTOL_MIN, lt=1)
    atol: float | None = Field(default=None, gt=0, lt=1)


class DrawSpec(StrictModel):
    """What the configuration figure draws.

    ``frames``: a chain of frame names (links are drawn between consecutive ones) or a list of chains; by default
    the robot's own skeleton. ``plane``: two world axes for a planar drawing (else chosen automatically: x–y when
    everything stays in that plane, 3-D otherwise). ``every``: samples between two drawn configurations.
    """

    frames: list[Any] | None = None
    plane: Annotated[list[Axis], Field(min_length=2, max_length=2)] | None = None
    every: int | None = Field(default=None, ge=1)
    path: Name | None = None


class TaskFileSpec(StrictModel):
    """A task-run file (``tasks/*.yaml``)."""

    name: SafeName
    description: str = ""
    robot: Any
    angle_unit: AngleUnit = "rad"
    q0: list[float] | None = None
    dt: float = Field(ge=DT_MIN, le=DT_MAX)
    steps: int | None = Field(default=None, ge=1, le=MAX_STEPS)
    duration: float | None = Field(default=None, gt=0, le=MAX_DURATION)
    integrator: IntegratorName = "euler"
    rtol: float = Field(default=1e-10, ge=RTOL_MIN, lt=1)
    atol: float = Field(default=1e-12, gt=0, lt=1)
    main: list[dict[str, Any]] = Field(default_factory=list)
    potentials: dict[Name, dict[str, Any]] = Field(default_factory=dict)
    monitors: dict[Name, dict[str, Any]] = Field(default_factory=dict)
    runs: dict[SafeName, RunSpec] = Field(min_length=1)
    draw: DrawSpec | None = None
    log_frames: list[Name] = Field(default_factory=list)
    #: The robot's collision shapes and pair filters (redundik.config.world_types.CollisionSpec).
    collision: dict[str, Any] | None = None
    #: Named environment obstacles (redundik.config.world_types.ObstacleSpec).
    obstacles: dict[Name, dict[str, Any]] = Field(default_factory=dict)
    plant: PlantSpec | None = None

    @model_validator(mode="after")
    def _duration(self) -> TaskFileSpec:
        if (self.steps is None) == (self.duration is None):
            raise ValueError("give exactly one of 'steps' (number of time steps) or 'duration' [s]")
        return self

    @field_validator("robot")
    @classmethod
    def _robot(cls, robot: Any) -> Any:
        return robot_reference(robot)

    @property
    def n_steps(self) -> int:
        """Number of time steps (``steps``, or ``duration / dt`` rounded)."""
        if self.steps is not None:
            return self.steps
        assert self.duration is not None  # guaranteed by the validator
        return max(1, round(self.duration / self.dt))
