"""The fused step (redundik.resolvers.fused) gives the per-task path's answer: q̇, terms, task error, diagnostics.

Every case runs two copies of the same robot, stack and resolver — one with ``fuse`` on, one off — on the same
configurations (the fused copy's closed loop), and compares each step. A case also asserts that the fused step was
really taken (or, where it must not be, that it was not).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import pinocchio as pin
import pytest

import redundik as rk
from redundik import resolvers as rs
from redundik.errors import TaskError
from redundik.kinematics.model import RobotModel
from redundik.kinematics.urdf import load_example_robot
from redundik.resolvers.fused import FusedPlan
from redundik.resolvers.kernels import frame_jacobian_lwa
from redundik.tasks.frame import FrameTask, PostureTask
from redundik.tasks.potentials import JointCentering
from redundik.tasks.stack import TaskStack
from redundik.tasks.subtasks import GradientSubtask
from redundik.tasks.trajectory import Circle, Hold, Line, PoseInterpolation

DT = 0.01


def _panda() -> RobotModel:
    return load_example_robot("panda")


def _q0(robot: RobotModel) -> np.ndarray:
    q = pin.neutral(robot.model)
    q[:7] = [0.0, -0.4, 0.0, -2.0, 0.0, 1.6, 0.8]
    return q


def _fused_plan(resolver: rs.Resolver) -> object:
    if isinstance(resolver, rs.PinvResolver):
        return resolver._fused[1] if resolver._fused else None
    plan = resolver._plan  # type: ignore[attr-defined]
    return plan.fused if plan is not None else None


def _compare(
    make_stack,
    method: str,
    steps: int = 120,
    edit=None,
    fused_expected: bool = True,
    fallbacks: list[str] | None = None,
    qp_steps: list[int] | None = None,
    paths: list[str] | None = None,
    **options,
) -> list[bool]:
    """Step a fused and a per-task copy on the fused copy's trajectory; q̇ and what the result reports must agree.

    Returns, per step, whether the fused copy took the fused step (a plan, and no per-task evaluation)."""
    copies = []
    for fuse in (True, False):
        robot = _panda()
        q = _q0(robot)
        robot.update(q)
        stack = make_stack(robot)
        stack.reset(robot)
        res = rs.make_resolver(method, **options)
        res.fuse = fuse  # type: ignore[attr-defined]
        copies.append((robot, stack, res))
    q = _q0(copies[0][0])
    took: list[bool] = []
    evaluated = [0]

    def counting(original):  # the per-task path of the fused copy evaluates its tasks: count it
        def evaluate(robot, t):
            evaluated[0] += 1
            return original(robot, t)

        return evaluate

    for task in copies[0][1].tasks:
        task.evaluate = counting(task.evaluate)  # type: ignore[method-assign]
    for k in range(steps):
        t = k * DT
        if edit is not None:
            for robot, stack, _ in copies:
                edit(k, robot, stack)
        before = evaluated[0]
        out = [res.step(robot, stack, q, t, DT) for robot, stack, res in copies]
        a, b = out
        scale = max(1.0, float(np.abs(b.dq).max()))
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12 * scale, err_msg=f"step {k}")
        assert a.fallback == b.fallback
        for part in ("dq_rank", "dq_null"):  # the split of q̇ (pinv: J⁺V and (I − J⁺J) z; read lazily when fused)
            pa, pb = getattr(a, part), getattr(b, part)
            assert (pa is None) == (pb is None), part
            if pb is not None:
                np.testing.assert_allclose(pa, pb, rtol=0, atol=1e-12 * scale, err_msg=f"{part}, step {k}")
        if fallbacks is not None and a.fallback is not None:
            fallbacks.append(a.fallback)
        if paths is not None:
            paths.append(str(a.info["path"]))
        if qp_steps is not None and a.info["qp"]:
            qp_steps.append(k)
        assert a.task_error == pytest.approx(b.task_error, rel=1e-12, abs=1e-15)
        assert [t.name for t in a.terms] == [t.name for t in b.terms]
        for ta, tb in zip(a.terms, b.terms, strict=True):
            np.testing.assert_allclose(ta.J, tb.J, rtol=0, atol=1e-13)
            np.testing.assert_allclose(ta.error, tb.error, rtol=0, atol=1e-13)
            np.testing.assert_allclose(ta.v, tb.v, rtol=0, atol=1e-11)
            assert ta.weight == tb.weight
        assert a.sigma_min == pytest.approx(b.sigma_min, rel=1e-9)
        assert a.damped == b.damped
        for key in ("qp", "backend", "active_limits", "rank", "iterations"):
            assert a.info.get(key) == b.info.get(key), key
        for key in ("level_residuals", "sigma_min"):
            if key in b.info:
                assert a.info[key] == pytest.approx(b.info[key], rel=1e-9, abs=1e-12), key
        took.append(isinstance(_fused_plan(copies[0][2]), FusedPlan) and evaluated[0] == before)
        q = copies[0][0].integrate(q, a.dq, DT)
    if fused_expected:
        assert sum(took) >= steps - 8, f"the fused step was taken on {sum(took)} of {steps} steps"
    return took


def _hand(traj, **kw) -> FrameTask:
    return FrameTask("panda_hand", traj, gain=kw.pop("gain", 20.0), **kw)


@pytest.mark.parametrize("method", ["wqp", "pinv", "hqp"])
@pytest.mark.parametrize(
    "traj",
    [
        lambda: Circle(0.05, 1.5, plane=("y", "z")),
        lambda: Line([0.02, -0.03, 0.01]),
        lambda: Hold(),
        lambda: PoseInterpolation([0.4, 0.1, 0.5], 1.0, rotation=pin.rpy.rpyToMatrix(3.0, 0.2, 0.1)),
    ],
    ids=["circle", "line", "hold", "interpolation"],
)
def test_fused_frame_and_posture_agree(method: str, traj) -> None:
    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack([_hand(traj()), PostureTask(gain=1.0)])

    _compare(stack, method)


@pytest.mark.parametrize(
    "axes",
    [
        "position",
        ["x", "z", "ry"],
        "orientation",
        ["y", "z", "rz", "ry", "rx", "x"],  # all six rows in another order (wqp's fused step read them as x … rz)
        ["rx", "ry", "rz", "x", "y", "z"],
        ["z", "x", "y"],
    ],
)
def test_fused_row_subsets_agree(axes) -> None:
    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack(
            [_hand(Circle(0.04, 2.0, plane=("x", "y")), axes=axes), PostureTask(gain=2.0)],
            [GradientSubtask(JointCentering(), gain=-0.5)],
        )

    for method in ("wqp", "pinv", "hqp"):
        _compare(stack, method, steps=60)


def test_fused_levels_weights_and_identity_tasks_agree() -> None:
    """wqp: two frame tasks on two levels, a posture at level 0 (an identity task) and a gradient subtask."""

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack(
            [
                _hand(Circle(0.05, 1.0, plane=("y", "z")), weight=2.0),
                FrameTask("panda_link5", Hold(), axes="position", gain=5.0, priority=1, weight=0.5),
                PostureTask(gain=1.0, priority=0, weight=0.01),
            ],
            [GradientSubtask(JointCentering(), gain=-1.0)],
        )

    _compare(stack, "wqp", steps=80)
    _compare(stack, "hqp", steps=80)


def test_fused_binding_limits_agree() -> None:
    """A tight joint limit binds on many steps: the fused plan hands the same QP to the backend."""

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack([_hand(Circle(0.08, 3.0, plane=("y", "z"))), PostureTask(gain=1.0)])

    tight = {"lower": {"panda_joint1": -0.01}, "upper": {"panda_joint1": 0.01}}
    _compare(stack, "wqp", steps=150, limits=tight)
    _compare(stack, "hqp", steps=150, limits=tight)


def test_fused_follows_run_time_edits() -> None:
    """Gains, weights, targets and trajectories changed between ticks reach the fused step."""

    def edit(k: int, robot: RobotModel, stack: TaskStack) -> None:
        hand, posture = stack.tasks
        if k == 20:
            hand.gain = 5.0
        if k == 30:
            hand.weight = 3.0
        if k == 40:
            posture.set_target(_q0(robot) + 0.05)
        if k == 50:
            hand.set_target(np.array([0.35, 0.05, 0.55]))  # a position: keeps the last target orientation
        if k == 70:
            hand.trajectory = Line([0.0, 0.02, 0.0])
            hand.trajectory.start(robot.frame_pose("panda_hand"))
        if k == 90:
            posture.gain = 3.0

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack([_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)])

    for method in ("wqp", "pinv", "hqp"):
        _compare(stack, method, steps=110, edit=edit)


def test_large_rotation_error_takes_the_per_task_path() -> None:
    """A target 2.5 rad away: the compiled log3 declines, the step goes the per-task way (Pinocchio's log3)."""

    def stack(robot: RobotModel) -> TaskStack:
        pose = robot.frame_pose("panda_hand").copy()
        target = pin.SE3(pose.rotation @ pin.exp3(np.array([0.0, 0.0, 2.5])), pose.translation)
        return TaskStack([_hand(Hold(target), gain=5.0), PostureTask(gain=1.0)])

    for method in ("wqp", "pinv", "hqp"):
        # (pinv without its joint-speed cap: capped at the Panda's velocity limits it turns 2.5 rad in more steps)
        uncapped = {"max_joint_speed": None} if method == "pinv" else {}
        took = _compare(stack, method, steps=60, fused_expected=False, **uncapped)
        assert not any(took[:20]), "a 2.5 rad rotation error went through the compiled log3"
        assert all(took[-10:]), "the fused step resumed once the rotation error is small"


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_potential_without_a_compiled_form_runs_mixed(method: str) -> None:
    """A potential without a compiled writer (a user's subclass that computes η its own way): its direction is
    written from Python into the compiled step's z (a mixed step, naming it), and the answer is the per-task path's."""
    from redundik.tasks.potentials import JointSine2

    class Steeper(JointSine2):  # its own gradient: the writer it inherits must not replace it
        def gradient(self, robot: RobotModel) -> np.ndarray:
            return 2.0 * super().gradient(robot)

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack(
            [_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)],
            [GradientSubtask(Steeper("panda_joint4", name="steeper"))],
        )

    paths: list[str] = []
    took = _compare(stack, method, steps=40, paths=paths)
    assert sum(took) >= 32
    assert set(paths[2:]) == {"mixed"}


