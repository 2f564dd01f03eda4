"""Write numbers (and words: a type's name, a file name) into a YAML config file's text
in place, keeping its comments and layout: `set_values(text, {("control", "pid", "kp"):
0.5, ...})`.

A path element `[NAME]` selects the item of a list whose `name` is NAME (a muscle:
`("muscles", "[m1]", "control", "pid", "kp")`).
A key that is present has its scalar's text replaced (block or flow style); an absent
key is inserted into its mapping (a line in a block mapping, `, key: value` in a flow
one), creating absent sections the same way. The result is parsed back and must hold
exactly the new values and everything else unchanged; where that cannot be done,
`YamlEditError` says why (the caller writes an overrides file instead).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping

import yaml

from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import PamdError

KeyPath = tuple[str, ...]
#: what a key may be set to: a number, or a word (a muscle's type, a file's name)
Value = float | str
#: a word written plain (unquoted) where YAML reads it back as the same string
_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_./-]*")


class YamlEditError(PamdError):
    """The file's text cannot be edited in place safely."""


def format_value(value: Value) -> str:
    """A number: three significant digits, never in exponent form (YAML 1.1 reads
    `1e+03` as a string). A word: plain where YAML reads it back as that word, else
    double-quoted (JSON's quoting is YAML's)."""
    if isinstance(value, str):
        plain = _PLAIN.fullmatch(value) is not None and yaml.safe_load(value) == value
        return value if plain else json.dumps(value)
    text = f"{value:.3g}"
    return f"{float(text):f}".rstrip("0") if "e" in text else text


def parsed_value(value: Value) -> JsonValue:
    """What YAML reads back for `value` as `format_value` writes it."""
    loaded: JsonValue = yaml.safe_load(format_value(value))
    return loaded if isinstance(value, str) else float(loaded)


def change_row(key: str, width: int, old: float, value: float) -> str:
    """One row of a "present / new / change" table: the new value as it is saved
    (`format_value`), its change from the present one counted on that."""
    saved = format_value(value)
    change = f"{100 * (float(saved) - old) / old:+.0f} %" if old else "new"
    return f"  {key:{width}s} {old:10.4g} {saved:>10s} {change:>8s}"


def set_values(text: str, values: Mapping[KeyPath, Value]) -> str:
    """`text` with each key path set to its value (see the module's doc)."""
    out = text
    for path, value in values.items():
        out = _set_one(out, path, format_value(value))
    _verify(text, out, values)
    return out


def _compose(text: str) -> yaml.MappingNode:
    try:
        root = yaml.compose(text)
    except yaml.YAMLError as exc:
        raise YamlEditError(f"not valid YAML: {exc}") from None
    if not isinstance(root, yaml.MappingNode):
        raise YamlEditError("the file is not a mapping")
    return root


def _child(node: yaml.MappingNode, key: str) -> tuple[yaml.Node, yaml.Node] | None:
    for k, v in node.value:
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            return k, v
    return None


def _item_name(key: str) -> str | None:
    return key[1:-1] if key.startswith("[") and key.endswith("]") else None


def _item(node: yaml.SequenceNode, name: str) -> yaml.MappingNode | None:
    for item in node.value:
        if isinstance(item, yaml.MappingNode):
            found = _child(item, "name")
            if found is not None and isinstance(found[1], yaml.ScalarNode) and \
                    found[1].value == name:
                return item
    return None


def _set_one(text: str, path: KeyPath, value: str) -> str:
    node = _compose(text)
    depth = 0
    while depth < len(path):
        key = path[depth]
        found = _child(node, key)
        if found is None:
            return _insert(text, node, path[depth:], value, depth)
        _, child = found
        if depth == len(path) - 1:
            if not isinstance(child, yaml.ScalarNode) or child.style not in (None, ""):
                raise YamlEditError(f"{'.'.join(path)} is not a plain number or word in the file")
            a, b = child.start_mark.index, child.end_mark.index
            return text[:a] + value + text[b:]
        name = _item_name(path[depth + 1])
        if name is not None:  # a list item by its name
            item = _item(child, name) if isinstance(child, yaml.SequenceNode) else None
            if item is None:
                raise YamlEditError(f"{key} has no item named {name!r}")
            node, depth = item, depth + 2
            continue
        if not isinstance(child, yaml.MappingNode):
            raise YamlEditError(f"{'.'.join(path[:depth + 1])} is not a section (mapping)")
        node, depth = child, depth + 1
    raise YamlEditError(f"{'.'.join(path)}: an empty key path")


def _nested(keys: KeyPath, value: str) -> JsonValue:
    return value if not keys else {keys[0]: _nested(keys[1:], value)}


def _insert(text: str, node: yaml.MappingNode, keys: KeyPath, value: str,
            depth: int) -> str:
    """Insert `keys` (the first is absent from `node`) with `value` into `node`."""
    if node.flow_style:
        end = node.end_mark.index - 1  # the closing brace
        if text[end] != "}":
            raise YamlEditError("a flow mapping that does not end with '}'")
        inner = _flow(keys, value)
        sep = ", " if node.value else ""
        return text[:end].rstrip() + sep + inner + text[end:]
    if node.value:
        first_key = node.value[0][0]
        indent = first_key.start_mark.column
        at = _last_end(node.value[-1][1])
        # after the line the last value ends on
        line_end = text.find("\n", at - 1 if text[at - 1:at] == "\n" else at)
        at = len(text) if line_end < 0 else line_end + 1
    else:
        if depth != 0:
            raise YamlEditError("an empty section to insert into")
        indent, at = 0, len(text)
    block = _block(keys, value, indent)
    prefix = "" if at == 0 or text[at - 1] == "\n" else "\n"
    return text[:at] + prefix + block + text[at:]


def _last_end(node: yaml.Node) -> int:
    """Where the last scalar (or flow collection) of `node` ends: a block collection's
    own end mark runs on over the comments after it, up to the next key."""
    while isinstance(node, (yaml.MappingNode, yaml.SequenceNode)) and not node.flow_style \
            and node.value:
        last = node.value[-1]
        node = last[1] if isinstance(last, tuple) else last
    return int(node.end_mark.index)


def _flow(keys: KeyPath, value: str) -> str:
    if len(keys) == 1:
        return f"{keys[0]}: {value}"
    return f"{keys[0]}: {{{_flow(keys[1:], value)}}}"


def _block(keys: KeyPath, value: str, indent: int) -> str:
    pad = " " * indent
    if len(keys) == 1:
        return f"{pad}{keys[0]}: {value}\n"
    return f"{pad}{keys[0]}:\n" + _block(keys[1:], value, indent + 2)


def _verify(before: str, after: str, values: Mapping[KeyPath, Value]) -> None:
    """The edited text must parse to the original data with exactly the new values."""
    try:
        want = yaml.safe_load(before) or {}
        got = yaml.safe_load(after)
    except yaml.YAMLError as exc:
        raise YamlEditError(f"the edit would not be valid YAML ({exc})") from None
    for path, value in values.items():
        node = want
        for key in path[:-1]:
            name = _item_name(key)
            if name is not None and isinstance(node, list):
                node = next((i for i in node if isinstance(i, dict) and i.get("name") == name),
                            None)
            elif isinstance(node, dict):
                node = node.setdefault(key, {}) if _item_name(key) is None else None
            if not isinstance(node, (dict, list)):
                raise YamlEditError(f"{'.'.join(path)}: not a section")
        if not isinstance(node, dict):
            raise YamlEditError(f"{'.'.join(path)}: not a section")
        node[path[-1]] = parsed_value(value)
    if got != want:
        raise YamlEditError("the edit would change more than the tuned keys")
