"""``rk.warm_up`` and ``redundik compile`` load the kernels ahead of a control loop, and every step says its path."""

from __future__ import annotations

import logging

import numpy as np
import pytest

import redundik as rk
from redundik.cli.main import main
from redundik.errors import ResolverError


def test_warm_up_steps_each_resolver_and_logs(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="redundik"):
        out = rk.warm_up(["pinv", "hqp"])
    assert set(out) == {"pinv", "hqp"} and all(np.isfinite(v) and v >= 0 for v in out.values())
    assert any("compiled kernels" in r.getMessage() for r in caplog.records)
    with pytest.raises(ResolverError):
        rk.warm_up(["nope"])


def test_compile_command(capsys: pytest.CaptureFixture[str]) -> None:
    from redundik._kernel_cache import cache_dir

    assert main(["compile"]) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert str(cache_dir()) in captured.err  # says where the kernels go
    for name in ("pinv", "feedback", "wqp", "hqp"):
        assert f"{name}:" in printed


def test_feedback_reports_every_member_interpreted() -> None:
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    q = np.radians([30.0, 60.0, -30.0])
    robot.update(q)
    stack.reset(robot)
    res = rk.make_resolver("feedback").step(robot, stack, q, 0.0, 0.01)
    assert res.info["path"] == "interpreted" and res.info["interpreted"] == ("3",)
