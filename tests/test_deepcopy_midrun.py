"""A resolver copied mid-run — ``copy.deepcopy`` or ``pickle`` of (robot, stack, resolver) together, as the message of
``Resolver.step`` recommends for another thread — steps exactly as an uncopied twin (built and stepped identically)
from then on, compiled or not (``fuse``), in the situations that use the state a copy could detach:

* ``DaqpBackend``'s split of a bounds-only QP (a robot with nv ≥ 22 whose joint limits bind): its cached views of
  the split's work buffers became arrays of their own in a copy, which then solved a stale problem (0.5 rad/s off);
* a ``TargetSubtask`` in the stack, which sends the per-task ``wqp`` step through the backend (the same split);
* the command watchdog stopping the robot: the copy dropped its reader of the stack's targets, took its first step for
  a new command and resumed while the original kept stopping (0.5 rad/s off);
* ``hqp``'s constrained cascade solving its level QPs in Python (a backend other than daqp's C entry): the copy's views
  of the level-QP buffer were frozen copies, so the backend solved a stale level QP (1.6–4 rad/s off);
* the proxsuite and OSQP backends, which hold a module: the copy raised TypeError.
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import redundik as rk
from redundik.config.loader import load_task
from redundik.resolvers.qp import daqp_native

TASKS = Path(__file__).resolve().parents[1] / "tasks"
PANDA_Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])

Loop = list[Any]  # [robot, stack, resolver]
Maker = Callable[[bool], tuple[Loop, np.ndarray, float]]
Edit = Callable[[int, Loop], None]


def _copied(loop: Loop, how: str) -> Loop:
    """(robot, stack, resolver) copied together (one memo), by ``copy.deepcopy`` or a pickle round trip."""
    objects = tuple(loop)
    clone = copy.deepcopy(objects) if how == "deepcopy" else pickle.loads(pickle.dumps(objects))
    return list(clone)


def _lockstep(make: Maker, fuse: bool, how: str, copy_at: int, steps: int, edit: Edit | None = None) -> list[Any]:
    """Two identical loops stepped from the same q (the twin's integration); one is copied before step ``copy_at``
    and the copy replaces it. Every step after the copy must give the twin's q̇ and watchdog state. ``edit(k, loop)``
    is applied to both loops before step k. Returns the twin's results from the copy on."""
    copied, q, dt = make(fuse)
    twin, _, _ = make(fuse)
    out = []
    for k in range(copy_at + steps):
        if k == copy_at:
            copied = _copied(copied, how)
        if edit is not None:
            edit(k, copied)
            edit(k, twin)
        a = copied[2].step(copied[0], copied[1], q, k * dt, dt)
        b = twin[2].step(twin[0], twin[1], q, k * dt, dt)
        if k >= copy_at:
            np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-12, err_msg=f"step {k}")
            assert a.info.get("watchdog") == b.info.get("watchdog"), f"step {k}"
            out.append(b)
        q = twin[0].integrate(q, b.dq, dt)
    return out


def _humanoid(
    method: str, fuse: bool, *, target: bool = False, slow_arms: bool = False, backend: str | None = None
) -> tuple[Loop, np.ndarray, float]:
    """tasks/humanoid_reach.yaml (32 dof: two hand frame tasks and joint centring), with a target subtask on a
    virtual point of the head camera (``target``: it drives joints onto their limits from the first steps) or the
    upper arm joints' velocity limited to 0.02 rad/s (``slow_arms``: their limits bind at every step)."""
    plan = load_task(TASKS / "humanoid_reach.yaml")
    spec = plan.runs["pinv"]
    stack = spec.stack
    if target:
        point = rk.VirtualPoint("rgbd_depth_frame", [0.0398, -0.6427, 0.8341], axes=["y"], name="vp")
        stack.subtasks.append(rk.TargetSubtask(point, -0.1764, rate=33.15, weight=1.375, name="vp_target"))
    options: dict[str, Any] = {} if backend is None else {"backend": backend}
    if slow_arms:
        slow = {f"arm_{side}_{i}_joint": 0.02 for side in ("left", "right") for i in range(1, 5)}
        options["limits"] = {"velocity_limits": slow}
    resolver = rk.make_resolver(method, **options)
    resolver.fuse = fuse
    robot = plan.robot.model
    q0 = np.array(spec.q0, dtype=float)
    robot.update(q0)
    stack.reset(robot)
    return [robot, stack, resolver], q0, plan.dt


def _split_was_used(make: Maker, fuse: bool, ticks: int) -> bool:
    """Whether a loop's backend split a bounds-only QP (``DaqpBackend._split_cache`` filled) within ``ticks``."""
    loop, q, dt = make(fuse)
    for k in range(ticks):
        q = loop[0].integrate(q, loop[2].step(loop[0], loop[1], q, k * dt, dt).dq, dt)
    return bool(loop[2].backend._split_cache)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize("fuse", [True, False])
