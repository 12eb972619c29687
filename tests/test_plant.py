"""The MuJoCo plant: ``plant: mujoco`` drives the Panda circle through simulated dynamics (tasks/panda_mujoco.yaml)."""

from __future__ import annotations

import copy
import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from redundik.errors import ConfigError
from tests.conftest import TASKS, load_yaml


@pytest.fixture(scope="module")
def mujoco_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``redundik run tasks/panda_mujoco.yaml`` (all three runs, no figures)."""
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("panda_mujoco")
    assert main(["run", str(TASKS / "panda_mujoco.yaml"), "--out", str(out), "--no-figures", "--quiet"]) == 0
    return out


def _task(tmp_path: Path, **plant: Any) -> Path:
    import yaml

    data = copy.deepcopy(load_yaml(TASKS / "panda_mujoco.yaml"))
    data["robot"] = str((TASKS / data["robot"]).resolve())
    data["duration"] = 0.5
    data["runs"] = {"pinv": data["runs"]["pinv"]}
    data["plant"].update(plant)
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def test_summary_reports_the_error_under_the_plant_next_to_the_kinematic_one(mujoco_out: Path) -> None:
    summary = json.loads((mujoco_out / "summary.json").read_text(encoding="utf-8"))
    assert list(summary["runs"]) == ["pinv", "wqp", "hqp"]
    for name, r in summary["runs"].items():
        assert r["plant"] == "mujoco" and r["substeps"] == 5
        assert r["max_task_error"] == r["plant_max_task_error"]
        # dynamics and servo lag cost tracking accuracy, but the closed loop still tracks the 5 cm circle
        assert r["kinematic_max_task_error"] < 1e-3, name
        assert 3 * r["kinematic_max_task_error"] < r["max_task_error"] < 0.02, name
        effort = r["actuator_effort"]["max_abs"]
        assert 5.0 < effort["panda_joint4"] <= 87.0 + 1e-9  # gravity + inertia, within the URDF effort limit
        assert r["limit_violations"] == 0 if name != "pinv" else True


def test_csv_logs_actuator_torques(mujoco_out: Path) -> None:
    with (mujoco_out / "wqp.csv").open(encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    cols = [header.index(f"u.panda_joint{i}") for i in range(1, 8)]
    u = np.array([[float(r[c]) for c in cols] for r in rows[1:]])
    assert u.shape == (801, 7) and np.all(np.isfinite(u))
    assert np.std(u[:, 3]) > 0.01  # the torques vary along the circle


def test_gravity_is_simulated(tmp_path: Path) -> None:
    """Without the gravity compensation the soft servos sag: the error grows; with gravity off it shrinks back."""
    from redundik.config import load_task
    from redundik.config.runner import run_task

    def err(**kw: Any) -> float:
        return run_task(load_task(_task(tmp_path, kp=300.0, kv=30.0, **kw)))["pinv"].summary["max_task_error"]

    compensated, sagging = err(gravity_compensation=True), err(gravity_compensation=False)
    weightless = err(gravity_compensation=False, gravity=False)
    assert sagging > 2 * compensated
    assert weightless < 0.5 * sagging


def test_velocity_actuators_track_too(tmp_path: Path) -> None:
    from redundik.config import load_task
    from redundik.config.runner import run_task

    r = run_task(load_task(_task(tmp_path, actuator="velocity", kv=200.0)))["pinv"]
    assert r.summary["plant"] == "mujoco" and r.summary["actuator"] == "velocity"
    assert r.summary["max_task_error"] < 0.02


def test_bad_rates_and_gains_are_one_line_errors(tmp_path: Path) -> None:
    from redundik.config import load_task
    from redundik.config.runner import run_task

    with pytest.raises(ConfigError, match=r"sim_dt.*must divide"):
        run_task(load_task(_task(tmp_path, sim_dt=0.003)))
    with pytest.raises(ConfigError, match=r"kp.*unknown joint 'elbow'"):
        run_task(load_task(_task(tmp_path, kp={"elbow": 1.0})))
    with pytest.raises(ConfigError, match=r"plant\.actuator"):
        load_task(_task(tmp_path, actuator="torque"))


def test_core_imports_no_mujoco_and_no_viewer() -> None:
    code = (
        "import sys, redundik.simulation, redundik.viewer\n"
        "from redundik.simulation import plant\n"
        "print(','.join(m for m in ('mujoco', 'meshcat', 'matplotlib', 'typer') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_plant_options_are_a_plain_record_checked_in_the_constructor() -> None:
    from redundik.config.schema import PlantSpec
    from redundik.simulation.plant import PlantOptions

    options = PlantSpec(type="mujoco", actuator="velocity", kv={"panda_joint1": 50.0}).options()
    assert options == PlantOptions(actuator="velocity", kv={"panda_joint1": 50.0})
    assert not hasattr(options, "model_dump")  # the library's record, not the YAML model
    with pytest.raises(ConfigError, match=r"actuator: actuator must be one of position, velocity, got 'torque'"):
        PlantOptions(actuator="torque")
    with pytest.raises(ConfigError, match=r"sim_dt: sim_dt must be a finite number > 0 \[s\], got 0.0"):
        PlantOptions(sim_dt=0.0)
    with pytest.raises(ConfigError, match=r"unknown plant type 'gazebo'; available: mujoco"):
        PlantOptions(type="gazebo")


def test_a_mujoco_plant_refuses_a_dh_robot() -> None:
    import redundik as rk
    from redundik.simulation.plant import PlantOptions, make_plant

    robot = rk.from_dh([rk.DHRow("1", a=1.0), rk.DHRow("2", a=1.0)])
    with pytest.raises(ConfigError, match=r"runs.a.plant: a MuJoCo plant needs a URDF robot"):
        make_plant(PlantOptions(), robot, None, control_dt=0.01, where="runs.a.plant")