def _chapter_potentials() -> list[Any]:
    from redundik.tasks.potentials import Clearance, JointSine2, JointValue, VirtualPoint

    return [
        JointSine2("panda_joint4"),
        JointValue("panda_joint2", 0.3),
        VirtualPoint("panda_link4", [0.3, 0.2, 0.5], axes=("x", "z")),
        Clearance("panda_link5", [0.5, 0.3, 0.4], radius=0.05),
    ]


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
@pytest.mark.parametrize("which", range(4))
def test_the_chapters_potentials_run_compiled(method: str, which: int) -> None:
    """A gradient subtask on each chapter potential with a compiled writer (sin²θ, (q − c)², a virtual point, a
    clearance): the step is compiled (``path == "compiled"``) and its q̇ is the per-task path's (1e-12); moving the
    potential's data between steps (a new point or centre) is followed without a new plan."""

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack(
            [_hand(Circle(0.05, 1.5, plane=("y", "z"))), PostureTask(gain=1.0)],
            [GradientSubtask(_chapter_potentials()[which], gain=-0.5 if which in (1, 2) else 0.5)],
        )

    def edit(k: int, robot: RobotModel, stack: TaskStack) -> None:
        pot = stack.subtasks[0].potential
        if k == 20 and hasattr(pot, "point"):
            pot.point = [0.2, 0.1, 0.6]
        if k == 20 and hasattr(pot, "center"):
            pot.center = [0.45, 0.2, 0.5]
        if k == 20 and hasattr(pot, "c"):
            pot.c = -0.2

    paths: list[str] = []
    took = _compare(stack, method, steps=40, edit=edit, paths=paths)
    assert sum(took) >= 36
    assert set(paths[2:]) == {"compiled"}


