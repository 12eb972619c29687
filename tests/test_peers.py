"""Interop with mink and pink: redundik potentials as their tasks (skipped if the ``peers`` extra is missing)."""

from __future__ import annotations

import importlib

import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import ModelError, TaskError
from redundik.kinematics.urdf import EXAMPLE_ROBOTS, example_robot_data_dir
from redundik.peers import JointMap, PeerImportError, PotentialTerm, require
from tests.helpers import planar3r, random_dh_robot

mink = pytest.importorskip("mink", reason="mink is not installed (optional extra redundik[peers])")
mujoco = pytest.importorskip("mujoco", reason="mujoco is not installed (optional extra redundik[peers])")
pink = pytest.importorskip("pink", reason="pin-pink is not installed (optional extra redundik[peers])")

from redundik.peers.mink_tasks import (  # noqa: E402 - after the skips
    MinkBestPostureTask,
    MinkManipulabilityTask,
    MinkPotentialTask,
    MinkVirtualPointTask,
)
from redundik.peers.pink_tasks import (  # noqa: E402
    PinkBestPostureTask,
    PinkManipulabilityTask,
    PinkPotentialTask,
    PinkVirtualPointTask,
)
from redundik.simulation.mujoco_model import mujoco_from_robot, mujoco_from_urdf  # noqa: E402

pytestmark = pytest.mark.peers

DT = 0.01
PANDA_Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])


def _urdf(name: str):
    return example_robot_data_dir() / EXAMPLE_ROBOTS[name][0]


@pytest.fixture(scope="module")
def panda() -> rk.RobotModel:
    return rk.load_example_robot("panda")


@pytest.fixture(scope="module")
def panda_mj(panda: rk.RobotModel):
    return mujoco_from_urdf(_urdf("panda"), panda, ["panda_hand", "panda_link4"])


@pytest.fixture(scope="module")
def talos() -> rk.RobotModel:
    return rk.load_example_robot("talos")


def _potentials() -> list[rk.Potential]:
    return [
        rk.Manipulability("panda_hand"),
        rk.Manipulability("panda_hand", axes="position"),
        rk.BestPosture("panda_hand", weights=np.linspace(1.0, 2.0, 9)),
        rk.VirtualPoint("panda_link4", [0.3, -0.2, 0.6]),
        rk.JointSine2("panda_joint4"),
    ]


def _random_q(robot: rk.RobotModel, rng: np.random.Generator) -> np.ndarray:
    q = robot.random_configuration(rng)
    if robot.model.joints[1].shortname() == "JointModelFreeFlyer":
        q[:3] = rng.normal(size=3)
        q[3:7] = pin.Quaternion(*rng.normal(size=4)).normalized().coeffs()
    return q


