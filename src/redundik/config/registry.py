"""One registry from YAML ``type:`` names to the library's own constructors; the YAML models are derived from them.

A type is declared once, by registering its constructor::

    register("clearance", "potential", Clearance)

and its YAML model (a strict pydantic model: ``type`` plus one key per constructor parameter) is derived from the
constructor's signature and type hints, with each key's description taken from the ``Args:`` section of its
docstring. Building an entry validates the mapping against that model, converts the values that need the robot or
the file's units, and calls the constructor; any error is a one-line :class:`~redundik.errors.ConfigError` naming
the YAML key path.

How parameters are derived (override any of it with ``params={"name": As(...)}``):

* hints ``str`` → a name (an integer in the YAML is taken as its text); ``float``/``int``/``bool`` → themselves;
  ``Sequence[float]``/``np.ndarray`` → a list of numbers (3 of them for ``center``/``point``/``position``);
  ``Mapping[str, float]`` → a mapping; ``X | None`` → optional; a :class:`~redundik.tasks.Trajectory` or
  :class:`~redundik.tasks.Potential` parameter → a nested typed mapping, built from its own section;
* parameter names ``frame``/``frame_a``/``frame_b``, ``frames``, ``joint``/``joint_i``/``joint_j`` and ``axes`` are
  checked against the robot (the message lists what exists);
* a parameter documented in ``[rad]`` or ``[rad/s]`` is read in the file's ``angle_unit``; one documented
  ``≥ 0`` or ``> 0`` gets that bound;
* ``name``: a main task takes an optional ``name`` key (default: its frame, else its type); potentials and monitors
  are named by their key under ``potentials:`` / ``monitors:``.

New types: call :func:`register` (in :mod:`redundik.config.types` for the library's own). The older
``register_task(name, model, build)`` of :mod:`redundik.config.builders` still works for a hand-written model.
"""

from __future__ import annotations

import collections.abc
import inspect
import re
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field, create_model

from redundik.config import schema as s
from redundik.config.builders import (
    MONITORS,
    POTENTIALS,
    TASKS,
    TRAJECTORIES,
    Context,
    _wrap,
    build_typed,
    check_axes,
    check_frame,
    check_joint,
    frame_list,
)
from redundik.config.yamlio import join_path
from redundik.errors import ConfigError

Section = Literal["task", "trajectory", "potential", "monitor"]
#: The registries by section (the same dict objects as :mod:`redundik.config.builders`' ``TASKS``, ...).
SECTIONS: dict[str, dict[str, Any]] = {
    "task": TASKS,
    "trajectory": TRAJECTORIES,
    "potential": POTENTIALS,
    "monitor": MONITORS,
}
#: What an error message calls an entry of each section.
WHAT = {"task": "main task", "trajectory": "trajectory", "potential": "potential", "monitor": "monitor"}

#: ``convert(value, ctx, path, spec)``: a validated YAML value → the constructor's argument.
Converter = Callable[[Any, Context, str, Any], Any]


@dataclass(frozen=True)
class As:
    """How one constructor parameter appears in YAML; anything left ``None`` is derived.

    Attributes:
        key: YAML key (default: the parameter name).
        annotation: YAML-side type (pydantic annotation).
        default: YAML default (default: the constructor's; ``...`` = required).
        bounds: Extra pydantic constraints (``{"ge": 0}``).
        convert: Turns the validated value into the argument (checks against the robot, units).
        hidden: Not a YAML key: ``convert(None, ctx, path, spec)`` computes the argument from the other keys.
    """

    key: str | None = None
    annotation: Any = None
    default: Any = None
    bounds: dict[str, Any] = field(default_factory=dict)
    convert: Converter | None = None
    hidden: bool = False


@dataclass(frozen=True)
class Param:
    """One constructor parameter as read from YAML."""

    name: str
    key: str | None
    convert: Converter | None


@dataclass(frozen=True)
class YamlType:
    """A registered type: its YAML name, section, constructor and derived model.

    Attributes:
        type_name: The ``type:`` value.
        section: Where it may appear.
        factory: The library's constructor (a class or a function).
        model: The derived pydantic model (validates the mapping, exports the JSON Schema).
        params: How each constructor parameter is read.
        name_param: The constructor parameter that receives the entry's name, or ``None``.
    """

    type_name: str
    section: str
    factory: Callable[..., Any]
    model: type[BaseModel]
    params: tuple[Param, ...]
    name_param: str | None

    def build(self, spec: Any, name: str, ctx: Context, path: str) -> Any:
        """Convert a validated ``spec`` and call the constructor; errors become :class:`ConfigError` at ``path``."""
        kwargs: dict[str, Any] = {}
        for p in self.params:
            value = None if p.key is None else getattr(spec, p.key)
            where = path if p.key is None else join_path(path, p.key)
            if p.convert is not None and (value is not None or p.key is None):
                value = p.convert(value, ctx, where, spec)
            if value is not None or p.key is None:
                kwargs[p.name] = value
        if self.name_param is not None:
            given = getattr(spec, "name", None) if "name" in type(spec).model_fields else None
            kwargs[self.name_param] = given or name
        return _wrap(path, lambda: self.factory(**kwargs))


