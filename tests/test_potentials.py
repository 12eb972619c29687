"""Every subtask potential's gradient against central finite differences, plus their defining properties."""

from __future__ import annotations

import numpy as np
import pytest

from redundik.errors import TaskError
from redundik.kinematics import DHRow, from_dh, load_example_robot
from redundik.tasks import (
    BestPosture,
    Clearance,
    JointCentering,
    JointSine2,
    JointValue,
    Manipulability,
    Potential,
    VirtualPoint,
)

from .helpers import fd_gradient, random_dh_robot


def _check_gradient(robot, potential: Potential, q: np.ndarray, atol: float = 1e-6) -> None:
    robot.update(q)
    potential.check(robot)
    g = potential.gradient(robot)

    def f(qq: np.ndarray) -> float:
        robot.update(qq)
        return potential.value(robot)

    np.testing.assert_allclose(g, fd_gradient(f, q), atol=atol, rtol=1e-5)


def _potentials() -> list[Potential]:
    return [
        JointSine2("j3"),
        JointValue("j1", 0.25),
        JointCentering(),
        JointCentering(center=np.linspace(-0.3, 0.3, 7), weights=np.arange(1.0, 8.0)),
        VirtualPoint("j3", [1.0, 2.0, 0.5]),
        VirtualPoint("j3", [1.0, 2.0, 0.5], axes=["x", "z"]),
        Clearance("j4", [0.3, -0.2, 0.4], radius=0.1),
        Clearance("j4", [0.3, -0.2, 0.4], radius=0.1, axes=["x", "z"]),
        Manipulability("j7"),
        Manipulability("j7", axes="position"),
        BestPosture("j7"),
        BestPosture(["j7", "j5"], weights=np.linspace(0.5, 2.0, 7), axes="position"),
    ]


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("potential", _potentials(), ids=lambda p: repr(p))
def test_gradient_matches_finite_differences(potential: Potential, seed: int) -> None:
    rng = np.random.default_rng(seed)
    robot = random_dh_robot(rng)
    q = robot.random_configuration(rng) * 0.9
    _check_gradient(robot, potential, q)


def test_manipulability_and_best_posture_on_panda() -> None:
    robot = load_example_robot("panda")
    rng = np.random.default_rng(3)
    q = robot.random_configuration(rng)
    for p in (Manipulability("panda_hand"), BestPosture("panda_hand", weights=np.linspace(1, 2, 9))):
        _check_gradient(robot, p, q, atol=2e-6)


def test_sin2_gradient_is_the_chapter_sin_2theta() -> None:
    robot = from_dh([DHRow("1", a=1), DHRow("2", a=1), DHRow("3", a=1)])
    q = np.array([0.4, -0.2, np.deg2rad(-30)])
    robot.update(q)
    p = JointSine2("3")
    p.check(robot)
    assert p.value(robot) == pytest.approx(np.sin(q[2]) ** 2)
    np.testing.assert_allclose(p.gradient(robot), [0, 0, np.sin(2 * q[2])])  # η = (0 0 sin 2θ3)ᵀ


def test_joint_centering_default_center_is_mid_range() -> None:
    robot = from_dh([DHRow("1", lower=-1, upper=3), DHRow("2", kind="prismatic", lower=0.2, upper=0.6)])
    robot.update(np.array([1.0, 0.4]))
    p = JointCentering()
    p.check(robot)
    assert p.value(robot) == pytest.approx(0.0)
    robot.update(np.array([2.0, 0.5]))
    assert p.value(robot) == pytest.approx(0.5 * (1.0**2 + 0.1**2))  # ½‖q − q_c‖², (5.9)
    np.testing.assert_allclose(p.gradient(robot), [1.0, 0.1])  # η = q − q_c, (5.10)


def test_best_posture_is_sum_of_eigenvalues_and_torques_are_jt_f() -> None:
    rng = np.random.default_rng(5)
    robot = random_dh_robot(rng)
    robot.update(robot.random_configuration(rng))
    w = np.linspace(0.5, 2.0, 7)
    p = BestPosture("j7", weights=w)
    p.check(robot)
    J = robot.frame_jacobian("j7")
    assert p.value(robot) == pytest.approx(np.sum(np.linalg.eigvalsh(J @ np.diag(w) @ J.T)))
    F = np.array([-1.0, 2.0, 0, 0, 0, 0])
    np.testing.assert_allclose(p.torques(robot, F), J.T @ F)
    # Rayleigh bound: λ_min ≤ FᵀJWJᵀF/FᵀF ≤ λ_max, whose sum is tr(JWJᵀ)
    tau = p.torques(robot, F)
    assert tau @ (w * tau) / (F @ F) <= p.value(robot) + 1e-12


