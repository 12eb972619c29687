"""``rk.ControlLoop`` (issue 33 item 7): deadline accounting on a simulated clock, the garbage collector kept out of the
ticks and restored afterwards, the iterator and the callback interfaces, the watchdog. No assertion on wall time."""

from __future__ import annotations

import gc
import logging

import numpy as np
import pytest

import redundik as rk
from redundik.control.loop import deadline_stats
from redundik.errors import ResolverError

PERIOD = 5e-4  # [s]


class FakeClock:
    """A clock that only moves when slept on or when a fake step takes time."""

    def __init__(self) -> None:
        self.now = 100.0
        self.slept = 0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds > 0.0
        self.slept += 1
        self.now += seconds


class Timed:
    """A resolver whose steps take the scripted time on the fake clock."""

    def __init__(self, inner: rk.Resolver, clock: FakeClock, durations: list[float]) -> None:
        self.inner, self.clock, self.durations = inner, clock, iter(durations)
        self.name = "timed"

    def step(self, robot: rk.RobotModel, stack: rk.TaskStack, q: np.ndarray, t: float, dt: float) -> rk.StepResult:
        res = self.inner.step(robot, stack, q, t, dt)
        self.clock.now += next(self.durations)
        return res


class Plant:
    """A perfect velocity-controlled robot: q ← q ⊕ q̇·period."""

    def __init__(self, robot: rk.RobotModel, q0: np.ndarray) -> None:
        self.robot, self.q, self.sent = robot, q0.copy(), 0

    def read(self) -> np.ndarray:
        return self.q.copy()

    def write(self, dq: np.ndarray) -> None:
        self.sent += 1
        self.q = self.robot.integrate(self.q, dq, PERIOD)


def _setup(resolver: str = "pinv", **loop_options: object) -> tuple[rk.ControlLoop, rk.FrameTask, Plant, FakeClock]:
    robot = rk.from_dh([rk.DHRow(str(k), a=0.3, alpha=np.pi / 2 if k % 2 else -np.pi / 2) for k in range(1, 8)])
    task = rk.FrameTask("7", axes="position", gain=20.0)
    stack = rk.TaskStack([task, rk.PostureTask(gain=1.0)])
    plant = Plant(robot, np.full(robot.nq, 0.3))
    clock = FakeClock()
    options: dict[str, object] = {"warm": False, "spin": 0.0, "gc_slack": None, "clock": clock, "sleep": clock.sleep}
    options.update(loop_options)
    loop = rk.ControlLoop(
        robot, stack, rk.make_resolver(resolver), period=PERIOD, read=plant.read, write=plant.write, **options
    )
    return loop, task, plant, clock


def _target(t: float) -> np.ndarray:
    return np.array([0.4 + 0.05 * np.sin(20 * t), 0.1 * t, 0.3])


def test_deadline_stats_on_a_simulated_clock() -> None:
    loop, _task, plant, clock = _setup()
    # 1000 ticks of 100 µs, but every 100th takes 900 µs: longer than the 500 µs period
    durations = [9e-4 if (k + 1) % 100 == 0 else 1e-4 for k in range(1000)]
    loop.resolver = Timed(loop.resolver, clock, durations)  # type: ignore[assignment]
    t0 = clock.now
    slots = []
    stats = loop.run(1000, on_tick=lambda tick: slots.append(tick.index))
    assert stats.ticks == 1000 and plant.sent == 1000
    # by hand: sorted times are 990 × 100 µs then 10 × 900 µs; linear interpolation at rank p·(n − 1)
    assert stats.p50 == pytest.approx(1e-4, abs=1e-12)
    assert stats.p99 == pytest.approx(1e-4 + 0.01 * 8e-4, abs=1e-12)  # rank 989.01: 1 % of the way to 900 µs
    assert stats.p999 == pytest.approx(9e-4, abs=1e-12)  # rank 998.001: between two 900 µs entries
    assert stats.max == pytest.approx(9e-4, abs=1e-12)
    assert stats.mean == pytest.approx((990 * 1e-4 + 10 * 9e-4) / 1000, abs=1e-12)
    assert stats.max_tick == pytest.approx(9e-4, abs=1e-12)
    # each long tick ends 400 µs into the next slot: an overrun, and that slot is skipped (no catching up)
    assert stats.overruns == 10 and stats.skipped == 10
    assert slots[:100] == list(range(100)) and slots[100] == 101
    # the last (1000th, long) tick had 9 skipped slots before it: slot 1008, and it ends 900 µs into it
    assert clock.now - t0 == pytest.approx(1008 * PERIOD + 9e-4, abs=1e-9)
    assert stats.gc_collections == 0


