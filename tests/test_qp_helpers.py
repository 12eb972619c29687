"""Builders shared by the QP tests: small stacks on small robots (built in the test, no files)."""

from __future__ import annotations

import numpy as np

import redundik as rk
from redundik.kinematics import DHRow
from redundik.resolvers.qp import TOLERANCE, available_backends

BACKENDS = available_backends()


def case2_robot(**row_kw: float) -> rk.RobotModel:
    """The chapter's 3R planar arm from D-H rows (a = 1, 1, 1)."""
    return rk.from_dh([DHRow(str(i + 1), a=1.0, **row_kw) for i in range(3)], name="planar3r")


CASE2_Q0 = np.radians([110.0, -40.0, -30.0])


def case2_stack(gain: float = 1.0, priority: int = 1) -> rk.TaskStack:
    """Case 2: tip line v = (0.2, −0.4) m/s, p = sin²θ3 with k = 1 as a gradient subtask."""
    return rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")],
        [rk.GradientSubtask(rk.JointSine2("3"), gain=gain)],
    )


def prepared(resolver: rk.Resolver, robot: rk.RobotModel, stack: rk.TaskStack, q: np.ndarray) -> None:
    """Update, reset and check as :func:`redundik.simulate` does before its loop."""
    robot.update(q)
    stack.reset(robot)
    resolver.reset()
    resolver.check(robot, stack)


def random_robot(rng: np.random.Generator, n: int, velocity: float = np.inf, limit: float = np.pi) -> rk.RobotModel:
    """A random spatial revolute D-H chain with n joints and the given limits."""
    rows = []
    for i in range(n):
        rows.append(
            DHRow(
                f"j{i + 1}",
                theta=float(rng.uniform(-np.pi, np.pi)),
                d=float(rng.uniform(-0.3, 0.3)),
                a=float(rng.uniform(0.2, 0.6)),
                alpha=float(rng.choice([-np.pi / 2, 0.0, np.pi / 2]) + rng.uniform(-0.2, 0.2)),
                lower=-limit,
                upper=limit,
                velocity=velocity,
            )
        )
    return rk.from_dh(rows, name=f"random{n}")


def tip(robot: rk.RobotModel) -> str:
    """Name of the last D-H frame."""
    return robot.joint_names[-1]


#: The one per-backend tolerance table of the property tests: largest |x − x_ref| against an exact active-set answer,
#: relative to max(1, ‖x_ref‖∞) [unit of x]. It is the backends' documented accuracy
#: (:data:`redundik.resolvers.qp.TOLERANCE`), with the settings of :mod:`redundik.resolvers.qp.backends` (osqp
#: eps 1e-8 and polishing, also from a stalled iterate; proxsuite eps_abs 1e-9 with the duality-gap check).
QP_TOLERANCE: dict[str, float] = dict(TOLERANCE)


def qp_tolerance(backend: str, reference: np.ndarray | float = 1.0) -> float:
    """Tolerance of ``backend`` for an answer of the size of ``reference`` (see :data:`QP_TOLERANCE`)."""
    return QP_TOLERANCE[backend] * max(1.0, float(np.max(np.abs(reference))))
