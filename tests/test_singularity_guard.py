"""The joint-speed cap and the singularity guard (issue 33, item 3; :mod:`redundik.resolvers.singularity`).

Sweeps drive the planar 3R arm and the Panda to their stretched-out singularity (a target outside reach) and back,
under every resolver. Expected values are independent of the code under test: the planar arm's closed-form
Jacobian, finite differences, the robot's velocity limits, and a twin resolver without cap or guard stepped from
the same configuration (what the limiter started from).
"""

from __future__ import annotations

import copy
import itertools
import math
from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError
from redundik.resolvers.singularity import (
    DECELERATE,
    DEFAULT_MAX_JOINT_SPEED,
    HALT,
    OK,
    SingularityGuard,
    jacobian_derivatives,
    manipulability_gradient,
    measure,
    singular_values,
)
from tests.helpers import fd_gradient, planar3r

RESOLVERS = ("pinv", "feedback", "wqp", "hqp")
TOOL = "panda_hand_tcp"


@pytest.fixture(scope="module")
def panda() -> rk.RobotModel:
    return rk.load_example_robot("panda")


def _planar_jacobian(q: np.ndarray) -> np.ndarray:
    """The 3R arm's tip Jacobian (x, y rows), a = 1, written out (the chapter's printed form)."""
    c = np.cumsum(q)
    J = np.zeros((2, 3))
    for k in range(3):
        J[0, k] = -np.sum(np.sin(c[k:]))
        J[1, k] = np.sum(np.cos(c[k:]))
    return J


def _setup(robot: rk.RobotModel, frame: str, axes: str, q0: np.ndarray, name: str, **opts: Any) -> tuple[Any, ...]:
    task = rk.FrameTask(frame, axes=axes, gain=10.0)
    stack = rk.TaskStack([task])
    resolver = rk.make_resolver(name, **opts)
    robot.update(q0)
    stack.reset(robot)
    return task, stack, resolver


def _panda_start(robot: rk.RobotModel) -> np.ndarray:
    q = robot.neutral()
    q[:7] = [0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8]
    return q


def _sweep_targets(start: np.ndarray, far: np.ndarray, n_out: int = 120, n_hold: int = 60) -> list[np.ndarray]:
    """Out from ``start`` to ``far`` (outside reach), held there, and back to ``start``."""
    out = [start + (far - start) * min(1.0, k / n_out) for k in range(n_out + n_hold)]
    back = [far + (start - far) * min(1.0, k / n_out) for k in range(n_out + n_hold)]
    return out + back


def _cases(panda: rk.RobotModel) -> dict[str, tuple[rk.RobotModel, str, str, np.ndarray, list[np.ndarray]]]:
    p3 = planar3r()
    q3 = np.array([0.3, 0.4, 0.3])
    p3.update(q3)
    tip = p3.frame_position("3")
    qp = _panda_start(panda)
    panda.update(qp)
    tcp = panda.frame_position(TOOL)
    return {
        "planar3r": (p3, "3", "planar", q3, _sweep_targets(tip, np.array([4.0, 0.5, 0.0]))),
        "panda": (panda, TOOL, "position", qp, _sweep_targets(tcp, tcp + np.array([1.2, 0.3, 0.4]))),
    }


def _run(case: tuple[Any, ...], name: str, dt: float = 0.01, twin: bool = False, **opts: Any) -> list[dict[str, Any]]:
    """Step along the sweep; per step: q, q̇, the result's info/relaxed, and (``twin``) the q̇ of a copy of the
    resolver without cap or guard stepped from the same configuration."""
    robot, frame, axes, q0, targets = case
    task, stack, resolver = _setup(robot, frame, axes, q0, name, **opts)
    q = q0.copy()
    rows = []
    for k, p in enumerate(targets):
        task.set_target(p)
        raw = None
        if twin:
            other = copy.deepcopy(resolver)
            other.singularity, other.max_joint_speed = None, None
            raw = np.array(other.step(robot, stack, q, k * dt, dt).dq)
            robot.update(q)
        res = resolver.step(robot, stack, q, k * dt, dt)
        info = dict(res.info)
        rows.append({"q": q.copy(), "dq": np.array(res.dq), "info": info, "relaxed": res.relaxed, "raw": raw})
        q = robot.integrate(q, res.dq, dt)
    return rows