def test_frame_jacobian_from_joint_jacobians_is_pinocchios() -> None:
    """frame_jacobian_lwa (the fused step's frame Jacobian from data.J) equals getFrameJacobian on every frame."""
    robot = _panda()
    model, data = robot.model, robot.data
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = pin.randomConfiguration(model)
        q += 0.01 * rng.normal(size=model.nq)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for fid in range(model.nframes):
            columns = np.zeros(model.nv, np.int64)
            for j in model.supports[model.frames[fid].parentJoint]:
                if j > 0:
                    jm = model.joints[j]
                    columns[jm.idx_v : jm.idx_v + jm.nv] = 1
            out = np.empty((6, model.nv))
            frame_jacobian_lwa(data.J, np.array(data.oMf[fid].translation), columns, out)
            ref = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(out, ref, rtol=0, atol=1e-15)


def test_gain_check_still_sees_run_time_changes() -> None:
    """The K·dt ≤ 2 check is skipped while no gain moved; a gain set between ticks (or a smaller dt) is still refused,
    and a task whose ``gain`` is its own property is read every step."""
    from redundik.errors import ResolverError
    from redundik.tasks.base import TaskTerm

    robot = _panda()
    q = _q0(robot)
    robot.update(q)
    hand = _hand(Circle(0.05, 1.5, plane=("y", "z")))
    stack = TaskStack([hand, PostureTask(gain=1.0)])
    stack.reset(robot)
    res = rs.make_resolver("wqp")
    for k in range(5):
        res.step(robot, stack, q, k * DT, DT)
    hand.gain = 250.0  # K·dt = 2.5
    with pytest.raises(ResolverError, match="task 'panda_hand' has gain 250"):
        res.step(robot, stack, q, 0.05, DT)
    hand.gain = 150.0
    res.step(robot, stack, q, 0.06, DT)
    with pytest.raises(ResolverError, match="K·dt"):
        res.step(robot, stack, q, 0.07, 0.02)  # the same gain, a larger dt: K·dt = 3

    class Dynamic(PostureTask):
        value = 1.0

        @property  # type: ignore[override]
        def gain(self) -> float:
            return self.value

        @gain.setter
        def gain(self, v: float) -> None:
            self.value = v

        def evaluate(self, robot: RobotModel, t: float) -> TaskTerm:
            return super().evaluate(robot, t)

    dyn = Dynamic()
    stack2 = TaskStack([_hand(Hold()), dyn])
    stack2.reset(robot)
    res2 = rs.make_resolver("pinv")
    res2.step(robot, stack2, q, 0.0, DT)
    dyn.value = 500.0  # not through Task's setter: still seen
    with pytest.raises(ResolverError, match="has gain 500"):
        res2.step(robot, stack2, q, 0.01, DT)