def test_a_copy_solves_its_split_qps_as_the_original(fuse: bool, how: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """wqp on 32 dof whose arms' velocity limits bind: each step's box QP goes to ``DaqpBackend.solve`` (daqp's C
    entry off), which splits it into its separable and coupled variables in work buffers it keeps. The copy is made
    after such solves."""
    monkeypatch.setattr(daqp_native, "enabled", False)

    def make(fuse: bool) -> tuple[Loop, np.ndarray, float]:
        return _humanoid("wqp", fuse, slow_arms=True)

    assert _split_was_used(make, fuse, 4)
    results = _lockstep(make, fuse, how, copy_at=4, steps=20)
    assert all(r.info["qp"] == 1 and r.info["n_active"] > 0 for r in results)  # (a split QP at every step)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize(
    ("fuse", "native"), [(False, True), (True, False), (False, False)], ids=["per-task", "compiled", "per-task-no-C"]
)
def test_a_copy_with_a_target_subtask_steps_as_the_original(
    fuse: bool, native: bool, how: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """wqp with a target subtask on a virtual point (the fuzzer's stack; its rate drives joints onto their limits):
    the per-task step goes through the template and the backend's split solve. The compiled step solves its box QPs
    through daqp's C entry, which keeps no split buffers; with that entry off (``native``) they go to the backend's
    split as well."""
    monkeypatch.setattr(daqp_native, "enabled", native)

    def make(fuse: bool) -> tuple[Loop, np.ndarray, float]:
        return _humanoid("wqp", fuse, target=True)

    assert _split_was_used(make, fuse, 4)
    results = _lockstep(make, fuse, how, copy_at=4, steps=20)
    assert all(r.info["qp"] == 1 for r in results)


def _panda_watched(method: str) -> Maker:
    """Panda drawing a circle, joint centring and a target subtask (set once, at the start), with a watchdog of
    timeout 0.05 s: the commands go stale at 0.06 s and the robot stops within 5 rad/s²."""

    def make(fuse: bool) -> tuple[Loop, np.ndarray, float]:
        robot = rk.load_example_robot("panda")
        hand = rk.FrameTask("panda_hand_tcp", rk.Circle(0.1, 3.0, plane=("y", "z")), gain=20.0)
        point = rk.VirtualPoint("panda_link4", [0.3, 0.2, 0.5], axes=["y"])
        subtasks = [rk.GradientSubtask(rk.JointCentering(), gain=-1.0), rk.TargetSubtask(point, -0.05, rate=5.0)]
        stack = rk.TaskStack([hand], subtasks)
        resolver = rk.make_resolver(method, command_timeout=0.05, stop_acceleration=5.0)
        resolver.fuse = fuse
        robot.update(PANDA_Q0)
        stack.reset(robot)
        return [robot, stack, resolver], PANDA_Q0.copy(), 0.01

    return make


def _new_target_at(tick: int) -> Edit:
    """At step ``tick``, a new target of the loop's own target subtask (a command: the watchdog resumes)."""

    def edit(k: int, loop: Loop) -> None:
        if k == tick:
            loop[1].subtasks[1].set_target(-0.04)

    return edit


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("method", ["wqp", "hqp"])
def test_a_copy_made_while_the_watchdog_stops_keeps_stopping(method: str, fuse: bool, how: str) -> None:
    """Copied while stopping, the copy keeps stopping (its first step is no command); a target set later on the copy's
    own stack is one, and it resumes as the original does."""
    results = _lockstep(_panda_watched(method), fuse, how, copy_at=20, steps=30, edit=_new_target_at(35))
    states = [r.info["watchdog"] for r in results]
    assert states[:15] == ["stopping"] * 15  # (steps 20-34: the copy's first steps)
    assert states[15] == "resuming"  # (step 35: the new target)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
@pytest.mark.parametrize("fuse", [True, False])
def test_a_copy_solves_hqp_level_qps_in_python_as_the_original(fuse: bool, how: str) -> None:
    """hqp with quadprog (no C entry: each level QP the compiled cascade writes into the plan's buffer is solved here,
    through views of that buffer), limits binding on 32 dof."""

    def make(fuse: bool) -> tuple[Loop, np.ndarray, float]:
        return _humanoid("hqp", fuse, target=True, backend="quadprog")

    results = _lockstep(make, fuse, how, copy_at=4, steps=12)
    assert all(r.info["qp"] >= 1 for r in results)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_with_the_osqp_backend_steps_as_the_original(how: str) -> None:
    """The OSQP backend (through qpsolvers, a module it holds) copies, and the copy steps as the original."""
    pytest.importorskip("qpsolvers")
    pytest.importorskip("osqp")

    def make(fuse: bool) -> tuple[Loop, np.ndarray, float]:
        return _humanoid("wqp", fuse, target=True, backend="osqp")

    results = _lockstep(make, False, how, copy_at=3, steps=10)
    assert all(r.info["qp"] == 1 and r.info["backend"] == "osqp" for r in results)


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_with_the_proxsuite_backend_steps(how: str) -> None:
    """The proxsuite backend (a module it holds) copies; the copy starts its QPs cold (a copied ProxQP object forgets
    its box constraints: its update raised and the step fell back), so its q̇ is the original's to within what
    ProxQP's tolerance and warm start leave open, not to the last bit."""
    pytest.importorskip("proxsuite")
    loop, q, dt = _humanoid("wqp", False, target=True, backend="proxsuite")
    for k in range(3):
        q = loop[0].integrate(q, loop[2].step(loop[0], loop[1], q, k * dt, dt).dq, dt)
    clone = _copied(loop, how)
    for k in range(3, 13):
        a = clone[2].step(clone[0], clone[1], q, k * dt, dt)
        b = loop[2].step(loop[0], loop[1], q, k * dt, dt)
        assert a.fallback is None and a.info["backend"] == "proxsuite", f"step {k}"
        np.testing.assert_allclose(a.dq, b.dq, rtol=0, atol=1e-4, err_msg=f"step {k}")
        q = loop[0].integrate(q, b.dq, dt)
