"""A step's lazy ``info`` answers a key its pending diagnostics cannot add without computing them.

A control loop that logs ``result.info.get("qp", 0)`` on a ``pinv`` step (no QP there) used to run the step's
σ_min diagnostics — an eigen-decomposition of JJᵀ — on every tick, outside the step but inside the loop. The pending
functions of ``pinv`` and ``feedback`` declare what they add (``resolvers.result.info_keys``); every other absent key
is answered at once. What the info reports does not change: checked against a twin result read in full.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import redundik as rk
from redundik.resolvers import feedback as feedback_module
from redundik.resolvers import pinv as pinv_module
from redundik.resolvers.result import LazyInfo, declared_keys, info_keys


def _stepped(method: str, fuse: bool, steps: int = 15) -> list[rk.StepResult]:
    """The results of ``steps`` steps of a Panda hand circle with posture and a centring gradient."""
    robot = rk.load_example_robot("panda")
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02])
    robot.update(q)
    stack = rk.TaskStack(
        [rk.FrameTask("panda_hand", rk.Circle(radius=0.05, omega=2.0), axes="pose", gain=20.0)],
        [rk.GradientSubtask(rk.JointCentering(), gain=-1.0)] if method != "feedback" else [],
    )
    stack.reset(robot)
    res = rk.make_resolver(method)
    if hasattr(res, "fuse"):
        res.fuse = fuse  # type: ignore[attr-defined]
    out, dt = [], 0.01
    for k in range(steps):
        r = res.step(robot, stack, q, k * dt, dt)
        q = robot.integrate(q, r.dq, dt)
        out.append(r)
    return out


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("method", ["pinv", "feedback"])
def test_an_absent_key_is_answered_without_the_diagnostics(
    method: str, fuse: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    module = pinv_module if method == "pinv" else feedback_module
    calls = []
    real = module.gram_sigma_min

    def counted(J: np.ndarray) -> float:
        calls.append(1)
        return real(J)

    monkeypatch.setattr(module, "gram_sigma_min", counted)
    res = _stepped(method, fuse)[-1]
    info = res.info
    assert isinstance(info, LazyInfo) and info._pending is not None  # (the case leaves σ_min pending)
    assert info.get("qp", 0) == 0 and "qp" not in info and info.get("backend") is None
    with pytest.raises(KeyError):
        info["qp"]
    assert calls == []  # nothing computed for them
    smin = info["sigma_min"]
    assert calls == [1] and smin == res.sigma_min and 0.0 < smin < np.inf


@pytest.mark.parametrize("fuse", [True, False])
@pytest.mark.parametrize("method", ["pinv", "feedback", "wqp", "hqp"])
def test_the_answers_are_those_of_the_full_info(method: str, fuse: bool) -> None:
    """Twin runs: one result's keys probed one at a time before anything was computed, the other's info read in
    full; the same answers (a declaration that left out a key the diagnostics add would fail here)."""
    probed, full = _stepped(method, fuse), _stepped(method, fuse)
    for a, b in zip(probed, full, strict=True):
        whole = dict(b.info.items())
        for key in [*whole, "qp", "backend", "rank", "not_a_key"]:
            value = a.info.get(key, "absent")
            assert (value == "absent") == (key not in whole), key
        assert set(a.info) == set(whole)


def test_declared_keys_reads_a_function_and_a_partial() -> None:
    @info_keys("sigma_min", "rank")
    def diag(x: float) -> tuple[float, bool, dict[str, object]]:
        return x, False, {"sigma_min": x}

    assert declared_keys(diag) == frozenset({"sigma_min", "rank"})
    assert declared_keys(functools.partial(diag, 1.0)) == frozenset({"sigma_min", "rank"})
    assert declared_keys(lambda: (0.0, False, {})) is None  # undeclared: any key may be added
    lazy = LazyInfo({"a": 1}, lambda: {"sigma_min": 2.0}, frozenset({"sigma_min"}))
    assert lazy.get("b") is None and lazy._pending is not None
    assert lazy["sigma_min"] == 2.0 and lazy._pending is None
    assert dict(LazyInfo({"a": 1}, lambda: {"z": 3}, None).items()) == {"a": 1, "z": 3}
