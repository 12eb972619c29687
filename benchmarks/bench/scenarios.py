"""The benchmark's robots and tasks, each expressed once per method on the same robot (identical task set).

Three scenarios (see ``docs/benchmark.md``):

* ``planar3r``: the chapter's 3R arm (D-H, a = 1 m), tip on the line v = (0.2, −0.4) m/s from q0 = (110°, −40°, −30°)
  for 5 s (the chapter's episode, repeated), subtask p = sin²θ3 raised (target 1 with K = 1/s; gradient k = 1 for
  ``pinv``).
* ``panda_circle``: Franka Panda (example-robot-data), pose task on ``panda_hand`` along a 5 cm circle in the y–z plane
  (period 4 s, orientation held), posture subtask, joint position and velocity limits; the 3-level ``hqp`` is
  [hand pose] > [elbow ≥ 10 cm from a post, an inequality] > [posture].
* ``talos``: Talos (``talos_reduced.urdf``, free flyer), both grippers on 5 cm circles (pose tasks), posture on the
  actuated joints, limits; the 3-level ``hqp`` puts a left-elbow clearance inequality between hands and posture.

What each method's stack means (the same task as the peers': frame tasks + posture + limits):

* ``wqp``: frame tasks and the library's :class:`~redundik.tasks.frame.PostureTask` given an explicit level
  (``priority=0``, weight 0.01: a main task of the frames' level) in one QP with the limits — literally the peers'
  weighted QP (their cost c weighs rows by c²). Without an explicit level the library's posture is a regularisation
  below every level (redundik's own meaning of a posture, not the peers' weighted sum). It covers every velocity
  coordinate, so on Talos it also pulls the floating base towards q0's (the peers leave the base free: six rows more
  for redundik). ``talos_actuated`` gives the same posture ``joints="actuated"``: the floating base left out, the
  peers' task set exactly.
* ``hqp``: frames (level 0) > post clearance, an inequality inactive on the circle (level 1) > the same posture
  rows (level 2), limits above all: the hierarchy whose null-space optimum is the closed forms' posture.
* ``pinv``: the posture as the null-space gradient z = −K_p(q − q0) on the actuated joints (eq. 5.8; the floating
  base of Talos is left free, as the peers do); no limits (pinv has none, so its
  rows on ``panda_tight`` and ``talos`` break them and are reported FAILED).
* ``feedback``: the posture as the same gradient subtask as ``pinv`` (the state-feedback law passes gradient
  subtasks through the null space, eq. 5.8); no limits either. The earlier target form p = ½‖q − q0‖² → 0 is
  unreachable while the frames move, and its decoupling gain ‖η‖/‖Pη‖ made Euler drift (docs/benchmark.md).
* ``planar3r``: no posture; sin²θ3 → 1 at 1/s as a target subtask (``feedback``, ``wqp``, ``hqp`` and the peers'
  1-row task), as the gradient k = 1 under ``pinv`` (which refuses target subtasks).

Each case is FAILED (and left out of the ratios) when its frame-task error exceeds :data:`ERROR_TOLERANCE`, its
robot does not move, it falls back on more than 1 % of the steps, or it breaks the joint limits
(:func:`benchmarks.bench.harness.case_status`).

Every frame task tracks its reference with feed-forward plus the error gain K = 1/dt, which is exactly the peers'
dead-beat task (gain α = 1 towards the pose of the next sample): J Δq = p_d(t + dt) − p(t) ≈ dt (ṗ_d + e/dt).
The posture is K_p = 1/s with weight 0.01 against 1 for the frames (peer costs 0.1 and 1: a peer's cost c weighs
its rows by c², and its gain α = K_p·dt).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from redundik.kinematics.dh import DHRow, from_dh
from redundik.kinematics.model import RobotModel
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir, load_example_robot
from redundik.tasks.base import Barrier, Potential, Task
from redundik.tasks.frame import FrameTask, PostureTask
from redundik.tasks.potentials import Clearance, JointCentering, JointSine2
from redundik.tasks.stack import TaskStack
from redundik.tasks.subtasks import BoundSubtask, GradientSubtask, Subtask, TargetSubtask
from redundik.tasks.trajectory import Circle, Line, Trajectory

POSTURE_GAIN = 1.0  # K_p [1/s]
#: Tracking tolerance of every scenario: 1 mm (and 1 mrad) on the stacked frame-task error, the contract's figure
#: for the control loop; a case above it is reported FAILED [m, rad].
ERROR_TOLERANCE = 1e-3
POSTURE_WEIGHT = 0.01  # against 1 for frame tasks (peer cost 0.1)


@dataclass
class FrameSpec:
    """One tracked frame: name, axes and a trajectory factory (each case gets a fresh trajectory)."""

    frame: str
    axes: str
    trajectory: Callable[[], Trajectory]


@dataclass
class Scenario:
    """One robot with its task set, expressed for every method.

    Attributes:
        key: Short name used in reports (``"panda"``).
        title: Human-readable description.
        robot: Factory of the redundik model (a fresh one per case).
        q0: Start configuration (redundik coordinates).
        dt: Control step [s].
        frames: The tracked frames.
        episode: Steps per episode (the run restarts from q0 after that many steps), ``None`` for continuous.
        monitor: Factory of the potential reported as the subtask value.
        monitor_label: What the monitored value is.
        urdf: (path, free_flyer) for the peers' models, or ``None`` for a D-H robot.
        posture: Whether the posture task is part of the set (QP methods and peers).
        peer_potential: For the peers: (potential factory, keyword arguments of the adapter task), or ``None``.
        error_tolerance: Largest stacked frame-task error a case may reach and still count as tracking [m and rad
            stacked]; above it the case is FAILED (see :func:`benchmarks.bench.harness.case_status`).
    """

    key: str
    title: str
    robot: Callable[[], RobotModel]
    q0: np.ndarray
    dt: float
    frames: list[FrameSpec]
    episode: int | None
    monitor: Callable[[], Potential]
    monitor_label: str
    urdf: tuple[str, bool] | None = None
    posture: bool = True
    peer_potential: tuple[Callable[[], Potential], dict[str, Any]] | None = None
    error_tolerance: float = ERROR_TOLERANCE
    stacks: dict[str, Callable[[RobotModel], TaskStack]] = field(default_factory=dict)
    #: Methods that apply (``None``: every method); the others are not built for this robot.
    methods: tuple[str, ...] | None = None
    #: Whether wqp/hqp run with every installed QP backend (else the default backend only).
    all_backends: bool = True
    #: Timed steps (and chunk) of this robot relative to the configured ones (slow robots run fewer).
    step_factor: float = 1.0
    #: Whether PlaCo runs this task set (the same URDF; see :mod:`benchmarks.bench.placo_peer`).
    placo: bool = False
    #: Largest frame-task error at the last step of every episode (``None``: not checked) [m and rad stacked].
    final_tolerance: float | None = None
    #: Gain of the frame tasks (``None``: 1/dt, the peers' dead-beat task).
    frame_gain: float | None = None
    #: The model the method's stack is bound to (``None``: a fresh :attr:`robot`): a collision world is built for
    #: one model object, so the runner takes that one and the common ruler another (with its own world).
    runner_robot: Callable[[], RobotModel] | None = None
    #: Teleoperation: redundik's frame tasks hold a target of their own that the runner moves with ``set_target``
    #: every tick (inside the timed tick) to the reference pose of t + dt; the peers are re-targeted every tick too.
    teleop: bool = False
    #: The class of redundik's frame tasks (a user's subclass in ``panda_user_task``).
    frame_class: type[FrameTask] = FrameTask
    #: Extra main tasks of redundik's stacks after the frame tasks (a user's own task in ``panda_custom_task``).
    extra_tasks: Callable[[], list[Task]] | None = None

    def frame_tasks(self, gain: float | None = None) -> list[Task]:
        """Fresh frame tasks with gain K = 1/dt (or ``gain``)."""
        k = (1.0 / self.dt if self.frame_gain is None else self.frame_gain) if gain is None else gain
        return [FrameTask(f.frame, f.trajectory(), axes=f.axes, gain=k, name=f.frame) for f in self.frames]

    def stack_tasks(self) -> list[Task]:
        """The main tasks of redundik's stacks: the frame tasks (of :attr:`frame_class`; without a trajectory when
        :attr:`teleop`: the runner sets their targets), then :attr:`extra_tasks`."""
        if not self.teleop and self.frame_class is FrameTask:
            tasks = self.frame_tasks()
        else:
            k = 1.0 / self.dt if self.frame_gain is None else self.frame_gain
            tasks = [
                self.frame_class(f.frame, None if self.teleop else f.trajectory(), axes=f.axes, gain=k, name=f.frame)
                for f in self.frames
            ]
        return tasks + (self.extra_tasks() if self.extra_tasks is not None else [])

    def posture_task(self, priority: int = 0) -> PostureTask:
        """The library's posture task towards q0, at an explicit level (weight 0.01: the peers' weighted sum)."""
        return PostureTask(self.q0, gain=POSTURE_GAIN, weight=POSTURE_WEIGHT, priority=priority)

    def actuated_posture_task(self, priority: int = 0) -> PostureTask:
        """The library's posture of the actuated joints (``joints="actuated"``: a floating base left out, as the
        peers' postures leave it), at an explicit level (``talos_actuated``)."""
        return PostureTask(self.q0, joints="actuated", gain=POSTURE_GAIN, weight=POSTURE_WEIGHT, priority=priority)

    def stack(self, method: str, robot: RobotModel) -> TaskStack:
        """The task stack of a redundik method (``pinv``, ``feedback``, ``wqp``, ``hqp``)."""
        return self.stacks[method](robot)


