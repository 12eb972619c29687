"""Reading YAML and turning validation errors into one-line :class:`~redundik.errors.ConfigError` messages.

Every message names the YAML key path (``runs.rank_null.subtasks.sin2_q3.gain``, ``main[0].frame``) and says
what was expected; YAML syntax errors name the file and line.
"""

from __future__ import annotations

import re
import types
import typing
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from redundik.errors import ConfigError, short_repr

# pydantic union members appear in error locations under these labels; they are not YAML keys.
_TYPE_LABELS = {"str", "int", "float", "bool", "list", "dict", "none", "None", "constrained-float", "constrained-int"}


#: Largest YAML file read [bytes] (the shipped files are below 40 KB).
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Deepest nesting of lists / mappings (the shipped files use at most 6 levels).
MAX_DEPTH = 48
#: Largest number of nodes a document may stand for once its aliases are expanded (billion laughs: 10⁹).
MAX_EXPANDED_NODES = 500_000
#: Largest number of nodes a document may hold as written (aliases counted once). With libyaml (PyYAML's C
#: parser, the usual install) a node costs ~2 µs to check and build, so a refusal takes well under a second; the
#: shipped files hold < 10 000, a sweep's explicit ``points`` list of 30 000 points ~120 000. Without libyaml the
#: pure-Python parser (~30 µs a node) is bounded at :data:`MAX_NODES_PURE_PYTHON`.
MAX_NODES = 400_000
MAX_NODES_PURE_PYTHON = 100_000
#: Longest list under a top-level key, refused while parsing (before the rest of the file is read): ``dh`` rows
#: (a 10 000-row table took 3-24 s to be refused after a full parse). 5× the schema's ``MAX_DH_ROWS`` = 200, so a
#: table just over the schema's limit still gets the schema's own message ("at most 200 D-H rows, got 201").
MAX_TOP_LEVEL_LIST: dict[str, int] = {"dh": 1000}
#: Longest error message built from a YAML problem [characters].
_MAX_MESSAGE = 240


class BoundedLoader(yaml.SafeLoader):
    """PyYAML's SafeLoader with bounds checked *while* composing, and duplicate mapping keys refused.

    * nesting depth ≤ :data:`MAX_DEPTH` (no RecursionError on 500 levels);
    * nodes as written ≤ :data:`MAX_NODES` (a refusal takes seconds, not the minutes 4 MiB of dense YAML take);
    * every node's size with its aliases expanded ≤ :data:`MAX_EXPANDED_NODES` (a billion-laughs file is refused
      after composing its few hundred real nodes, before anything walks the expanded structure);
    * recursive aliases (``&a [*a]``) refused.
    """

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0
        self._weights: dict[int, int] = {}

    def fetch_flow_collection_start(self, TokenClass: Any) -> None:
        # refuse deep flow nesting ([[[[...) in the scanner already: its simple-key bookkeeping is quadratic in depth
        if self.flow_level >= MAX_DEPTH:
            raise yaml.scanner.ScannerError(None, None, f"nesting deeper than {MAX_DEPTH} levels", self.get_mark())
        super().fetch_flow_collection_start(TokenClass)

    def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()  # type: ignore[no-untyped-call]  # untyped in types-PyYAML
            target = self.anchors.get(event.anchor)
            if target is not None and id(target) not in self._weights:
                raise yaml.composer.ComposerError(
                    None, None, f"recursive alias *{short_repr(event.anchor, 40)}", event.start_mark
                )
            return super().compose_node(parent, index)
        event = self.peek_event()  # type: ignore[no-untyped-call]  # untyped in types-PyYAML
        self._nodes += 1
        if self._nodes > MAX_NODES_PURE_PYTHON:  # checked as the nodes come: a huge file is refused before its end
            raise yaml.composer.ComposerError(
                None,
                None,
                f"more than {MAX_NODES_PURE_PYTHON} values in one file (a generated file too large?)",
                event.start_mark,
            )
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"nesting deeper than {MAX_DEPTH} levels", event.start_mark
                )
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        weight = 1
        if isinstance(node, yaml.SequenceNode):
            weight += sum(self._weights.get(id(c), 1) for c in node.value)
        elif isinstance(node, yaml.MappingNode):
            weight += sum(self._weights.get(id(k), 1) + self._weights.get(id(v), 1) for k, v in node.value)
        if weight > MAX_EXPANDED_NODES:
            raise yaml.composer.ComposerError(
                None,
                None,
                f"the document expands to more than {MAX_EXPANDED_NODES} nodes through its aliases (an alias bomb?)",
                event.start_mark,
            )
        self._weights[id(node)] = weight
        return node