def test_manipulability_is_sqrt_det_and_zero_at_singularity() -> None:
    robot = from_dh([DHRow("1", a=1), DHRow("2", a=1)])
    p = Manipulability("2", axes="planar")
    robot.update(np.array([0.3, 0.0]))  # stretched: singular
    assert p.value(robot) == pytest.approx(0.0, abs=1e-12)
    g = p.gradient(robot)  # one-sided: bending the elbow raises p at rate a1 a2 |cos θ2| = 1
    assert np.all(np.isfinite(g)) and abs(g[1]) == pytest.approx(1.0)
    robot.update(np.array([0.3, 1.0]))
    assert p.value(robot) == pytest.approx(abs(np.sin(1.0)))  # 2R arm: √det(JJᵀ) = a1 a2 |sin θ2|


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: JointValue("j1", float("nan")), "must be finite"),
        (lambda: VirtualPoint("j1", [0, 0]), "expected 3 numbers"),
        (lambda: VirtualPoint("j1", [0, 0, 0], axes=["x", "rz"]), "axes must be among x, y, z"),
        (lambda: Clearance("j1", [0, 0, 0], radius=-1), "radius must be ≥ 0"),
        (lambda: BestPosture("j1", weights=[1, -1, 1, 1, 1, 1, 1]), "weights must be > 0"),
        (lambda: Manipulability("j1", axes="diagonal"), "unknown axes 'diagonal'"),
    ],
)
def test_bad_parameters_raise(make, match) -> None:
    with pytest.raises(TaskError, match=match):
        make()


def test_unknown_frame_or_joint_is_reported_at_check() -> None:
    robot = random_dh_robot(np.random.default_rng(0))
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match="subtask 'sin2_j99': joint 'j99' does not exist"):
        JointSine2("j99").check(robot)
    with pytest.raises(TaskError, match="frame 'elbow' does not exist"):
        VirtualPoint("elbow", [0, 0, 0]).check(robot)
    with pytest.raises(TaskError, match="weights: expected 7 numbers"):
        BestPosture("j7", weights=[1.0] * 6).check(robot)  # the chapter's W has 6 entries for 7 joints


# ---------------------------------------------------------------------------------------------------- barriers
def _barriers():
    """Every barrier class with a robot it applies to: (id, builder of (robot, barrier, q))."""
    from redundik.collision import CollisionAvoidance, CollisionWorld, Obstacle, make_shape
    from redundik.kinematics import example_robot_data_dir
    from redundik.tasks.balance import SupportPolygon

    def collision(seed: int):
        import pinocchio as pin

        robot = load_example_robot("panda")
        ball = Obstacle("ball", make_shape("sphere", radius=0.05), pin.SE3(np.eye(3), np.array([0.4, 0.1, 0.4])))
        world = CollisionWorld.from_urdf(robot, example_robot_data_dir() / "panda_description/urdf/panda.urdf", [ball])
        return (
            robot,
            CollisionAvoidance(world, influence=10.0, safety=0.01),
            robot.random_configuration(np.random.default_rng(seed)),
        )

    def support(seed: int):
        robot = load_example_robot("talos")
        rng = np.random.default_rng(seed)
        q = robot.neutral()
        q[7:] += rng.uniform(-0.3, 0.3, robot.nq - 7)
        return robot, SupportPolygon(["left_sole_link", "right_sole_link"]), q

    return [("collision", collision), ("support_polygon", support)]


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize(("kind", "make"), _barriers(), ids=lambda x: x if isinstance(x, str) else "")
def test_barrier_jacobian_matches_finite_differences(kind: str, make, seed: int) -> None:
    """H = ∂h/∂q of every barrier class (rows fixed at q) against central differences along q ⊕ ε e_k."""
    import pinocchio as pin

    from redundik.tasks import Barrier

    robot, barrier, q = make(seed)
    assert isinstance(barrier, Barrier)
    robot.update(q)
    barrier.check(robot)
    term = barrier.evaluate(robot)
    assert term.h.size > 0 and term.H.shape == (term.h.size, robot.nv)
    names = list(term.names)
    eps = 1e-6
    fd = np.zeros_like(term.H)
    for k in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[k] = eps
        vals = []
        for sgn in (1, -1):
            robot.update(pin.integrate(robot.model, q, sgn * dq))
            t = barrier.evaluate(robot)
            vals.append(np.array([t.h[t.names.index(n)] for n in names]))
        fd[:, k] = (vals[0] - vals[1]) / (2 * eps)
    np.testing.assert_allclose(term.H, fd, atol=2e-6)
    if isinstance(barrier, Potential):  # both roles: the potential's gradient is checked too
        if robot.nq == robot.nv:
            _check_gradient(robot, barrier, q, atol=2e-5)
        else:  # a floating base: the support margin's gradient is the active edge's row of H
            robot.update(q)
            np.testing.assert_allclose(barrier.gradient(robot), term.H[int(np.argmin(term.h))])
