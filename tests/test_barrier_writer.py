"""A barrier's compiled form (``Barrier.compiled_barrier``, ``CompiledBarrier``): the support polygon's writer gives
its ``evaluate``'s rows, a bound subtask calls it in place of ``evaluate``, a subclass with rows of its own keeps
them, a user's barrier can give one, and a malformed one is refused with its name."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik.config import load_task
from redundik.errors import TaskError
from redundik.tasks.balance import SupportPolygon
from redundik.tasks.barrier_rows import barrier_values, barrier_writer

os.environ.setdefault("REDUNDIK_COLD_START", "wait")
TASKS = Path(__file__).resolve().parents[1] / "tasks"
FEET = ["left_sole_link", "right_sole_link"]


def _talos_configurations(robot: rk.RobotModel, count: int) -> list[np.ndarray]:
    rng = np.random.default_rng(4)
    out = []
    for _ in range(count):
        q = pin.randomConfiguration(robot.model)
        q[:3] = rng.normal(size=3)  # (the free flyer: a base anywhere)
        out.append(q)
    return out


@pytest.mark.parametrize("rate", [None, 7.0])
def test_support_polygons_writer_gives_its_evaluates_rows(rate: float | None) -> None:
    """h, H and γ of the compiled writer against ``evaluate`` (Pinocchio's ``jacobianCenterOfMass``) at random
    configurations of TALOS's floating base and joints, to 1e-12; a new margin is read at the next call."""
    robot = rk.load_example_robot("talos")
    robot.update(robot.neutral())
    sp = SupportPolygon(FEET, margin=0.02, rate=rate)
    sp.check(robot)
    for k, q in enumerate(_talos_configurations(robot, 6)):
        if k == 3:
            sp.margin = 0.05
        robot.update(q)
        form = barrier_writer(sp, robot)
        assert form is not None and form.rows == len(sp.b) == len(form.names)
        h, H = barrier_values(form, robot)
        term = sp.evaluate(robot)
        np.testing.assert_allclose(h, term.h, rtol=0, atol=1e-12)
        np.testing.assert_allclose(H, term.H, rtol=0, atol=1e-12)
        assert form.names == term.names
        assert (term.gamma is None) == (form.gamma == 0) and (rate is None or np.all(term.gamma == form.gamma))


def test_a_bound_subtask_takes_the_writers_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    """A bound subtask on the support polygon calls its writer, not ``evaluate``: the rows ``evaluate`` would give
    (1e-12), named alike; the subtask counts as compiled."""
    robot = rk.load_example_robot("talos")
    robot.update(robot.neutral())
    sp = SupportPolygon(FEET, margin=0.02, rate=20.0)
    bound = rk.BoundSubtask(sp, rate=5.0)
    sp.check(robot)
    q = _talos_configurations(robot, 1)[0]
    robot.update(q)
    want = (-sp.evaluate(robot).H, np.minimum(20.0, 100.0) * sp.evaluate(robot).h)

    def refused(self: Any, robot: Any) -> Any:
        raise AssertionError("evaluate called")

    monkeypatch.setattr(SupportPolygon, "evaluate", refused)
    C, d, names = bound.rows(robot, 0.01)
    np.testing.assert_allclose(C, want[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(d, want[1], rtol=0, atol=1e-10)
    assert names == [f"{bound.name}:edge{i}" for i in range(len(d))]
    assert bound.rows_compiled(robot)


def test_a_subclass_with_its_own_rows_keeps_them() -> None:
    """A subclass that overrides ``evaluate`` below the class that defines the writer gets no writer: its own
    rows run, and the subtask is named as written from Python."""

    class Shifted(SupportPolygon):
        def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
            term = super().evaluate(robot)
            return rk.BarrierTerm(term.h + 1.0, term.H, term.names, term.gamma)

    robot = rk.load_example_robot("talos")
    robot.update(robot.neutral())
    sp = Shifted(FEET, margin=0.02)
    bound = rk.BoundSubtask(sp)
    sp.check(robot)
    assert barrier_writer(sp, robot) is None and not bound.rows_compiled(robot)
    h = bound.values(robot)[0]
    np.testing.assert_allclose(h, SupportPolygon.evaluate(sp, robot).h + 1.0, rtol=0, atol=1e-15)


@numba.njit
def _floor_rows(q, poses, jw, ints, floats, h, H):  # type: ignore[no-untyped-def]
    """h = z − z_min of the origin of frame ints[0] (its joint: ints[1]'s columns), H = its world z velocity row."""
    f = ints[0]
    pz = poses[f, 11]
    h[0] = pz - floats[0]
    px, py = poses[f, 9], poses[f, 10]
    for c in range(jw.shape[1]):
        if ints[1 + c]:
            H[0, c] = jw[2, c] + jw[3, c] * py - jw[4, c] * px


class _Floor(rk.Barrier):
    """A user's barrier with a compiled writer: keep a frame's origin above z_min."""

    def __init__(self, frame: str, z_min: float, form: Any = None) -> None:
        self.name, self.frame, self.z_min, self.form = "floor", frame, z_min, form

    def evaluate(self, robot: rk.RobotModel) -> rk.BarrierTerm:
        h = np.array([robot.frame_position(self.frame)[2] - self.z_min])
        return rk.BarrierTerm(h, robot.frame_jacobian(self.frame)[2:3].copy(), ["z"])

    def compiled_barrier(self, robot: rk.RobotModel) -> Any:
        if self.form is not None:
            return self.form
        fid = robot.frame_id(self.frame)
        cols = np.zeros(robot.nv, dtype=np.int64)
        model = robot.model
        for j in model.supports[model.frames[fid].parentJoint]:
            if j > 0:
                cols[model.joints[j].idx_v] = 1
        ints = np.concatenate([[fid], cols]).astype(np.int64)
        return rk.CompiledBarrier(_floor_rows, 1, ints, np.array([self.z_min]), ["z"])


def test_a_users_barrier_with_a_writer_gives_its_rows() -> None:
    robot = rk.load_example_robot("panda")
    q = np.array([0.1, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7, 0.02, 0.02])
    robot.update(q)
    floor = _Floor("panda_hand", 0.2)
    bound = rk.BoundSubtask(floor)
    form = barrier_writer(floor, robot)
    assert form is not None and bound.rows_compiled(robot)
    h, H = barrier_values(form, robot)
    term = floor.evaluate(robot)
    np.testing.assert_allclose(h, term.h, rtol=0, atol=1e-14)
    np.testing.assert_allclose(H, term.H, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("form", "message"),
    [
        ("rows", "must return a CompiledBarrier or None, got str"),
        (rk.CompiledBarrier(_floor_rows, 2, np.zeros(1, dtype=np.int64), np.zeros(1), ["z"]), "one name per row"),
        (rk.CompiledBarrier(_floor_rows, -1, np.zeros(1, dtype=np.int64), np.zeros(1), []), "rows must be"),
        (rk.CompiledBarrier(_floor_rows, 1, np.zeros(1), np.zeros(1), ["z"]), "ints must be a 1-D int64"),
        (rk.CompiledBarrier(None, 1, np.zeros(1, dtype=np.int64), np.zeros(1), ["z"]), "kernel is not callable"),
        (rk.CompiledBarrier(_floor_rows, 1, np.zeros(1, dtype=np.int64), np.zeros(1), ["z"], -1.0), "gamma must"),
        (rk.CompiledBarrier(_floor_rows, 1, np.zeros(1, dtype=np.int64), np.zeros(1), ["z"], np.nan), "gamma must"),
    ],
)
def test_a_malformed_writer_is_refused_with_the_barriers_name(form: Any, message: str) -> None:
    robot = rk.load_example_robot("panda")
    robot.update(robot.neutral())
    with pytest.raises(TaskError, match=f"barrier 'floor': .*{message}"):
        barrier_writer(_Floor("panda_hand", 0.2, form), robot)


def test_humanoid_balance_names_only_the_collision_barrier() -> None:
    """The shipped balance run: the support polygon's rows come from its writer; only coal's collision barrier is
    written from Python (``info["interpreted"]``), on the compiled step and in the names a step that is not fused
    gives (the support polygon, a potential too, was named there by its lack of a compiled gradient)."""
    plan = load_task(TASKS / "humanoid_balance.yaml")
    robot = plan.robot.model
    for name, run in plan.runs.items():
        q = run.q0.copy()
        run.stack.reset(robot)
        for k in range(3):
            res = run.resolver.step(robot, run.stack, q, k * 0.01, 0.01)
            q = robot.integrate(q, res.dq, 0.01)
        assert set(res.info["interpreted"]) == {"self_collision"}, (name, res.info["interpreted"])
        # (the names a step that is not fused reports, e.g. during a cold start: the same)
        assert run.resolver._interpreted_members(robot, run.stack) == ("self_collision",), name


@numba.njit
def _nan_rows(q, poses, jw, ints, floats, h, H):  # type: ignore[no-untyped-def]
    """A broken writer: h = NaN."""
    h[0] = np.nan


@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_writer_that_gives_nan_stops_the_step_and_names_the_subtask(method: str) -> None:
    """A barrier writer whose h is not finite: the step stops (q̇ = 0, no NaN in the output) and its fallback names
    the bound subtask; the robot's state stays valid."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.1, -0.5, 0.2, -2.0, 0.1, 1.6, 0.7, 0.02, 0.02])
    robot.update(q)
    form = rk.CompiledBarrier(_nan_rows, 1, np.zeros(1, dtype=np.int64), np.zeros(1), ["z"])
    bound = rk.BoundSubtask(_Floor("panda_hand", 0.2, form), name="broken_floor")
    stack = rk.TaskStack([rk.FrameTask("panda_hand", rk.Circle(0.05, 2.0, ("y", "z"))), rk.PostureTask()], [bound])
    stack.reset(robot)
    res = rk.make_resolver(method)
    for k in range(3):
        out = res.step(robot, stack, q, 0.01 * k, 0.01)
        assert np.all(out.dq == 0.0) and out.fallback is not None and "broken_floor" in out.fallback, out.fallback