# ---------------------------------------------------------------------------------------------------------- 3R
def _planar3r() -> RobotModel:
    lim = np.pi
    rows = [DHRow(str(i), a=1.0, lower=-lim, upper=lim, velocity=np.pi) for i in (1, 2, 3)]
    return from_dh(rows, name="planar3r")


def planar3r_scenario() -> Scenario:
    """The chapter's 3R line task (section 5.2, Figs. 5.7–5.8)."""
    sc = Scenario(
        key="planar3r",
        title="3R arm (D-H), tip on a line, sin²θ3 raised",
        robot=_planar3r,
        q0=np.deg2rad([110.0, -40.0, -30.0]),
        dt=0.01,
        frames=[FrameSpec("3", "planar", lambda: Line([0.2, -0.4]))],
        episode=500,
        monitor=lambda: JointSine2("3"),
        monitor_label="sin²θ3",
        posture=False,
        peer_potential=(lambda: JointSine2("3"), {"mode": "target", "target": 1.0, "rate": 1.0, "cost": 1.0}),
    )
    sc.stacks = {
        "pinv": lambda r: TaskStack(sc.frame_tasks(), [GradientSubtask(JointSine2("3"), gain=1.0)]),
        "feedback": lambda r: TaskStack(sc.frame_tasks(), [TargetSubtask(JointSine2("3"), target=1.0)]),
        "wqp": lambda r: TaskStack(sc.frame_tasks(), [TargetSubtask(JointSine2("3"), target=1.0)]),
        "hqp": lambda r: TaskStack(sc.frame_tasks(), [TargetSubtask(JointSine2("3"), target=1.0)]),
    }
    return sc


