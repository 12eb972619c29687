"""``ControlLoop``: redundik at a fixed rate, with deadline accounting and the garbage collector kept out of the ticks.

Each tick k has a slot on a fixed grid, start + k·period. The loop waits for the slot, then reads q (``read()``),
resolves one step (``resolver.step(robot, stack, q, k·period, period)``), sends q̇ (``write(dq)``) and hands the tick
to the caller — as the next item of :meth:`ControlLoop.ticks` (an iterator) or as the argument of the ``on_tick``
callback of :meth:`ControlLoop.run`. The caller sets the next targets there; both interfaces run the same code, so
they give the same q for the same targets.

* **Warm-up**: before the first tick, :func:`redundik.warmup.warm_up` compiles (or loads) the resolver's kernels, so
  the first ticks do not pay a numba compilation of tens of seconds. The first tick still checks and plans the stack
  (a few ms for ``hqp``): it is counted like any other.
* **Deadlines**: the step time is the duration of ``resolver.step`` alone; :class:`DeadlineStats` gives its p50, p99,
  p99.9 and max (NumPy's linear-interpolation percentiles), and counts *overruns*: ticks whose work (read, step, write
  and the caller's own code) ended after the next slot. After an overrun the loop does not try to catch up: it waits
  for the next free slot, and counts the slots it skipped (``t`` jumps by as many periods: the resolver's ``dt``
  stays the period).
* **Garbage collector**: at the start the loop collects everything, moves what survives to the permanent generation
  (``gc.freeze()``: the collector never scans it again) and disables automatic collections, so none can start
  inside a tick (a full collection of a big heap takes milliseconds). Between ticks, when at least ``gc_slack``
  seconds remain before the next slot and a generation is over its threshold (``gc.get_threshold()``), it collects
  the young generations (0, or 0 and 1): their cost is bounded by what was allocated since, tens of µs. The oldest
  generation is never collected during the run. At the end — also when an exception leaves the loop — the frozen
  objects are returned to the collector and automatic collection is enabled again if it was before.
* **Pacing**: the loop sleeps until ``spin`` seconds before a slot and busy-waits the rest (``time.sleep`` wakes up
  late by 50-100 µs on a general-purpose kernel); ``clock`` and ``sleep`` can be replaced (a simulated clock).
* **Stop on error**: an exception that leaves the loop — a read that fails or gives no configuration (a NaN: the
  step refuses it), a refused step, a failed write, the caller's ``on_tick``, ``KeyboardInterrupt`` — is preceded by
  one last command q̇ = 0 (``write(zeros)``), so that the robot is not left running its last q̇; a note on the
  exception says so (or that this command failed too). A run that ends, is stopped or broken out of leaves the last
  command as it was.
* **Watchdog**: ``command_timeout`` sets the resolver's (:mod:`redundik.resolvers.watchdog`): when the caller stops
  setting targets, the robot is brought to rest; each tick's ``result.info`` says so.

``tick.result`` and its arrays are valid until the next tick (a resolver reuses its buffers): copy what you keep.
"""

from __future__ import annotations

import array
import gc
import logging
import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from redundik.errors import ResolverError, short_repr

if TYPE_CHECKING:
    from redundik.kinematics.model import RobotModel
    from redundik.resolvers.base import Resolver, StepResult
    from redundik.tasks.stack import TaskStack

_LOG = logging.getLogger("redundik")


@dataclass(frozen=True)
class Tick:
    """One tick of a :class:`ControlLoop`.

    Attributes:
        index: The tick's slot k on the grid (its deadline is start + k·period; skipped slots are not ticks).
        t: The time given to the resolver, k·period [s].
        q: The configuration ``read()`` returned.
        result: The resolver's step (its q̇ was sent with ``write``); valid until the next tick.
        step_time: Duration of ``resolver.step`` [s].
        late: How long after its slot the tick started [s].
    """

    index: int
    t: float
    q: np.ndarray
    result: StepResult
    step_time: float
    late: float


