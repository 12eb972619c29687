"""Validation errors as one-line :class:`~redundik.errors.ConfigError` messages, and YAML key paths.

Every message names the YAML key path (``runs.rank_null.subtasks.sin2_q3.gain``, ``main[0].frame``) and says what
was expected (the allowed keys of an unknown one, the bounds of a value or a length).
"""

from __future__ import annotations

import types
import typing
from typing import Any

from pydantic import BaseModel, ValidationError

from redundik.errors import ConfigError, short_repr

# pydantic union members appear in error locations under these labels; they are not YAML keys.
_TYPE_LABELS = {"str", "int", "float", "bool", "list", "dict", "none", "None", "constrained-float", "constrained-int"}


def join_path(prefix: str, *parts: str | int) -> str:
    """Append keys / list indices to a key path: ``join_path("main", 0, "frame") == "main[0].frame"``.

    A prefix ending in a space (``"planar3r.yaml: "``, a file name) is followed directly by the first key.
    """
    out = prefix
    for p in parts:
        if isinstance(p, str) and (len(p) > 40 or not p.isprintable()):
            p = short_repr(p, 40)  # a key path never carries unbounded or control-character input
        if isinstance(p, int):
            out += f"[{p}]"
        elif not out or out.endswith(" "):
            out = f"{out}{p}"
        else:
            out = f"{out}.{p}"
    return out


def _unwrap(tp: Any) -> list[Any]:
    """The candidate types of an annotation (through Optional / Union / Annotated)."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(tp)[0])
    if origin is typing.Union or origin is types.UnionType:
        out: list[Any] = []
        for a in typing.get_args(tp):
            out.extend(_unwrap(a))
        return out
    return [tp]


def _annotations_at(model: type[BaseModel], loc: tuple[Any, ...]) -> list[Any]:
    """The annotations reached by following ``loc`` (keys, list indices) through the model's fields, dict values
    and list items."""
    current: list[Any] = [model]
    for part in loc:
        nxt: list[Any] = []
        for tp in current:
            for cand in _unwrap(tp):
                origin = typing.get_origin(cand)
                if isinstance(cand, type) and issubclass(cand, BaseModel) and isinstance(part, str):
                    field = cand.model_fields.get(part)
                    if field is not None:
                        nxt.append(field.annotation)
                elif origin is dict:
                    nxt.append(typing.get_args(cand)[1])
                elif origin is list and isinstance(part, int):
                    nxt.append(typing.get_args(cand)[0])
        current = nxt
    return current


def _allowed_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str] | None:
    """Follow ``loc`` through the model's annotations; the field names of the model reached, if any."""
    for tp in _annotations_at(model, loc):
        for cand in _unwrap(tp):
            if isinstance(cand, type) and issubclass(cand, BaseModel):
                return list(cand.model_fields)
    return None


def _length_bounds(model: type[BaseModel], loc: tuple[Any, ...]) -> tuple[int | None, int | None]:
    """(min_length, max_length) declared on the field at ``loc`` (pydantic reports only the violated one)."""
    if not loc or not isinstance(loc[-1], str):
        return None, None
    lo: int | None = None
    hi: int | None = None
    metas: list[Any] = []
    for tp in _annotations_at(model, loc[:-1]):
        for cand in _unwrap(tp):
            if isinstance(cand, type) and issubclass(cand, BaseModel) and loc[-1] in cand.model_fields:
                field = cand.model_fields[loc[-1]]
                metas += list(field.metadata)
                stack = [field.annotation]
                while stack:
                    a = stack.pop()
                    if typing.get_origin(a) is typing.Annotated:
                        for m in typing.get_args(a)[1:]:
                            metas += list(getattr(m, "metadata", [m]))
                    stack += [x for x in typing.get_args(a) if typing.get_origin(x) is not None]
    for m in metas:
        lo = getattr(m, "min_length", lo) if getattr(m, "min_length", None) is not None else lo
        hi = getattr(m, "max_length", hi) if getattr(m, "max_length", None) is not None else hi
    return lo, hi


def _short(value: Any) -> str:
    return short_repr(value, 60)


def _yaml_bool_hint(got: object) -> str:
    """For a boolean where text was expected: YAML 1.1 (PyYAML) reads an unquoted yes/no/on/off as true/false."""
    if isinstance(got, bool):
        return " (YAML reads an unquoted yes, no, on, off, true or false as a boolean: quote the text, e.g. 'on')"
    return ""


