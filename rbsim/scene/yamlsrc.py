"""YAML text -> plain Python values that remember where they came from.

`load_yaml` reads the parser's events (libyaml's parser when PyYAML has it, else
PyYAML's own) and builds the values itself, without recursion: mappings become
:class:`YMap` (a dict with the line and column of every key and value), sequences
:class:`YList`, scalars stay plain ``str``/``int``/``float``/``bool``/``None``. It never
raises for bad input; every problem is returned as a :class:`Problem`.

Differences from ``yaml.safe_load``, chosen for scene files:

- numbers follow YAML 1.2: ``1e-3``, ``1E5``, ``-2.5e+3``, ``.5`` and ``-.5`` are floats,
  ``010`` is ten and ``1:30`` a string (YAML 1.1 reads octal and base 60);
- only ``true``/``false`` are booleans; ``yes``/``no``/``on``/``off``/``y``/``n`` stay strings;
- dates and ``=`` stay strings; tags other than the core ones (str, int, float, bool,
  null, map, seq) are an error;
- a duplicate key in one mapping is an error naming both lines;
- an alias (``*name``) is a copy of its anchor, so changing one use changes no other;
  merge keys (``<<: *defaults``) work as in YAML 1.1.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import yaml
from yaml.nodes import ScalarNode

Path = tuple[str | int, ...]

_TAG = "tag:yaml.org,2002:"
_STR, _INT, _FLOAT, _BOOL, _NULL = (_TAG + t for t in ("str", "int", "float", "bool", "null"))
_MAP, _SEQ, _MERGE = _TAG + "map", _TAG + "seq", _TAG + "merge"

# YAML 1.2 core-schema floats (plus YAML 1.1 underscores): a dot or an exponent is enough.
_FLOAT_RE = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
    |[0-9][0-9_]*[eE][-+]?[0-9]+)
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
_INT_RE = re.compile(r"^(?:[-+]?[0-9][0-9_]*|0x[0-9a-fA-F_]+|0o[0-7_]+)$")
_BOOL_RE = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")


_MAX_VALUES = 1_000_000  # values copied by expanding aliases
_MAX_DEPTH = 500  # nested collections (a scene needs fewer than 10)


class _Broken:
    def __repr__(self) -> str:
        return "BROKEN"


BROKEN: Any = _Broken()  # a value that could not be read (its problem is already reported)


class _TooLarge(Exception):
    pass


class _Loader(yaml.SafeLoader):
    """SafeLoader with the implicit resolvers described in the module docstring."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag in (_NULL, _MERGE)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_FLOAT, _FLOAT_RE, list("-+0123456789."))
_Loader.add_implicit_resolver(_INT, _INT_RE, list("-+0123456789"))
_Loader.add_implicit_resolver(_BOOL, _BOOL_RE, list("tTfF"))


@dataclass(frozen=True, slots=True)
class Mark:
    """Where a value came from: 1-based line and column in the file, or, for a value
    given on the command line, ``origin`` (such as ``"--set world.dt"``) and line 0."""

    line: int
    column: int
    origin: str | None = None


@dataclass(frozen=True, slots=True)
class Problem:
    """One error: where (mark), which key (path, possibly empty) and what."""

    mark: Mark
    path: Path
    message: str


class YMap(dict):
    """A mapping from the document. ``key_marks[k]`` is where key ``k`` is written,
    ``value_marks[k]`` where its value is (for a block collection value: the key),
    ``mark`` where the mapping itself starts."""

    __slots__ = ("key_marks", "value_marks", "mark", "block")

    def __init__(self, mark: Mark) -> None:
        super().__init__()
        self.mark = mark
        self.block = False  # written in block style (over several lines)
        self.key_marks: dict[str, Mark] = {}
        self.value_marks: dict[str, Mark] = {}

    def put(self, key: str, value: Any, key_mark: Mark, value_mark: Mark) -> None:
        """Set ``key`` to ``value`` and remember where both came from."""
        self[key] = value
        self.key_marks[key] = key_mark
        self.value_marks[key] = value_mark

    def remove(self, key: str) -> None:
        """Delete ``key`` (if present) with its marks."""
        self.pop(key, None)
        self.key_marks.pop(key, None)
        self.value_marks.pop(key, None)


