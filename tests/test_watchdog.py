"""The command watchdog (issue 33 item 4): stale targets stop the robot within its acceleration (and jerk) limits,
a new target resumes smoothly, under every resolver."""

from __future__ import annotations

import numpy as np
import pytest

import redundik as rk
from redundik.errors import ResolverError
from redundik.resolvers.watchdog import ARMED, RESUMING, STOPPED, STOPPING, Watchdog, jerk_step

DT = 0.01  # [s]
TIMEOUT = 0.1  # [s]
ACC = 2.0  # [rad/s²]
LAST_TARGET = 0.5  # [s]: the stream of targets stops here
RESUME = 1.6  # [s]: a new target then


def _arm() -> rk.RobotModel:
    return rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])


def _resolver(name: str, **dog: object) -> rk.Resolver:
    if name in ("wqp", "hqp"):  # the deceleration limit is the resolver's rate limit
        return rk.make_resolver(name, limits={"acceleration": ACC}, command_timeout=TIMEOUT, **dog)
    return rk.make_resolver(name, command_timeout=TIMEOUT, stop_acceleration=ACC, **dog)


def _run(resolver: rk.Resolver, steps: int = 260) -> tuple[np.ndarray, list[dict[str, object]], np.ndarray]:
    """A teleoperated tool: a moving target every tick until LAST_TARGET, none until RESUME, then a new one.
    Returns (t, info per step, q̇ per step)."""
    robot = _arm()
    task = rk.FrameTask("7", axes="position", gain=5.0)
    stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)])
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    stack.reset(robot)
    home = robot.frame_pose("7").translation.copy()
    ts, infos, dqs = [], [], []
    for k in range(steps):
        t = k * DT
        if t <= LAST_TARGET + 1e-12:
            task.set_target(home + np.array([0.0, 0.3 * t, 0.0]))
        elif t >= RESUME - 1e-9:  # a new target, streamed again from then on (the same one every tick)
            task.set_target(home + np.array([0.05, 0.0, 0.0]))
        res = resolver.step(robot, stack, q, t, DT)
        ts.append(t)
        infos.append({key: res.info[key] for key in ("watchdog", "command_age", "command_stale")})
        dqs.append(res.dq.copy())
        q = robot.integrate(q, res.dq, DT)
    return np.array(ts), infos, np.array(dqs)


@pytest.mark.parametrize("name", ["pinv", "feedback", "wqp", "hqp"])
def test_stale_targets_stop_within_the_acceleration_limit_and_a_new_target_resumes(name: str) -> None:
    ts, infos, dqs = _run(_resolver(name))
    states = [i["watchdog"] for i in infos]
    first_stop = states.index(STOPPING)
    # the timeout triggers at the first step more than TIMEOUT after the last target, not before
    assert ts[first_stop] - LAST_TARGET > TIMEOUT - 1e-9
    assert ts[first_stop - 1] - LAST_TARGET <= TIMEOUT + 1e-9
    assert all(s == ARMED for s in states[:first_stop])
    assert np.abs(dqs[first_stop - 1]).max() > 0.05, "the robot was moving when the commands stopped"
    # rest reached, exactly, and reported as stale until the new target
    stopped = states.index(STOPPED)
    resume = round(RESUME / DT)
    assert stopped < resume
    assert all(s == STOPPING for s in states[first_stop:stopped])
    assert all(s == STOPPED for s in states[stopped:resume])
    assert not np.any(dqs[stopped:resume])
    assert all(i["command_stale"] for i in infos[first_stop:resume])
    assert not any(i["command_stale"] for i in infos[:first_stop])
    # deceleration and re-acceleration within the limit (to 1e-9) on every joint, also across the hand-overs
    ddq = np.abs(np.diff(dqs[first_stop - 1 :], axis=0)) / DT
    window = ddq[: resume - first_stop + 8]  # the stop, the rest, the resume and its first armed steps
    if name in ("wqp", "hqp"):
        window = ddq  # their own rate limit holds from there on too
    assert window.max() <= ACC + 1e-9
    # the new target resumes control: resuming, then armed, and the tool converges on it
    assert states[resume] in (RESUMING, ARMED)
    assert states[-1] == ARMED and infos[-1]["command_age"] == 0.0
    assert np.abs(dqs[-1]).max() < np.abs(dqs[resume + 20]).max() or np.abs(dqs[-1]).max() < 1e-3


