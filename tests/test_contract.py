"""The control-loop contract: one stack, one meaning under every resolver; validation; exact rank deficiency;
strict priority; bounded damping; targets at run time; feedback never freezes.

Tolerances (stated once):

* ``pinv``, ``hqp`` and ``feedback`` (no target subtask) compute the same q̇ = J⁺V + (I − J⁺J)z: they agree to 1e-9
  (relative to ‖V‖ + ‖z‖) when no limit is active;
* ``wqp`` weights each level ρ = 1e-4 below the one above; its main-task velocity J q̇ differs from J J⁺V by at most
  (ρ σ_max ‖z‖ + 1.01 ρ ‖V‖)/σ_min² (the normal equations in the SVD basis), checked with a 1.5× margin.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, assume, given, seed, settings
from hypothesis import strategies as st

import redundik as rk
from redundik.resolvers.linalg import damped_svd, pseudo_inverse
from redundik.resolvers.singularity import DEFAULT_MAX_JOINT_SPEED
from tests.test_qp_helpers import case2_robot, random_robot, tip

RHO = 1e-4
ROOT = Path(__file__).resolve().parents[1]


def _random_problem(seed_: int, n: int, posture: bool, axes: str):
    rng = np.random.default_rng(seed_)
    robot = random_robot(rng, n)
    q = robot.random_configuration(rng)
    subs: list[rk.Subtask] = [rk.GradientSubtask(rk.JointCentering(), gain=float(rng.uniform(-2, 2)))]
    if rng.uniform() < 0.5:
        subs.append(rk.GradientSubtask(rk.JointSine2(robot.joint_names[1]), gain=float(rng.uniform(-2, 2))))
    tasks: list[rk.Task] = [
        rk.FrameTask(tip(robot), rk.Line(rng.uniform(-0.3, 0.3, 3).tolist()), axes=axes, gain=float(rng.uniform(0, 5)))
    ]
    if posture:  # the pink/mink idiom: a low-weight posture in the task list
        tasks.append(rk.PostureTask(gain=float(rng.uniform(0.1, 2)), weight=1e-3))
    return robot, q, rk.TaskStack(tasks, subs)


def _step(name: str, robot: rk.RobotModel, stack: rk.TaskStack, q: np.ndarray) -> rk.StepResult:
    resolver = rk.make_resolver(name, limits=False) if name in ("wqp", "hqp") else rk.make_resolver(name)
    robot.update(q)
    stack.reset(robot)
    return resolver.step(robot, stack, q, 0.1, 0.01)


@seed(20261201)
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(
    seed_=st.integers(0, 2**31 - 1),
    n=st.integers(4, 8),
    posture=st.booleans(),
    axes=st.sampled_from(["position", "pose"]),
)
def test_four_resolvers_agree_on_the_main_task_velocity(seed_: int, n: int, posture: bool, axes: str) -> None:
    robot, q, stack = _random_problem(seed_, n, posture, axes)
    assume(not (axes == "pose" and n < 7))
    res = {name: _step(name, robot, stack, q) for name in ("pinv", "hqp", "feedback", "wqp")}
    J = res["pinv"].terms[0].J
    V = res["pinv"].terms[0].v
    s = np.linalg.svd(J, compute_uv=False)
    assume(s[-1] >= 0.05)  # away from singularities: no damping anywhere
    z = res["pinv"].dq_null
    scale = float(np.linalg.norm(V) + np.linalg.norm(res["pinv"].dq) + 1.0)
    for name in ("hqp", "feedback"):
        np.testing.assert_allclose(res[name].dq, res["pinv"].dq, atol=1e-9 * scale, err_msg=name)
        assert res[name].fallback is None and not res[name].damped
    np.testing.assert_allclose(J @ res["pinv"].dq, V, atol=1e-9 * scale)  # the main task is met exactly
    zfull = stack.null_target(robot, res["pinv"].terms, stack.layout())
    assert z is not None and zfull is not None
    bound = (RHO * s[0] * np.linalg.norm(zfull) + 1.01 * RHO * np.linalg.norm(V)) / s[-1] ** 2
    assert np.linalg.norm(J @ res["wqp"].dq - V) <= 1.5 * bound + 1e-12
    assert res["wqp"].fallback is None
    for r in res.values():  # every resolver reports σ_min of the main task
        assert r.sigma_min == pytest.approx(s[-1], rel=1e-6)


def _level_residual(res: rk.StepResult, level: int) -> float:
    return float(res.info[f"residual_L{level}"])  # type: ignore[arg-type]


@seed(20261202)
@settings(max_examples=200, deadline=None)
@given(seed_=st.integers(0, 2**31 - 1), n=st.integers(3, 8), duplicate=st.booleans(), zero_row=st.booleans())
def test_lower_levels_never_change_higher_levels(seed_: int, n: int, duplicate: bool, zero_row: bool) -> None:
    """Strict priority, rank-deficient levels included: level 0's residual is the same with or without lower levels."""
    rng = np.random.default_rng(seed_)
    robot = random_robot(rng, n)
    q = robot.random_configuration(rng)
    frame = tip(robot)
    axes = ["x", "y"] + (["z"] if n > 3 else [])
    top: list[rk.Task] = [rk.FrameTask(frame, rk.Line(rng.uniform(-1, 1, 3).tolist()), axes=axes, gain=1.0)]
    if duplicate:  # the same rows twice: exact rank deficiency
        top.append(rk.FrameTask(frame, rk.Line(rng.uniform(-1, 1, 3).tolist()), axes=axes, gain=1.0, name="dup"))
    if zero_row:  # a row of the z axis of a joint frame that cannot move the base joint's... any zero row
        top.append(rk.JointCoupling(robot.joint_names[0], robot.joint_names[1], gain=1.0, name="couple", offset=0.0))
    lower = [
        rk.TargetSubtask(rk.JointValue(robot.joint_names[-1], 2.0, name="far"), target=0.0, rate=3.0),
        rk.GradientSubtask(rk.JointCentering(), gain=float(rng.uniform(-3, 3))),
    ]
    alone = _step("hqp", robot, rk.TaskStack(list(top)), q)
    full = _step("hqp", robot, rk.TaskStack(list(top), lower), q)
    r0 = _level_residual(alone, 0)
    assert _level_residual(full, 0) == pytest.approx(r0, abs=1e-9)
    if alone.damped:  # a near-singular level is damped by design (σ_min < ε): its optimum is the damped one
        return
    # the optimum of level 0 alone (numpy's lstsq of its stacked rows, not the resolver's kernel)
    A = np.vstack([t.J for t in alone.terms])
    b = np.concatenate([t.v for t in alone.terms])
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    assert r0 == pytest.approx(float(np.linalg.norm(A @ x - b)), abs=1e-9)


