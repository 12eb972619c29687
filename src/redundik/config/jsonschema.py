"""``redundik schema``: a JSON Schema of task files (and robot configs) for editors, from the same models.

The file-level models (:mod:`redundik.config.schema`) give the top-level keys; every ``main`` task, trajectory,
potential and monitor entry is a ``oneOf`` over the models the registry derived from the library's constructors
(:mod:`redundik.config.registry`), told apart by their ``type`` constant. Point an editor at it with a first line
``# yaml-language-server: $schema=redundik-task.schema.json`` (VS Code's YAML extension, and others).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

_REF = "#/$defs/{model}"
DRAFT = "https://json-schema.org/draft/2020-12/schema"


def _collect(model: type[BaseModel], defs: dict[str, Any]) -> dict[str, Any]:
    """Add ``model`` (and what it refers to) to ``defs``; returns a ``$ref`` to it."""
    schema = model.model_json_schema(ref_template=_REF)
    defs.update(schema.pop("$defs", {}))
    defs[model.__name__] = schema
    return {"$ref": _REF.format(model=model.__name__)}


def _one_of(models: list[type[BaseModel]], defs: dict[str, Any]) -> dict[str, Any]:
    return {"oneOf": [_collect(m, defs) for m in models]}


def robot_schema() -> dict[str, Any]:
    """JSON Schema of a robot config (``configs/*.yaml``)."""
    from redundik.config.schema import RobotSpec

    schema = RobotSpec.model_json_schema(ref_template=_REF)
    return {"$schema": DRAFT, **schema, "title": "redundik robot config"}


def task_schema() -> dict[str, Any]:
    """JSON Schema of a task file (``tasks/*.yaml``), every typed entry spelled out."""
    from redundik.config.builders import MONITORS, POTENTIALS, TASKS, TRAJECTORIES
    from redundik.config.schema import RobotSpec, TaskFileSpec

    defs: dict[str, Any] = {}
    root = TaskFileSpec.model_json_schema(ref_template=_REF)
    defs.update(root.pop("$defs", {}))
    trajectories = _one_of([k.model for k in TRAJECTORIES.values()], defs)
    potentials = _one_of([k.model for k in POTENTIALS.values()], defs)
    monitors = _one_of([k.model for k in [*POTENTIALS.values(), *MONITORS.values()]], defs)
    tasks = _one_of([k.model for k in TASKS.values()], defs)
    for kind in TASKS.values():  # nested typed entries of a task: its trajectory, its potential
        props = defs[kind.model.__name__]["properties"]
        for key, nested in (("trajectory", trajectories), ("potential", potentials)):
            if key in props and props[key].get("anyOf", [{}])[0].get("type") == "object":
                props[key] = {
                    **{k: v for k, v in props[key].items() if k != "anyOf"},
                    "anyOf": [nested, {"type": "null"}],
                }
            elif key in props and props[key].get("type") == "object":
                props[key] = {**{k: v for k, v in props[key].items() if k != "type"}, **nested}
    props = root["properties"]
    props["main"] = {**props["main"], "items": tasks}
    props["potentials"] = {**props["potentials"], "additionalProperties": potentials}
    props["monitors"] = {**props["monitors"], "additionalProperties": monitors}
    props["robot"] = {
        "description": "A robot config path (relative to this file), 'example-robot-data:NAME', or an inline config.",
        "anyOf": [{"type": "string"}, _collect(RobotSpec, defs)],
    }
    run = defs["RunSpec"]["properties"]
    run["main"] = {**run["main"], "anyOf": [{"type": "array", "items": tasks}, {"type": "null"}]}
    run["extra_main"] = {**run["extra_main"], "items": tasks}
    return {"$schema": DRAFT, **root, "title": "redundik task file", "$defs": defs}
