"""Inputs and checks the hostile-input tests share: the planar task and robot config, the Panda sweep cut to a few
points, and the rule that an error is one line (``error: ...``), never a traceback or an internal error."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

import redundik as rk
from redundik.cli.main import EXIT_INTERNAL
from tests.conftest import CONFIGS, TASKS

ROOT = Path(__file__).resolve().parents[1]
TASK = (TASKS / "planar3r_line.yaml").read_text(encoding="utf-8").replace("../configs/", f"{CONFIGS}/")
ROBOT = (CONFIGS / "planar3r.yaml").read_text(encoding="utf-8")
SWEEP = (
    (ROOT / "sweeps" / "panda_reach.yaml")
    .read_text(encoding="utf-8")
    .replace("../configs/", f"{CONFIGS}/")
    .replace("num: 160", "num: 2")
    .replace("num: 128", "num: 2")
)
#: Seconds after which a refusal counts as a hang (generous: the machine may be loaded).
HANG_GUARD_S = 10.0
Cli = Callable[..., tuple[int, str, str]]


def _one_line_error(code: int, err: str, expected_code: int = 3) -> None:
    """The command exited with ``expected_code`` and one line ``error: ...`` on stderr: never a traceback, and an
    internal error only where that is the exit code expected."""
    assert code == expected_code, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert expected_code == EXIT_INTERNAL or "internal error" not in err, err


def _write(tmp_path: Path, text: str, name: str = "f.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _planar() -> tuple[rk.RobotModel, rk.TaskStack, np.ndarray]:
    robot = rk.from_dh([rk.DHRow("1", a=1), rk.DHRow("2", a=1), rk.DHRow("3", a=1)])
    stack = rk.TaskStack(
        [rk.FrameTask("3", rk.Line([0.2, -0.4]), axes="planar")], [rk.GradientSubtask(rk.JointSine2("3"))]
    )
    q = np.array([0.3, 0.5, -0.4])
    robot.update(q)
    stack.reset(robot)
    return robot, stack, q