def test_duplicated_row_level_keeps_its_exact_optimum() -> None:
    """A level-0 task given twice (an exactly rank-deficient level) is solved exactly, not damped."""
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    tip_task = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")
    twin = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar", name="twin")
    lower = rk.TargetSubtask(rk.JointValue("1", 3.0, name="pull"), target=0.0, rate=5.0)
    res = _step("hqp", robot, rk.TaskStack([tip_task, twin], [lower]), q)
    assert _level_residual(res, 0) <= 1e-9
    assert not res.damped and res.fallback is None
    np.testing.assert_allclose(res.terms[0].J @ res.dq, [0.2, -0.4], atol=1e-9)


def test_planar_arm_with_position_axes_tracks_exactly() -> None:
    """axes='position' on a planar arm has a zero z row: the rule must not damp it (it used to: 1.6 mm/s off)."""
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4, 0.0]), axes="position")])
    for name in ("pinv", "hqp", "feedback"):
        res = _step(name, robot, stack, q)
        np.testing.assert_allclose(res.terms[0].J @ res.dq, [0.2, -0.4, 0.0], atol=1e-12, err_msg=name)
        assert not res.damped, name
    log = rk.simulate(robot, stack, rk.PinvResolver(), q, dt=0.01, steps=100)
    assert not log.damped.any()