def _construct_mapping(loader: BoundedLoader, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        mark = key_node.start_mark
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, f"a {type(key).__name__} cannot be a mapping key (line {mark.line + 1})", mark
            ) from None
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {short_repr(key, 60)} (line {mark.line + 1})", mark
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


BoundedLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
# YAML 1.2 exponent floats (``1e7``, ``1.5e3``, ``-2E-3``): PyYAML (YAML 1.1) reads them as strings, so ``steps: 1e7``
# would be "expected an integer, got '1e7'" instead of being seen as the number it is.
BoundedLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


#: YAML 1.1 integers that read as something else than they look: ``010`` is octal (8), ``1:30`` base 60 (90).
_OCTAL = re.compile(r"^[-+]?0[0-9_]+$")
_SEXAGESIMAL = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")


def _refuse_surprising_number(loader: BoundedLoader, node: yaml.ScalarNode, value: object) -> None:
    """Refuse the YAML 1.1 number forms nobody means in a robot file (PyYAML reads them silently)."""
    text = str(node.value)
    shown = short_repr(text, 40)
    if _OCTAL.match(text):
        raise yaml.constructor.ConstructorError(
            None,
            None,
            f"{shown}: YAML reads a number with a leading zero as octal (= {value}); write it without the leading "
            "zero, or quote it if it is a name",
            node.start_mark,
        )
    if _SEXAGESIMAL.match(text):
        raise yaml.constructor.ConstructorError(
            None,
            None,
            f"{shown}: YAML reads numbers with ':' as base 60 (= {value}); write the number itself, or quote it if "
            "it is a name",
            node.start_mark,
        )


def _construct_int(loader: BoundedLoader, node: yaml.ScalarNode) -> int:
    value = loader.construct_yaml_int(node)
    _refuse_surprising_number(loader, node, value)
    return value


def _construct_float(loader: BoundedLoader, node: yaml.ScalarNode) -> float:
    value = loader.construct_yaml_float(node)
    if ":" in str(node.value):
        _refuse_surprising_number(loader, node, value)
    return value


BoundedLoader.add_constructor("tag:yaml.org,2002:int", _construct_int)
BoundedLoader.add_constructor("tag:yaml.org,2002:float", _construct_float)

_CLoader: Any = getattr(yaml, "CSafeLoader", None)  # None: PyYAML built without libyaml


if _CLoader is not None:

    class FastLoader(_CLoader):  # type: ignore[misc]
        """libyaml's parser with :class:`BoundedLoader`'s constructors and resolvers (duplicate keys refused, YAML
        1.2 exponent floats, octal / base-60 numbers refused); used after :func:`_check_events` bounded the
        document."""

    FastLoader.yaml_constructors = dict(BoundedLoader.yaml_constructors)
    FastLoader.yaml_implicit_resolvers = {k: list(v) for k, v in BoundedLoader.yaml_implicit_resolvers.items()}


def _error(problem: str, event: Any) -> yaml.composer.ComposerError:
    return yaml.composer.ComposerError(None, None, problem, event.start_mark)