# ---------------------------------------------------------------------------------------------------------- Panda
PANDA_Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def panda_scenario() -> Scenario:
    """Panda hand on a 5 cm circle (orientation held) + posture + limits; hqp has 3 levels."""
    omega = 2.0 * np.pi / 4.0
    sc = Scenario(
        key="panda_circle",
        title="Panda, hand on a 5 cm circle, posture, limits",
        robot=lambda: load_example_robot("panda"),
        q0=PANDA_Q0.copy(),
        dt=0.01,
        frames=[FrameSpec("panda_hand", "pose", lambda: Circle(0.05, omega, ("y", "z")))],
        episode=None,
        monitor=lambda: JointCentering(center=PANDA_Q0, name="posture_dist"),
        monitor_label="½‖q − q0‖²",
        urdf=EXAMPLE_ROBOTS["panda"],
        placo=True,
    )
    sc.stacks = {
        "pinv": lambda r: TaskStack(sc.stack_tasks(), [_posture_gradient(r, PANDA_Q0)]),
        "feedback": lambda r: TaskStack(sc.stack_tasks(), [_posture_gradient(r, PANDA_Q0)]),
        "wqp": lambda r: TaskStack([*sc.stack_tasks(), sc.posture_task()]),
        "hqp": lambda r: TaskStack(
            [*sc.stack_tasks(), sc.posture_task(priority=2)], [_post_clearance(r, "panda_link4", PANDA_Q0)]
        ),
    }
    return sc