@dataclass(frozen=True)
class DeadlineStats:
    """Deadline accounting of a run (times in seconds).

    Attributes:
        period: The loop's period [s].
        ticks: Ticks run.
        p50: Median step time (``resolver.step``) [s].
        p99: 99th percentile of the step time [s].
        p999: 99.9th percentile of the step time [s].
        max: Longest step [s].
        mean: Mean step time [s].
        max_tick: Longest tick, from its slot to the end of the caller's code [s].
        overruns: Ticks that ended after the next slot.
        skipped: Slots skipped after overruns.
        gc_collections: Young-generation collections run between ticks.
    """

    period: float
    ticks: int
    p50: float
    p99: float
    p999: float
    max: float
    mean: float
    max_tick: float
    overruns: int
    skipped: int
    gc_collections: int

    def __str__(self) -> str:
        us = 1e6
        return (
            f"{self.ticks} ticks at {1 / self.period:g} Hz: step p50 {us * self.p50:.0f} µs, "
            f"p99 {us * self.p99:.0f} µs, p99.9 {us * self.p999:.0f} µs, max {us * self.max:.0f} µs; "
            f"{self.overruns} overruns, "
            f"{self.skipped} skipped slots, {self.gc_collections} collections between ticks"
        )


def deadline_stats(
    period: float,
    step_times: np.ndarray,
    tick_times: np.ndarray,
    overruns: int = 0,
    skipped: int = 0,
    gc_collections: int = 0,
) -> DeadlineStats:
    """The :class:`DeadlineStats` of a run's step times and tick times [s] (zeros when there was no tick)."""
    if step_times.size == 0:
        return DeadlineStats(period, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, overruns, skipped, gc_collections)
    p50, p99, p999 = np.percentile(step_times, [50.0, 99.0, 99.9])
    return DeadlineStats(
        period=period,
        ticks=int(step_times.size),
        p50=float(p50),
        p99=float(p99),
        p999=float(p999),
        max=float(step_times.max()),
        mean=float(step_times.mean()),
        max_tick=float(tick_times.max()) if tick_times.size else 0.0,
        overruns=overruns,
        skipped=skipped,
        gc_collections=gc_collections,
    )