def test_damped_svd_damps_only_small_nonzero_directions_and_stays_bounded() -> None:
    rng = np.random.default_rng(0)
    U, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    Vt, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    eps, lmax = 1e-2, 5e-2
    for sig in ([2.0, 1.0, 0.5, 0.0], [2.0, 1.0, 1e-3, 0.0], [2.0, 1.0, 1e-7, 1e-9], [3.0, 2.0, 1.0, 1.1e-2]):
        J = U @ np.diag(sig) @ Vt[:4]
        d = damped_svd(J, epsilon=eps, max_damping=lmax)
        big = np.array(sig) >= eps
        np.testing.assert_allclose(d.inv[: int(big.sum())], 1.0 / np.array(sig)[big], rtol=1e-9)  # exact where large
        assert d.rank == int(np.count_nonzero(np.array(sig) > 1e-10 * sig[0]))
        assert d.damped == bool(any(1e-10 * sig[0] < s < eps for s in sig))
        # ‖J⁺_λ‖ ≤ 1/ε with these defaults (λ_max > ε/√2): |q̇| ≤ ‖V‖/ε near any singularity
        assert np.linalg.norm(d.pinv, 2) <= 1.0 / eps * (1 + 1e-9)
        np.testing.assert_allclose(J @ d.null_basis, 0.0, atol=1e-12)


@pytest.mark.parametrize("cond", [1.0, 10.0, 100.0, 999.0])
def test_fast_path_agrees_with_the_svd_on_ill_conditioned_jacobians(cond: float) -> None:
    rng = np.random.default_rng(int(cond))
    U, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    Vt, _ = np.linalg.qr(rng.normal(size=(9, 9)))
    s = np.geomspace(cond * 0.02, 0.02, 6)  # σ_min = 0.02 ≥ ε: undamped
    J = U @ np.diag(s) @ Vt[:6]
    pi = pseudo_inverse(J)
    ref = np.linalg.pinv(J, rcond=1e-15)
    assert not pi.damped
    assert np.linalg.norm(pi.pinv - ref) <= 1e-9 * np.linalg.norm(ref)
    P = pi.pinv
    for lhs, rhs in ((J @ P @ J, J), (P @ J @ P, P), ((J @ P).T, J @ P), ((P @ J).T, P @ J)):  # Moore–Penrose (5.4)
        assert np.linalg.norm(lhs - rhs) <= 1e-9 * max(1.0, np.linalg.norm(rhs))


def test_every_resolver_reports_sigma_min_and_damping_near_a_singularity() -> None:
    robot = case2_robot()
    q = np.array([0.2, 1e-4, -1e-4])  # almost stretched
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    for name in ("pinv", "feedback", "hqp", "wqp"):
        res = _step(name, robot, stack, q)
        assert res.sigma_min < 1e-2 and res.damped, name
        assert np.linalg.norm(res.dq) <= np.linalg.norm([0.2, -0.4]) / 1e-2 * (1 + 1e-9), name