def actuated_weights(robot: RobotModel) -> np.ndarray:
    """Per-q̇ weights (nv,): 1 on the actuated 1-dof joints, 0 on a floating base — the rows of the
    peers' posture tasks (actuated joints only), so that the closed forms' posture potential is the same posture."""
    w = np.zeros(robot.nv)
    for j in robot.joints:
        if j.idx_q >= 0 and j.kind != "other":
            w[j.idx_v] = 1.0
    return w


def _posture_gradient(robot: RobotModel, q0: np.ndarray) -> Subtask:
    """The closed forms' posture: z = −K_p ∇½‖q − q0‖²_W on the actuated joints (eq. 5.8), the null-space twin of the
    peers' posture of the actuated joints (whose null-space optimum is the same −K_p(q − q0)_a)."""
    return GradientSubtask(JointCentering(center=q0, weights=actuated_weights(robot)), gain=-POSTURE_GAIN)


def _post_clearance(robot: RobotModel, frame: str, q0: np.ndarray, side: float = 0.25) -> Subtask:
    """Level 1 of the 3-level hqp: keep ``frame`` ≥ 10 cm from a vertical post (r = 5 cm) 25 cm to its side.

    An inequality level, inactive at the start (the issue's elbow–obstacle example), between the frame tasks
    (level 0) and the posture (level 2).
    """
    robot.update(q0)
    center = robot.frame_position(frame) + np.array([0.0, side, 0.0])
    return BoundSubtask(
        Clearance(frame, center, radius=0.05, axes=("x", "y"), name="post_clearance"), lower=0.10, rate=10.0, priority=1
    )


def _panda_tight() -> RobotModel:
    """The Panda with panda_joint1 limited to ±0.02 rad, so the circle keeps a joint limit active."""
    base = load_example_robot("panda")
    model = base.model.copy()
    iq = base.joint("panda_joint1").idx_q
    model.lowerPositionLimit[iq], model.upperPositionLimit[iq] = -0.02, 0.02
    return RobotModel(model, name="panda_tight")


def panda_tight_scenario() -> Scenario:
    """The Panda circle with a joint limit that binds (panda_joint1 ∈ ±0.02 rad): the QP backends really work.

    Not one of the issue's target cases; it shows what each backend costs when a constraint is active (in the
    plain circle no limit is reached, so wqp/hqp take their closed-form shortcut and never call a backend).
    """
    sc = panda_scenario()
    sc.key = "panda_tight"
    sc.title = "Panda circle with panda_joint1 limited to ±0.02 rad (an active limit)"
    sc.robot = _panda_tight
    sc.placo = False  # PlaCo reads the URDF's limits
    sc.urdf = None  # peers: MuJoCo model built from the modified redundik model (same kinematics, new limits)
    return sc


