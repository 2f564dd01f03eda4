"""YAML loading that remembers where every key came from, and refuses, as a
ConfigError with file, line and key, every input that would otherwise end in a
traceback or a hang: bytes that are not UTF-8, control characters, numbers too long
to be a setting, nesting deeper than any config needs, aliases that expand beyond
any config's size (or into themselves), and keys that are not plain values.

Mappings load as `LinedDict`: a dict that also knows its own line and the line of
each key, so validation errors can name the line an operator has to edit. It is
declared in `pamd.wire.schema.engine`, beside what validates it, so that the io process
parses commands without loading this module or PyYAML.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import yaml

from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import ConfigError, ConfigIssue
from pamd.wire.schema.engine import LinedDict, LinedList

#: Deepest nesting of mappings and lists a file may have (a rig config needs 6).
MAX_DEPTH = 32
#: Most values a file may hold once its aliases are expanded (a rig config has hundreds).
MAX_VALUES = 100_000
#: Longest integer a setting may be written with (2**64 has 20 digits).
MAX_DIGITS = 40
#: Largest file read as a config, plan or calibration (the biggest shipped is ~5 KB).
MAX_BYTES = 1 << 20


class OversizedNumber:
    """An integer written with more digits than any setting has; validation names
    its key (it is never a valid value)."""

    def __init__(self, digits: int) -> None:
        self.digits = digits

    def __repr__(self) -> str:
        return f"a number of {self.digits} digits"


def _issue(file: str, line: int | None, path: str, expected: str, found: str) -> ConfigError:
    return ConfigError([ConfigIssue(file, line, path, expected, found)])


def _path_text(parts: list[str]) -> str:
    if len(parts) > 8:
        parts = [*parts[:4], "...", *parts[-2:]]
    return "".join(parts).lstrip(".")


class _Loader(yaml.SafeLoader):
    def __init__(self, text: str, file: str) -> None:
        super().__init__(text)  # reads (and checks) the first characters at once
        self.name = file
        self._path: list[str] = []

    # index: the item's position, the key node of a mapping value, or None for the root
    # (wider than the stub's `int`, as the composer calls it)
    def compose_node(self, parent: yaml.Node | None,
                     index: int | yaml.Node | None) -> yaml.Node | None:
        if isinstance(index, int):
            part = f"[{index}]"
        elif isinstance(index, yaml.ScalarNode):
            part = f".{index.value}"
        else:
            part = ""  # a key, or the root
        self._path.append(part)
        try:
            if len(self._path) > MAX_DEPTH + 1:
                peek: Callable[[], yaml.Event] = self.peek_event  # untyped in the stubs
                mark = peek().start_mark  # a parsed event has one
                raise _issue(self.name, mark.line + 1 if mark else None,
                             _path_text(self._path[:-1]),
                             f"nesting at most {MAX_DEPTH} levels deep",
                             "deeper nesting")
            # the stub types index as int only; the composer passes key nodes and None
            return super().compose_node(parent, index)  # type: ignore[arg-type]
        finally:
            self._path.pop()

    def get_single_node(self) -> yaml.Node | None:
        node = super().get_single_node()
        if node is not None:
            _check_expansion(node, self.name)
        return node


def _check_expansion(root: yaml.Node, file: str) -> None:
    """Walk the node graph once (shared anchors once, memoised): an alias inside its own
    anchor, or aliases that expand beyond MAX_VALUES or MAX_DEPTH, are refused."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = _children(node)
        if done:
            on_path.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in children)
            depth[key] = 1 + max((depth[id(c)] for c in children), default=0)
            line = node.start_mark.line + 1
            if size[key] > MAX_VALUES:
                raise _issue(file, line, "", f"at most {MAX_VALUES} values once aliases are "
                             "expanded", f"{size[key]} (write the values out instead)")
            if depth[key] > MAX_DEPTH + 1:
                raise _issue(file, line, "", f"nesting at most {MAX_DEPTH} levels deep once "
                             "aliases are expanded", f"{depth[key] - 1} levels")
            continue
        if key in size:
            continue
        if key in on_path:
            raise _issue(file, node.start_mark.line + 1, "",
                         "an alias (*name) outside the value its anchor (&name) marks",
                         "an alias inside its own anchor")
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in size)


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LinedDict:
    loader.flatten_mapping(node)
    out = LinedDict()
    out.line = node.start_mark.line + 1
    out.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if not isinstance(key, (str, int, float, bool)) and key is not None:
            raise _issue(loader.name, line, "", "a plain key (a name)",
                         "a mapping or list as a key")
        if key in out.key_lines:
            raise _issue(loader.name, line, str(key), "each key once", "a duplicate key")
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = line
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LinedList:
    out = LinedList(loader.construct_object(child, deep=True) for child in node.value)
    out.line = node.start_mark.line + 1
    out.item_lines = [child.start_mark.line + 1 for child in node.value]
    return out


