"""The YAML registry: every public type is reachable from YAML, models are derived from the constructors, schema."""

from __future__ import annotations

import copy
import inspect
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import redundik.tasks as tasks_pkg
from redundik.config import load_task, run_task
from redundik.config.builders import MONITORS, POTENTIALS, TASKS, TRAJECTORIES
from redundik.config.registry import As, YamlType, register
from redundik.errors import ConfigError
from redundik.tasks import Potential, Task, Trajectory
from tests.conftest import TASKS as TASK_DIR


def _public_types() -> list[type]:
    out = []
    for name in tasks_pkg.__all__:
        obj = getattr(tasks_pkg, name)
        if inspect.isclass(obj) and issubclass(obj, (Task, Potential, Trajectory)) and not inspect.isabstract(obj):
            out.append(obj)
    return out


@pytest.mark.parametrize("cls", _public_types(), ids=lambda c: c.__name__)
def test_every_public_type_has_a_yaml_type(cls: type) -> None:
    registered = {
        k.factory for reg in (TASKS, POTENTIALS, TRAJECTORIES) for k in reg.values() if isinstance(k, YamlType)
    }
    assert cls in registered, f"{cls.__name__} has no YAML type: register it in redundik/config/types.py"


def test_models_are_derived_from_constructors() -> None:
    clearance = POTENTIALS["clearance"].model
    fields = clearance.model_fields
    assert list(fields) == ["type", "frame", "center", "radius", "axes"]  # the signature of Clearance, name excepted
    assert fields["radius"].default == 0.0
    point = POTENTIALS["virtual_point"].model.model_fields["frame"]
    assert point.description == 'The frame whose origin moves (e.g. the elbow, D-H frame ``"3"``).'  # its Args:
    frame = TASKS["frame"].model.model_json_schema()["properties"]
    assert frame["gain"]["anyOf"][0]["minimum"] == 0  # "gain: K [1/s] ≥ 0" in the docstring
    assert frame["weight"]["exclusiveMinimum"] == 0  # "(> 0)"
    assert "priority" in frame  # a constructor parameter is a YAML key without anyone writing it twice


@pytest.fixture
def planar(planar_task_data: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(planar_task_data)
    data["steps"] = 100
    return data


def test_joint_coupling_and_potential_task_from_yaml(planar: dict[str, Any], write_yaml: Callable[..., Path]) -> None:
    planar["main"][0]["trajectory"]["velocity"] = [0.02, -0.04]
    planar["main"].append({"type": "joint_coupling", "joint_i": "2", "joint_j": "3", "gain": 1.0, "priority": 1})
    planar["runs"] = {
        "coupled": {"resolver": "hqp"},
        "potential": {
            "resolver": "hqp",
            "main": [
                planar["main"][0],
                {
                    "type": "potential",
                    "potential": {"type": "sin2", "joint": "3"},
                    "target": 1.0,
                    "rate": 2.0,
                    "priority": 1,
                    "name": "s3",
                },
            ],
        },
    }
    res = run_task(load_task(write_yaml(planar)))
    q = res["coupled"].log.q
    np.testing.assert_allclose(q[:, 1] - q[:, 2], q[0, 1] - q[0, 2], atol=1e-6)  # θ2 − θ3 held (in rad)
    s3 = np.sin(res["potential"].log.q[:, 2]) ** 2
    assert s3[0] < 0.3 and s3[-1] > 0.8  # sin²θ3 driven towards 1 at level 1


@pytest.mark.parametrize(
    ("entry", "path", "words"),
    [
        (
            {"type": "potential", "potential": {"type": "sin2", "joint": "7"}, "target": 1.0},
            "main[1].potential.joint",
            ["joint '7' does not exist", "available: 1, 2, 3"],
        ),
        (
            {"type": "potential", "potential": {"type": "sine", "joint": "3"}, "target": 1.0},
            "main[1].potential.type",
            ["unknown potential type 'sine'", "sin2"],
        ),
        ({"type": "joint_coupling", "joint_i": "2", "joint_j": "2"}, "main[1]", ["joint_i and joint_j must differ"]),
        (
            {"type": "joint_coupling", "joint_i": "2", "joint_j": "3", "joint_k": "3"},
            "main[1].joint_k",
            ["unknown key 'joint_k'", "allowed keys: type, joint_i, joint_j, offset"],
        ),
        ({"type": "joint_coupling", "joint_i": "2", "joint_j": "3", "weight": 0}, "main[1].weight", ["must be > 0"]),
        ({"type": "teleport"}, "main[1].type", ["unknown main task type 'teleport'", "joint_coupling", "potential"]),
    ],
)
def test_new_types_have_key_path_errors(
    planar: dict[str, Any], write_yaml: Callable[..., Path], entry: dict[str, Any], path: str, words: list[str]
) -> None:
    planar["main"].append(entry)
    with pytest.raises(ConfigError) as info:
        load_task(write_yaml(planar))
    assert info.value.path == path, str(info.value)
    for w in words:
        assert w in str(info.value), str(info.value)


def test_angles_follow_the_docstring_units(planar: dict[str, Any]) -> None:
    planar["main"][0]["trajectory"] = {"type": "circle", "radius": 0.1, "omega": 90.0, "phase": 180.0}
    traj = load_task(planar).runs["rank_only"].stack.tasks[0].trajectory
    assert traj.omega == pytest.approx(np.pi / 2) and traj.phase == pytest.approx(np.pi)  # "omega: ω [rad/s]", deg file


def test_register_a_new_type(planar: dict[str, Any]) -> None:
    def half_sine(joint: str, scale: float = 0.5, *, name: str | None = None) -> Potential:
        """½·sin²θ_j, for this test.

        Args:
            joint: The joint.
            scale: Factor (> 0).
            name: Potential name.
        """
        return tasks_pkg.JointSine2(joint, name=name)

    register("half_sine", "potential", half_sine, params={"scale": As(default=0.5)})
    try:
        planar["potentials"]["sin2_q3"] = {"type": "half_sine", "joint": "3"}
        plan = load_task(planar)
        assert plan.runs["rank_null"].stack.subtasks[0].name == "sin2_q3"
        planar["potentials"]["sin2_q3"]["scale"] = -1
        with pytest.raises(ConfigError, match=r"^potentials.sin2_q3.scale: must be > 0"):
            load_task(planar)
    finally:
        del POTENTIALS["half_sine"]


def test_torques_monitor_is_a_registered_function() -> None:
    assert MONITORS["torques"].model.model_fields["force"].is_required()


def test_json_schema_accepts_every_shipped_task_and_names_every_type(cli) -> None:  # type: ignore[no-untyped-def]
    jsonschema = pytest.importorskip("jsonschema")  # in the test extra
    code, out, _ = cli("schema")
    schema = json.loads(out)
    assert code == 0
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    for f in sorted(TASK_DIR.glob("*.yaml")):
        errors = [e.message for e in validator.iter_errors(yaml.safe_load(f.read_text(encoding="utf-8")))]
        assert not errors, (f.name, errors[:3])
    data = yaml.safe_load((TASK_DIR / "planar3r_line.yaml").read_text(encoding="utf-8"))
    data["potentials"]["sin2_q3"]["jiont"] = "3"
    assert not validator.is_valid(data)
    for reg in (TASKS, POTENTIALS, TRAJECTORIES, MONITORS):
        for kind in reg.values():
            assert kind.model.__name__ in schema["$defs"]