# ---------------------------------------------------------------------------------------------------------- models
@pytest.mark.parametrize("name", ["panda", "talos"])
def test_mujoco_sites_match_pinocchio_frames(name: str) -> None:
    robot = rk.load_example_robot(name)
    frames = ["panda_hand", "panda_link7"] if name == "panda" else ["gripper_left_base_link", "arm_right_7_link"]
    model = mujoco_from_urdf(_urdf(name), robot, frames, free_flyer=EXAMPLE_ROBOTS[name][1])
    jmap = JointMap.from_mujoco(robot, model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = _random_q(robot, rng)
        data.qpos[:] = jmap.to_peer_q(q)
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(jmap.to_robot_q(data.qpos), q, atol=1e-15)
        robot.update(q)
        for f in frames:
            sid = model.site(f).id
            np.testing.assert_allclose(data.site_xpos[sid], robot.frame_position(f), atol=1e-9)
            np.testing.assert_allclose(data.site_xmat[sid].reshape(3, 3), robot.frame_pose(f).rotation, atol=1e-9)


def test_mujoco_from_dh_robot_matches() -> None:
    robot = random_dh_robot(np.random.default_rng(3), n=6)
    frames = [robot.joint_names[-1], robot.joint_names[2]]
    model = mujoco_from_robot(robot, frames)
    jmap = JointMap.from_mujoco(robot, model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = robot.random_configuration(rng)
        data.qpos[:] = jmap.to_peer_q(q)
        mujoco.mj_kinematics(model, data)
        robot.update(q)
        for f in frames:
            np.testing.assert_allclose(data.site_xpos[model.site(f).id], robot.frame_position(f), atol=1e-9)
    for j in robot.joints:
        np.testing.assert_allclose(model.jnt_range[model.joint(j.name).id], [j.lower, j.upper])


def test_mujoco_from_panda_model_with_unaligned_joint(panda: rk.RobotModel) -> None:
    """The generic builder handles axis-aligned and unaligned joints (the Panda's second finger is (0, −1, 0))."""
    model = mujoco_from_robot(panda, ["panda_hand", "panda_leftfinger", "panda_rightfinger"])
    jmap = JointMap.from_mujoco(panda, model)
    data = mujoco.MjData(model)
    q = panda.random_configuration(np.random.default_rng(8))
    data.qpos[:] = jmap.to_peer_q(q)
    mujoco.mj_kinematics(model, data)
    panda.update(q)
    for f in ("panda_hand", "panda_leftfinger", "panda_rightfinger"):
        np.testing.assert_allclose(data.site_xpos[model.site(f).id], panda.frame_position(f), atol=1e-9)


def test_joint_map_reorders_by_name_and_rejects_other_robots(panda: rk.RobotModel) -> None:
    # a MuJoCo model whose joints come in another order than Pinocchio's: indices must follow names
    robot = planar3r()
    spec = mujoco.MjSpec()
    body = spec.worldbody
    for name in ("3", "1", "2"):  # name order differs from the chain order
        body = body.add_body(name=f"b{name}", mass=1.0, inertia=[1e-3] * 3)
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    model = spec.compile()
    jmap = JointMap.from_mujoco(robot, model)
    q_peer = np.array([0.3, 0.1, 0.2])  # joint "3" first
    np.testing.assert_allclose(jmap.to_robot_q(q_peer), [0.1, 0.2, 0.3])
    np.testing.assert_allclose(jmap.gradient_to_peer(np.array([1.0, 2.0, 3.0]), q_peer), [3.0, 1.0, 2.0])
    with pytest.raises(ModelError, match="panda_joint1"):
        JointMap.from_mujoco(panda, model)
    with pytest.raises(ModelError, match="missing"):
        JointMap.from_pinocchio(panda, robot.model)


def test_free_flyer_gradient_maps_to_mujoco_tangent(talos: rk.RobotModel) -> None:
    """η_peer·δv = p(q ⊕_MuJoCo δv) − p(q) to first order, with MuJoCo's world-frame linear base velocity."""
    model = mujoco_from_urdf(_urdf("talos"), talos, ["gripper_left_base_link"], free_flyer=True)
    pot = rk.VirtualPoint("gripper_left_base_link", [0.4, 0.3, 0.9])
    term = PotentialTerm(pot, talos, mode="target", target=0.0)
    term.joint_map = JointMap.from_mujoco(talos, model)
    rng = np.random.default_rng(5)
    q_peer = term.joint_map.to_peer_q(_random_q(talos, rng))
    _, eta = term.evaluate(q_peer)
    h = 1e-6
    fd = np.zeros(model.nv)
    for i in range(model.nv):
        vals = []
        for s in (1.0, -1.0):
            qp = q_peer.copy()
            dv = np.zeros(model.nv)
            dv[i] = s * h
            mujoco.mj_integratePos(model, qp, dv, 1.0)
            vals.append(term.evaluate(qp)[0])
        fd[i] = (vals[0] - vals[1]) / (2 * h)
    np.testing.assert_allclose(eta, fd, atol=1e-7)
    assert np.abs(eta[:3]).max() > 1e-3  # the base block is really exercised


# ---------------------------------------------------------------------------------------------------------- Jacobians
@pytest.mark.parametrize("peer", ["mink", "pink"])
def test_task_jacobian_is_the_exact_gradient(peer: str, panda: rk.RobotModel, panda_mj) -> None:
    rng = np.random.default_rng(7)
    for pot in _potentials():
        helper = rk.load_example_robot("panda")
        if peer == "mink":
            task = MinkPotentialTask(pot, helper, mode="target", target=0.5, cost=2.0)
            conf = mink.Configuration(panda_mj)
        else:
            task = PinkPotentialTask(pot, helper, mode="target", target=0.5, cost=2.0)
            model = pin.Model(panda.model)
            conf = pink.Configuration(model, model.createData(), panda.neutral())
        for _ in range(4):
            q = panda.random_configuration(rng)
            if peer == "mink":
                conf.update(task.term.joint_map.to_peer_q(q) if task.term.joint_map else q)
            else:
                conf.update(q)
            J = task.compute_jacobian(conf)
            e = task.compute_error(conf)
            panda.update(q)
            pot.check(panda)
            eta = pot.gradient(panda)
            jmap = task.term.joint_map
            assert J.shape == (1, jmap.nv_peer)
            back = np.zeros(panda.nv)
            back[jmap.rk_v] = J[0, jmap.peer_v]
            np.testing.assert_allclose(back, eta, atol=1e-9, rtol=0)
            np.testing.assert_allclose(e, [pot.value(panda) - 0.5], atol=1e-12)


def test_errors_per_mode(panda: rk.RobotModel) -> None:
    pot = rk.JointSine2("panda_joint4")
    up = PotentialTerm(pot, panda, mode="increase", speed=0.2, dt=DT)
    down = PotentialTerm(pot, panda, mode="decrease", speed=0.2, dt=DT)
    np.testing.assert_allclose(up.error(0.3), [-0.2 * DT])
    np.testing.assert_allclose(down.error(0.3), [0.2 * DT])
    fb = PotentialTerm(pot, panda, mode="target", target=0.8, rate=4.0, target_rate=0.1, dt=DT)
    assert fb.gain == pytest.approx(4.0 * DT)
    # J Δq = −α e  ⇔  ηᵀΔq = dt (ṗ_d + K (p_d − p))  (state-feedback law, one Euler step)
    np.testing.assert_allclose(-fb.gain * fb.error(0.5), [DT * (0.1 + 4.0 * (0.8 - 0.5))])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mode": "target"}, "needs a finite target"),
        ({"mode": "target", "target": 1.0, "rate": 2.0}, "needs dt"),
        ({"mode": "target", "target": 1.0, "rate": 200.0, "dt": 0.01}, "≤ 1"),
        ({"mode": "increase"}, "needs dt"),
        ({"mode": "increase", "dt": 0.01, "speed": -1.0}, "speed must be > 0"),
        ({"mode": "up"}, "mode must be"),
        ({"mode": "target", "target": 0.0, "gain": 2.0}, r"gain α must be in \[0, 1\]"),
    ],
)
def test_bad_arguments_raise_task_errors(kwargs: dict, message: str, panda: rk.RobotModel) -> None:
    with pytest.raises(TaskError, match=message):
        MinkPotentialTask(rk.JointSine2("panda_joint4"), panda, **kwargs)


