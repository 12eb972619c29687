"""The row protocol's compiled form (issue 31): a task gives its rows as a compiled writer (``Task.compiled_rows``),
which the resolvers' compiled step calls in place of ``evaluate`` — the built-in joint coupling and relative pose, and
a user's task of one file. The writer's rows equal an independent Pinocchio formula, the compiled step equals the
per-task path, and the path is reported as compiled."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.errors import TaskError
from redundik.kinematics.lie_kernels import frame_jacobian_lwa
from redundik.kinematics.model import RobotModel
from redundik.tasks.base import CompiledRows, Task, TaskTerm
from redundik.tasks.row_kernels import log3
from redundik.tasks.rows import CompiledTask, write_rows

DT = 0.01


@numba.njit(cache=False)
def _height_rows(q, t, poses, jw, ints, floats, gain, J, e, v):
    """One row: the height of frame ints[0] towards floats[0]."""
    jac = np.empty((6, jw.shape[1]))
    frame_jacobian_lwa(jw, poses[ints[0], 9:12], ints[1:], jac)
    J[0, :] = jac[2, :]
    e[0] = floats[0] - poses[ints[0], 11]
    v[0] = gain * e[0]


class ElbowHeight(CompiledTask):
    """A user's task in one file: its data, its writer, nothing else."""

    def __init__(self, z: float, gain: float = 2.0) -> None:
        self._init_task("elbow", gain=gain, weight=0.5)
        self.floats = np.array([z])
        self.ints = np.zeros(0, dtype=np.int64)

    def compiled_rows(self, robot: RobotModel) -> CompiledRows:
        if self.ints.shape[0] != 1 + robot.nv:
            fid = robot.frame_id("panda_link4")
            cols = np.zeros(robot.nv, dtype=np.int64)
            cols[:4] = 1  # (joints 1-4 move link 4)
            self.ints = np.concatenate([[fid], cols]).astype(np.int64)
        return CompiledRows(_height_rows, 1, self.ints, self.floats)

    def __repr__(self) -> str:
        return "ElbowHeight()"


class ElbowHeightPython(Task):
    """The same rows from Pinocchio, in Python (the reference)."""

    def __init__(self, z: float, gain: float = 2.0) -> None:
        self._init_task("elbow", gain=gain, weight=0.5)
        self.z = z

    def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
        J = robot.frame_jacobian("panda_link4")[2:3]
        e = np.array([self.z - robot.frame_position("panda_link4")[2]])
        return TaskTerm(self.name, J, self.gain * e, e, self.weight)

    def __repr__(self) -> str:
        return "ElbowHeightPython()"


def _panda(q7=(0.1, -0.4, 0.2, -2.0, 0.1, 1.6, 0.8)) -> tuple[RobotModel, np.ndarray]:
    robot = rk.load_example_robot("panda")
    q = pin.neutral(robot.model)
    q[:7] = q7
    robot.update(q)
    return robot, q


def _stack(extra: Task) -> rk.TaskStack:
    return rk.TaskStack(
        [rk.FrameTask("panda_hand_tcp", rk.Circle(0.05, np.pi, plane=("y", "z")), gain=20.0), extra, rk.PostureTask()]
    )


def test_log3_equals_pinocchio_including_near_pi() -> None:
    rng = np.random.default_rng(3)
    out = np.empty(3)
    for k in range(3000):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        theta = [np.pi - 10 ** rng.uniform(-9, -1), 10 ** rng.uniform(-9, 0), rng.uniform(0, np.pi)][k % 3]
        R = pin.exp3(theta * u)
        log3(R, out)
        np.testing.assert_allclose(out, pin.log3(R), rtol=0, atol=1e-8 if k % 3 == 0 else 1e-12)