def _construct_int(loader: _Loader, node: yaml.ScalarNode) -> int | OversizedNumber:
    digits = sum(ch.isalnum() for ch in str(node.value))
    if digits > MAX_DIGITS:
        return OversizedNumber(digits)
    return loader.construct_yaml_int(node)


# Numbers as YAML 1.2 writes them too: PyYAML (YAML 1.1) reads `1e12` and `5e-3` as text,
# which an operator would only meet as a puzzling "found '1e12' (text)".
_Loader.yaml_implicit_resolvers = {k: list(v) for k, v in
                                   yaml.SafeLoader.yaml_implicit_resolvers.items()}
_FLOAT_12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")
for _first in "-+0123456789":
    _Loader.yaml_implicit_resolvers.setdefault(_first, []).insert(
        0, ("tag:yaml.org,2002:float", _FLOAT_12))

_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)
_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)


def load_yaml_text(text: str, file: str) -> JsonValue:
    """Parse YAML text; every problem becomes a ConfigError with the line."""
    loader: _Loader | None = None
    try:
        loader = _Loader(text, file)
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else None
        raise _issue(file, line, "", "valid YAML", f"{exc.problem or exc}") from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        raise _issue(file, line, _key_on_line(text, line), "printable text",
                     f"the control character U+{exc.character:04X}") from None
    except RecursionError:  # not reachable within MAX_DEPTH; kept so no input can crash
        raise _issue(file, None, "", f"nesting at most {MAX_DEPTH} levels deep",
                     "deeper nesting") from None
    finally:
        if loader is not None:
            loader.dispose()


_KEY_RE = re.compile(r"^\s*(?:-\s+)?([^\s:#][^:#]*?)\s*:(?:\s|$)")


def _key_on_line(text: str, line: int) -> str:
    """The key written on 1-based `line` of `text`, if one is ("" if not)."""
    lines = text.splitlines()
    if 0 < line <= len(lines):
        m = _KEY_RE.match(lines[line - 1])
        if m:
            return m.group(1).strip("'\"")
    return ""


def read_text(path: str, what: str = "a readable YAML file") -> str:
    """A file's text; a missing, unreadable, oversized or non-UTF-8 file is a
    ConfigError saying why (and, for bad bytes, where)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise _issue(path, None, "", what, exc.strerror or str(exc)) from None
    if len(data) > MAX_BYTES:
        raise _issue(path, None, "", f"{what} of at most {MAX_BYTES // 1024} KiB",
                     "a larger file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        shown = data.decode("utf-8", errors="replace")
        raise _issue(path, line, _key_on_line(shown, line), "UTF-8 text",
                     f"the byte 0x{data[exc.start]:02x}, which is not UTF-8 (save the "
                     "file as UTF-8)") from None


def load_yaml_file(path: str) -> JsonValue:
    """Read and parse a YAML file; a missing or unreadable file is a ConfigError."""
    return load_yaml_text(read_text(path), path)