def test_missing_peer_gives_actionable_error(monkeypatch: pytest.MonkeyPatch) -> None:
    real = importlib.import_module

    def fake(name: str, *args, **kwargs):
        if name == "mink":
            raise ImportError("No module named 'mink'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", fake)
    with pytest.raises(PeerImportError, match=r"install redundik\[peers\]"):
        require("mink")


# ---------------------------------------------------------------------------------------------------------- IK steps
def _mink_run(tasks, model, q0: np.ndarray, steps: int = 15) -> mink.Configuration:
    conf = mink.Configuration(model, q0)
    posture = mink.PostureTask(model, cost=1e-3)
    posture.set_target_from_configuration(conf)
    for _ in range(steps):
        v = mink.solve_ik(conf, [*tasks, posture], DT, "daqp", damping=1e-6)
        conf.integrate_inplace(v, DT)
    return conf


def _pink_run(tasks, robot: rk.RobotModel, q0: np.ndarray, steps: int = 15):
    model = pin.Model(robot.model)
    conf = pink.Configuration(model, model.createData(), q0)
    posture = pink.tasks.PostureTask(cost=1e-3)
    posture.set_target_from_configuration(conf)
    for _ in range(steps):
        v = pink.solve_ik(conf, [*tasks, posture], DT, solver="daqp", damping=1e-6)
        conf.integrate_inplace(v, DT)
    return conf