@pytest.mark.parametrize("robot_name", ["panda", "talos"])
def test_com_writer_equals_pinocchio(robot_name: str) -> None:
    """The compiled CoM rows against Pinocchio's ``jacobianCenterOfMass`` (a floating base included)."""
    robot = rk.load_example_robot(robot_name)
    rng = np.random.default_rng(2)
    task = rk.tasks.CoMTask(target=[0.1, -0.05, 0.4], axes=("x", "z"), gain=3.0)
    for _ in range(5):
        q = robot.random_configuration(rng) if robot_name == "panda" else pin.randomConfiguration(robot.model)
        if robot_name == "talos":
            q[:3] = rng.normal(size=3)
        robot.update(q)
        form = task.compiled_rows(robot)
        assert form is not None
        J, e, v = np.zeros((2, robot.nv)), np.zeros(2), np.zeros(2)
        write_rows(form, robot, 0.0, task.gain, J, e, v)
        Jc = pin.jacobianCenterOfMass(robot.model, robot.model.createData(), q)
        c = pin.centerOfMass(robot.model, robot.model.createData(), q)
        np.testing.assert_allclose(J, Jc[[0, 2]], rtol=0, atol=1e-12)
        np.testing.assert_allclose(e, (np.array([0.1, -0.05, 0.4]) - c)[[0, 2]], rtol=0, atol=1e-12)
        np.testing.assert_allclose(v, 3.0 * e, rtol=0, atol=1e-12)
    task.target = [0.0, 0.0, 0.2]  # a new target is data: the writer sees it without a new form
    revision = task.form_revision
    assert task.compiled_rows(robot).floats[:3].tolist() == [0.0, 0.0, 0.2]
    assert task.form_revision == revision


