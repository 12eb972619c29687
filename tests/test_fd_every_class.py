"""Every ``Task``, ``Potential`` and ``Barrier`` class of redundik against central finite differences (issue 31).

The classes are found, not listed: every module of the package is imported and the subclasses of the three bases
are walked; each concrete one must have a case in :data:`CASES` (a new class without one fails
:func:`test_every_concrete_class_has_a_case`). A case builds (robot, object, q) from a seed. The differences are
taken along the configuration manifold, q ⊕ ±ε e_k (``pinocchio.integrate``), so floating-base robots are checked in
their tangent coordinates as the Jacobians are:

* a task: its error e = desired − actual has ∂e/∂q = −J. The task is reset at q first (a held target is then the
  pose at q, e = 0, where the log map's Jacobian is the identity; a given target keeps its e ≠ 0);
* a potential: η = ∂p/∂q;
* a barrier: H = ∂h/∂q, its rows matched by name (the active rows are those at q).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import cache

import numpy as np
import pinocchio as pin
import pytest

from redundik.kinematics import RobotModel, example_robot_data_dir, load_example_robot
from redundik.tasks import (
    BestPosture,
    Clearance,
    FrameTask,
    JointCentering,
    JointCoupling,
    JointSine2,
    JointValue,
    JointWaypoints,
    Manipulability,
    PostureTask,
    VirtualPoint,
)
from redundik.tasks.balance import CoMTask, ContactTask, SupportPolygon
from redundik.tasks.base import Barrier, Potential, Task
from redundik.tasks.potential_task import PotentialTask
from redundik.tasks.relative import RelativePoseTask

from .helpers import import_every_module, random_dh_robot

EPS = 1e-6
Case = Callable[[int], tuple[RobotModel, object, np.ndarray]]


@cache
def _example(name: str) -> RobotModel:
    return load_example_robot(name)


def _dh(seed: int) -> tuple[RobotModel, np.ndarray]:
    """The random 7-joint D-H chain (joints and frames j1..j7, two prismatic) at a random configuration."""
    rng = np.random.default_rng(seed)
    robot = random_dh_robot(rng)
    return robot, robot.random_configuration(rng) * 0.9


def _talos(seed: int) -> tuple[RobotModel, np.ndarray]:
    """TALOS (a free-flyer base) at a random base pose and joints near neutral."""
    robot = _example("talos")
    rng = np.random.default_rng(seed)
    q = robot.neutral()
    q[:3] = rng.uniform(-0.5, 0.5, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.4, 0.4, 3))).coeffs()
    q[7:] += rng.uniform(-0.3, 0.3, robot.nq - 7)
    return robot, q


def _panda(seed: int) -> tuple[RobotModel, np.ndarray]:
    robot = _example("panda")
    return robot, robot.random_configuration(np.random.default_rng(seed))


def on(robot: Callable[[int], tuple[RobotModel, np.ndarray]], make: Callable[[], object]) -> Case:
    def build(seed: int) -> tuple[RobotModel, object, np.ndarray]:
        model, q = robot(seed)
        return model, make(), q

    return build


def _collision() -> object:
    from redundik.collision import CollisionAvoidance, CollisionWorld, Obstacle, make_shape

    robot = _example("panda")
    ball = Obstacle("ball", make_shape("sphere", radius=0.05), pin.SE3(np.eye(3), np.array([0.4, 0.1, 0.4])))
    world = CollisionWorld.from_urdf(robot, example_robot_data_dir() / "panda_description/urdf/panda.urdf", [ball])
    return CollisionAvoidance(world, influence=10.0, safety=0.01)


def _collision_class() -> type:
    from redundik.collision import CollisionAvoidance

    return CollisionAvoidance


#: Per concrete class: (case id, builder). Every class needs at least one.
CASES: dict[type, list[tuple[str, Case]]] = {
    FrameTask: [
        ("dh_pose", on(_dh, lambda: FrameTask("j7"))),
        ("dh_position_xz", on(_dh, lambda: FrameTask("j6", axes=["x", "z", "rz"]))),
        ("talos_hand", on(_talos, lambda: FrameTask("gripper_left_joint"))),
    ],
    PostureTask: [
        ("dh", on(_dh, lambda: PostureTask())),
        ("talos_free_flyer", on(_talos, lambda: PostureTask())),
        ("talos_actuated", on(_talos, lambda: PostureTask(joints="actuated"))),
        ("talos_some_joints", on(_talos, lambda: PostureTask(joints=["root_joint", "arm_left_4_joint"]))),
    ],
    CoMTask: [("talos", on(_talos, lambda: CoMTask()))],
    ContactTask: [("talos_sole", on(_talos, lambda: ContactTask("left_sole_link")))],
    RelativePoseTask: [
        ("dh", on(_dh, lambda: RelativePoseTask("j7", "j3"))),
        ("talos_hands", on(_talos, lambda: RelativePoseTask("gripper_left_joint", "gripper_right_joint"))),
    ],
    PotentialTask: [("dh_virtual_point", on(_dh, lambda: PotentialTask(VirtualPoint("j7", [1.0, 2.0, 0.5]), 0.3)))],
    JointCoupling: [("dh", on(_dh, lambda: JointCoupling("j2", "j4", offset=0.1)))],
    JointSine2: [("dh", on(_dh, lambda: JointSine2("j3")))],
    JointValue: [("dh", on(_dh, lambda: JointValue("j1", 0.25)))],
    JointCentering: [
        ("dh", on(_dh, lambda: JointCentering())),
        ("dh_weighted", on(_dh, lambda: JointCentering(center=np.linspace(-0.3, 0.3, 7), weights=np.arange(1.0, 8)))),
        ("talos_free_flyer", on(_talos, lambda: JointCentering())),
    ],
    VirtualPoint: [
        ("dh", on(_dh, lambda: VirtualPoint("j3", [1.0, 2.0, 0.5]))),
        ("dh_xz", on(_dh, lambda: VirtualPoint("j3", [1.0, 2.0, 0.5], axes=["x", "z"]))),
        ("talos_hand", on(_talos, lambda: VirtualPoint("gripper_left_joint", [0.5, 0.2, 1.0]))),
    ],
    Clearance: [
        ("dh", on(_dh, lambda: Clearance("j4", [0.3, -0.2, 0.4], radius=0.1))),
        ("dh_xz", on(_dh, lambda: Clearance("j4", [0.3, -0.2, 0.4], radius=0.1, axes=["x", "z"]))),
        ("talos_hand", on(_talos, lambda: Clearance("gripper_left_joint", [0.5, 0.2, 1.0], radius=0.05))),
    ],
    Manipulability: [
        ("dh", on(_dh, lambda: Manipulability("j7"))),
        ("dh_position", on(_dh, lambda: Manipulability("j7", axes="position"))),
        ("panda", on(_panda, lambda: Manipulability("panda_hand"))),
    ],
    BestPosture: [
        ("dh", on(_dh, lambda: BestPosture("j7"))),
        ("dh_two", on(_dh, lambda: BestPosture(["j7", "j5"], weights=np.linspace(0.5, 2.0, 7), axes="position"))),
        ("panda", on(_panda, lambda: BestPosture("panda_hand", weights=np.linspace(1, 2, 9)))),
    ],
    JointWaypoints: [("dh", on(_dh, lambda: JointWaypoints("j2", [0.4, -0.3])))],
    SupportPolygon: [("talos", on(_talos, lambda: SupportPolygon(["left_sole_link", "right_sole_link"])))],
    _collision_class(): [("panda_ball", on(_panda, _collision))],
}


def _concrete_classes() -> set[type]:
    """Every concrete subclass of Task, Potential and Barrier defined in redundik (all its modules imported)."""
    import_every_module()
    found: set[type] = set()
    todo: list[type] = [Task, Potential, Barrier]
    while todo:
        cls = todo.pop()
        for sub in cls.__subclasses__():
            if sub.__module__.startswith("redundik.") and sub not in found:
                found.add(sub)
                todo.append(sub)
    return {c for c in found if not inspect.isabstract(c)}


def test_every_concrete_class_has_a_case() -> None:
    classes = _concrete_classes()
    missing = sorted(f"{c.__module__}.{c.__qualname__}" for c in classes - set(CASES))
    assert not missing, f"add a finite-difference case to CASES for: {missing}"
    assert {FrameTask, PostureTask, Clearance, SupportPolygon} <= classes  # the walk sees the library's classes


def _fd_columns(robot: RobotModel, q: np.ndarray, values: Callable[[], np.ndarray]) -> np.ndarray:
    """Central differences of ``values()`` (evaluated on the updated robot) along q ⊕ ±ε e_k, one column per k."""
    cols = []
    for k in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[k] = EPS
        robot.update(pin.integrate(robot.model, q, dq))
        plus = values()
        robot.update(pin.integrate(robot.model, q, -dq))
        minus = values()
        cols.append((plus - minus) / (2 * EPS))
    robot.update(q)
    return np.column_stack(cols)


def _check_task(robot: RobotModel, task: Task, q: np.ndarray) -> None:
    robot.update(q)
    task.reset(robot)
    term = task.evaluate(robot, 0.0)
    assert term.J.shape == (term.error.size, robot.nv)
    fd = _fd_columns(robot, q, lambda: task.evaluate(robot, 0.0).error)
    np.testing.assert_allclose(-term.J, fd, atol=2e-6, rtol=1e-5)


def _check_potential(robot: RobotModel, potential: Potential, q: np.ndarray) -> None:
    robot.update(q)
    potential.check(robot)
    g = potential.gradient(robot)
    assert g.shape == (robot.nv,)
    fd = _fd_columns(robot, q, lambda: np.array([potential.value(robot)]))[0]
    np.testing.assert_allclose(g, fd, atol=2e-6, rtol=1e-5)


def _check_barrier(robot: RobotModel, barrier: Barrier, q: np.ndarray) -> None:
    robot.update(q)
    barrier.check(robot)
    term = barrier.evaluate(robot)
    assert term.h.size > 0 and term.H.shape == (term.h.size, robot.nv)
    names = list(term.names)

    def rows() -> np.ndarray:
        t = barrier.evaluate(robot)
        return np.array([t.h[t.names.index(n)] for n in names])

    np.testing.assert_allclose(term.H, _fd_columns(robot, q, rows), atol=2e-6)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize(
    ("cls", "make"),
    [(cls, make) for cls, cases in CASES.items() for _, make in cases],
    ids=[f"{cls.__name__}-{name}" for cls, cases in CASES.items() for name, _ in cases],
)
def test_derivatives_match_finite_differences(cls: type, make: Case, seed: int) -> None:
    robot, obj, q = make(seed)
    assert type(obj) is cls
    checked = 0
    if isinstance(obj, Task):
        _check_task(robot, obj, q)
        checked += 1
    if isinstance(obj, Barrier):
        _check_barrier(robot, obj, q)
        checked += 1
    if isinstance(obj, Potential):
        _check_potential(robot, obj, q)
        checked += 1
    assert checked


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize(
    ("cls", "make"),
    [(cls, make) for cls, cases in CASES.items() if issubclass(cls, Potential) for _, make in cases],
    ids=[f"{cls.__name__}-{name}" for cls, cases in CASES.items() if issubclass(cls, Potential) for name, _ in cases],
)
def test_compiled_writers_equal_value_and_gradient(cls: type, make: Case, seed: int) -> None:
    """A potential's compiled writer (what a compiled step calls for a gradient or a target subtask's row) gives the
    p and η of its ``value`` and ``gradient``, for every potential class that has one (a new one is checked too)."""
    from redundik.tasks.potential_rows import compiled_writer

    robot, potential, q = make(seed)
    assert isinstance(potential, Potential)
    robot.update(q)
    potential.check(robot)
    writer = compiled_writer(potential, robot)
    if writer is None:
        return
    from redundik.kinematics.memory import jacobian_view, se3_vector_view

    jw, poses = jacobian_view(robot.data), se3_vector_view(robot.data.oMf)  # (what a compiled step passes)
    assert jw is not None and poses is not None
    eta = np.zeros(robot.nv)
    p = writer.kernel(robot.q, poses, jw, writer.ints, writer.floats, eta)
    assert p == pytest.approx(potential.value(robot), rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(eta, potential.gradient(robot), rtol=1e-12, atol=1e-12)


def test_joint_centering_has_no_writer_on_a_free_flyer_orientation() -> None:
    """A centre given for every coordinate weighs the free flyer's orientation, which is not a subtraction
    (Pinocchio's difference): no compiled writer, so a target subtask on it keeps its Python row. The default centre
    (the middle of the finite ranges) leaves the base out: a writer."""
    from redundik.tasks.potential_rows import compiled_writer

    robot, q = _talos(0)
    robot.update(q)
    assert compiled_writer(JointCentering(center=robot.neutral()), robot) is None
    assert compiled_writer(JointCentering(), robot) is not None