def _check_events(text: str) -> None:
    """Walk libyaml's event stream once (no nodes built) and refuse, as soon as it is seen: more than
    :data:`MAX_NODES` nodes, nesting deeper than :data:`MAX_DEPTH`, a node that expands through aliases to more than
    :data:`MAX_EXPANDED_NODES` nodes, a recursive alias, or a top-level list longer than its
    :data:`MAX_TOP_LEVEL_LIST` bound.

    Raises:
        yaml.YAMLError: with the mark of the offending node (syntax errors too, from libyaml).
    """
    loader = _CLoader(text)
    # per open collection: [expanded weight so far, anchor, items, bounded key it is the list of, is a mapping,
    # the next node is a key, the last key]
    stack: list[list[Any]] = []
    weights: dict[str, int] = {}
    open_anchors: set[str] = set()
    nodes = 0
    Scalar, Alias = yaml.ScalarEvent, yaml.AliasEvent
    starts = (yaml.SequenceStartEvent, yaml.MappingStartEvent)
    ends = (yaml.SequenceEndEvent, yaml.MappingEndEvent)
    try:
        while True:
            event = loader.get_event()
            if event is None or isinstance(event, yaml.StreamEndEvent):
                return
            weight = 0
            if isinstance(event, Scalar) or isinstance(event, Alias) or isinstance(event, starts):
                if isinstance(event, Alias):
                    if event.anchor in open_anchors:
                        raise _error(f"recursive alias *{short_repr(event.anchor, 40)}", event)
                    weight = weights.get(event.anchor or "", 1)
                else:
                    nodes += 1
                    if nodes > MAX_NODES:
                        raise _error(f"more than {MAX_NODES} values in one file (a generated file too large?)", event)
                if stack:
                    top = stack[-1]
                    top[2] += 1
                    if top[3] is not None and top[2] > MAX_TOP_LEVEL_LIST[top[3]]:
                        raise _error(
                            f"'{top[3]}' has more than {MAX_TOP_LEVEL_LIST[top[3]]} entries: refused while parsing",
                            event,
                        )
                if isinstance(event, starts):
                    if len(stack) >= MAX_DEPTH:
                        raise _error(f"nesting deeper than {MAX_DEPTH} levels", event)
                    key = None
                    last = stack[0][6] if len(stack) == 1 and stack[0][4] and not stack[0][5] else None
                    if (
                        isinstance(last, str)
                        and last in MAX_TOP_LEVEL_LIST
                        and isinstance(event, yaml.SequenceStartEvent)
                    ):
                        key = last
                    if event.anchor:
                        open_anchors.add(event.anchor)
                    is_map = isinstance(event, yaml.MappingStartEvent)
                    stack.append([1, event.anchor, 0, key, is_map, is_map, None])
                    continue
                if isinstance(event, Scalar):
                    weight = 1
                    if event.anchor:
                        weights[event.anchor] = 1
            elif isinstance(event, ends):
                done = stack.pop()
                weight = done[0]
                if weight > MAX_EXPANDED_NODES:
                    raise _error(
                        f"the document expands to more than {MAX_EXPANDED_NODES} nodes through its aliases "
                        "(an alias bomb?)",
                        event,
                    )
                if done[1]:
                    open_anchors.discard(done[1])
                    weights[done[1]] = weight
            else:
                continue
            if stack:
                top = stack[-1]
                top[0] += weight
                if top[0] > MAX_EXPANDED_NODES:
                    raise _error(
                        f"the document expands to more than {MAX_EXPANDED_NODES} nodes through its aliases "
                        "(an alias bomb?)",
                        event,
                    )
                if top[4]:  # a mapping: alternate key / value
                    if top[5]:
                        top[6] = event.value if isinstance(event, Scalar) else None
                    top[5] = not top[5]
    finally:
        loader.dispose()


def _one_line(text: str, limit: int = _MAX_MESSAGE) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def not_a_file(path: Path) -> str | None:
    """Why ``path`` cannot be read as a file (``"it is a folder, not a file"``, ...), or ``None`` if it can.

    Raises:
        OSError, ValueError: the path cannot even be looked at (too long, an embedded NUL).
    """
    if path.is_file():
        return None
    if path.is_dir():
        return "it is a folder, not a file"
    if path.exists():
        return "it is not a regular file (a device, a pipe or a socket)"
    return "it does not exist"