# ---------------------------------------------------------------------------------------------------- converters
def _frame(value: Any, ctx: Context, path: str, spec: Any) -> str:
    return check_frame(ctx, value, path)


def _frames(value: Any, ctx: Context, path: str, spec: Any) -> list[str]:
    return frame_list(value, ctx, path)


def _joint(value: Any, ctx: Context, path: str, spec: Any) -> str:
    return check_joint(ctx, value, path)


def _axes(position_only: bool) -> Converter:
    def convert(value: Any, ctx: Context, path: str, spec: Any) -> tuple[str, ...]:
        return check_axes(value, path, position_only=position_only)

    return convert


def _angle(value: Any, ctx: Context, path: str, spec: Any) -> Any:
    if isinstance(value, list):
        return [v * ctx.scale for v in value]
    return value * ctx.scale


def joint_unit(joint_key: str) -> Converter:
    """A value in the angle unit if the joint named by ``spec.<joint_key>`` is revolute, else in the length unit."""

    def convert(value: Any, ctx: Context, path: str, spec: Any) -> Any:
        joint = getattr(spec, joint_key)
        if ctx.robot.joint(check_joint(ctx, joint, path)).kind != "revolute":
            return value
        return [v * ctx.scale for v in value] if isinstance(value, list) else value * ctx.scale

    return convert


def configuration(size: str = "nq") -> Converter:
    """A configuration (``nq``) or per-velocity vector (``nv``) written in the file's angle unit."""
    from redundik.config.robot import configuration_from_file

    def convert(value: Any, ctx: Context, path: str, spec: Any) -> np.ndarray:
        return configuration_from_file(value, ctx.robot, ctx.angle_unit, path, size)

    return convert


def per_joint(value: Any, ctx: Context, path: str, spec: Any) -> np.ndarray:
    """One number per velocity coordinate (size nv), no unit conversion."""
    if len(value) != ctx.robot.nv:
        raise ConfigError(f"expected {ctx.robot.nv} values (one per joint), got {len(value)}", path)
    return np.asarray(value, dtype=float)


def nested(section: str) -> Converter:
    """A typed mapping of another section (a frame task's ``trajectory``, a potential task's ``potential``)."""

    def convert(value: Any, ctx: Context, path: str, spec: Any) -> Any:
        name = getattr(spec, "name", None) or section
        return build_typed(SECTIONS[section], value, str(name), ctx, path, WHAT[section])

    return convert


_NAMED = {
    "frame": _frame,
    "frame_a": _frame,
    "frame_b": _frame,
    "frames": _frames,
    "joint": _joint,
    "joint_i": _joint,
    "joint_j": _joint,
}
#: Parameters that are one point or vector in space (3 numbers).
_POINTS = {"center", "point", "position", "xyz"}


# ---------------------------------------------------------------------------------------------------- derivation
def arg_docs(obj: Any) -> dict[str, str]:
    """Parameter descriptions from the ``Args:`` section of a (Google-style) docstring of ``obj`` or its __init__."""
    texts = [inspect.getdoc(obj) or ""]
    if inspect.isclass(obj):
        texts.append(inspect.getdoc(obj.__init__) or "")
    out: dict[str, str] = {}
    for text in texts:
        m = re.search(r"^Args:\n((?:[ \t]+.*\n?|\n)+)", text, re.M)
        if not m:
            continue
        current = None
        for line in m.group(1).splitlines():
            item = re.match(r"^ {4}(\*{0,2}\w+)(?: \(.*?\))?: (.*)$", line)
            if item:
                current = item.group(1)
                out[current] = item.group(2).strip()
            elif current and line.startswith("     "):
                out[current] += " " + line.strip()
    return out


def _strip_none(tp: Any) -> tuple[Any, bool]:
    origin = typing.get_origin(tp)
    if origin is typing.Union or origin is types.UnionType:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        optional = len(args) < len(typing.get_args(tp))
        return (args[0] if len(args) == 1 else typing.Union[tuple(args)]), optional  # noqa: UP007
    return tp, False


def _derive(name: str, hint: Any, doc: str, default: Any) -> tuple[Any, Converter | None]:
    """The YAML annotation and converter of a parameter from its hint, name, docstring and default."""
    from redundik.tasks import Potential, Trajectory

    tp, optional = _strip_none(hint)
    ann: Any
    conv: Converter | None = None
    origin = typing.get_origin(tp)
    if name == "axes":
        ann, conv = Any, _axes(position_only=default == "position")
    elif name in _NAMED:
        ann = s.Name | list[s.Name] if name == "frames" else s.Name
        conv = _NAMED[name]
    elif tp is str:
        ann = s.Name
    elif inspect.isclass(tp) and issubclass(tp, Trajectory):
        ann, conv = dict[str, Any], nested("trajectory")
    elif inspect.isclass(tp) and issubclass(tp, Potential):
        ann, conv = dict[str, Any], nested("potential")
    elif tp in (float, int, bool):
        ann = tp
    elif origin in (collections.abc.Mapping, dict):
        ann = dict[s.Name, float]
    elif tp is np.ndarray or origin in (collections.abc.Sequence, list, tuple) or "ndarray" in str(tp):
        ann = s.Vec3 if name in _POINTS else list[float]
    else:
        raise TypeError(f"parameter '{name}': no YAML form for {hint!r}; give it one with params={{...: As(...)}}")
    if conv is None and re.search(r"\[rad(/s)?\]", doc):
        conv = _angle
    if optional:
        ann = ann | None
    return ann, conv


