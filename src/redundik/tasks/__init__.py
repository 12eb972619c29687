"""The task API: tasks (J, V, e), potentials (p, η), barriers (h, H), typed subtasks, the stack, trajectories.

Besides the frame, posture, coupling and balance tasks: the relative pose of two end-effectors (:mod:`.relative`,
section 5.3) and a joint visiting waypoints (:mod:`.waypoints`, the (6+1) robot's round trip).
"""

from redundik.tasks.balance import CoMTask, ContactTask, SupportPolygon
from redundik.tasks.base import (
    Barrier,
    BarrierTerm,
    CompiledBarrier,
    CompiledGradient,
    CompiledRows,
    Potential,
    Task,
    TaskTerm,
    stack_terms,
)
from redundik.tasks.coupling import JointCoupling
from redundik.tasks.frame import AXIS_SETS, DEFAULT_HOLD_GAIN, FrameTask, PostureTask
from redundik.tasks.potential_rows import CompiledPotential
from redundik.tasks.potential_task import PotentialTask
from redundik.tasks.potentials import (
    BestPosture,
    Clearance,
    JointCentering,
    JointSine2,
    JointValue,
    Manipulability,
    VirtualPoint,
)
from redundik.tasks.relative import RelativePoseTask
from redundik.tasks.rows import CompiledTask
from redundik.tasks.stack import LevelPlan, StackLayout, TaskStack
from redundik.tasks.subtasks import BoundSubtask, GradientSubtask, Subtask, TargetSubtask
from redundik.tasks.trajectory import Circle, Hold, Line, PoseInterpolation, Trajectory
from redundik.tasks.waypoints import JointWaypoints

__all__ = [
    "AXIS_SETS",
    "DEFAULT_HOLD_GAIN",
    "Barrier",
    "BarrierTerm",
    "BestPosture",
    "BoundSubtask",
    "Circle",
    "Clearance",
    "CoMTask",
    "CompiledBarrier",
    "CompiledGradient",
    "CompiledPotential",
    "CompiledRows",
    "CompiledTask",
    "ContactTask",
    "FrameTask",
    "GradientSubtask",
    "Hold",
    "JointCentering",
    "JointCoupling",
    "JointSine2",
    "JointValue",
    "JointWaypoints",
    "LevelPlan",
    "Line",
    "Manipulability",
    "PoseInterpolation",
    "PostureTask",
    "Potential",
    "PotentialTask",
    "RelativePoseTask",
    "StackLayout",
    "Subtask",
    "SupportPolygon",
    "TargetSubtask",
    "Task",
    "TaskStack",
    "TaskTerm",
    "Trajectory",
    "VirtualPoint",
    "stack_terms",
]