def test_deadline_stats_of_known_samples() -> None:
    times = np.arange(1, 11, dtype=float) * 1e-4  # 100 … 1000 µs
    stats = deadline_stats(1e-3, times, times + 5e-5, overruns=2, skipped=3)
    assert stats.p50 == pytest.approx(5.5e-4)  # rank 4.5: halfway between 500 and 600 µs
    assert stats.p99 == pytest.approx(9.91e-4)  # rank 8.91
    assert stats.p999 == pytest.approx(9.991e-4)  # rank 8.991
    assert stats.max == pytest.approx(1e-3) and stats.max_tick == pytest.approx(1.05e-3)
    assert (stats.overruns, stats.skipped, stats.ticks) == (2, 3, 10)
    assert deadline_stats(1e-3, np.zeros(0), np.zeros(0)).ticks == 0
    assert "10 ticks at 1000 Hz" in str(stats)


def test_iterator_and_callback_give_the_same_q() -> None:
    loop_a, task_a, plant_a, _ = _setup("wqp")
    for tick in loop_a.ticks(200):
        task_a.set_target(_target(tick.t))
    loop_b, task_b, plant_b, _ = _setup("wqp")
    loop_b.run(200, on_tick=lambda tick: task_b.set_target(_target(tick.t)))
    assert plant_a.sent == plant_b.sent == 200
    assert np.array_equal(plant_a.q, plant_b.q)
    assert np.linalg.norm(plant_a.q - np.full(7, 0.3)) > 1e-2  # it moved


def test_garbage_collection_is_off_in_the_ticks_and_restored_after_an_exception() -> None:
    assert gc.isenabled()
    loop, *_ = _setup()

    def boom(tick: rk.Tick) -> None:
        assert not gc.isenabled() and gc.get_freeze_count() > 0
        if tick.index == 5:
            raise RuntimeError("from the callback")

    with pytest.raises(RuntimeError, match="from the callback"):
        loop.run(50, on_tick=boom)
    assert gc.isenabled() and gc.get_freeze_count() == 0
    with pytest.raises(RuntimeError, match="from the body"):
        for tick in loop.ticks(50):
            if tick.index == 3:
                raise RuntimeError("from the body")
    assert gc.isenabled() and gc.get_freeze_count() == 0
    for tick in loop.ticks(50):  # leaving with break
        if tick.index == 2:
            break
    assert gc.isenabled() and gc.get_freeze_count() == 0
    gc.disable()
    try:  # a collector the caller had disabled stays disabled
        loop.run(3)
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_young_generations_are_collected_between_ticks_when_there_is_slack() -> None:
    loop, task, _, _ = _setup(gc_slack=1e-4)
    keep = []

    def allocate(tick: rk.Tick) -> None:
        task.set_target(_target(tick.t))
        keep.append([[] for _ in range(2000)])  # tracked containers: over generation 0's threshold every tick

    stats = loop.run(20, on_tick=allocate)
    assert stats.gc_collections >= 19


def test_warm_up_runs_before_the_first_read() -> None:
    events: list[str] = []
    loop, _, plant, _ = _setup(warm=lambda: events.append("warm"))
    read = plant.read

    def logged_read() -> np.ndarray:
        events.append("read")
        return read()

    loop.read = logged_read
    loop.run(3)
    assert events == ["warm", "read", "read", "read"]


def test_the_watchdog_stops_the_robot_when_the_caller_stops_setting_targets() -> None:
    loop, task, plant, _ = _setup("wqp", command_timeout=0.01)
    loop.resolver.limits.acceleration = 50.0  # type: ignore[attr-defined]
    states, qs = [], []

    def stream(tick: rk.Tick) -> None:
        states.append(tick.result.info["watchdog"])
        qs.append(plant.q.copy())
        if tick.t < 0.05:
            task.set_target(_target(tick.t))

    loop.run(duration=0.15, on_tick=stream)
    assert states[0] == "armed" and "stopping" in states and states[-1] == "stopped"
    stopped = states.index("stopped")
    assert stopped < len(states) - 20
    assert np.array_equal(qs[stopped], qs[-1])  # at rest from the first stopped tick on


def test_stop_and_duration() -> None:
    loop, *_ = _setup()
    stats = loop.run(duration=10 * PERIOD)
    assert stats.ticks == 10
    stats = loop.run(on_tick=lambda tick: tick.index < 6)  # False after tick 6 ends the run
    assert stats.ticks == 7
    count = 0
    for _tick in loop.ticks():
        count += 1
        if count == 4:
            loop.stop()
    assert count == 4


