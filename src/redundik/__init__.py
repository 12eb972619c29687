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

# The top level is lazy (PEP 562): ``import redundik`` loads only the error classes and the version, and a name
# such as ``redundik.FrameTask`` imports its subpackage (Pinocchio, SciPy) on first use. So ``redundik --help`` and
# ``redundik validate`` start without the numerical stack, and the CLI never pays for what it does not use.
from typing import TYPE_CHECKING, Any

from redundik import _coldstart
from redundik._version import __version__
from redundik.errors import (
    ConfigError,
    MechanismError,
    ModelError,
    RedundikError,
    ResolverError,
    SolverError,
    TaskError,
)


def _background_warm_up(resolvers: list[str]) -> dict[str, float]:
    """:func:`redundik.warmup.warm_up`, for the cold start's background thread (:mod:`redundik._coldstart`)."""
    from redundik.warmup import warm_up

    return warm_up(resolvers, ik=False)


_coldstart.WARM_UP = _background_warm_up
if _coldstart.background():  # the first steps run the kernels' own code: numba is imported by the thread compiling them
    from redundik import _kernel_cache

    _kernel_cache.defer_numba()

if TYPE_CHECKING:
    from redundik.control import ControlLoop, DeadlineStats, Tick, Watchdog
    from redundik.ik import IKBatchResult, IKResult, solve_ik, solve_ik_batch
    from redundik.kinematics import DHRow, RobotModel, dh_matrix, from_dh, from_urdf, load_example_robot
    from redundik.resolvers import (
        FeedbackResolver,
        HierarchicalQPResolver,
        JointLimits,
        PinvResolver,
        Resolver,
        SingularityGuard,
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
        CompiledBarrier,
        CompiledGradient,
        CompiledPotential,
        CompiledRows,
        CompiledTask,
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
        RelativePoseTask,
        Subtask,
        TargetSubtask,
        Task,
        TaskStack,
        TaskTerm,
        VirtualPoint,
    )
    from redundik.warmup import warm_up


#: Public name → the module that defines it (imported on first access).
_LAZY: dict[str, str] = {
    "ControlLoop": "redundik.control",
    "DeadlineStats": "redundik.control",
    "Tick": "redundik.control",
    "Watchdog": "redundik.control",
    "IKBatchResult": "redundik.ik",
    "IKResult": "redundik.ik",
    "solve_ik": "redundik.ik",
    "solve_ik_batch": "redundik.ik",
    "warm_up": "redundik.warmup",
    "DHRow": "redundik.kinematics",
    "RobotModel": "redundik.kinematics",
    "dh_matrix": "redundik.kinematics",
    "from_dh": "redundik.kinematics",
    "from_urdf": "redundik.kinematics",
    "load_example_robot": "redundik.kinematics",
    "FeedbackResolver": "redundik.resolvers",
    "HierarchicalQPResolver": "redundik.resolvers",
    "JointLimits": "redundik.resolvers",
    "PinvResolver": "redundik.resolvers",
    "Resolver": "redundik.resolvers",
    "SingularityGuard": "redundik.resolvers",
    "StepResult": "redundik.resolvers",
    "WeightedQPResolver": "redundik.resolvers",
    "make_resolver": "redundik.resolvers",
    "pseudo_inverse": "redundik.resolvers",
    "SimulationLog": "redundik.simulation",
    "simulate": "redundik.simulation",
    "Barrier": "redundik.tasks",
    "BarrierTerm": "redundik.tasks",
    "BestPosture": "redundik.tasks",
    "BoundSubtask": "redundik.tasks",
    "Circle": "redundik.tasks",
    "Clearance": "redundik.tasks",
    "CompiledBarrier": "redundik.tasks",
    "CompiledGradient": "redundik.tasks",
    "CompiledPotential": "redundik.tasks",
    "CompiledRows": "redundik.tasks",
    "CompiledTask": "redundik.tasks",
    "FrameTask": "redundik.tasks",
    "GradientSubtask": "redundik.tasks",
    "Hold": "redundik.tasks",
    "JointCentering": "redundik.tasks",
    "JointCoupling": "redundik.tasks",
    "JointSine2": "redundik.tasks",
    "JointValue": "redundik.tasks",
    "Line": "redundik.tasks",
    "Manipulability": "redundik.tasks",
    "PoseInterpolation": "redundik.tasks",
    "PostureTask": "redundik.tasks",
    "Potential": "redundik.tasks",
    "PotentialTask": "redundik.tasks",
    "RelativePoseTask": "redundik.tasks",
    "Subtask": "redundik.tasks",
    "TargetSubtask": "redundik.tasks",
    "Task": "redundik.tasks",
    "TaskStack": "redundik.tasks",
    "TaskTerm": "redundik.tasks",
    "VirtualPoint": "redundik.tasks",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'redundik' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later accesses skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "Barrier",
    "BarrierTerm",
    "BestPosture",
    "BoundSubtask",
    "Circle",
    "Clearance",
    "CompiledBarrier",
    "CompiledGradient",
    "CompiledPotential",
    "CompiledRows",
    "CompiledTask",
    "ConfigError",
    "ControlLoop",
    "DHRow",
    "DeadlineStats",
    "FeedbackResolver",
    "FrameTask",
    "GradientSubtask",
    "HierarchicalQPResolver",
    "Hold",
    "IKBatchResult",
    "IKResult",
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
    "RelativePoseTask",
    "Resolver",
    "ResolverError",
    "RobotModel",
    "SimulationLog",
    "SingularityGuard",
    "SolverError",
    "StepResult",
    "Subtask",
    "TargetSubtask",
    "Task",
    "TaskError",
    "TaskStack",
    "TaskTerm",
    "Tick",
    "VirtualPoint",
    "Watchdog",
    "WeightedQPResolver",
    "__version__",
    "dh_matrix",
    "from_dh",
    "from_urdf",
    "load_example_robot",
    "make_resolver",
    "pseudo_inverse",
    "simulate",
    "solve_ik",
    "solve_ik_batch",
    "warm_up",
]