def test_com_writer_on_a_dh_chain_reads_its_bodies_through_their_frames() -> None:
    """A DH chain has no joint frames (each joint carries its row's frame, placed off the joint): the compiled CoM
    reads each body through that frame, its lever expressed there — Pinocchio's CoM and J_c to 1e-12; a chain
    without mass has no compiled CoM (``evaluate``: Pinocchio's)."""
    rows = [rk.DHRow(str(k), a=0.3, d=0.05 * k, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 7)]
    robot = rk.from_dh(rows)
    task = rk.tasks.CoMTask(target=[0.1, -0.05, 0.4], gain=2.0)
    assert task.compiled_rows(robot) is None  # (no mass: nothing to weigh)
    rng = np.random.default_rng(3)
    model = robot.model
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia(rng.uniform(0.5, 2.0), rng.normal(0.0, 0.1, 3), np.eye(3))
    task = rk.tasks.CoMTask(target=[0.1, -0.05, 0.4], gain=2.0)
    for _ in range(4):
        q = rng.uniform(-2.0, 2.0, robot.nq)
        robot.update(q)
        form = task.compiled_rows(robot)
        assert form is not None
        J, e, v = np.zeros((3, robot.nv)), np.zeros(3), np.zeros(3)
        write_rows(form, robot, 0.0, task.gain, J, e, v)
        data = model.createData()
        Jc = pin.jacobianCenterOfMass(model, data, q)
        np.testing.assert_allclose(J, Jc, rtol=0, atol=1e-12)
        np.testing.assert_allclose(e, np.array([0.1, -0.05, 0.4]) - data.com[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("kind", ["relative", "coupling", "user"])
def test_writer_rows_equal_pinocchio(kind: str) -> None:
    robot, q = _panda()
    rng = np.random.default_rng(1)
    if kind == "relative":
        task: Task = rk.RelativePoseTask("panda_link4", "panda_hand", axes="pose", gain=3.0)
        task.reset(robot)
        ref = pin.SE3(task._target)  # type: ignore[attr-defined]  # (the captured relative pose)
    elif kind == "coupling":
        task = rk.JointCoupling("panda_joint1", "panda_joint3", offset=0.2, gain=3.0)
        task.reset(robot)
    else:
        task = ElbowHeight(0.5, gain=3.0)
    for _ in range(5):  # other configurations: the writer reads the new poses and Jacobians
        q[:7] += rng.normal(scale=0.3, size=7)
        robot.update(q)
        term = task.evaluate(robot, 0.0)
        if kind == "relative":
            ia, ib = robot.frame_id("panda_link4"), robot.frame_id("panda_hand")
            Ta, Tb = robot.frame_pose(ia), robot.frame_pose(ib)
            rel = Tb.actInv(Ta)
            e = np.concatenate([ref.translation - rel.translation, pin.log3(ref.rotation @ rel.rotation.T)])
            Ja, Jb = robot.frame_jacobian(ia), robot.frame_jacobian(ib)
            d = Ta.translation - Tb.translation
            Jv = Ja[:3] - Jb[:3] + pin.skew(d) @ Jb[3:]
            J = np.vstack([Tb.rotation.T @ Jv, Tb.rotation.T @ (Ja[3:] - Jb[3:])])
        elif kind == "coupling":
            e = np.array([0.2 - (q[0] - q[2])])
            J = np.zeros((1, robot.nv))
            J[0, 0], J[0, 2] = 1.0, -1.0
        else:
            ref_term = ElbowHeightPython(0.5, gain=3.0).evaluate(robot, 0.0)
            e, J = ref_term.error, ref_term.J
        np.testing.assert_allclose(term.J, J, rtol=0, atol=1e-12)
        np.testing.assert_allclose(term.error, e, rtol=0, atol=1e-12)
        np.testing.assert_allclose(term.v, 3.0 * e, rtol=0, atol=1e-12)


def _make(kind: str) -> Task:
    if kind == "com":
        return rk.tasks.CoMTask(axes=("x", "y"), gain=2.0, weight=0.3)
    if kind == "relative":
        return rk.RelativePoseTask("panda_link4", "panda_hand", axes=("z", "rx"), gain=2.0, weight=0.3)
    if kind == "coupling":
        return rk.JointCoupling("panda_joint1", "panda_joint3", gain=2.0, weight=0.3)
    return ElbowHeight(0.45)


def _fused_and_per_task(method: str, kind: str) -> list[tuple[RobotModel, rk.TaskStack, Any]]:
    """The same stack with a ``kind`` member, twice: (robot, stack, resolver) on the fused step, then on the per-task
    path."""
    copies = []
    for fuse in (True, False):
        robot, _ = _panda()
        stack = _stack(_make(kind))
        stack.reset(robot)
        res = rk.make_resolver(method)
        res.fuse = fuse  # type: ignore[attr-defined]
        copies.append((robot, stack, res))
    return copies


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["relative", "coupling", "user", "com"])
def test_compiled_writer_step_equals_per_task_path(method: str, kind: str) -> None:
    copies = _fused_and_per_task(method, kind)
    q = copies[0][0].q.copy()
    for k in range(25):
        a, b = (res.step(robot, stack, q, k * DT, DT) for robot, stack, res in copies)
        assert b.info["path"] == "interpreted"
        assert a.info["path"] == "compiled", (k, a.info["path"], a.info.get("interpreted"))
        assert a.info["interpreted"] == ()
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-10)
        for ta, tb in zip(a.terms, b.terms, strict=True):
            np.testing.assert_allclose(ta.J, tb.J, rtol=0, atol=1e-12)
            np.testing.assert_allclose(ta.v, tb.v, rtol=0, atol=1e-11)
        q = copies[0][0].integrate(q, a.dq, DT)


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("kind", ["relative", "user"])
def test_a_compiled_writers_terms_read_after_later_steps_are_those_of_their_step(method: str, kind: str) -> None:
    """A result keeps its step's rows: its terms, read only after the loop has stepped on (the QP's least-squares
    buffers rewritten since), equal the per-task path's at that step."""
    copies = _fused_and_per_task(method, kind)
    q = copies[0][0].q.copy()
    kept = []
    for k in range(8):
        a, b = (res.step(robot, stack, q, k * DT, DT) for robot, stack, res in copies)
        assert a.info["path"] == "compiled"
        kept.append((a, [(t.J.copy(), t.v.copy(), t.error.copy()) for t in b.terms]))
        q = copies[0][0].integrate(q, a.dq, DT)
    for a, expected in kept:
        for term, (J, v, e) in zip(a.terms, expected, strict=True):
            np.testing.assert_allclose(term.J, J, rtol=0, atol=1e-12)
            np.testing.assert_allclose(term.v, v, rtol=0, atol=1e-11)
            np.testing.assert_allclose(term.error, e, rtol=0, atol=1e-12)


