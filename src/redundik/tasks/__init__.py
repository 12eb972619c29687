"""The task API: main tasks (J, V, e), subtask potentials (p, η) and trajectories."""

from redundik.tasks.base import Potential, Subtask, Task, TaskStack, TaskTerm, stack_terms
from redundik.tasks.coupling import JointCoupling
from redundik.tasks.frame import AXIS_SETS, FrameTask, PostureTask
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
from redundik.tasks.trajectory import Circle, Hold, Line, PoseInterpolation, Trajectory

__all__ = [
    "AXIS_SETS",
    "BestPosture",
    "Circle",
    "Clearance",
    "FrameTask",
    "Hold",
    "JointCentering",
    "JointCoupling",
    "JointSine2",
    "JointValue",
    "Line",
    "Manipulability",
    "PoseInterpolation",
    "PostureTask",
    "Potential",
    "PotentialTask",
    "Subtask",
    "Task",
    "TaskStack",
    "TaskTerm",
    "Trajectory",
    "VirtualPoint",
    "stack_terms",
]
