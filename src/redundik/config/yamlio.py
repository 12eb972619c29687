"""Reading YAML safely: bounded in size, depth and alias expansion, no surprising scalars, duplicate keys refused.

YAML syntax errors name the file and line. The one-line messages of validation errors (and the key paths
``join_path`` builds) are :mod:`redundik.config.validation`'s, re-exported here for the readers of task files.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from redundik.config.validation import config_error, join_path, validate
from redundik.errors import ConfigError, short_repr

__all__ = [
    "MAX_DEPTH",
    "MAX_EXPANDED_NODES",
    "MAX_FILE_BYTES",
    "MAX_NODES",
    "MAX_TOP_LEVEL_LIST",
    "BoundedLoader",
    "config_error",
    "join_path",
    "not_a_file",
    "parse_yaml",
    "read_yaml",
    "validate",
]


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
#: (after a full parse, a 10 000-row table would take 3-24 s to be refused). 5× the schema's ``MAX_DH_ROWS`` = 200,
#: so a table just over the schema's limit still gets the schema's own message ("at most 200 D-H rows, got 201").
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