def _positive(value: object, key: str, *, zero: bool = False) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ResolverError(f"control loop: {key} must be a number [s], got {short_repr(value)}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the float range (10**400): out of range, refused below
        x = math.inf
    if not (math.isfinite(x) and (x >= 0.0 if zero else x > 0.0)):
        raise ResolverError(
            f"control loop: {key} must be finite and {'≥' if zero else '>'} 0 [s], got {short_repr(value)}"
        )
    return x


def _check_parts(robot: object, stack: object, resolver: object) -> None:
    """Refuse at construction what would fail at the first tick (an ``AttributeError`` deep in a step): a robot that
    is not a :class:`~redundik.kinematics.RobotModel`, a stack that is not a :class:`~redundik.tasks.TaskStack` (a
    list of tasks), a resolver without a callable ``step``.

    Raises:
        ResolverError: naming the argument and what was expected.
    """
    from redundik.kinematics.model import RobotModel
    from redundik.tasks.stack import TaskStack

    if not isinstance(robot, RobotModel):
        raise ResolverError(
            f"control loop: robot must be a RobotModel (rk.load_example_robot, rk.from_urdf, ...), got "
            f"{type(robot).__name__} {short_repr(robot)}"
        )
    if not isinstance(stack, TaskStack):
        hint = " (wrap the tasks: rk.TaskStack([...]))" if isinstance(stack, (list, tuple)) else ""
        raise ResolverError(f"control loop: stack must be a TaskStack, got {type(stack).__name__}{hint}")
    if not callable(getattr(resolver, "step", None)):
        raise ResolverError(
            f"control loop: resolver must be a resolver (rk.make_resolver(...)), got {type(resolver).__name__} "
            f"{short_repr(resolver)}"
        )


class ControlLoop:
    """Runs ``resolver.step`` at a fixed rate on a robot read and commanded through two callables (module docstring).

    Args:
        robot: The model.
        stack: The task stack (the caller sets its targets between ticks).
        resolver: The resolver (one per loop).
        period: The control period [s].
        read: Returns the measured configuration q (nq,).
        write: Sends the commanded q̇ (nv,) (held for one period).
        warm: Warm the resolver's kernels before the first tick (``True``), or a callable that does it, or ``False``.
        reset: Reset the stack at the first tick's q (``stack.reset``: trajectories anchored there).
        command_timeout: The watchdog's timeout [s] (``resolver.command_timeout``); ``None`` leaves the resolver's.
        gc_slack: Collect the young generations between ticks only when this much time [s] is left before the next
            slot (``"auto"``: half the period); ``None`` never collects during the run.
        spin: Busy-wait this long [s] before each slot instead of sleeping (0: sleep only).
        clock: Monotonic time [s] (default ``time.perf_counter``).
        sleep: Sleeps a duration [s] (default ``time.sleep``).

    Raises:
        ResolverError: a period, slack or spin that is not a finite number > 0 (≥ 0), read/write not callable, a
            robot that is not a RobotModel, a stack that is not a TaskStack, a resolver without a ``step``.
    """

    def __init__(
        self,
        robot: RobotModel,
        stack: TaskStack,
        resolver: Resolver,
        *,
        period: float,
        read: Callable[[], np.ndarray],
        write: Callable[[np.ndarray], object],
        warm: bool | Callable[[], object] = True,
        reset: bool = True,
        command_timeout: float | None = None,
        gc_slack: float | str | None = "auto",
        spin: float = 2e-4,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], object] = time.sleep,
    ) -> None:
        _check_parts(robot, stack, resolver)
        self.period = _positive(period, "period")
        for key, fn in (("read", read), ("write", write), ("clock", clock), ("sleep", sleep)):
            if not callable(fn):
                raise ResolverError(f"control loop: {key} must be callable, got {short_repr(fn)}")
        self.robot, self.stack, self.resolver = robot, stack, resolver
        self.read, self.write, self.clock, self.sleep = read, write, clock, sleep
        self.warm, self.reset = warm, reset
        self.gc_slack: float | None = None
        if isinstance(gc_slack, str) and gc_slack == "auto":  # (an array's == is elementwise)
            self.gc_slack = 0.5 * self.period
        elif gc_slack is not None:
            self.gc_slack = _positive(gc_slack, "gc_slack", zero=True)
        self.spin = _positive(spin, "spin", zero=True)
        if command_timeout is not None:
            resolver.command_timeout = command_timeout
        self._stop = False
        self._halted: BaseException | None = None  # the exception the loop last commanded q̇ = 0 for
        self._clear()

    def _clear(self) -> None:
        self._steps = array.array("d")
        self._ticks = array.array("d")
        self._overruns = self._skipped = self._collections = 0

    @property
    def stats(self) -> DeadlineStats:
        """The deadline accounting of the last (or current) run."""
        steps = np.frombuffer(self._steps, dtype=float) if len(self._steps) else np.zeros(0)
        ticks = np.frombuffer(self._ticks, dtype=float) if len(self._ticks) else np.zeros(0)
        return deadline_stats(self.period, steps, ticks, self._overruns, self._skipped, self._collections)

    @property
    def step_times(self) -> np.ndarray:
        """The step time of every tick of the last run [s] (a copy)."""
        return np.array(self._steps, dtype=float)

    def stop(self) -> None:
        """End the run after the current tick."""
        self._stop = True

    def run(
        self,
        ticks: int | None = None,
        *,
        duration: float | None = None,
        on_tick: Callable[[Tick], object] | None = None,
    ) -> DeadlineStats:
        """Run ``ticks`` ticks (or for ``duration`` seconds of the grid, or until :meth:`stop`), calling
        ``on_tick(tick)`` after each (a return value of ``False`` stops the run); returns the stats."""
        iterator = self.ticks(ticks, duration=duration)
        try:
            for tick in iterator:
                if on_tick is not None and on_tick(tick) is False:
                    break
        except BaseException as exc:  # (on_tick's; the ticks' own were halted where they were raised)
            if exc is not self._halted:
                self._halt(exc)
            raise
        finally:
            iterator.close()
        return self.stats

    def ticks(self, ticks: int | None = None, *, duration: float | None = None) -> Generator[Tick, None, None]:
        """The ticks as an iterator (the loop's body is the caller's ``for`` body): ``ticks`` ticks, or the slots of
        ``duration`` seconds of the grid (fewer ticks after overruns), or until :meth:`stop`. Breaking out of the
        ``for`` ends the run too."""
        if ticks is not None and duration is not None:
            raise ResolverError("control loop: give ticks or duration, not both")
        most, slots = math.inf, math.inf
        if ticks is not None:
            if isinstance(ticks, bool) or not isinstance(ticks, (int, np.integer)) or ticks < 0:
                raise ResolverError(f"control loop: ticks must be an integer ≥ 0, got {short_repr(ticks)}")
            most = int(ticks)
        if duration is not None:
            slots = math.ceil(_positive(duration, "duration") / self.period - 1e-9)
        return self._ticks_gen(most, slots)

    def _ticks_gen(self, most: float, slots: float) -> Generator[Tick, None, None]:
        """At most ``most`` ticks within the first ``slots`` slots."""
        self._clear()
        self._stop = False
        if most <= 0 or slots <= 0:
            return
        self._warm_up()
        was_enabled = gc.isenabled()
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            start = self.clock()
            k = done = 0
            while done < most and k < slots and not self._stop:
                slot = start + k * self.period
                try:
                    self._wait(slot)
                    tick = self._tick(k, slot)
                except BaseException as exc:  # a read, step or write that failed, Ctrl-C: the robot told to stop
                    self._halt(exc)
                    raise
                yield tick
                done += 1
                end = self.clock()
                self._ticks.append(end - slot)
                k = self._next_slot(k, end - start)
        finally:
            gc.unfreeze()
            if was_enabled:
                gc.enable()

    def _halt(self, exc: BaseException) -> None:
        """Command q̇ = 0 as an exception leaves the loop (a read that failed or gave no configuration, a refused
        step, a failed write, the caller's ``on_tick``, ``KeyboardInterrupt``): the robot is not left running its last
        command; the exception says so in a note (or that this command failed too)."""
        self._halted = exc
        try:
            self.write(np.zeros(self.robot.nv))
        except Exception as again:
            note = f"control loop: the stop command q̇ = 0 after this error failed too: {again!r}"
        else:
            note = "control loop: q̇ = 0 was commanded after this error"
        add_note = getattr(exc, "add_note", None)  # (Python ≥ 3.11; the log says it on any)
        if add_note is not None:
            add_note(note)
        _LOG.warning("%s (%s: %s)", note, type(exc).__name__, exc)

    def _warm_up(self) -> None:
        warm = self.warm
        if callable(warm):
            warm()
        elif warm:
            from redundik.warmup import RESOLVERS, warm_up

            name = getattr(self.resolver, "name", "")
            if name in RESOLVERS:
                warm_up((name,))

    def _tick(self, k: int, slot: float) -> Tick:
        """Read, step, write."""
        began = self.clock()
        q = self.read()
        t = k * self.period
        if k == 0 and self.reset:
            self.robot.update(q)
            self.stack.reset(self.robot)
        t0 = self.clock()
        result = self.resolver.step(self.robot, self.stack, q, t, self.period)
        t1 = self.clock()
        self.write(result.dq)
        self._steps.append(t1 - t0)
        return Tick(k, t, q, result, t1 - t0, began - slot)

    def _next_slot(self, k: int, elapsed: float) -> int:
        """The slot after tick k, given the time elapsed since the start [s]: k + 1, or the next free slot after an
        overrun (counted, with the slots skipped)."""
        nxt = k + 1
        if elapsed > nxt * self.period:
            self._overruns += 1
            free = math.ceil(elapsed / self.period)
            self._skipped += free - nxt
            nxt = free
        return nxt

    def _wait(self, slot: float) -> None:
        """Wait for ``slot`` [s of clock], collecting the young generations if there is slack for it."""
        slack = self.gc_slack
        while True:
            remaining = slot - self.clock()
            if remaining <= 0.0:
                return
            if slack is not None and remaining >= slack:
                gen = _due_generation()
                if gen >= 0:
                    gc.collect(gen)
                    self._collections += 1
                    continue
            if remaining > self.spin:
                self.sleep(remaining - self.spin)


def _due_generation() -> int:
    """The youngest-first generation to collect (0, or 1 when generation 1 is over its threshold too; never 2),
    or −1 when generation 0 is under its threshold."""
    count, threshold = gc.get_count(), gc.get_threshold()
    if threshold[0] <= 0 or count[0] < threshold[0]:
        return -1
    return 1 if threshold[1] > 0 and count[1] >= threshold[1] else 0