def test_a_trajectory_that_turns_nan_falls_back_as_the_per_task_path_does() -> None:
    """A user trajectory (sampled in Python, then handed to the compiled call) whose twist turns NaN: both paths
    report the same fallback and return a finite q̇."""
    from redundik.tasks.trajectory import Trajectory

    class Glitch(Trajectory):
        def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            twist = np.zeros(6)
            if 0.195 < t < 0.255:
                twist[1] = np.nan
            return self._p0.copy(), self._R0, twist

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack([_hand(Glitch(), gain=5.0), PostureTask(gain=1.0)])

    for method in ("wqp", "pinv", "hqp"):
        seen: list[str] = []
        took = _compare(stack, method, steps=40, fused_expected=False, fallbacks=seen)
        assert any(took[:15]), "the fused step took the user trajectory (sampled in Python)"
        assert len(seen) == 6 and all(f.startswith("non-finite q̇ (from panda_hand)") for f in seen), seen


def test_fused_rate_window_agrees() -> None:
    """Acceleration limits (the rate window around the previous q̇) reach the fused step's box."""

    def stack(robot: RobotModel) -> TaskStack:
        return TaskStack([_hand(Circle(0.06, 3.0, plane=("y", "z"))), PostureTask(gain=1.0)])

    _compare(stack, "wqp", steps=100, limits={"acceleration": 20.0})
    _compare(stack, "hqp", steps=100, limits={"acceleration": 20.0})