def _is_scalar(ann: Any) -> bool:
    """Whether a YAML annotation holds one value (a number), not a list or mapping (through Optional/Annotated)."""
    origin = typing.get_origin(ann)
    if origin is typing.Annotated:
        return _is_scalar(typing.get_args(ann)[0])
    if origin is typing.Union or origin is types.UnionType:
        return all(_is_scalar(a) for a in typing.get_args(ann) if a is not type(None))
    return origin not in (list, tuple, dict) and ann not in (list, tuple, dict)


def _doc_bounds(doc: str) -> dict[str, Any]:
    """Bounds a docstring states: ``≥ 0`` → ge=0, ``> 0`` → gt=0 (for a number; the entries of a list parameter
    documented ``≥ 0`` are checked by the constructor: pydantic cannot compare a list with 0)."""
    if re.search(r"≥ 0\b", doc):
        return {"ge": 0}
    if re.search(r"(?<![≥<])> 0\b", doc):
        return {"gt": 0}
    return {}


def register(
    type_name: str,
    section: Section,
    factory: Callable[..., Any],
    *,
    params: dict[str, As] | None = None,
    exclude: tuple[str, ...] = (),
    extra: dict[str, tuple[Any, Any]] | None = None,
    description: str | None = None,
) -> YamlType:
    """Make ``type: type_name`` available in ``section``, built by ``factory``; the YAML model is derived.

    Args:
        type_name: The ``type:`` value.
        section: ``task`` (under ``main:``), ``trajectory`` (a frame task's ``trajectory:``), ``potential`` (under
            ``potentials:``, also usable as a monitor) or ``monitor`` (under ``monitors:`` only).
        factory: The constructor (class or function); its parameters become the YAML keys.
        params: Overrides of how single parameters are read (:class:`As`).
        exclude: Parameters not offered in YAML (they keep the constructor's default).
        extra: YAML keys that are not parameters, ``{key: (annotation, default)}`` (read by a hidden parameter's
            converter).
        description: Model description (default: the first line of the factory's docstring).

    Returns:
        The registered type.

    Raises:
        TypeError: a parameter whose hint has no YAML form and no override.
    """
    params = params or {}
    sig = inspect.signature(factory)
    target = factory.__init__ if inspect.isclass(factory) else factory
    hints = typing.get_type_hints(target)
    docs = arg_docs(factory)
    fields: dict[str, Any] = {"type": (Literal[type_name], ...)}
    read: list[Param] = []
    name_param = None
    for pname, p in sig.parameters.items():
        if pname in exclude or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        if pname == "name":
            name_param = "name"
            if section == "task":
                fields["name"] = (s.Name | None, Field(default=None, description="Task name."))
            continue
        over = params.get(pname, As())
        doc = docs.get(pname, "")
        default = p.default if p.default is not inspect.Parameter.empty else ...
        if over.hidden:
            read.append(Param(pname, None, over.convert))
            continue
        conv: Converter | None
        if over.annotation is not None and over.convert is not None:  # (both given: nothing to derive)
            ann, conv = over.annotation, over.convert
        else:
            ann, conv = _derive(pname, hints.get(pname, Any), doc, default)
        ann = over.annotation if over.annotation is not None else ann
        conv = over.convert if over.convert is not None else conv
        if over.default is not None:
            default = over.default
        key = over.key or pname
        bounds = dict(over.bounds) or (_doc_bounds(doc) if _is_scalar(ann) else {})
        if isinstance(default, tuple):
            default = list(default)
        if isinstance(default, list):
            fields[key] = (ann, Field(default_factory=lambda d=default: list(d), description=doc, **bounds))
        else:
            fields[key] = (ann, Field(default=default, description=doc, **bounds))
        read.append(Param(pname, key, conv))
    for key, (ann, default) in (extra or {}).items():
        fields[key] = (ann, Field(default=default, description=docs.get(key, "")))
    doc_line = description or (inspect.getdoc(factory) or type_name).split("\n")[0]
    model = create_model(
        f"{section.capitalize()}_{type_name}",
        __base__=s.StrictModel,
        __doc__=f"{WHAT[section].capitalize()} ``type: {type_name}``: {doc_line}",
        **fields,
    )
    entry = YamlType(type_name, section, factory, model, tuple(read), name_param)
    SECTIONS[section][type_name] = entry
    return entry


#: The bound ``> 0``, used by several registrations.
POSITIVE: dict[str, Any] = {"gt": 0}
#: A 3-vector, optional.
OptVec3 = Annotated[list[float], Field(min_length=3, max_length=3)] | None