@pytest.mark.parametrize("name", RESOLVERS)
@pytest.mark.parametrize("robot_name", ["planar3r", "panda"])
def test_sweep_through_singularity_capped_and_flagged(panda: rk.RobotModel, robot_name: str, name: str) -> None:
    case = _cases(panda)[robot_name]
    robot = case[0]
    vel = robot.velocity_limits
    cap = np.where(np.isfinite(vel) & (vel > 0), vel, DEFAULT_MAX_JOINT_SPEED)
    rows = _run(case, name, twin=True, singularity=SingularityGuard())
    states = [r["info"]["singularity"] for r in rows]
    # (the Panda's joint 4 stops 0.07 rad short of a straight elbow: under the QPs' position limits its arm cannot
    # stretch out fully, and the sweep reaches the guard's deceleration zone)
    reached = DECELERATE if robot_name == "panda" and name in ("wqp", "hqp") else HALT
    assert reached in states, f"{name} on {robot_name}: the sweep never reached {reached} (states {set(states)})"
    assert states[-1] == OK, f"{name} on {robot_name}: not released at the end of the sweep"
    for k, r in enumerate(rows):
        dq, raw = r["dq"], r["raw"]
        assert np.all(np.abs(dq) <= cap * (1 + 1e-9)), f"step {k}: |q̇| {np.abs(dq).max():.3g} over the cap"
        changed = not np.allclose(dq, raw, rtol=1e-9, atol=1e-12)
        if changed:  # every step whose q̇ the limiter changed says so, and why
            assert r["relaxed"], f"{name} on {robot_name}, step {k}: q̇ changed but not flagged"
        if np.any(np.abs(raw) > cap * (1 + 1e-9)):
            assert changed and r["relaxed"], f"step {k}: over-cap q̇ returned unflagged"
        if "max_joint_speed" in r["relaxed"]:
            assert r["info"]["capped"] is True and 0 < r["info"]["speed_scale"] < 1
        if "singularity" in r["relaxed"]:
            assert r["info"]["singularity_scale"] < 1.0


@pytest.mark.parametrize("name", RESOLVERS)
def test_unguarded_sweep_is_capped_by_default(panda: rk.RobotModel, name: str) -> None:
    """Without a guard the default cap still bounds |q̇| near the singularity; switched off, the closed forms
    reach hundreds of rad/s there (the issue's measured failure), so the sweep does probe a spike."""
    case = _cases(panda)["planar3r"]
    rows = _run(case, name)
    assert max(np.abs(r["dq"]).max() for r in rows) <= DEFAULT_MAX_JOINT_SPEED * (1 + 1e-9)
    capped = [r for r in rows if "max_joint_speed" in r["relaxed"]]
    assert capped and all(r["info"]["capped"] for r in capped)
    off = _run(case, name, max_joint_speed=None)
    assert max(np.abs(r["dq"]).max() for r in off) > 10 * DEFAULT_MAX_JOINT_SPEED


def test_gradient_matches_finite_differences_planar() -> None:
    robot = planar3r()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 3)
        _task, stack, resolver = _setup(robot, "3", "planar", q, "pinv")
        res = resolver.step(robot, stack, q, 0.0, 0.01)
        J = np.vstack([t.J for t in res.main_terms])
        np.testing.assert_allclose(J, _planar_jacobian(q), atol=1e-12)
        H = jacobian_derivatives(res, robot, stack)
        assert H is not None
        g = manipulability_gradient(J, H)

        def w(x: np.ndarray) -> float:
            Jx = _planar_jacobian(x)
            return math.sqrt(np.linalg.det(Jx @ Jx.T))

        np.testing.assert_allclose(g, fd_gradient(w, q), rtol=1e-6, atol=1e-8)


def test_gradient_matches_finite_differences_panda(panda: rk.RobotModel) -> None:
    rng = np.random.default_rng(4)
    for axes, rows in (("pose", slice(0, 6)), ("position", slice(0, 3))):
        q = panda.random_configuration(rng)
        _task, stack, resolver = _setup(panda, TOOL, axes, q, "pinv")
        res = resolver.step(panda, stack, q, 0.0, 0.01)
        J = np.vstack([t.J for t in res.main_terms])
        H = jacobian_derivatives(res, panda, stack)
        assert H is not None
        g = manipulability_gradient(J, H)

        def w(x: np.ndarray, rows: slice = rows) -> float:
            panda.update(x)
            return singular_values(panda.frame_jacobian(TOOL)[rows])[2]

        np.testing.assert_allclose(g, fd_gradient(w, q), rtol=1e-5, atol=1e-7)