# ---------------------------------------------------------------------------------------------------------- Talos
#: Talos half-sitting posture (actuated joints), the usual start of its examples.
TALOS_HALF_SITTING: dict[str, float] = {
    "leg_left_3_joint": -0.411354,
    "leg_left_4_joint": 0.859395,
    "leg_left_5_joint": -0.448041,
    "leg_left_6_joint": -0.001708,
    "leg_right_3_joint": -0.411354,
    "leg_right_4_joint": 0.859395,
    "leg_right_5_joint": -0.448041,
    "leg_right_6_joint": -0.001708,
    "torso_2_joint": 0.006761,
    "arm_left_1_joint": 0.25847,
    "arm_left_2_joint": 0.173046,
    "arm_left_3_joint": -0.0002,
    "arm_left_4_joint": -0.525366,
    "arm_left_7_joint": 0.1,
    "gripper_left_joint": -0.005,
    "arm_right_1_joint": -0.25847,
    "arm_right_2_joint": -0.173046,
    "arm_right_3_joint": 0.0002,
    "arm_right_4_joint": -0.525366,
    "arm_right_7_joint": 0.1,
    "gripper_right_joint": -0.005,
}


def talos_q0(robot: RobotModel) -> np.ndarray:
    """Half-sitting configuration of a Talos model (base at the origin)."""
    q = robot.neutral()
    for name, val in TALOS_HALF_SITTING.items():
        q[robot.joint(name).idx_q] = val
    return q


def talos_scenario() -> Scenario:
    """Talos with a free flyer: both grippers on 5 cm circles (pose), posture, limits."""
    robot0 = load_example_robot("talos")
    q0 = talos_q0(robot0)
    omega = 2.0 * np.pi / 4.0
    hands = ["gripper_left_base_link", "gripper_right_base_link"]
    sc = Scenario(
        key="talos",
        title="Talos (free flyer), two grippers on 5 cm circles, posture, limits",
        robot=lambda: load_example_robot("talos"),
        q0=q0,
        dt=0.01,
        frames=[
            FrameSpec(hands[0], "pose", lambda: Circle(0.05, omega, ("y", "z"))),
            FrameSpec(hands[1], "pose", lambda: Circle(0.05, omega, ("y", "z"), phase=np.pi)),
        ],
        episode=None,
        monitor=lambda: JointCentering(center=q0, name="posture_dist"),
        monitor_label="½‖q − q0‖²",
        urdf=EXAMPLE_ROBOTS["talos"],
        placo=True,
    )
    sc.stacks = {
        "pinv": lambda r: TaskStack(sc.stack_tasks(), [_posture_gradient(r, q0)]),
        "feedback": lambda r: TaskStack(sc.stack_tasks(), [_posture_gradient(r, q0)]),
        "wqp": lambda r: TaskStack([*sc.stack_tasks(), sc.posture_task()]),
        "hqp": lambda r: TaskStack(
            [*sc.stack_tasks(), sc.posture_task(priority=2)], [_post_clearance(r, "arm_left_4_link", q0)]
        ),
    }
    return sc


def talos_actuated_scenario() -> Scenario:
    """``talos`` with ``PostureTask(joints="actuated")`` in ``wqp``/``hqp``: the peers' task set exactly (their postures
    leave the floating base out). Its peers are ``talos``'s (the same task set)."""
    sc = talos_scenario()
    sc.key = "talos_actuated"
    sc.title = 'Talos as `talos`, posture = `PostureTask(joints="actuated")` (the floating base left out, as peers do)'
    sc.methods, sc.placo, sc.all_backends = ("wqp", "hqp"), False, False
    post = _post_clearance
    sc.stacks = {
        "wqp": lambda r: TaskStack([*sc.stack_tasks(), sc.actuated_posture_task()]),
        "hqp": lambda r: TaskStack(
            [*sc.stack_tasks(), sc.actuated_posture_task(priority=2)], [post(r, "arm_left_4_link", sc.q0)]
        ),
    }
    return sc