def test_the_uniform_stop_keeps_the_direction_and_takes_the_predicted_number_of_steps() -> None:
    _ts, infos, dqs = _run(_resolver("pinv"))
    states = [i["watchdog"] for i in infos]
    first, stopped = states.index(STOPPING), states.index(STOPPED)
    v0 = dqs[first - 1]
    for v in dqs[first:stopped]:
        cos = v @ v0 / (np.linalg.norm(v) * np.linalg.norm(v0))
        assert cos == pytest.approx(1.0, abs=1e-12)  # the joint path keeps its direction
    # the first zero q̇ comes ⌈max|q̇_i| / (a_max dt)⌉ steps after the last one the resolver sent
    assert stopped - first + 1 == int(np.ceil(np.abs(v0).max() / (ACC * DT) - 1e-9))


def test_jerk_limited_stop_and_resume() -> None:
    jerk = 40.0  # [rad/s³]
    _ts, infos, dqs = _run(_resolver("pinv", stop_jerk=jerk), steps=300)
    states = [i["watchdog"] for i in infos]
    first, stopped = states.index(STOPPING), states.index(STOPPED)
    resume = round(RESUME / DT)
    ddq = np.diff(dqs, axis=0) / DT
    dddq = np.diff(ddq, axis=0) / DT
    # q̈[k] = (q̇[k] − q̇[k−1])/dt; jerk[k] = (q̈[k+1] − q̈[k])/dt: every jerk of a step the watchdog wrote
    assert np.abs(ddq[first : resume + 1]).max() <= ACC + 1e-9
    assert np.abs(dddq[first : stopped + 1]).max() <= jerk + 1e-9
    assert not np.any(dqs[stopped:resume])
    assert np.abs(dddq[stopped : resume - 2]).max() == 0.0  # (dddq[k] reads q̇[k..k+2])
    assert np.abs(dddq[resume - 2 : resume + 10]).max() <= jerk + 1e-9  # the resume is jerk-limited too
    assert states[-1] == ARMED


def test_jerk_step_lands_on_rest_from_random_states() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        n = 5
        amax, jmax, dt = rng.uniform(1, 10, n), rng.uniform(10, 200, n), 10 ** rng.uniform(-3, -1.5)
        v, a = rng.uniform(-2, 2, n), rng.uniform(-1, 1, n) * amax
        zero = np.zeros(n)
        for _k in range(100000):
            v2, a2 = jerk_step(v, a, zero, amax, jmax, dt)
            assert np.all(np.abs(a2) <= amax * (1 + 1e-12))
            assert np.all(np.abs(a2 - a) <= jmax * dt * (1 + 1e-9))
            v, a = v2, a2
            if np.all(np.abs(v) <= 1e-12) and np.all(np.abs(a) <= jmax * dt):
                break
        else:
            raise AssertionError("never came to rest")


def test_jerk_step_without_a_jerk_limit_on_some_joints() -> None:
    amax, jmax, dt = np.full(3, 2.0), np.array([50.0, np.inf, 50.0]), 0.01
    v, a, zero = np.array([0.5, -0.5, 0.2]), np.zeros(3), np.zeros(3)
    for _ in range(1000):
        v2, a2 = jerk_step(v, a, zero, amax, jmax, dt)
        assert np.all(np.isfinite(v2)) and np.all(np.abs(a2) <= amax * (1 + 1e-12))
        assert np.all(np.abs(a2 - a)[[0, 2]] <= jmax[[0, 2]] * dt * (1 + 1e-9))
        v, a = v2, a2
    assert np.all(np.abs(v) <= 1e-12)


def test_the_resolvers_jerk_limit_is_the_stops() -> None:
    """A jerk limit on the resolver's limits (``limits.jerk``) shapes the stop when the watchdog has none."""
    jerk = 40.0
    resolver = _resolver("wqp")
    resolver.limits.jerk = jerk  # type: ignore[attr-defined]
    _ts, infos, dqs = _run(resolver, steps=160)
    states = [i["watchdog"] for i in infos]
    first, stopped = states.index(STOPPING), states.index(STOPPED)
    assert stopped - first > 2
    dddq = np.diff(dqs, n=2, axis=0) / DT**2
    assert np.abs(dddq[first - 2 : stopped]).max() <= jerk + 1e-9  # (dddq[k] reads q̇[k..k+2]: from the hand-over)