def test_hysteresis_no_chattering() -> None:
    guard = SingularityGuard(slow_at=40.0, halt_at=120.0, release_at=30.0)
    rng = np.random.default_rng(0)
    for centre in (40.0, 120.0):  # κ hovering at a threshold, noise ±5
        state, seq = OK, []
        for kappa in centre + rng.uniform(-5.0, 5.0, 200):
            state = guard.next_state(state, float(kappa))
            seq.append(state)
        changes = sum(a != b for a, b in itertools.pairwise(seq))
        assert changes <= 1, f"κ around {centre}: {changes} state changes"
    assert guard.next_state(HALT, 35.0) == HALT and guard.next_state(HALT, 29.0) == OK


@pytest.mark.parametrize("name", RESOLVERS)
def test_sweep_states_change_few_times(panda: rk.RobotModel, name: str) -> None:
    rows = _run(_cases(panda)["planar3r"], name, singularity=True)
    states = [r["info"]["singularity"] for r in rows]
    changes = sum(a != b for a, b in itertools.pairwise(states))
    assert changes <= 6, f"{name}: {changes} state changes over one out-and-back sweep: {states}"


@pytest.mark.parametrize("name", RESOLVERS)
def test_halted_allows_only_motion_away(panda: rk.RobotModel, name: str) -> None:
    """While halted, no step approaches the singularity to first order (∇w·q̇ ≥ 0); once the target comes back
    within reach, the arm moves away from the singularity and the guard releases."""
    robot, frame, axes, q0, targets = _cases(panda)["planar3r"]
    rows = _run((robot, frame, axes, q0, targets), name, singularity=True)
    halted = [r for r in rows if r["info"]["singularity"] == HALT]
    assert halted
    moved_away = 0
    for r in halted:
        _task, stack, resolver = _setup(robot, frame, axes, r["q"], "pinv")
        res = resolver.step(robot, stack, r["q"], 0.0, 0.01)
        J = np.vstack([t.J for t in res.main_terms])
        H = jacobian_derivatives(res, robot, stack)
        assert H is not None
        slope = float(manipulability_gradient(J, H) @ r["dq"])
        assert slope >= -1e-9 * max(1.0, float(np.abs(r["dq"]).max()))
        moved_away += slope > 1e-6
    assert moved_away > 0, "the halted guard never let the arm move away from the singularity"


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_tiny_dt_reference_step_capped_and_flagged(panda: rk.RobotModel, name: str) -> None:
    """A 0.5 m reference step over dt = 1e-9 s with gain 1/dt: the issue measured 9.7e8 rad/s from pinv."""
    dt = 1e-9
    q = _panda_start(panda)
    task, stack, resolver = _setup(panda, TOOL, "position", q, name)
    task.gain = 1.0 / dt
    panda.update(q)
    task.set_target(panda.frame_position(TOOL) + np.array([0.5, 0.0, 0.0]))
    res = resolver.step(panda, stack, q, 0.0, dt)
    assert np.all(np.abs(res.dq) <= panda.velocity_limits * (1 + 1e-9))
    if name in ("pinv", "feedback"):
        assert res.info["capped"] is True and "max_joint_speed" in res.relaxed
        assert res.info["speed_scale"] < 1e-6
        off = _setup(panda, TOOL, "position", q, name, max_joint_speed=None)
        off[0].gain = 1.0 / dt
        off[0].set_target(panda.frame_position(TOOL) + np.array([0.5, 0.0, 0.0]))
        assert np.abs(off[2].step(panda, off[1], q, 0.0, dt).dq).max() > 1e6  # what the cap caught