# ------------------------------------------------------------------------------------------------ validation
@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_step_validates_q_and_dt(name: str) -> None:
    robot = case2_robot()
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    resolver = rk.make_resolver(name)
    q = np.radians([110.0, -40.0, -30.0])
    for bad_q, msg in (
        ([np.nan, 0, 0], "NaN or infinite"),
        ([0.0, 0.0], "2 entries"),
        (["a", 0, 0], "array of 3"),
        ([0.0, 2e9, 0.0], r"q\[1\] = 2e\+09 is beyond ±1e\+09"),  # sin/cos of it: no significant digit left
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # (and no warning on the way)
            with pytest.raises(rk.ResolverError, match=msg):
                resolver.step(
                    robot, stack, np.array(bad_q, dtype=object if isinstance(bad_q[0], str) else float), 0.0, 0.01
                )
    # ‖q‖² overflows: the same error whether NumPy's overflow is ignored, warned of (silenced), raised as a
    # warning (-W error) or as a floating-point error; never the bare warning or exception
    for over, filt in (("ignore", "default"), ("warn", "error"), ("raise", "default")):
        with warnings.catch_warnings(), np.errstate(over=over):
            warnings.simplefilter(filt)
            with pytest.raises(rk.ResolverError, match=r"q\[2\] = -1e\+200 is beyond"):
                resolver.step(robot, stack, np.array([0.0, 0.0, -1e200]), 0.0, 0.01)
    for dt, msg in (
        (0.0, "dt must be > 0"),
        (-0.01, "dt must be > 0"),
        (np.inf, "dt must be finite"),
        (np.nan, "finite"),
    ):
        with pytest.raises(rk.ResolverError, match=msg):
            resolver.step(robot, stack, q, 0.0, dt)
    with pytest.raises(rk.ResolverError, match="t must be finite"):
        resolver.step(robot, stack, q, np.nan, 0.01)
    stack.tasks[0].gain = 300.0  # K·dt = 3 > 2
    with pytest.raises(rk.ResolverError, match=r"K·dt = 3 > 2 makes the first-order loop diverge"):
        resolver.step(robot, stack, q, 0.0, 0.01)


def test_step_rechecks_a_stack_that_changed() -> None:
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    resolver = rk.PinvResolver()
    resolver.step(robot, stack, q, 0.0, 0.01)
    stack.subtasks.append(rk.BoundSubtask(rk.JointSine2("3"), lower=0.1))
    with pytest.raises(rk.ResolverError, match="'sin2_3' is a bound subtask; pinv accepts gradient subtasks"):
        resolver.step(robot, stack, q, 0.0, 0.01)
    stack.subtasks[0] = rk.TargetSubtask(rk.JointSine2("3"), target=1.0)
    with pytest.raises(rk.ResolverError, match=r"target subtask; pinv accepts gradient.*'feedback', 'wqp' or 'hqp'"):
        resolver.step(robot, stack, q, 0.0, 0.01)
    stack.subtasks[0] = rk.JointSine2("3")  # type: ignore[call-overload]
    with pytest.raises(rk.ResolverError, match=r"subtasks\[0\]: expected a Subtask, got JointSine2"):
        resolver.step(robot, stack, q, 0.0, 0.01)


def test_repeated_names_and_bad_subtask_values_are_refused() -> None:
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    a = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar", name="tip")
    b = rk.FrameTask("2", axes="planar", name="tip")
    with pytest.raises(rk.ResolverError, match=r"unique.*\['tip'\]"):
        rk.PinvResolver().step(robot, rk.TaskStack([a, b]), q, 0.0, 0.01)
    with pytest.raises(rk.TaskError, match="gain must be a finite number"):
        rk.GradientSubtask(rk.JointSine2("3"), gain=np.nan)
    with pytest.raises(rk.TaskError, match="weight must be > 0"):
        rk.TargetSubtask(rk.JointSine2("3"), target=1.0, weight=0.0)
    with pytest.raises(rk.TaskError, match=r"lower \(2.0\) > upper \(1.0\)"):
        rk.BoundSubtask(rk.JointSine2("3"), lower=2.0, upper=1.0)
    with pytest.raises(rk.TaskError, match="needs lower and/or upper"):
        rk.BoundSubtask(rk.JointSine2("3"))
    with pytest.raises(rk.TaskError, match="priority must be an integer level"):
        rk.TargetSubtask(rk.JointSine2("3"), target=1.0, priority=-1)
    with pytest.raises(rk.ResolverError, match="epsilon must be a finite number"):
        rk.FeedbackResolver(epsilon=np.nan)


def test_no_resolver_tests_a_concrete_task_class() -> None:
    """Tasks declare what resolvers may exploit (identity Jacobian, regularisation): no isinstance on task classes."""
    import re

    src = ROOT / "src" / "redundik" / "resolvers"
    pattern = re.compile(r"isinstance\([^)]*(Task|Posture|Frame|Subtask|Potential|Centering)\b")
    hits = [
        f"{p.name}:{i}"
        for p in src.rglob("*.py")
        for i, ln in enumerate(p.read_text().splitlines())
        if pattern.search(ln)
    ]
    assert not hits, hits


# ------------------------------------------------------------------------------------------------ feedback
def test_feedback_is_not_frozen_at_a_potentials_own_target() -> None:
    """N = 0 exactly at the target (p = (q3 − c)² at q3 = c): k = 0, q̇ = J⁺V — never 0/0, never a silent zero."""
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    pot = rk.JointValue("3", float(q[2]), name="at_target")
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], [rk.TargetSubtask(pot, target=0.0)])
    res = _step("feedback", robot, stack, q)
    J = res.terms[0].J
    np.testing.assert_allclose(res.dq, np.linalg.pinv(J) @ np.array([0.2, -0.4]), atol=1e-12)
    assert res.fallback is None and np.linalg.norm(res.dq) > 0.1


