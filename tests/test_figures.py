"""The figures take simulation logs and plain options: a control loop written in Python draws without a task file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import redundik as rk

pytest.importorskip("matplotlib")

from redundik.reporting.plots import FigureOptions, LoggedRun, logged_runs, split_task_errors

SEGMENTS = [("0", "1"), ("1", "2"), ("2", "3")]


def _loop() -> tuple[rk.RobotModel, rk.TaskStack, rk.SimulationLog]:
    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0), rk.DHRow("3", a=1.0)])
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], [rk.GradientSubtask(rk.JointSine2("3"), gain=1.0)]
    )
    q0 = np.radians([30.0, 40.0, -60.0])
    log = rk.simulate(robot, stack, rk.PinvResolver(), q0, dt=0.01, steps=60, log_frames=("0", "1", "2", "3"))
    return robot, stack, log


def test_figures_and_gif_of_a_python_loop_import_no_yaml_layer(tmp_path: Path) -> None:
    code = f"""
import sys
from pathlib import Path
from tests.test_figures import SEGMENTS, _loop
from redundik.reporting.gif import write_gif
from redundik.reporting.plots import FigureOptions, LoggedRun, write_figures

robot, stack, log = _loop()
out = Path({str(tmp_path)!r})
options = FigureOptions("loop", segments=SEGMENTS, path_frame="3")
runs = {{"pinv": LoggedRun(log, stack, label="pinv"), "bare": log}}
names = sorted(p.name for p in write_figures(runs, robot, out, options))
names.append(write_gif(runs, robot, out / "loop.gif", options, frames=5).name)
print(names, sorted(m for m in ("redundik.config", "redundik.cli", "pydantic") if m in sys.modules))
"""
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, timeout=300)
    assert proc.returncode == 0, proc.stderr
    names = ["configurations.png", "joints.png", "potentials.png", "task_error.png", "loop.gif"]
    assert proc.stdout.strip() == f"{names} []"
    for name in names:
        assert (tmp_path / name).stat().st_size > 1000, name


def test_a_bare_log_is_a_run_without_a_stack() -> None:
    robot, stack, log = _loop()
    runs = logged_runs({"a": log, "b": LoggedRun(log, stack)})
    assert runs["a"] == LoggedRun(log) and runs["b"].stack is stack
    assert split_task_errors(robot, log) == {}  # no stack: nothing to recompute
    assert FigureOptions().segments == () and FigureOptions().kinds == {}