def test_feed_keeps_the_watchdog_armed() -> None:
    robot = _arm()
    stack = rk.TaskStack([rk.FrameTask("7", rk.Circle(0.05, np.pi), gain=1.0)])  # moves with t: no target set
    resolver = _resolver("pinv")
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    stack.reset(robot)
    assert isinstance(resolver.watchdog, Watchdog)
    for k in range(40):
        resolver.watchdog.feed()
        res = resolver.step(robot, stack, q, k * DT, DT)
        assert res.info["watchdog"] == ARMED
        q = robot.integrate(q, res.dq, DT)
    res = resolver.step(robot, stack, q, 40 * DT + TIMEOUT + DT, DT)  # no feed for longer than the timeout
    assert res.info["watchdog"] == STOPPING and res.info["command_stale"] is True


def test_a_watchdog_without_a_deceleration_limit_is_refused_at_the_first_step() -> None:
    robot = _arm()
    stack = rk.TaskStack([rk.FrameTask("7", axes="position", gain=5.0)])
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    stack.reset(robot)
    for name in ("pinv", "wqp"):  # (wqp's limits without an acceleration give none)
        resolver = rk.make_resolver(name, command_timeout=0.05)
        with pytest.raises(ResolverError, match="no deceleration limit"):
            resolver.step(robot, stack, q, 0.0, DT)  # at the start, not when the stop is due


def test_a_resolver_with_a_watchdog_copies_and_pickles() -> None:
    import copy
    import pickle

    robot = _arm()
    task = rk.FrameTask("7", axes="position", gain=5.0)
    stack = rk.TaskStack([task])
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    stack.reset(robot)
    resolver = _resolver("wqp")
    resolver.step(robot, stack, q, 0.0, DT)
    for twin in (copy.deepcopy(resolver), pickle.loads(pickle.dumps(resolver))):
        assert twin.command_timeout == TIMEOUT
        assert twin.step(robot, stack, q, DT, DT).info["watchdog"] == ARMED
        assert twin.step(robot, stack, q, 0.5, DT).info["command_stale"] is True


def test_a_streamed_posture_target_counts_as_a_command_and_no_watchdog_adds_nothing() -> None:
    robot = _arm()
    posture = rk.PostureTask(gain=2.0)
    stack = rk.TaskStack([rk.FrameTask("7", axes="position", gain=5.0), posture])
    q = np.full(robot.nq, 0.3)
    robot.update(q)
    stack.reset(robot)
    watched, plain = _resolver("hqp"), rk.make_resolver("hqp", limits={"acceleration": ACC})
    for k in range(30):  # 0.3 s of posture targets, 3 timeouts long (the same one again: a command too)
        posture.set_target(np.full(robot.nq, 0.35))
        res = watched.step(robot, stack, q, k * DT, DT)
        assert res.info["watchdog"] == ARMED and res.info["command_age"] == 0.0
        q = robot.integrate(q, res.dq, DT)
    assert "watchdog" not in plain.step(robot, stack, q, 0.0, DT).info


def test_options_are_checked() -> None:
    with pytest.raises(ResolverError, match="command_timeout"):
        rk.make_resolver("pinv", command_timeout=-1.0)
    with pytest.raises(ResolverError, match="command_timeout too"):
        rk.make_resolver("pinv", stop_acceleration=1.0)
    with pytest.raises(ResolverError, match="acceleration"):
        Watchdog(0.1, acceleration=0.0)
    with pytest.raises(ResolverError, match="jerk"):
        Watchdog(0.1, jerk=float("inf"))
    resolver = rk.make_resolver("wqp")
    assert resolver.command_timeout is None
    resolver.command_timeout = 0.2
    assert resolver.command_timeout == 0.2 and isinstance(resolver.watchdog, Watchdog)
    resolver.command_timeout = None
    assert resolver.watchdog is None


@pytest.mark.parametrize("integrator", ["rk4", "rk45"])
def test_a_simulated_run_with_stage_evaluations_stops_at_the_sample_rate(integrator: str) -> None:
    """rk4/rk45 call the resolver at intermediate stages; the watchdog's state is saved and put back around them like
    the resolver's own, so the stop advances once per sample (q̈ between samples within the limit)."""
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.0, -0.5]), axes="planar", gain=1.0)])  # no target is ever set
    resolver = rk.make_resolver("pinv", command_timeout=0.1, stop_acceleration=ACC)
    log = rk.simulate(robot, stack, resolver, np.radians([110.0, -40.0, -30.0]), dt=DT, steps=80, integrator=integrator)
    dq = log.dq[:-1]
    assert np.abs(dq[5]).max() > 0.1 and not np.any(dq[-10:])  # moving at first, at rest at the end
    assert np.abs(np.diff(dq[5:], axis=0)).max() / DT <= ACC + 1e-9