def test_bad_options_are_refused() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0)])
    stack = rk.TaskStack([rk.FrameTask("2", axes="planar")])
    resolver = rk.make_resolver("pinv")
    ok = {"read": lambda: np.zeros(2), "write": lambda dq: None}
    with pytest.raises(ResolverError, match="period"):
        rk.ControlLoop(robot, stack, resolver, period=0.0, **ok)  # type: ignore[arg-type]
    with pytest.raises(ResolverError, match="read must be callable"):
        rk.ControlLoop(robot, stack, resolver, period=1e-3, read=None, write=ok["write"])  # type: ignore[arg-type]
    loop = rk.ControlLoop(robot, stack, resolver, period=1e-3, warm=False, **ok)  # type: ignore[arg-type]
    with pytest.raises(ResolverError, match="ticks"):
        loop.run(-1)
    with pytest.raises(ResolverError, match="not both"):
        loop.run(3, duration=1.0)


class Recording(Plant):
    """A plant that records every command and can fail to read or to write at a given call."""

    def __init__(self, robot: rk.RobotModel, q0: np.ndarray, bad_read: int = -1, bad_write: int = -1) -> None:
        super().__init__(robot, q0)
        self.commands: list[np.ndarray] = []
        self.reads, self.bad_read, self.bad_write = 0, bad_read, bad_write

    def read(self) -> np.ndarray:
        self.reads += 1
        if self.reads == self.bad_read:
            return np.full_like(self.q, np.nan)  # (a sensor glitch)
        return super().read()

    def write(self, dq: np.ndarray) -> None:
        if len(self.commands) == self.bad_write:
            self.commands.append(dq.copy())
            raise OSError("bus error")
        self.commands.append(dq.copy())
        super().write(dq)


def _recording(**plant_options: int) -> tuple[rk.ControlLoop, Recording, FakeClock]:
    loop, task, plant, clock = _setup()
    task.set_target(_target(0.0))  # (away from the start: every tick commands some q̇)
    rec = Recording(plant.robot, plant.q, **plant_options)
    loop.read, loop.write = rec.read, rec.write
    return loop, rec, clock


def test_an_exception_leaving_the_loop_commands_zero_velocity(caplog: pytest.LogCaptureFixture) -> None:
    """A bad read (NaN: the step refuses it), the caller's callback or body raising, Ctrl-C while the loop sleeps: the
    last command sent is q̇ = 0 (the robot is not left on its last q̇), and the exception says so."""
    loop, rec, _ = _recording(bad_read=4)
    with caplog.at_level(logging.WARNING, logger="redundik"), pytest.raises(ResolverError, match="NaN") as err:
        loop.run(20)
    assert len(rec.commands) == 4 and np.abs(rec.commands[2]).max() > 0  # (three ticks moved the robot)
    np.testing.assert_array_equal(rec.commands[-1], np.zeros(rec.robot.nv))
    assert "q̇ = 0 was commanded after this error (ResolverError" in caplog.text
    assert "q̇ = 0 was commanded" in "".join(getattr(err.value, "__notes__", ["q̇ = 0 was commanded"]))  # (3.11+)

    loop, rec, _ = _recording()

    def callback(tick: rk.Tick) -> None:
        if tick.index == 5:
            raise RuntimeError("from the callback")

    with pytest.raises(RuntimeError, match="from the callback"):
        loop.run(20, on_tick=callback)
    assert len(rec.commands) == 7 and not rec.commands[-1].any() and rec.commands[-2].any()

    loop, rec, clock = _recording()

    def interrupted_sleep(seconds: float) -> None:
        if clock.slept == 6:
            raise KeyboardInterrupt
        clock.sleep(seconds)

    loop.sleep = interrupted_sleep
    with pytest.raises(KeyboardInterrupt):
        loop.run(20)
    assert not rec.commands[-1].any() and rec.commands[-2].any()


def test_a_run_that_ends_or_breaks_leaves_the_last_command_as_it_was() -> None:
    loop, rec, _ = _recording()
    loop.run(6)
    assert len(rec.commands) == 6 and rec.commands[-1].any()
    for tick in loop.ticks(20):
        if tick.index == 3:
            break
    assert len(rec.commands) == 10 and rec.commands[-1].any()


def test_a_failed_write_is_followed_by_a_stop_attempt_and_said_when_that_fails_too(
    caplog: pytest.LogCaptureFixture,
) -> None:
    loop, rec, _ = _recording(bad_write=3)
    with pytest.raises(OSError, match="bus error"):
        loop.run(20)
    assert len(rec.commands) == 5 and not rec.commands[-1].any()  # (the failed one, then q̇ = 0 went through)
    rec.bad_write = len(rec.commands)  # every write fails from now on
    rec.write = lambda dq: (_ for _ in ()).throw(OSError("bus down"))  # type: ignore[method-assign]
    loop.write = rec.write
    with caplog.at_level(logging.WARNING, logger="redundik"), pytest.raises(OSError, match="bus down"):
        loop.run(5)
    assert "the stop command q̇ = 0 after this error failed too: OSError('bus down')" in caplog.text