def _read_text(path: Path, what: str) -> str:
    """The file's text: size-bounded, not binary, valid UTF-8; any problem is a one-line ConfigError."""
    shown = short_repr(str(path), 200).strip("'\"")
    try:
        problem = not_a_file(path)
        if problem is not None:
            raise ConfigError(f"cannot read {what} '{shown}': {problem}")
        with path.open("rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"cannot read {what} '{shown}': {exc.strerror or type(exc).__name__}") from None
    except ValueError as exc:  # e.g. an embedded NUL in the path
        raise ConfigError(f"cannot read {what} '{shown}': {_one_line(str(exc), 80)}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(f"{what} is larger than {MAX_FILE_BYTES // (1024 * 1024)} MiB; refusing to read it", shown)
    if b"\0" in raw:
        raise ConfigError(f"{what} is a binary file (it contains NUL bytes), not YAML text", shown)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ConfigError(f"{what} is not UTF-8 text (bad byte 0x{raw[exc.start]:02x} at line {line})", shown) from None


def parse_yaml(text: str, where: str) -> Any:
    """Parse YAML text with libyaml (:func:`_check_events` first, then :class:`FastLoader`) or, without libyaml,
    :class:`BoundedLoader`; a problem is a one-line ConfigError at ``where:line``."""
    loader = BoundedLoader(text) if _CLoader is None else None
    try:
        if loader is None:
            _check_events(text)
            loader = FastLoader(text)
        return loader.get_single_data()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f"{where}:{mark.line + 1}" if mark is not None else where
        problem = getattr(exc, "problem", None) or type(exc).__name__
        context = getattr(exc, "context", None)
        if "tag:yaml.org,2002:merge" in str(problem):
            problem = "merge keys ('<<: *anchor') are not supported: write the keys out (plain aliases are fine)"
        msg = f"invalid YAML: {problem}" + (f" ({context})" if context else "")
        raise ConfigError(_one_line(msg), at) from None
    except RecursionError:  # belt and braces: the depth bound should make this unreachable
        raise ConfigError(f"invalid YAML: nesting deeper than {MAX_DEPTH} levels", where) from None
    finally:
        if loader is not None:
            loader.dispose()


def read_yaml(path: Path, what: str = "file") -> dict[str, Any]:
    """Read a YAML file whose top level must be a mapping: **the one reader of every YAML entry point**.

    Task files, robot configs, parallel-mechanism configs (and any later format) go through here: the file size
    (:data:`MAX_FILE_BYTES`), nesting depth (:data:`MAX_DEPTH`) and alias expansion (:data:`MAX_EXPANDED_NODES`)
    are bounded while parsing, so a hostile file fails in milliseconds.

    Raises:
        ConfigError: missing, unreadable, too large, binary or non-UTF-8 file; YAML syntax error (with
            ``file:line``); duplicate key; alias bomb; too deep nesting; non-mapping top level. Always one line.
    """
    path = Path(path)
    text = _read_text(path, what)
    shown = short_repr(str(path), 200).strip("'\"")
    data = parse_yaml(text, shown)
    if not isinstance(data, dict):
        raise ConfigError(f"expected a mapping of keys at the top level, got {type(data).__name__}", shown)
    return data


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


def _allowed_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str] | None:
    """Follow ``loc`` through the model's annotations; the field names of the model reached, if any."""
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
    for tp in current:
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
    current: list[Any] = [model]
    for part in loc[:-1]:
        nxt: list[Any] = []
        for tp in current:
            for cand in _unwrap(tp):
                origin = typing.get_origin(cand)
                if isinstance(cand, type) and issubclass(cand, BaseModel) and isinstance(part, str):
                    f = cand.model_fields.get(part)
                    if f is not None:
                        nxt.append(f.annotation)
                elif origin is dict:
                    nxt.append(typing.get_args(cand)[1])
                elif origin is list and isinstance(part, int):
                    nxt.append(typing.get_args(cand)[0])
        current = nxt
    metas: list[Any] = []
    for tp in current:
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