def _message(err: dict[str, Any], allowed: list[str] | None, bounds: tuple[int | None, int | None]) -> str:
    kind = err["type"]
    ctx = err.get("ctx") or {}
    got = err.get("input")
    if kind == "extra_forbidden":
        key = err["loc"][-1] if err["loc"] else "?"
        tail = f"; allowed keys: {', '.join(allowed)}" if allowed else ""
        return f"unknown key '{key}'{tail}"
    if kind == "missing":
        return "required key is missing"
    if kind == "invalid_key":
        if got is None or isinstance(got, bool):
            what = "null" if got is None else f"{str(got).lower()} (a boolean)"
        else:
            what = f"{_short(got)} ({'a number' if isinstance(got, (int, float)) else type(got).__name__})"
        return f"key {what} is not text: keys are names (quote the key if it is one)"
    if kind in ("float_type", "float_parsing"):
        return f"expected a number, got {_short(got)}"
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return f"expected an integer, got {_short(got)}"
    if kind == "finite_number":
        return f"expected a finite number, got {_short(got)}"
    if kind == "string_type":
        return f"expected a string, got {_short(got)}{_yaml_bool_hint(got)}"
    if kind == "bool_type":
        return f"expected true or false, got {_short(got)}"
    if kind == "list_type":
        return f"expected a list, got {_short(got)}"
    if kind in ("dict_type", "model_type", "model_attributes_type"):
        return f"expected a mapping, got {_short(got)}"
    if kind == "literal_error":
        return f"expected one of {ctx.get('expected', '?')}, got {_short(got)}{_yaml_bool_hint(got)}"
    if kind in ("too_short", "too_long"):
        lo = ctx.get("min_length", bounds[0])
        hi = ctx.get("max_length", bounds[1])
        n = ctx.get("actual_length")
        field_type = ctx.get("field_type", "List")
        if kind == "too_short" and field_type in ("Dictionary", "Object"):
            return "must not be empty"
        if lo is not None and hi is not None:
            want = f"{lo}" if lo == hi else f"{lo} to {hi}"
        else:
            want = f"at least {lo}" if lo is not None else f"at most {hi}"
        return f"expected {want} values, got {n}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": "≥", "less_than": "<", "less_than_equal": "≤"}[kind]
        bound = next(iter(ctx.values())) if ctx else "?"
        return f"must be {op} {bound}, got {_short(got)}"
    if kind == "value_error":
        msg = str(err["msg"])
        return msg.removeprefix("Value error, ")
    return str(err["msg"])


#: Error kinds that only say "the value is not of this union member's type".
_MISMATCH_KINDS = {
    "float_type", "float_parsing", "int_type", "int_parsing", "int_from_float", "string_type", "bool_type",
    "list_type", "dict_type", "model_type", "model_attributes_type", "literal_error", "none_required",
}  # fmt: skip


def _is_union_label(part: object) -> bool:
    """Whether a part of an error location is pydantic's label of a union member, not a YAML key.

    Labels are type names (``float``, ``constrained-float``, ``list[float]``, ``literal['home']``) or the class
    name of a model member (``RangeSpec``).
    """
    if not isinstance(part, str):
        return False
    return part in _TYPE_LABELS or "[" in part or part in _model_names()


def _model_names() -> set[str]:
    names: set[str] = set()
    todo = list(BaseModel.__subclasses__())
    while todo:
        cls = todo.pop()
        if cls.__name__ not in names:
            names.add(cls.__name__)
            todo.extend(cls.__subclasses__())
    return names


def _relevant(errors: list[Any]) -> list[Any]:
    """The errors worth reporting first: for a value checked against a union (``x: 0.5`` or ``x: {start, stop,
    num}``), pydantic reports one error per member; the member whose type the value has is the one the user meant,
    so its error (``x.num: must be ≤ 1000000``) beats "expected a number" from the member it was never meant for."""
    labelled = [
        any(_is_union_label(p) for p in e["loc"]) and e["type"] in _MISMATCH_KINDS and _is_union_label(e["loc"][-1])
        for e in errors
    ]
    if any(labelled) and not all(labelled):
        return [e for e, mismatch in zip(errors, labelled, strict=True) if not mismatch]
    return errors


def config_error(exc: ValidationError, model: type[BaseModel], prefix: str = "") -> ConfigError:
    """The first error of a pydantic ``ValidationError`` as a :class:`ConfigError` with its key path.

    Args:
        exc: The validation error.
        model: The model that was validated (to list the allowed keys of an unknown one).
        prefix: Key path of the validated mapping inside the file (``""`` for the top level).
    """
    errors = _relevant(exc.errors())
    err = errors[0]
    loc = tuple(p for p in err["loc"] if not _is_union_label(p))
    # the other errors, counted once per key path (a union reports one error per member at the same path)
    others = {tuple(p for p in e["loc"] if not _is_union_label(p)) for e in errors[1:]} - {loc}
    if err["type"] == "invalid_key":  # the key itself is the last part: the error belongs to its mapping
        loc = loc[:-1]
    allowed = _allowed_keys(model, loc[:-1]) if err["type"] == "extra_forbidden" else None
    path = join_path(prefix, *loc) if loc else (prefix.rstrip(": ") or "(top level)")
    bounds = _length_bounds(model, loc) if err["type"] in ("too_short", "too_long") else (None, None)
    msg = _message(dict(err, loc=loc), allowed, bounds)
    if others:
        msg += f" (and {len(others)} more error{'s' if len(others) > 1 else ''})"
    return ConfigError(msg, path)


def validate(model: type[BaseModel], data: Any, prefix: str = "") -> Any:
    """Validate ``data`` with ``model``; a failure becomes a :class:`ConfigError` at ``prefix``."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise config_error(exc, model, prefix) from None