class YList(list):
    """A sequence from the document; ``item_marks[i]`` is where item ``i`` is written."""

    __slots__ = ("item_marks", "mark", "block")

    def __init__(self, mark: Mark) -> None:
        super().__init__()
        self.mark = mark
        self.block = False  # written in block style (over several lines)
        self.item_marks: list[Mark] = []


def format_path(path: Path) -> str:
    """('bodies', 3, 'shape', 'circle') -> 'bodies[3].shape.circle'."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


def line_column(text: str, index: int) -> tuple[int, int]:
    """1-based (line, column) of character ``index`` in ``text``."""
    line = text.count("\n", 0, index) + 1
    return line, index - (text.rfind("\n", 0, index) + 1) + 1


def load_yaml(text: str, origin: str | None = None) -> tuple[Any, Mark, list[Problem]]:
    """Parse one YAML document. Returns (value, mark of the value, problems).

    The value is None for an empty document or after a syntax error. With ``origin``
    set (a value given on the command line), every mark is ``Mark(0, 0, origin)``.
    libyaml parses when it is installed (several times faster); on a syntax error the
    text is parsed again by PyYAML's own parser, whose messages are clearer.
    """
    builder = _Builder(origin)
    start = builder.mark_at(0, 0)
    try:
        if _FastLoader is not None:
            try:
                return builder.run(_FastLoader(text))
            except yaml.YAMLError:
                builder = _Builder(origin)
        return builder.run(_Loader(text))
    except yaml.MarkedYAMLError as err:
        return None, start, [_syntax_problem(err, builder)]
    except yaml.reader.ReaderError as err:
        line, column = line_column(text, err.position)
        message = f"character #x{err.character:04x} is not allowed in a YAML file"
        return None, start, [Problem(builder.mark_at(line - 1, column - 1), (), message)]
    except RecursionError:
        message = f"the document is nested too deeply (more than {_MAX_DEPTH} levels)"
        return None, start, [Problem(start, (), message)]
    except _TooLarge:
        message = f"aliases expand the document to more than {_MAX_VALUES} values"
        return None, start, [Problem(start, (), message)]


# The trees of the last texts parsed by load_yaml_tree: a batch resolves one scene's text
# hundreds of times, each time with its own overrides, and parsing was most of that
# (1.6 of 2.6 ms for a 16-body scene). Texts longer than PARSED_TEXT_MAX are not kept.
_PARSED: dict[str, tuple[Any, Mark, list[Problem], Shared]] = {}
PARSED_KEEP = 8  # texts
PARSED_TEXT_MAX = 1 << 20  # characters


class Shared:
    """A parsed text's tree as load_yaml_tree shares it between the loads of that text
    (no load changes its nodes: an override changes copies, see copy_node), and what the
    checks of a load have worked out from those nodes, for the next loads: `found`, keyed
    by the caller's tuples, which name nodes by id (valid while the tree lives, and so
    only for nodes that `holds`)."""

    __slots__ = ("nodes", "found")

    def __init__(self, root: Any) -> None:
        self.nodes: frozenset[int] = frozenset(id(n) for n in _containers(root))
        self.found: dict[tuple, Any] = {}

    def holds(self, value: Any) -> bool:
        """Whether `value` is a mapping or list of the shared tree."""
        return id(value) in self.nodes


def _containers(value: Any) -> Iterator[Any]:
    """The YMaps and YLists of a tree, `value` first."""
    stack = [value]
    while stack:
        node = stack.pop()
        if isinstance(node, YMap | YList):
            yield node
            stack.extend(node.values() if isinstance(node, YMap) else node)


def load_yaml_tree(text: str) -> tuple[Any, Mark, list[Problem], Shared]:
    """load_yaml(text) and its Shared: a text met again is not parsed again. The tree is
    shared with every other load of the text: the caller changes copies of its nodes
    (copy_node), never the nodes themselves."""
    found = _PARSED.get(text)
    if found is None:
        root, mark, problems = load_yaml(text)
        found = (root, mark, problems, Shared(root))
        if len(text) <= PARSED_TEXT_MAX:
            if len(_PARSED) >= PARSED_KEEP:
                _PARSED.pop(next(iter(_PARSED)))
            _PARSED[text] = found
    root, mark, problems, shared = found
    return root, mark, list(problems), shared


def copy_node(value: Any) -> Any:
    """A shallow copy of a YMap or YList (its items and marks shared), or `value`."""
    if isinstance(value, YMap):
        out = YMap(value.mark)
        out.block = value.block
        out.update(value)
        out.key_marks.update(value.key_marks)
        out.value_marks.update(value.value_marks)
        return out
    if isinstance(value, YList):
        out_list = YList(value.mark)
        out_list.block = value.block
        out_list.extend(value)
        out_list.item_marks.extend(value.item_marks)
        return out_list
    return value


def copy_tree(value: Any, on_node: Callable[[], None] | None = None) -> Any:
    """A copy of a parsed tree: its YMaps and YLists new, with their marks; the scalars
    (immutable) shared. on_node() is called before each value is copied (the builder's
    budget for aliases: it may raise to stop the copy)."""
    if on_node is not None:
        on_node()
    out = copy_node(value)
    if isinstance(out, YMap):
        for key, item in out.items():
            out[key] = copy_tree(item, on_node)
    elif isinstance(out, YList):
        for i, item in enumerate(out):
            out[i] = copy_tree(item, on_node)
    return out


def _syntax_problem(err: yaml.MarkedYAMLError, builder: _Builder) -> Problem:
    mark = err.problem_mark or err.context_mark
    where = builder.mark_at(mark.line, mark.column) if mark else builder.mark_at(0, 0)
    problem = err.problem or "invalid YAML"
    message = f"YAML syntax error: {problem}"
    if err.context:
        context_mark = err.context_mark
        if context_mark and builder.origin is None and context_mark.line != mark.line:
            message += f" ({err.context} at line {context_mark.line + 1})"
        else:
            message += f" ({err.context})"
    if "'\\t'" in problem:
        message += "; tabs are not allowed for indentation in YAML, use spaces"
    return Problem(where, (), message)


class _Frame:
    """A mapping or sequence whose end event has not come yet."""

    __slots__ = (
        "value",
        "path",
        "anchor",
        "key",
        "key_mark",
        "skip",
        "merging",
        "merges",
        "broken",
    )

    def __init__(self, value: YMap | YList, path: Path, anchor: str | None) -> None:
        self.value = value
        self.path = path
        self.anchor = anchor
        self.key: str | None = None  # mapping: the key waiting for its value
        self.key_mark: Mark | None = None
        self.skip = False  # mapping: drop the value of a bad or duplicate key
        self.merging = False  # mapping: the key is `<<`
        self.merges: list[tuple[Any, Mark]] = []  # mapping: values of `<<` keys
        self.broken = False  # an unsupported tag: the value becomes BROKEN

    def child_path(self) -> Path:
        if isinstance(self.value, YList):
            return self.path + (len(self.value),)
        return self.path + (self.key,) if self.key is not None else self.path


class _Builder:
    """Parser events -> YMap/YList/scalars, without recursion, collecting problems."""

    def __init__(self, origin: str | None) -> None:
        self.origin = origin
        self.problems: list[Problem] = []
        self.anchors: dict[str, tuple[Any, Mark]] = {}
        self.open_anchors: set[str] = set()
        self.budget = _MAX_VALUES  # nested aliases can expand a small file exponentially

    def mark_at(self, line0: int, column0: int) -> Mark:
        if self.origin is not None:
            return Mark(0, 0, self.origin)
        return Mark(line0 + 1, column0 + 1)

    def mark(self, event: Any) -> Mark:
        return self.mark_at(event.start_mark.line, event.start_mark.column)

    def error(self, mark: Mark, path: Path, message: str) -> None:
        self.problems.append(Problem(mark, path, message))

    def run(self, loader: Any) -> tuple[Any, Mark, list[Problem]]:
        try:
            loader.get_event()  # stream start
            if loader.check_event(yaml.StreamEndEvent):
                return None, self.mark_at(0, 0), self.problems
            loader.get_event()  # document start
            value, mark = self.document(loader)
            loader.get_event()  # document end
            if not loader.check_event(yaml.StreamEndEvent):
                extra = self.mark(loader.get_event())
                self.error(extra, (), "a scene file holds one YAML document; found a second")
            return value, mark, self.problems
        finally:
            if hasattr(loader, "dispose"):
                loader.dispose()

    def document(self, loader: Any) -> tuple[Any, Mark]:
        stack: list[_Frame] = []
        while True:
            event = loader.get_event()
            path = stack[-1].child_path() if stack else ()
            if isinstance(event, yaml.CollectionStartEvent):
                mark = self.mark(event)
                container = YMap(mark) if isinstance(event, yaml.MappingStartEvent) else YList(mark)
                container.block = not event.flow_style
                if event.anchor is not None:
                    self.open_anchors.add(event.anchor)
                if len(stack) >= _MAX_DEPTH:
                    raise RecursionError
                stack.append(_Frame(container, path, event.anchor))
                if event.tag not in (None, "!", _MAP, _SEQ):
                    self.error(mark, path, f"unsupported YAML tag {_short(event.tag)}")
                    stack[-1].broken = True
                continue
            if isinstance(event, yaml.CollectionEndEvent):
                frame = stack.pop()
                value, mark = frame.value, frame.value.mark
                if isinstance(value, YMap):
                    self.merge(value, frame.merges, frame.path)
                if frame.broken:
                    value = BROKEN
                if frame.anchor is not None:
                    self.open_anchors.discard(frame.anchor)
                    self.anchors[frame.anchor] = (value, mark)
            elif isinstance(event, yaml.AliasEvent):
                value, mark = self.alias(event, path)
            else:
                value, mark = self.scalar(event, path), self.mark(event)
                if event.anchor is not None:
                    self.anchors[event.anchor] = (value, mark)
            if not stack:
                return value, mark
            self.add(stack[-1], value, mark, event)

    def add(self, frame: _Frame, value: Any, mark: Mark, event: Any) -> None:
        """Put a finished value into the collection being built."""
        target = frame.value
        if isinstance(target, YList):
            target.append(value)
            target.item_marks.append(mark)
            return
        if frame.key is None and not frame.skip and not frame.merging:  # the value is a key
            if isinstance(event, yaml.ScalarEvent) and _resolve(event) == _MERGE:
                frame.merging = True
            elif isinstance(event, yaml.ScalarEvent) or isinstance(value, str):
                key = event.value if isinstance(event, yaml.ScalarEvent) else value
                if key in target:
                    first = target.key_marks[key]
                    where = f"line {first.line}" if first.line else first.origin
                    self.error(
                        mark,
                        frame.path + (key,),
                        f"duplicate key {key!r} (first at {where}, again at line {mark.line})",
                    )
                    frame.skip = True
                else:
                    frame.key, frame.key_mark = key, mark
            else:
                if value is not BROKEN:
                    self.error(mark, frame.path, "a key must be a plain name")
                frame.skip = True
            return
        if frame.skip:
            frame.skip = False
        elif frame.merging:
            frame.merges.append((value, mark))
            frame.merging = False
        else:
            block = getattr(value, "block", False) and not isinstance(event, yaml.AliasEvent)
            target.put(frame.key, value, frame.key_mark, frame.key_mark if block else mark)
        frame.key = None

    def merge(self, target: YMap, merges: list[tuple[Any, Mark]], path: Path) -> None:
        """Apply `<<` merge keys: explicit keys win, then earlier merge sources."""
        for value, mark in merges:
            sources = value if isinstance(value, YList) else [value]
            for source in sources:
                if not isinstance(source, YMap):
                    self.error(mark, path, "a merge key '<<' needs a mapping or a list of them")
                    continue
                for key, item in source.items():
                    if key not in target:
                        target.put(key, item, source.key_marks[key], source.value_marks[key])

    def alias(self, event: Any, path: Path) -> tuple[Any, Mark]:
        mark = self.mark(event)
        if event.anchor in self.open_anchors:
            self.error(mark, path, "recursive alias: a value cannot contain itself")
            return BROKEN, mark
        if event.anchor not in self.anchors:
            self.error(mark, path, f"undefined alias *{event.anchor} (no &{event.anchor} before)")
            return BROKEN, mark
        value, _ = self.anchors[event.anchor]
        return self.copy(value), mark  # a copy: a --set on one use must not change the others

    def copy(self, value: Any) -> Any:
        return copy_tree(value, self._spend)

    def _spend(self) -> None:
        """One value of the budget; _TooLarge when it is spent."""
        self.budget -= 1
        if self.budget < 0:
            raise _TooLarge

    def scalar(self, event: Any, path: Path) -> Any:
        tag = _resolve(event)
        if tag == _STR:
            return event.value
        constructor = _SCALARS.get(tag)
        if constructor is None:
            self.error(self.mark(event), path, f"unsupported YAML tag {_short(tag)}")
            return BROKEN
        try:
            return constructor(ScalarNode(tag, event.value))
        except (ValueError, KeyError):
            name = tag.removeprefix(_TAG)
            self.error(self.mark(event), path, f"{event.value!r} is not a valid {name}")
            return BROKEN


def _short(tag: str) -> str:
    """'tag:yaml.org,2002:foo' -> '!!foo', as it is written."""
    return "!!" + tag.removeprefix(_TAG) if tag.startswith(_TAG) else tag


def _resolve(event: yaml.ScalarEvent) -> str:
    """The tag of a scalar: explicit, or found by the implicit resolvers of _Loader."""
    if event.tag not in (None, "!"):
        return event.tag
    if event.implicit[0]:  # plain (unquoted)
        for tag, regexp in _Loader.yaml_implicit_resolvers.get(event.value[:1], ()):
            if regexp.match(event.value):
                return tag
    return _STR


def _construct_int(node: ScalarNode) -> int:
    text = node.value.replace("_", "")
    sign = -1 if text.startswith("-") else 1
    digits = text.lstrip("+-")
    if digits[:2] in ("0x", "0o"):
        return sign * int(digits[2:], 16 if digits[1] == "x" else 8)
    return sign * int(digits, 10)


_CONSTRUCTOR = yaml.constructor.SafeConstructor()
_SCALARS = {
    _INT: _construct_int,
    _FLOAT: _CONSTRUCTOR.construct_yaml_float,
    _BOOL: _CONSTRUCTOR.construct_yaml_bool,
    _NULL: lambda node: None,
    _MERGE: lambda node: "<<",  # only meaningful as a key, see _Builder.add
}

if getattr(yaml, "__with_libyaml__", False):

    class _FastLoader(yaml.CSafeLoader):
        """libyaml's parser with the resolvers of _Loader."""

        yaml_implicit_resolvers = _Loader.yaml_implicit_resolvers

else:  # pragma: no cover - PyYAML without libyaml
    _FastLoader = None  # type: ignore[assignment, misc]
