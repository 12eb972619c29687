"""redundik: differential inverse kinematics of redundant robots.

q̇ = J⁺V + (I − J⁺J)z, resolved by the chapter's closed forms (pseudo-inverse with null-space projection, the
state-feedback gain law) and by QP task stacks, on Pinocchio models built from D-H tables or URDF.

Typical control-loop use::

    import redundik as rk
    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1), rk.DHRow("3", a=1)])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
                         [rk.GradientSubtask(rk.JointSine2("3"), gain=1.0)])
    resolver = rk.PinvResolver()
    robot.update(q); stack.reset(robot)
    for tick in ...:
        dq = resolver.step(robot, stack, q, t, dt).dq
        q = robot.integrate(q, dq, dt)
"""

from redundik.errors import (
    ConfigError,
    MechanismError,
    ModelError,
    RedundikError,
    ResolverError,
    SolverError,
    TaskError,
)
from redundik.kinematics import DHRow, RobotModel, dh_matrix, from_dh, from_urdf, load_example_robot
from redundik.resolvers import (
    FeedbackResolver,
    HierarchicalQPResolver,
    JointLimits,
    PinvResolver,
    Resolver,
    StepResult,
    WeightedQPResolver,
    make_resolver,
    pseudo_inverse,
)
from redundik.simulation import SimulationLog, simulate
from redundik.tasks import (
    Barrier,
    BarrierTerm,
    BestPosture,
    BoundSubtask,
    Circle,
    Clearance,
    FrameTask,
    GradientSubtask,
    Hold,
    JointCentering,
    JointCoupling,
    JointSine2,
    JointValue,
    Line,
    Manipulability,
    PoseInterpolation,
    PostureTask,
    Potential,
    PotentialTask,
    Subtask,
    TargetSubtask,
    Task,
    TaskStack,
    TaskTerm,
    VirtualPoint,
)

__version__ = "0.1.0"

__all__ = [
    "Barrier",
    "BarrierTerm",
    "BestPosture",
    "BoundSubtask",
    "Circle",
    "Clearance",
    "ConfigError",
    "DHRow",
    "FeedbackResolver",
    "FrameTask",
    "GradientSubtask",
    "HierarchicalQPResolver",
    "Hold",
    "JointCentering",
    "JointCoupling",
    "JointLimits",
    "JointSine2",
    "JointValue",
    "Line",
    "Manipulability",
    "MechanismError",
    "ModelError",
    "PinvResolver",
    "PoseInterpolation",
    "PostureTask",
    "Potential",
    "PotentialTask",
    "RedundikError",
    "Resolver",
    "ResolverError",
    "RobotModel",
    "SimulationLog",
    "SolverError",
    "StepResult",
    "Subtask",
    "TargetSubtask",
    "Task",
    "TaskError",
    "TaskStack",
    "TaskTerm",
    "VirtualPoint",
    "WeightedQPResolver",
    "__version__",
    "dh_matrix",
    "from_dh",
    "from_urdf",
    "load_example_robot",
    "make_resolver",
    "pseudo_inverse",
    "simulate",
]
