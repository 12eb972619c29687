"""``rk.warm_up`` and ``redundik compile`` load the kernels ahead of a control loop, and every step says its path."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import redundik as rk
from redundik.cli.main import main
from redundik.errors import ResolverError


def test_warm_up_steps_each_resolver_and_logs(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="redundik"):
        out = rk.warm_up(["pinv", "hqp"])
    assert set(out) == {"pinv", "hqp", "solve_ik"} and all(np.isfinite(v) and v >= 0 for v in out.values())
    assert any("compiled kernels" in r.getMessage() for r in caplog.records)
    with pytest.raises(ResolverError):
        rk.warm_up(["nope"])


def test_compile_command(capsys: pytest.CaptureFixture[str]) -> None:
    from redundik._kernel_cache import cache_dir

    assert main(["compile"]) == 0
    captured = capsys.readouterr()
    printed = captured.out
    assert str(cache_dir()) in captured.err  # says where the kernels go
    for name in ("pinv", "feedback", "wqp", "hqp", "solve_ik"):
        assert f"{name}:" in printed


def test_warm_up_compiles_solve_ik_ahead(tmp_path: Path) -> None:
    """After ``rk.warm_up(ik=True)`` on an empty cache, ``solve_ik`` and its batch form compile nothing (numba's
    compile events): ``redundik compile`` covers the IK too."""
    code = textwrap.dedent(
        """
        import json, numpy as np, redundik as rk
        from numba.core import event
        out = rk.warm_up([], ik=True)
        found = []

        class Listener(event.Listener):
            def on_start(self, ev):
                found.append(ev.data["dispatcher"].py_func.__qualname__)

            def on_end(self, ev):
                pass

        event.register("numba:compile", Listener())
        robot = rk.load_example_robot("panda")
        q = robot.neutral()
        robot.update(q)
        T = robot.frame_pose("panda_hand")
        ok = [rk.solve_ik(robot, "panda_hand", T, q).success, rk.solve_ik(robot, "panda_hand", T.translation).success]
        ok += list(rk.solve_ik_batch(robot, "panda_hand", [T, T], q).success)
        print(json.dumps({"keys": sorted(out), "found": sorted(set(found)), "ok": [bool(x) for x in ok]}))
        """
    )
    env = {**os.environ, "REDUNDIK_CACHE_DIR": str(tmp_path)}
    cmd = [sys.executable, "-c", code]
    run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert got["keys"] == ["solve_ik"] and got["found"] == [] and all(got["ok"])


def test_feedback_reports_its_path() -> None:
    """``feedback`` takes its compiled step; switched off (``fuse = False``) every member is named interpreted."""
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
    stack = rk.TaskStack([rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")])
    q = np.radians([30.0, 60.0, -30.0])
    robot.update(q)
    stack.reset(robot)
    resolver = rk.make_resolver("feedback")
    res = resolver.step(robot, stack, q, 0.0, 0.01)
    assert res.info["path"] == "compiled" and res.info["interpreted"] == ()
    resolver.fuse = False  # type: ignore[attr-defined]
    res = resolver.step(robot, stack, q, 0.0, 0.01)
    assert res.info["path"] == "interpreted" and res.info["interpreted"] == ("3",)