@pytest.mark.parametrize("name", RESOLVERS)
def test_default_guard_leaves_answers_away_from_singularities(panda: rk.RobotModel, name: str) -> None:
    q0 = _panda_start(panda)
    panda.update(q0)
    goal = panda.frame_position(TOOL) + np.array([0.05, -0.05, 0.05])
    runs = []
    for opts in ({"max_joint_speed": None}, {"singularity": SingularityGuard()}):
        task, stack, resolver = _setup(panda, TOOL, "pose", q0, name, **opts)
        task.gain = 2.0
        task.set_target(goal)
        q, out = q0.copy(), []
        for k in range(100):
            res = resolver.step(panda, stack, q, k * 0.01, 0.01)
            out.append((np.array(res.dq), dict(res.info), res.relaxed))
            q = panda.integrate(q, res.dq, 0.01)
        runs.append(out)
    for (dq0, _, _), (dq1, info, relaxed) in zip(*runs, strict=True):
        assert info["condition"] < SingularityGuard().release_at  # (the run stays away from singularities)
        assert info["singularity"] == OK and not relaxed
        np.testing.assert_array_equal(dq0, dq1)


def test_measure_and_info_columns(panda: rk.RobotModel) -> None:
    q = _panda_start(panda)
    _task, stack, resolver = _setup(panda, TOOL, "pose", q, "pinv", singularity={"slow_at": 50, "halt_at": 90})
    res = resolver.step(panda, stack, q, 0.0, 0.01)
    J = panda.frame_jacobian(TOOL)
    s = np.linalg.svd(J, compute_uv=False)
    assert res.info["condition"] == pytest.approx(s[0] / s[-1], rel=1e-9)
    assert res.info["manipulability"] == pytest.approx(math.sqrt(np.linalg.det(J @ J.T)), rel=1e-9)
    assert res.info["singularity"] == OK and res.info["singularity_state"] == 0
    plain = rk.make_resolver("pinv").step(panda, stack, q, 0.0, 0.01)
    assert "condition" not in plain.info  # nothing measured on the hot path without a guard
    m = measure(plain, panda)
    assert m["condition"] == pytest.approx(s[0] / s[-1], rel=1e-9)
    assert m["sigma_min"] == pytest.approx(s[-1], rel=1e-9)


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ({"slow_at": 10, "halt_at": 5}, "release_at < slow_at ≤ halt_at"),
        ({"slow_at": 10, "release_at": 20}, "release_at < slow_at"),
        ({"slow_down": 10}, "unknown key"),
        ({"slow_at": "x"}, "must be a number"),
        ({"max_loss": 0.0}, "max_loss"),
        (3.0, "must be a SingularityGuard"),
    ],
)
def test_bad_guard_options_are_named(value: object, words: str) -> None:
    with pytest.raises(ResolverError, match=words):
        rk.make_resolver("pinv", singularity=value)


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan, True, "fast", np.ones(9), [1.0]])
def test_bad_max_joint_speed_is_named(value: object) -> None:
    with pytest.raises(ResolverError, match="max_joint_speed"):
        rk.make_resolver("feedback", max_joint_speed=value)


def test_options_survive_copy_and_reset(panda: rk.RobotModel) -> None:
    resolver = rk.make_resolver("wqp", singularity=True, max_joint_speed=1.5)
    clone = copy.deepcopy(resolver)
    assert clone.singularity == SingularityGuard() and clone.max_joint_speed == 1.5
    resolver.singularity = None
    assert resolver.singularity is None and clone.singularity is not None


def _yaml_run(planar_task_data: dict[str, Any], write_yaml: Any, options: dict[str, Any]) -> Any:
    from redundik.config import load_task
    from redundik.config.runner import run_task

    data = planar_task_data
    data["runs"] = {
        "plain": {"resolver": "pinv", "options": {"max_joint_speed": None}},
        "guarded": {"resolver": "pinv", "options": options},
    }
    return run_task(load_task(write_yaml(data)))


def test_yaml_options_and_csv_columns(planar_task_data: dict[str, Any], write_yaml: Any) -> None:
    """The task file's ``options`` carry both settings; the measures are columns of the run's per-step record
    (``log.extras``, which the CSV writes), and on the chapter's line, away from singularities, the guarded run is
    the plain one."""
    options = {"max_joint_speed": 5.0, "singularity": {"slow_at": 40, "halt_at": 120, "release_at": 30}}
    results = _yaml_run(planar_task_data, write_yaml, options)
    log, plain = results["guarded"].log, results["plain"].log
    for column in ("condition", "manipulability", "singularity_state", "singularity_scale"):
        assert column in log.extras and np.isfinite(log.extras[column]).all(), column
    assert np.all(log.extras["singularity_state"] == 0)
    np.testing.assert_array_equal(log.dq, plain.dq)
    # the manipulability column is the chapter's 3R arm's √det(J Jᵀ) along the run
    w = [math.sqrt(np.linalg.det(_planar_jacobian(q) @ _planar_jacobian(q).T)) for q in log.q[:-1]]
    np.testing.assert_allclose(log.extras["manipulability"], w, rtol=1e-9)