def test_fused_hqp_bounds_and_gradients_agree() -> None:
    """hqp: a clearance inequality that binds on about half the steps (its rows written beside the compiled call,
    then the QP cascade on the fused rows), a posture as the null-space regulariser with a gradient subtask (z
    computed in the call), and a second frame task on a level of its own (the rows' destinations in the buffers)."""
    from redundik.tasks.potentials import Clearance
    from redundik.tasks.subtasks import BoundSubtask

    def stack(robot: RobotModel) -> TaskStack:
        centre = robot.frame_position("panda_link4") + np.array([0.0, -0.115, 0.0])
        return TaskStack(
            [
                _hand(Circle(0.08, 2.0, plane=("y", "z"))),
                FrameTask("panda_link5", Hold(), axes=["z"], gain=2.0),
                PostureTask(gain=1.0),
            ],
            [
                BoundSubtask(Clearance("panda_link4", centre, 0.05, axes=("x", "y")), lower=0.06, rate=5.0),
                GradientSubtask(JointCentering(), gain=-0.5),
            ],
        )

    qp: list[int] = []
    _compare(stack, "hqp", steps=150, qp_steps=qp, levels={"panda_link5": 1})
    assert 40 <= len(qp) <= 120, f"the clearance bound on {len(qp)} of 150 steps"
    _compare(stack, "hqp", steps=80)  # the link's height beside the hand, at level 0


@pytest.mark.parametrize(
    ("scenario", "method"),
    [
        ("talos_actuated", "wqp"),
        ("talos", "wqp"),
        ("talos", "pinv"),
        ("talos_actuated", "hqp"),
        ("panda_circle", "hqp"),
        ("snake10", "hqp"),
    ],
)
def test_benchmark_stacks_fused_agree(scenario: str, method: str) -> None:
    """Talos (free-flyer base, two hands, a posture: ``talos_actuated``'s benchmark-only class of the actuated joints,
    or ``talos``'s library ``PostureTask`` of every coordinate, the base's error Pinocchio's difference — limits
    binding on a third of the steps), the Panda's 3-level hqp (a post clearance between hand and posture) and the
    snake's (three clearances, a centering gradient): the benchmark's stacks take the fused step and give the
    per-task path's q̇ and terms."""
    from benchmarks.bench.runners import RedundikRunner
    from benchmarks.bench.scenarios import SCENARIOS

    runners = []
    for fuse in (True, False):
        r = RedundikRunner(SCENARIOS[scenario](), method, None, {})
        r.resolver.fuse = fuse  # type: ignore[attr-defined]
        runners.append(r)
    fused, plain = runners
    dt = fused.scenario.dt
    fused_steps = 0
    for k in range(150):
        t = k * dt
        a = fused.resolver.step(fused.robot, fused.stack, fused.q, t, dt)
        b = plain.resolver.step(plain.robot, plain.stack, fused.q, t, dt)
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-11, err_msg=f"step {k}")
        assert a.fallback == b.fallback and a.info.get("qp") == b.info.get("qp")
        assert a.task_error == pytest.approx(b.task_error, rel=1e-11)
        for ta, tb in zip(a.terms, b.terms, strict=True):
            np.testing.assert_allclose(ta.J, tb.J, rtol=0, atol=1e-13)
            np.testing.assert_allclose(ta.v, tb.v, rtol=0, atol=1e-11)
        fused_steps += isinstance(_fused_plan(fused.resolver), FusedPlan)
        fused.q = fused.robot.integrate(fused.q, a.dq, dt)
    assert fused_steps >= 148