def _value(pot: rk.Potential, robot: rk.RobotModel, q: np.ndarray) -> float:
    robot.update(q)
    pot.check(robot)
    return pot.value(robot)


@pytest.mark.parametrize("peer", ["mink", "pink"])
def test_ik_steps_move_the_potential_as_asked(peer: str, panda: rk.RobotModel, panda_mj) -> None:
    helper = rk.load_example_robot("panda")
    q0 = PANDA_Q0
    jmap = JointMap.from_mujoco(panda, panda_mj)
    cases = {
        "man_up": (rk.Manipulability("panda_hand"), "increase", {"speed": 0.02}),
        "trace_down": (rk.BestPosture("panda_hand"), "decrease", {"speed": 0.5}),
        "vp_to_zero": (rk.VirtualPoint("panda_link4", [0.5, 0.3, 0.4]), "target", {"target": 0.0, "rate": 5.0}),
        "sin2_up_to": (rk.JointSine2("panda_joint4"), "target", {"target": 0.95, "rate": 5.0}),
        "sin2_down_to": (rk.JointSine2("panda_joint4"), "target", {"target": 0.2, "rate": 5.0}),
    }
    for key, (pot, mode, kw) in cases.items():
        cls = MinkPotentialTask if peer == "mink" else PinkPotentialTask
        task = cls(pot, helper, mode=mode, dt=DT, cost=10.0, **kw)
        p0 = _value(pot, panda, q0)
        if peer == "mink":
            q1 = jmap.to_robot_q(_mink_run([task], panda_mj, jmap.to_peer_q(q0)).q)
        else:
            q1 = _pink_run([task], panda, q0).q
        p1 = _value(pot, panda, q1)
        goes_up = mode == "increase" or (mode == "target" and kw["target"] > p0)
        assert (p1 > p0 + 1e-6) if goes_up else (p1 < p0 - 1e-6), (key, p0, p1)
        if mode == "target":  # first-order decay towards p_d: the gap shrinks, without overshoot
            assert abs(p1 - kw["target"]) < abs(p0 - kw["target"])


def test_named_tasks_and_repr(panda: rk.RobotModel, panda_mj) -> None:
    tasks = [
        MinkManipulabilityTask(panda, "panda_hand", dt=DT, speed=0.1),
        MinkBestPostureTask(panda, "panda_hand", dt=DT),
        MinkVirtualPointTask(panda, "panda_link4", [0.3, 0.0, 0.5], rate=2.0, dt=DT),
        PinkManipulabilityTask(panda, "panda_hand", axes="position", dt=DT),
        PinkBestPostureTask(panda, ["panda_hand", "panda_link4"], dt=DT),
        PinkVirtualPointTask(panda, "panda_link4", [0.3, 0.0, 0.5]),
    ]
    modes = [t.term.mode for t in tasks]
    assert modes == ["increase", "decrease", "target", "increase", "decrease", "target"]
    assert "increase" in repr(tasks[0]) and "target=0.0" in repr(tasks[5])
    assert tasks[2].gain == pytest.approx(2.0 * DT)
