"""``wqp``, pink and mink solve the same weighted problem under ``docs/from-pink-and-mink.md``'s mapping (a peer's
cost c is a weight c², its gain α is K = α/dt, a posture of cost c sits at ``level_ratio`` = c²). Their frame error is
the body twist log6 with the Jacobian −Jlog6·J_local; redundik's is the base-aligned position error and log3 with the
base-aligned Jacobian. The two agree at zero error, so on the same small problem the q̇ agree to first order in the
error. On TALOS (a free flyer) the peers' posture leaves the root joint out: ``PostureTask(joints="actuated")`` in the
frame task's level poses their problem. Skipped without the ``peers`` extra."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk

pink = pytest.importorskip("pink", reason="pin-pink is not installed (optional extra redundik[peers])")
mink = pytest.importorskip("mink", reason="mink is not installed (optional extra redundik[peers])")

from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir  # noqa: E402 - after the skips
from redundik.peers import JointMap  # noqa: E402
from redundik.simulation.mujoco_model import mujoco_from_urdf  # noqa: E402

pytestmark = pytest.mark.peers

DT = 0.01
HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
TOOL = "panda_hand_tcp"


def _problem(seed: int, size: float) -> tuple[rk.RobotModel, np.ndarray, pin.SE3, float]:
    """The Panda at a configuration ``size`` away from home, a hand goal ``size`` away from its pose there; the
    largest error of the problem (hand position [m], rotation [rad], posture [rad])."""
    rng = np.random.default_rng(seed)
    robot = rk.load_example_robot("panda")
    q = HOME.copy()
    q[:7] += size * rng.uniform(-1.0, 1.0, 7)
    robot.update(q)
    hand = robot.frame_pose(TOOL)
    goal = pin.SE3(
        hand.rotation @ pin.exp3(size * rng.uniform(-1.0, 1.0, 3)), hand.translation + size * rng.uniform(-1.0, 1.0, 3)
    )
    error = max(np.abs(pin.log6(hand.actInv(goal)).vector).max(), np.abs(q - HOME).max())
    return robot, q, goal, error


def _pink_velocity(
    robot: rk.RobotModel, q: np.ndarray, frame: str, goal: pin.SE3, ref: np.ndarray, cost: float
) -> np.ndarray:
    """pink's velocity: a frame task of costs 1 and gain 1 towards ``goal``, a posture of ``cost`` and gain 1 towards
    ``ref`` (pink leaves a root joint out of it), no limits."""
    configuration = pink.Configuration(robot.model, robot.model.createData(), q)
    hand = pink.tasks.FrameTask(frame, position_cost=1.0, orientation_cost=1.0, gain=1.0)
    hand.set_target(goal)
    posture = pink.tasks.PostureTask(cost=cost, gain=1.0)
    posture.set_target(ref)
    return np.asarray(
        pink.solve_ik(configuration, [hand, posture], DT, solver="daqp", damping=1e-12, limits=[], safety_break=False)
    )


def _mink_velocity(
    robot: rk.RobotModel, key: str, q: np.ndarray, frame: str, goal: pin.SE3, ref: np.ndarray, cost: float
) -> np.ndarray:
    """mink's velocity on the same problem, its MuJoCo model made from the example robot ``key``'s URDF (a site at
    ``frame``; a free joint where redundik has a free flyer, which mink's posture leaves out), q̇ mapped back to
    redundik's joints (the free joint's linear velocity into the base frame)."""
    urdf, free_flyer = EXAMPLE_ROBOTS[key]
    model = mujoco_from_urdf(example_robot_data_dir() / urdf, robot, [frame], free_flyer=free_flyer)
    joints = JointMap.from_mujoco(robot, model)
    configuration = mink.Configuration(model, joints.to_peer_q(q))
    hand = mink.FrameTask(frame, "site", position_cost=1.0, orientation_cost=1.0, gain=1.0)
    hand.set_target(mink.SE3.from_matrix(goal.homogeneous))
    posture = mink.PostureTask(model, cost=cost, gain=1.0)
    posture.set_target(joints.to_peer_q(ref))
    v = np.asarray(mink.solve_ik(configuration, [hand, posture], DT, solver="daqp", damping=1e-12, limits=[]))
    return joints.velocity_to_robot(v, q)


def _pink_dq(robot: rk.RobotModel, q: np.ndarray, goal: pin.SE3, cost: float) -> np.ndarray:
    return _pink_velocity(robot, q, TOOL, goal, HOME, cost)


def _mink_dq(robot: rk.RobotModel, q: np.ndarray, goal: pin.SE3, cost: float) -> np.ndarray:
    return _mink_velocity(robot, "panda", q, TOOL, goal, HOME, cost)


PEERS = {"pink": _pink_dq, "mink": _mink_dq}


def _wqp_dq(robot: rk.RobotModel, q: np.ndarray, goal: pin.SE3, level_ratio: float) -> np.ndarray:
    """redundik's ``wqp`` on the same problem, mapped: K = α/dt, the posture's level at ``level_ratio``, no limits,
    no damping, no speed cap."""
    hand, posture = rk.FrameTask(TOOL, gain=1.0 / DT), rk.PostureTask(gain=1.0 / DT)
    stack = rk.TaskStack([hand, posture])
    robot.update(q)
    stack.reset(robot)
    hand.set_target(goal)
    posture.set_target(HOME)
    resolver = rk.make_resolver(
        "wqp", backend="daqp", level_ratio=level_ratio, damping=0.0, lm_damping=0.0, max_joint_speed=None,
        limits=rk.JointLimits(position=False, velocity=False),
    )  # fmt: skip
    result = resolver.step(robot, stack, q, 0.0, DT)
    assert result.fallback is None, result.fallback
    return np.asarray(result.dq)


@pytest.mark.parametrize("size", [1e-5, 1e-4, 1e-3])
@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("peer", sorted(PEERS))
def test_wqp_and_a_peer_give_the_same_velocity_to_first_order_in_the_error(peer: str, seed: int, size: float) -> None:
    robot, q, goal, error = _problem(seed, size)
    cost = 1e-2
    v_peer = PEERS[peer](robot, q, goal, cost)
    dq = _wqp_dq(robot, q, goal, cost**2)
    scale = np.abs(v_peer).max()
    assert scale > 1e-3  # (the problem asks for motion)
    gap = np.abs(dq - v_peer).max() / scale
    assert gap <= 2.0 * error, (gap, error)
    # the mapping matters: the posture's level at c instead of c² is another problem, ten times outside that bound
    wrong = np.abs(_wqp_dq(robot, q, goal, cost) - v_peer).max() / scale
    assert wrong > 10.0 * max(gap, 2.0 * error), (wrong, gap, error)


GRIPPER = "gripper_left_base_link"


def _talos_problem(seed: int, size: float) -> tuple[rk.RobotModel, np.ndarray, np.ndarray, pin.SE3, float]:
    """TALOS (a free flyer) with its joints ``size`` away from a reference inside their limits, a gripper goal
    ``size`` away; the reference, and the largest error of the problem."""
    rng = np.random.default_rng(seed)
    robot = rk.load_example_robot("talos")
    ref = robot.neutral()
    lower, upper = robot.lower_limits[6:], robot.upper_limits[6:]
    ref[7:] = np.clip(ref[7:], lower + 2 * size, upper - 2 * size)
    q = ref.copy()
    q[7:] += size * rng.uniform(-1.0, 1.0, robot.nq - 7)
    robot.update(q)
    hand = robot.frame_pose(GRIPPER)
    goal = pin.SE3(
        hand.rotation @ pin.exp3(size * rng.uniform(-1.0, 1.0, 3)), hand.translation + size * rng.uniform(-1.0, 1.0, 3)
    )
    error = max(np.abs(pin.log6(hand.actInv(goal)).vector).max(), np.abs(q - ref).max())
    return robot, q, ref, goal, error


def _pink_talos(robot: rk.RobotModel, q: np.ndarray, ref: np.ndarray, goal: pin.SE3, cost: float) -> np.ndarray:
    return _pink_velocity(robot, q, GRIPPER, goal, ref, cost)


def _mink_talos(robot: rk.RobotModel, q: np.ndarray, ref: np.ndarray, goal: pin.SE3, cost: float) -> np.ndarray:
    return _mink_velocity(robot, "talos", q, GRIPPER, goal, ref, cost)


TALOS_PEERS = {"pink": _pink_talos, "mink": _mink_talos}


@pytest.mark.parametrize("size", [1e-5, 1e-4, 1e-3])
@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("peer", sorted(TALOS_PEERS))
def test_on_a_floating_base_a_peers_posture_is_one_on_the_actuated_joints(peer: str, seed: int, size: float) -> None:
    """pink's and mink's postures leave the root joint out. Mapped as ``PostureTask(joints="actuated")`` in the frame
    task's level with weight c² (the peers' problem: ‖task‖² + c²‖posture‖² + damping), ``wqp`` gives their q̇ to
    first order in the error; the same posture over every coordinate (the base pulled towards the reference's) does
    not."""
    robot, q, ref, goal, error = _talos_problem(seed, size)
    cost = 1e-2
    v_peer = TALOS_PEERS[peer](robot, q, ref, goal, cost)

    def wqp(joints: str | None) -> np.ndarray:
        task = rk.FrameTask(GRIPPER, gain=1.0 / DT)
        stack = rk.TaskStack([task, rk.PostureTask(ref, joints=joints, gain=1.0 / DT, priority=0, weight=cost**2)])
        robot.update(q)
        stack.reset(robot)
        task.set_target(goal)
        resolver = rk.make_resolver(
            "wqp", backend="daqp", damping=0.0, lm_damping=0.0, max_joint_speed=None,
            limits=rk.JointLimits(position=False, velocity=False),
        )  # fmt: skip
        result = resolver.step(robot, stack, q, 0.0, DT)
        assert result.fallback is None and result.info["path"] == "compiled", (result.fallback, result.info)
        return np.asarray(result.dq)

    scale = np.abs(v_peer).max()
    assert scale > 1e-3 and np.abs(v_peer[:6]).max() > 0.1 * scale  # (the peer moves the base)
    gap = np.abs(wqp("actuated") - v_peer).max() / scale
    assert gap <= 2.0 * error, (gap, error)
    wrong = np.abs(wqp(None) - v_peer).max() / scale
    assert wrong > 10.0 * max(gap, 2.0 * error), (wrong, gap, error)