def test_yaml_bad_guard_key_is_named(planar_task_data: dict[str, Any], write_yaml: Any) -> None:
    with pytest.raises(rk.RedundikError, match=r"singularity.*unknown key.*slow"):
        _yaml_run(planar_task_data, write_yaml, {"singularity": {"slow": 40}})


@pytest.mark.parametrize("name", ["pinv", "wqp"])
def test_batch_caps_as_the_loop(panda: rk.RobotModel, name: str) -> None:
    """The batch applies each problem's cap as its step would (and says where); a guard is refused there."""
    from redundik.resolvers import BatchResolver

    rng = np.random.default_rng(7)
    Q = np.array([panda.random_configuration(rng) for _ in range(12)])
    T = np.empty((12, 4, 4))
    for i in range(12):
        panda.update(panda.random_configuration(rng))
        T[i] = panda.frame_pose(TOOL).homogeneous
    batch = BatchResolver(
        rk.make_resolver(name, limits=False) if name == "wqp" else rk.make_resolver(name), panda, TOOL, gain=50.0
    )
    got, ref = batch.solve(Q, T, 0.01), batch.solve_loop(Q, T, 0.01)
    np.testing.assert_allclose(got.dq, ref.dq, atol=1e-9, rtol=0)
    assert got.capped.any() and np.array_equal(got.capped, ref.capped)
    assert np.all(np.abs(got.dq) <= panda.velocity_limits * (1 + 1e-12))
    guarded = BatchResolver(rk.make_resolver(name, singularity=True), panda, TOOL)
    with pytest.raises(ResolverError, match="singularity guard"):
        guarded.solve(Q, T, 0.01)


def test_run_summary_counts_capped_and_halted_steps(planar_task_data: dict[str, Any], write_yaml: Any) -> None:
    from redundik.config import load_task
    from redundik.config.runner import run_task, summarise

    data = planar_task_data
    data["runs"] = {"capped": {"resolver": "pinv", "gains": {"tip": 20}, "options": {"max_joint_speed": 0.05}}}
    plan = load_task(write_yaml(data))
    result = run_task(plan)["capped"]
    summary = summarise(plan, result)
    speeds = np.abs(result.log.dq[:-1]).max(axis=1)
    assert summary["capped_steps"] == int(np.sum(speeds >= 0.05 * (1 - 1e-12))) > 0
    assert np.all(speeds <= 0.05 * (1 + 1e-12))


class _OpaqueFrameTask(rk.FrameTask):
    """A frame task of the user's own (its ``evaluate`` overridden): the guard knows no ∂J/∂q for it."""

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        return super().evaluate(robot, t)


def test_a_main_task_without_derivatives_slows_and_stops(panda: rk.RobotModel) -> None:
    """Without ∇w the guard cannot tell approach from retreat: it leaves an ok step alone, slows every
    decelerating one by the smoothstep, and a halted step stands still."""
    robot, _, _, q0, targets = _cases(panda)["planar3r"]
    guard = SingularityGuard()
    task = _OpaqueFrameTask("3", axes="planar", gain=10.0)
    stack = rk.TaskStack([task])
    resolver = rk.make_resolver("pinv", singularity=guard, max_joint_speed=None)
    robot.update(q0)
    stack.reset(robot)
    q, seen = q0.copy(), set()
    for k, p in enumerate(targets[:200]):
        task.set_target(p)
        twin = copy.deepcopy(resolver)
        twin.singularity = None
        raw = np.array(twin.step(robot, stack, q, k * 0.01, 0.01).dq)
        res = resolver.step(robot, stack, q, k * 0.01, 0.01)
        state, kappa = res.info["singularity"], res.info["condition"]
        seen.add(state)
        assert jacobian_derivatives(res, robot, stack) is None
        if state == OK:
            np.testing.assert_array_equal(res.dq, raw)
        elif state == DECELERATE:
            np.testing.assert_allclose(res.dq, raw * guard.slowdown(kappa), rtol=1e-12, atol=1e-15)
        else:
            assert not np.any(res.dq) and "singularity" in res.relaxed
        q = robot.integrate(q, res.dq, 0.01)
    assert HALT in seen