@pytest.mark.slow
def test_feedback_on_the_panda_tracks_and_drives_its_potential_to_target() -> None:
    robot = rk.load_example_robot("panda")
    q0 = np.array([0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0.02, 0.02])
    errs = {}
    for name in ("pinv", "feedback"):
        circle = rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, np.pi, plane=("y", "z")), gain=50.0)
        if name == "pinv":
            subs: list[rk.Subtask] = [rk.GradientSubtask(rk.JointCentering(), gain=-2.0)]
        else:  # drive (q3 − 0.3)² to 0 at 4 /s: its gradient vanishes at the target (the old frozen case)
            subs = [rk.TargetSubtask(rk.JointValue("panda_joint3", 0.3, name="j3"), target=0.0, rate=4.0)]
        log = rk.simulate(robot, rk.TaskStack([circle], subs), rk.make_resolver(name), q0, dt=1e-3, steps=2000)
        pos = np.array([robot.frame_position("panda_hand_tcp") for _ in [robot.update(qq) for qq in log.q[-1:]]])
        assert np.isfinite(pos).all() and not log.fallbacks
        errs[name] = log.max_task_error
        if name == "feedback":
            p = log.potentials["j3"]
            assert p[-1] / p[0] == pytest.approx(np.exp(-8.0), rel=0.05)  # ṗ = −K p: e^{−8} after 2 s (Euler: ~1 %)
    assert errs["feedback"] <= 2.0 * errs["pinv"] + 1e-6, errs


# ------------------------------------------------------------------------------------------------ run-time targets
def test_frame_targets_set_at_run_time_survive_reset() -> None:
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    robot.update(q)
    task = rk.FrameTask("3", axes="planar")
    assert task.gain == rk.tasks.DEFAULT_HOLD_GAIN  # no trajectory: hold with the default gain
    stack = rk.TaskStack([task])
    stack.reset(robot)
    p = robot.frame_position("3").copy()
    task.set_target(p + np.array([0.1, 0.0, 0.0]))  # position only
    stack.reset(robot)
    res = rk.PinvResolver().step(robot, stack, q, 0.0, 0.01)
    np.testing.assert_allclose(res.terms[0].error, [0.1, 0.0], atol=1e-12)
    T = np.eye(4)
    T[:3, 3] = p + np.array([0.0, -0.2, 0.0])
    task.set_target(T)
    stack.reset(robot)
    np.testing.assert_allclose(task.evaluate(robot, 0.0).error, [0.0, -0.2], atol=1e-12)
    task.set_target(pin.SE3(np.eye(3), p))
    np.testing.assert_allclose(task.evaluate(robot, 0.0).error, [0.0, 0.0], atol=1e-12)
    robot.update(q + 0.1)
    task.set_target_from_configuration(robot)
    np.testing.assert_allclose(task.evaluate(robot, 0.0).error, [0.0, 0.0], atol=1e-12)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    for target, msg in ((bad, "not a rigid transform"), (np.ones(5), "got shape"), ([np.nan] * 3, "NaN")):
        with pytest.raises(rk.TaskError, match=msg):
            task.set_target(target)


def test_posture_and_potential_targets_at_run_time() -> None:
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    robot.update(q)
    posture = rk.PostureTask(gain=2.0)
    stack = rk.TaskStack([posture])
    stack.reset(robot)
    posture.set_target(q + 0.1)
    stack.reset(robot)  # keeps what was set
    np.testing.assert_allclose(posture.evaluate(robot, 0.0).error, 0.1, atol=1e-12)
    with pytest.raises(rk.TaskError, match="NaN"):
        posture.set_target([np.nan, 0, 0])
    sub = rk.TargetSubtask(rk.JointSine2("3"), target=0.5)
    sub.set_target(0.9, 0.1)
    _, v, e = sub.row(robot)
    assert e == pytest.approx(0.9 - np.sin(q[2]) ** 2) and v == pytest.approx(0.1 + e)
    with pytest.raises(rk.TaskError, match="target must be a finite number"):
        sub.set_target(np.inf)


