"""Threads and resolvers: one resolver per thread is exact; a resolver stepped by two threads at once refuses the
second call with a clear error instead of mixing their scratch buffers (a silent wrong answer before)."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import pytest

import redundik as rk

RESOLVERS = ["pinv", "feedback", "wqp", "hqp"]


def _arm() -> rk.RobotModel:
    return rk.from_dh([rk.DHRow(str(i), a=1.0) for i in range(1, 5)], name="planar4r")


def _stack() -> rk.TaskStack:
    return rk.TaskStack([rk.FrameTask("4", rk.Line([0.2, -0.4]), axes="planar", gain=5.0)])


class BlockingTask(rk.Task):
    """A one-row task whose evaluation waits for ``release`` after signalling ``entered`` (holds a step open)."""

    def __init__(self) -> None:
        self._init_task("blocking", gain=1.0)
        self.entered, self.release = threading.Event(), threading.Event()

    def evaluate(self, robot: rk.RobotModel, t: float) -> rk.TaskTerm:
        self.entered.set()
        assert self.release.wait(30.0), "the test never released the step"
        J = np.ones((1, robot.nv))
        e = np.array([0.1])
        return rk.TaskTerm(self.name, J, e, e, self.weight)

    def __repr__(self) -> str:
        return "BlockingTask()"


@pytest.mark.parametrize("method", RESOLVERS)
def test_a_resolver_stepped_by_two_threads_at_once_refuses_the_second(method: str) -> None:
    resolver = rk.make_resolver(method)
    robot_a, stack_a = _arm(), rk.TaskStack([BlockingTask()])
    task = stack_a.tasks[0]
    assert isinstance(task, BlockingTask)
    q = np.full(4, 0.3)
    out: list[object] = []
    first = threading.Thread(target=lambda: out.append(resolver.step(robot_a, stack_a, q, 0.0, 0.01)))
    first.start()
    try:
        assert task.entered.wait(30.0)
        robot_b, stack_b = _arm(), _stack()  # its own robot and stack: only the resolver is shared
        with pytest.raises(rk.ResolverError, match="another thread is inside a step"):
            resolver.step(robot_b, stack_b, q, 0.0, 0.01)
    finally:
        task.release.set()
        first.join(30.0)
    assert len(out) == 1 and np.isfinite(out[0].dq).all()  # type: ignore[attr-defined]
    # once the first step is over the resolver is free again, in any thread
    robot_b, stack_b = _arm(), _stack()
    robot_b.update(q)
    stack_b.reset(robot_b)
    assert np.isfinite(resolver.step(robot_b, stack_b, q, 0.0, 0.01).dq).all()


def test_a_step_that_raises_leaves_the_resolver_free() -> None:
    resolver = rk.make_resolver("pinv")
    robot, stack = _arm(), _stack()
    with pytest.raises(rk.ResolverError):
        resolver.step(robot, stack, np.full(4, np.nan), 0.0, 0.01)
    q = np.full(4, 0.3)
    robot.update(q)
    stack.reset(robot)
    assert np.isfinite(resolver.step(robot, stack, q, 0.0, 0.01).dq).all()


def _run(method: str, steps: int = 60) -> np.ndarray:
    robot, stack = _arm(), _stack()
    resolver = rk.make_resolver(method)
    q = np.array([0.6, -0.4, -0.3, 0.2])
    robot.update(q)
    stack.reset(robot)
    out = np.empty((steps, 4))
    for k in range(steps):
        out[k] = resolver.step(robot, stack, q, 0.01 * k, 0.01).dq
        q = robot.integrate(q, out[k], 0.01)
    return out


@pytest.mark.parametrize("method", RESOLVERS)
def test_one_resolver_per_thread_is_exact(method: str) -> None:
    serial = _run(method)
    results: dict[int, np.ndarray] = {}
    threads = [threading.Thread(target=lambda k=k: results.__setitem__(k, _run(method))) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(120.0)
    assert sorted(results) == [0, 1, 2, 3]
    for k in range(4):
        np.testing.assert_array_equal(results[k], serial)


@pytest.mark.parametrize("method", RESOLVERS)
def test_a_resolver_that_stepped_still_pickles_and_copies(method: str) -> None:
    import copy

    robot, stack = _arm(), _stack()
    resolver = rk.make_resolver(method)
    q = np.array([0.6, -0.4, -0.3, 0.2])
    robot.update(q)
    stack.reset(robot)
    resolver.step(robot, stack, q, 0.0, 0.01)
    for clone in (pickle.loads(pickle.dumps(resolver)), copy.deepcopy(resolver), copy.copy(resolver)):
        r2, s2 = _arm(), _stack()
        r2.update(q)
        s2.reset(r2)
        assert np.isfinite(clone.step(r2, s2, q, 0.0, 0.01).dq).all()