def test_user_writer_tracks_its_target() -> None:
    """The user's task, compiled, drives the elbow's height to its target while the hand holds (pinv)."""
    robot, q = _panda()
    elbow = ElbowHeight(robot.frame_position("panda_link4")[2] - 0.05, gain=5.0)
    stack = rk.TaskStack([rk.FrameTask("panda_hand_tcp", gain=5.0), elbow, rk.PostureTask(gain=0.1)])
    stack.reset(robot)
    res = rk.make_resolver("wqp")
    for k in range(300):
        out = res.step(robot, stack, q, k * DT, DT)
        q = robot.integrate(q, out.dq, DT)
    robot.update(q)
    assert out.info["path"] == "compiled"
    assert abs(robot.frame_position("panda_link4")[2] - elbow.floats[0]) < 2e-3


class BadForm(CompiledTask):
    def __init__(self, form: object) -> None:
        self._init_task("bad")
        self.form = form

    def compiled_rows(self, robot: RobotModel):
        return self.form

    def __repr__(self) -> str:
        return "BadForm()"


@pytest.mark.parametrize(
    ("form", "words"),
    [
        (None, "returned None"),
        ((1, 2, 3, 4), "must return a CompiledRows"),
        (CompiledRows(None, 1, np.zeros(0, dtype=np.int64), np.zeros(0)), "kernel is not callable"),
        (CompiledRows(_height_rows, -1, np.zeros(0, dtype=np.int64), np.zeros(0)), "rows must be an integer"),
        (CompiledRows(_height_rows, 1, np.zeros(2), np.zeros(0)), "ints must be a 1-D int64"),
    ],
)
@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_bad_writer_is_named(form: object, words: str, method: str) -> None:
    robot, q = _panda()
    stack = _stack(BadForm(form))
    stack.reset(robot)
    res = rk.make_resolver(method)
    with pytest.raises(TaskError, match=words) as err:
        for k in range(3):
            res.step(robot, stack, q, k * DT, DT)
    assert "'bad'" in str(err.value)


@numba.njit(cache=False)
def _nan_rows(q, t, poses, jw, ints, floats, gain, J, e, v):  # type: ignore[no-untyped-def]
    J[0, 0] = 1.0
    e[0] = floats[0] * np.nan  # a user's formula that breaks (0/0, log of a negative, ...)
    v[0] = gain * e[0]


class NanWriter(CompiledTask):
    def __init__(self) -> None:
        self._init_task("nan_row")

    def compiled_rows(self, robot: RobotModel) -> CompiledRows:
        return CompiledRows(_nan_rows, 1, np.zeros(1, dtype=np.int64), np.ones(1))

    def __repr__(self) -> str:
        return "NanWriter()"


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_writer_that_gives_nan_stops_the_robot_and_names_itself(method: str) -> None:
    """A compiled writer writes straight into the step's rows (pinv, wqp): a NaN it writes reaches no q̇. The step
    degrades to q̇ = 0 and its fallback names the writer's task, as for a Python task's NaN."""
    robot, q = _panda()
    stack = _stack(NanWriter())
    stack.reset(robot)
    res = rk.make_resolver(method)
    for k in range(3):
        out = res.step(robot, stack, q, k * DT, DT)
        assert np.isfinite(out.dq).all() and not out.dq.any()
        assert out.fallback is not None and "nan_row" in out.fallback