def test_teleop_example_tracks_a_moving_and_jumping_target() -> None:
    import json

    for name in ("pinv", "wqp", "hqp", "feedback"):
        proc = subprocess.run(
            [sys.executable, str(ROOT / "examples" / "teleop.py"), "--resolver", name],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stdout + proc.stderr
        rec = json.loads(proc.stdout.strip().splitlines()[-1])
        assert rec["error_at_jump_m"] > 0.03  # the jump really happened
        assert rec["settled_error_m"] < 5e-3 and rec["error_before_jump_m"] < 5e-3  # lag of a 0.1 m/s target at 40 /s
        assert rec["fallback_steps"] == 0 and rec["limit_violation"] == 0.0


class _NaNPotential(rk.Potential):
    """A broken user potential: its gradient is NaN (the step must say so, not return NaN)."""

    name = "broken"

    def value(self, robot: rk.RobotModel) -> float:
        return 0.0

    def gradient(self, robot: rk.RobotModel) -> np.ndarray:
        return np.full(robot.nv, np.nan)


class _HugeLine(rk.Line):
    """A line at (1e308, −1e308) that skips the constructor's bounds (as a user's own trajectory could)."""

    def __init__(self) -> None:
        self.velocity = np.array([1e308, -1e308, 0.0])


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_a_non_finite_intermediate_is_a_diagnosed_fallback(name: str) -> None:
    robot = case2_robot()
    q = np.radians([110.0, -40.0, -30.0])
    tip_task = rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")
    stack = rk.TaskStack([tip_task], [rk.GradientSubtask(_NaNPotential())])
    res = _step(name, robot, stack, q)
    assert np.isfinite(res.dq).all()
    assert res.fallback is not None and "non-finite" in res.fallback
    assert "subtask 'broken'" in res.fallback  # the source is named
    if name != "pinv":  # as a target subtask's row (a least-squares level under hqp, a weighted row under wqp)
        target = rk.TaskStack([tip_task], [rk.TargetSubtask(_NaNPotential(), target=0.0, rate=1.0)])
        with np.errstate(invalid="ignore"):
            res = _step(name, robot, target, q)
        assert np.isfinite(res.dq).all()
        assert res.fallback is not None and "subtask 'broken'" in res.fallback, res.fallback
    # such a line is refused where it is made; a trajectory of one's own that asks for it anyway is resolved as
    # asked, and the overflow it causes is refused by the integration, never handed on as an infinite q
    with pytest.raises(rk.TaskError, match="line velocity"):
        rk.Line([1e308, -1e308])
    huge = rk.TaskStack([rk.FrameTask("3", _HugeLine(), axes="planar", gain=1.0)])
    with np.errstate(over="ignore", invalid="ignore"):
        res = _step(name, robot, huge, q)
    assert np.isfinite(res.dq).all()
    if res.fallback is None:  # resolved as asked (pinv, hqp, feedback), then scaled to the joint-speed cap, flagged
        assert "max_joint_speed" in res.relaxed and res.info["capped"] is True
        assert np.abs(res.dq).max() <= DEFAULT_MAX_JOINT_SPEED
        uncapped = rk.make_resolver(name, max_joint_speed=None, **({"limits": False} if name == "hqp" else {}))
        with np.errstate(over="ignore", invalid="ignore"):
            res = uncapped.step(robot, huge, q, 0.1, 0.01)
        with np.errstate(over="ignore", invalid="ignore"), pytest.raises(rk.ModelError, match="not finite"):
            robot.integrate(q, res.dq, 10.0)  # without the cap: integrating it overflows, and says so
    else:  # wqp's normal equations overflow (‖v‖² ~ 1e616): a diagnosed fallback
        assert "non-finite" in res.fallback or "failed" in res.fallback


def test_a_frame_task_on_a_world_fixed_frame_is_refused() -> None:
    robot = case2_robot()
    robot.update(np.radians([110.0, -40.0, -30.0]))
    with pytest.raises(rk.TaskError, match="frame '0' is fixed to the world"):
        rk.TaskStack([rk.FrameTask("0", axes="planar")]).reset(robot)