def test_blas_is_limited_inside_a_step_and_restored_after() -> None:
    """``blas_threads = "auto"``: on a robot with nv ≥ 64 the BLAS libraries run one thread inside the step and
    get their own count back after it (a task reads the count while the step evaluates it)."""
    from benchmarks.bench.scenarios import SCENARIOS
    from threadpoolctl import threadpool_info

    from redundik.resolvers.base import _USER_CHOSE_THREADS, BLAS_LIMIT_NV

    def blas_threads() -> list[int]:
        return [int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]

    if _USER_CHOSE_THREADS or max(blas_threads(), default=1) == 1:
        pytest.skip("the BLAS thread count is the user's, or already 1: nothing to limit")
    sc = SCENARIOS["snake80"]()
    robot = sc.robot()
    assert robot.nv >= BLAS_LIMIT_NV
    seen: list[list[int]] = []

    class Reading(PostureTask):
        def evaluate(self, robot: RobotModel, t: float):  # type: ignore[no-untyped-def]
            seen.append(blas_threads())
            return super().evaluate(robot, t)

    robot.update(sc.q0)
    stack = TaskStack([FrameTask(str(robot.nv), Hold(), gain=5.0), Reading(gain=1.0)])
    stack.reset(robot)
    res = rs.make_resolver("wqp")
    res.fuse = False  # the per-task path: the task's evaluate runs inside the step
    res.step(robot, stack, sc.q0, 0.0, DT)  # (the first step loads SciPy's OpenBLAS too)
    before = blas_threads()
    res.step(robot, stack, sc.q0, DT, DT)
    assert seen and all(n == 1 for n in seen[-1]), seen
    assert blas_threads() == before


@numba.njit
def _nan_gradient(q, poses, jw, ints, floats, eta):  # type: ignore[no-untyped-def]
    eta[0] = np.nan
    return 0.0


class _NanPotential(rk.CompiledPotential):
    name = "nan_writer"

    def compiled_gradient(self, robot: RobotModel) -> rk.CompiledGradient:
        return rk.CompiledGradient(_nan_gradient, np.zeros(0, np.int64), np.zeros(0))


class _MalformedPotential(rk.CompiledPotential):
    name = "malformed_writer"

    def compiled_gradient(self, robot: RobotModel) -> rk.CompiledGradient:
        return rk.CompiledGradient(_nan_gradient, np.zeros(0), np.zeros(0))  # ints not int64


@pytest.mark.parametrize("method", ["pinv", "wqp", "hqp"])
def test_a_potential_writer_that_writes_nan_stops_the_step_and_names_it(method: str) -> None:
    """A compiled gradient writer that writes NaN: q̇ = 0 and the fallback names its subtask; a malformed writer is
    refused with a TaskError naming the potential."""
    robot = _panda()
    q = _q0(robot)
    robot.update(q)
    stack = TaskStack([_hand(None, gain=5.0)], [GradientSubtask(_NanPotential(), gain=1.0)])
    stack.reset(robot)
    res = rs.make_resolver(method)
    for k in range(3):
        out = res.step(robot, stack, q, k * DT, DT)
        assert np.all(out.dq == 0.0)
        assert out.fallback is not None and "nan_writer" in out.fallback
    bad = TaskStack([_hand(None, gain=5.0)], [GradientSubtask(_MalformedPotential(), gain=1.0)])
    bad.reset(robot)
    with pytest.raises(TaskError, match=r"malformed_writer.*ints must be a 1-D int64 array"):
        rs.make_resolver(method).step(robot, bad, q, 0.0, DT)