# ---------------------------------------------------------------------------------------------------------- snake
#: Joint counts of the snake scaling cases (``snake10`` … ``snake160``).
SNAKE_SIZES: tuple[int, ...] = (10, 20, 40, 80, 160)


def _snake(n: int) -> RobotModel:
    """The n-joint yaw–pitch snake of section 5.2 (D-H, links 4/n m, ±90°, 2 rad/s), built here from its rows."""
    rows = [
        DHRow(str(i + 1), a=4.0 / n, alpha=np.pi / 2 if i % 2 == 0 else -np.pi / 2, lower=-np.pi / 2,
              upper=np.pi / 2, velocity=2.0)
        for i in range(n)
    ]  # fmt: skip
    return from_dh(rows, name=f"snake{n}")


def snake_scenario(n: int) -> Scenario:
    """The snake of n joints: tip pose on a 15 cm circle (x–y, period 5 s), joint centering, three link
    clearances from points 12 cm beside the links at n/4, n/2, 3n/4 (section 5.2's scaling run).

    ``pinv`` descends the clearances and the centering in the null space (gradients, eq. 5.15); ``wqp`` and
    ``hqp`` keep the clearances ≥ 3 cm as inequalities (hqp: level 1) with the centering gradient below.
    Not a peer comparison (pinv, wqp, hqp only, default backend): the growth of the step time with n.
    """
    q0 = np.array([np.deg2rad(15 * np.sin(0.35 * i)) if i % 2 == 0 else np.deg2rad(10) for i in range(n)])
    frames = [str(n // 4), str(n // 2), str(3 * n // 4)]
    robot0 = _snake(n)
    robot0.update(q0)
    centers = [robot0.frame_position(f) + np.array([0.0, 0.12, 0.0]) for f in frames]

    def clearances() -> list[Clearance]:
        return [Clearance(f, c, 0.06, name=f"clear{f}") for f, c in zip(frames, centers, strict=True)]

    def closed_form(r: RobotModel) -> TaskStack:
        subs: list[Subtask] = [GradientSubtask(JointCentering(), gain=-1.0)]
        subs += [GradientSubtask(c, gain=0.3) for c in clearances()]
        return TaskStack(sc.frame_tasks(), subs)

    def qp(r: RobotModel) -> TaskStack:
        subs: list[Subtask] = [BoundSubtask(c, lower=0.03, rate=2.0, priority=1) for c in clearances()]
        subs.append(GradientSubtask(JointCentering(), gain=-1.0))
        return TaskStack(sc.frame_tasks(), subs)

    step_factor = {10: 1.0, 20: 1.0, 40: 0.5, 80: 0.25, 160: 0.1}.get(n, 0.1)
    sc = Scenario(
        key=f"snake{n}",
        title=f"snake, {n} joints (D-H), tip pose on a 15 cm circle, centering, 3 clearances",
        robot=lambda: _snake(n),
        q0=q0,
        dt=0.01,
        frames=[FrameSpec(str(n), "pose", lambda: Circle(0.15, 2.0 * np.pi / 5.0, ("x", "y")))],
        episode=None,
        monitor=lambda: JointCentering(name="centering"),
        monitor_label="½‖q‖²",
        posture=False,
        methods=("pinv", "wqp", "hqp"),
        all_backends=False,
        step_factor=step_factor,
    )
    sc.stacks = {"pinv": closed_form, "wqp": qp, "hqp": qp}
    return sc


# ---------------------------------------------------------------------------------------------------------- shelf
#: The task file of the collision case (issue 12 item 5).
SHELF_TASK = Path(__file__).resolve().parents[2] / "tasks" / "panda_shelf.yaml"


class MinCollisionDistance(Potential):
    """Monitor: the signed distance of the closest pair of a collision world [m] (negative: penetration)."""

    def __init__(self, world: Any) -> None:
        self.world, self.name = world, "min_collision_distance"

    def check(self, robot: RobotModel) -> None:
        self.world.check(robot)

    def value(self, robot: RobotModel) -> float:
        return float(self.world.closest(robot)[1])

    def gradient(self, robot: RobotModel) -> np.ndarray:  # a monitor only
        raise NotImplementedError


def panda_shelf_scenario() -> Scenario:
    """``tasks/panda_shelf.yaml``'s ``wqp`` run, as the config loader builds it: the hand on a 2 s line into a shelf
    bay past a post, posture, the collision velocity damper on 60 candidate pairs (capsules fitted to the Panda's
    collision meshes, SRDF-filtered self pairs, four obstacles), joint limits; 3 s episodes from q0.

    Status: the hand may leave its line while the damper bends the arm around the post (tolerance 2 cm during the
    motion), must end within 1 mm of the target at the end of every episode, and no pair may penetrate
    (``min_collision_distance`` ≥ 0).
    """
    from redundik.config.loader import load_task

    plan = load_task(SHELF_TASK)
    run = plan.runs["wqp"]
    base = plan.robot.model
    hand = run.stack.tasks[0]
    assert isinstance(hand, FrameTask)
    trajectory = hand.trajectory
    metrics_plan = load_task(SHELF_TASK)  # its own world for the common ruler

    sc = Scenario(
        key="panda_shelf",
        title="Panda reaching into a shelf past a post, collision damper (60 pairs), posture, limits",
        robot=lambda: metrics_plan.robot.model,
        q0=run.q0.copy(),
        dt=plan.dt,
        frames=[FrameSpec(hand.frame, "pose", lambda: copy.deepcopy(trajectory))],
        episode=plan.steps,
        monitor=lambda: MinCollisionDistance(metrics_plan.world),
        monitor_label="min collision distance [m]",
        posture=False,
        error_tolerance=0.02,
        methods=("wqp",),
        all_backends=False,
    )
    sc.runner_robot = lambda: base
    # for pink's barrier on the same geometry (runners.PinkShelfRunner)
    avoid = next(s.source for s in run.stack.subtasks if isinstance(getattr(s, "source", None), Barrier))
    posture = next(s for s in run.stack.subtasks if isinstance(s, GradientSubtask))
    sc.world, sc.avoid = plan.world, avoid  # type: ignore[attr-defined]
    sc.urdf_file = str(plan.robot.urdf)  # type: ignore[attr-defined]
    sc.posture_center = np.asarray(posture.potential.center, dtype=float)  # type: ignore[attr-defined]
    sc.posture_gain = -float(posture.gain)  # type: ignore[attr-defined]
    sc.level_ratio = float(getattr(run.resolver, "level_ratio", 1e-4))  # type: ignore[attr-defined]
    sc.pairs = plan.world.n_pairs  # type: ignore[attr-defined]
    sc.final_tolerance = ERROR_TOLERANCE
    sc.frame_gain = float(hand.gain)
    sc.stacks = {"wqp": lambda r: run.stack}
    return sc


SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "planar3r": planar3r_scenario,
    "panda_circle": panda_scenario,
    "panda_tight": panda_tight_scenario,
    "talos": talos_scenario,
    "talos_actuated": talos_actuated_scenario,
    **{f"snake{n}": (lambda n=n: snake_scenario(n)) for n in SNAKE_SIZES},  # type: ignore[misc]
    "panda_shelf": panda_shelf_scenario,
}


def urdf_path(scenario: Scenario) -> str:
    """Absolute path of the scenario's URDF (for the peers' models)."""
    if scenario.urdf is None:
        raise ValueError(f"scenario '{scenario.key}' has no URDF")
    return str(example_robot_data_dir() / scenario.urdf[0])
