"""The validation engine: YAML values -> frozen dataclasses, with every problem
reported by file, line and key path.

A schema is a frozen dataclass whose fields carry metadata: `doc` (one sentence),
optional `unit`, `min`, `max` (inclusive) and `gt` (exclusive lower bound), `why` (the
physics of the bounds, said with a value outside them), always
within the domain of the field's unit (`pamd.wire.schema.domains`: every number has one), and
`ceiling`: a safe upper value below `max` that only `safety.relax_ceilings: true` lets a
value pass (values above it are collected in `Context.over_ceiling`, never silently).
Supported field types: bool, int, float, str, Literal[...], X | None, nested
dataclasses, tuple[X, ...] and dict[str, Any] (kept raw, validated later by
whoever owns it: driver options are validated with the driver's own dataclass).
Unknown keys are errors. A field renamed keeps its old key as `old` (`spec("sine", "...",
old="kind")`): a file that says the old key still loads, one that says both is refused
at the second key's line. The same metadata generates the config reference.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import types
import typing
from dataclasses import MISSING, dataclass, field
from typing import Any, Literal, Union

from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import ConfigError, ConfigIssue
from pamd.wire.schema.domains import FieldMeta, bounds, subnormal

#: A field's type as the schema writes it: a class (bool, int, float, str, a dataclass),
#: `X | None`, `Literal[...]`, `tuple[X, ...]`, `dict[str, Any]` or `Any`.
SchemaType = object
#: a schema's dataclass
_D = typing.TypeVar("_D")

#: What a key in a YAML mapping may be (a plain value; lists and mappings are refused).
YamlKey = str | int | float | bool | None


class LinedDict(dict[YamlKey, JsonValue]):  # a YAML mapping: its keys need not be strings
    """A mapping from YAML with `line` (its own) and `key_lines` (per key), 1-based."""

    line: int | None = None
    key_lines: dict[YamlKey, int]


class LinedList(list[JsonValue]):
    """A sequence from YAML with `line` and `item_lines`, 1-based."""

    line: int | None = None
    item_lines: list[int]


# Any: as `dataclasses.field`, so that `rate_hz: float = spec(...)` type-checks
def spec(default: object = MISSING, doc: str = "", **meta: object) -> Any:
    """A schema field: `spec(1000.0, "Loop rate.", unit="Hz", gt=0)`."""
    meta["doc"] = doc
    if isinstance(default, (list, dict)):
        raise TypeError("use tuples or default_factory for mutable defaults")
    if dataclasses.is_dataclass(default):
        return field(default_factory=lambda: default, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass
class Context:
    """Where we are: the file being validated and the problems found so far."""

    file: str
    issues: list[ConfigIssue] = field(default_factory=list)
    #: values within their bounds but above their safe `ceiling` (the loader decides)
    over_ceiling: list[ConfigIssue] = field(default_factory=list)

    def add(self, line: int | None, path: str, expected: str, found: str = "") -> None:
        self.issues.append(ConfigIssue(self.file, line, path, expected, found))

    def raise_if_any(self) -> None:
        if self.issues:
            raise ConfigError(self.issues)


def describe(value: object) -> str:
    """How a found value is shown to the operator."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, (dict,)):
        return "a mapping"
    if isinstance(value, (list,)):
        return "a list"
    if isinstance(value, str):
        return f"{value!r} (text)"
    return repr(value)


def _type_name(tp: SchemaType) -> str:
    if tp is Any:  # Any: the schema type of a mapping kept raw (a driver's options)
        return "a mapping (checked by its owner)"
    origin = typing.get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return " or ".join(_type_name(a) for a in args) + " or null"
    if origin is tuple:
        return f"a list of {_type_name(typing.get_args(tp)[0])}"
    if origin is dict:
        return "a mapping"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    names: dict[object, str] = {bool: "true or false", int: "an integer", float: "a number",
                                str: "text"}
    return names.get(tp, str(tp))


def _bounds_text(meta: FieldMeta) -> str:
    unit = f" {meta['unit']}" if meta.get("unit") else ""
    parts = []
    if "gt" in meta:
        parts.append(f"greater than {meta['gt']}{unit}")
    if "min" in meta:
        parts.append(f"at least {meta['min']}{unit}")
    if "ceiling" in meta:
        parts.append(f"at most {meta['ceiling']}{unit} ({meta['max']}{unit} with "
                     "safety.relax_ceilings: true)")
    elif "max" in meta:
        parts.append(f"at most {meta['max']}{unit}")
    return " and ".join(parts)


# Any: the built value is of the type `tp` names at run time (a YAML value checked
# here), which the caller's field declares
def build(tp: SchemaType, value: object, ctx: Context, path: str, line: int | None,
          meta: FieldMeta | None = None) -> Any:  # Any: see above
    """Validate `value` against type `tp`; record issues in ctx; return the built
    value (or None where it was invalid)."""
    return _builder(tp)(tp, value, ctx, path, line, meta or {})


class _Builder(typing.Protocol):
    """Builds a value of one sort of schema type (the arguments as `build` takes them)."""

    # Any: as `build`: the value of the type `tp` names at run time
    def __call__(self, tp: SchemaType, value: object, ctx: Context, path: str,
                 line: int | None, meta: FieldMeta) -> Any: ...  # Any: see above


def _builder(tp: SchemaType) -> _Builder:
    """The builder for the sort of schema type `tp` is."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        return _build_optional
    if origin is Literal:
        return _build_literal
    if origin is tuple:
        return _build_tuple
    if tp is Any:  # Any: a mapping kept raw, checked later by its owner
        return _build_raw
    if origin is dict or tp is dict:
        return _build_mapping
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _build_nested
    return _SCALAR_BUILDERS.get(tp, _unsupported)


def _build_optional(tp: SchemaType, value: object, ctx: Context, path: str,
                    line: int | None, meta: FieldMeta) -> object:
    """`X | None`: null stays None, anything else is built as X."""
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if value is None:
        return None
    return build(args[0], value, ctx, path, line, meta)


def _build_literal(tp: SchemaType, value: object, ctx: Context, path: str,
                   line: int | None, meta: FieldMeta) -> object:
    """`Literal[...]`: one of the allowed values (a boolean never stands for a number)."""
    allowed = typing.get_args(tp)
    if value not in allowed or isinstance(value, bool) != isinstance(allowed[0], bool):
        ctx.add(line, path, _type_name(tp), describe(value))
        return None
    return value


def _build_tuple(tp: SchemaType, value: object, ctx: Context, path: str,
                 line: int | None, meta: FieldMeta) -> object:
    """`tuple[X, ...]`: a list, each item built as X at its own line."""
    if not isinstance(value, list):
        ctx.add(line, path, _type_name(tp), describe(value))
        return None
    item_tp = typing.get_args(tp)[0]
    lines = getattr(value, "item_lines", [line] * len(value))
    return tuple(
        build(item_tp, v, ctx, f"{path}[{i}]", lines[i]) for i, v in enumerate(value)
    )


def _build_raw(tp: SchemaType, value: object, ctx: Context, path: str,
               line: int | None, meta: FieldMeta) -> object:
    """`Any`: kept as it is, checked later by its owner."""
    return value


def _build_mapping(tp: SchemaType, value: object, ctx: Context, path: str,
                   line: int | None, meta: FieldMeta) -> object:
    """`dict[str, Any]`: any mapping, kept raw."""
    if not isinstance(value, dict):
        ctx.add(line, path, "a mapping", describe(value))
        return None
    return value


def _build_nested(tp: SchemaType, value: object, ctx: Context, path: str,
                  line: int | None, meta: FieldMeta) -> object:
    """A nested dataclass."""
    assert isinstance(tp, type)
    return build_dataclass(tp, value, ctx, path, line)


def _build_bool(tp: SchemaType, value: object, ctx: Context, path: str,
                line: int | None, meta: FieldMeta) -> object:
    if not isinstance(value, bool):
        ctx.add(line, path, "true or false", describe(value))
        return None
    return value


def _build_str(tp: SchemaType, value: object, ctx: Context, path: str,
               line: int | None, meta: FieldMeta) -> object:
    if not isinstance(value, str):
        ctx.add(line, path, "text", describe(value))
        return None
    return value


def _build_number(tp: SchemaType, value: object, ctx: Context, path: str,
                  line: int | None, meta: FieldMeta) -> object:
    """An int or a float: of that type (never a boolean), finite and of a physical size
    (floats), within its bounds; above its safe ceiling is noted in ctx.over_ceiling."""
    ok = isinstance(value, int) if tp is int else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok or not isinstance(value, (int, float)):
        ctx.add(line, path, _type_name(tp) + _unit_suffix(meta), describe(value))
        return None
    if tp is float:
        value = float(value)
        if not _float_is_physical(value, ctx, path, line):
            return None
    meta = bounds(typing.cast(type, tp), meta)
    if not _within_bounds(value, meta, ctx, path, line):
        return None
    _note_over_ceiling(value, meta, ctx, path, line)
    return value


def _float_is_physical(value: float, ctx: Context, path: str, line: int | None) -> bool:
    """Whether a float is finite and not subnormal (reported in ctx when not)."""
    if not math.isfinite(value):
        ctx.add(line, path, "a finite number", describe(value))
        return False
    if subnormal(value):
        ctx.add(line, path, "a number of a physical size (0, or at least 2.2e-308 in "
                "magnitude)", describe(value))
        return False
    return True


def _within_bounds(value: float, meta: FieldMeta, ctx: Context, path: str,
                   line: int | None) -> bool:
    """Whether a number lies within its `gt`, `min` and `max` (reported when not)."""
    bad = (
        ("gt" in meta and not value > meta["gt"])
        or ("min" in meta and value < meta["min"])
        or ("max" in meta and value > meta["max"])
    )
    if bad:
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        why = f" ({meta['why']})" if meta.get("why") else ""
        ctx.add(line, path, f"a value {_bounds_text(meta)}{why}", f"{value}{unit}")
    return not bad


def _note_over_ceiling(value: float, meta: FieldMeta, ctx: Context, path: str,
                       line: int | None) -> None:
    """A number above its safe `ceiling` goes to ctx.over_ceiling (the loader decides)."""
    if "ceiling" in meta and value > meta["ceiling"]:
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        ctx.over_ceiling.append(ConfigIssue(
            ctx.file, line, path, f"at most {meta['ceiling']}{unit} (the safe ceiling; "
            "`safety.relax_ceilings: true` allows up to "
            f"{meta.get('max', 'any')}{unit})", f"{value}{unit}"))


def _unsupported(tp: SchemaType, value: object, ctx: Context, path: str,
                 line: int | None, meta: FieldMeta) -> object:
    raise TypeError(f"schema type {tp!r} at {path} is not supported")


_SCALAR_BUILDERS: dict[object, _Builder] = {
    bool: _build_bool, str: _build_str, int: _build_number, float: _build_number,
}


def _unit_suffix(meta: FieldMeta) -> str:
    return f" in {meta['unit']}" if meta.get("unit") else ""


def build_dataclass(cls: type[_D], value: object, ctx: Context, path: str, line: int | None
                    ) -> _D | None:
    """Validate a mapping against dataclass `cls`: unknown keys, missing keys, each
    field's type and bounds. Returns an instance (invalid fields left at default), or
    None where the value is no mapping or a required field is invalid (both reported
    in ctx: after `ctx.raise_if_any()` the instance is there)."""
    if value is None:
        value = LinedDict()
        value.line, value.key_lines = line, {}
    if not isinstance(value, dict):
        ctx.add(line, path, f"a mapping of {cls.__name__} keys", describe(value))
        return None
    key_lines = getattr(value, "key_lines", {})
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"schema type {cls!r} at {path or 'the root'} is not a dataclass")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    hints = typing.get_type_hints(cls)
    prefix = f"{path}." if path else ""
    olds = {f.metadata["old"]: name for name, f in fields.items() if "old" in f.metadata}
    _report_unknown_keys(value, list(fields), ctx, prefix, line, olds)
    kwargs: dict[str, object] = {}  # the fields' built values
    for name, f in fields.items():
        key = _key_given(value, name, f, ctx, prefix)
        if key is None:
            if f.default is MISSING and f.default_factory is MISSING:
                ctx.add(getattr(value, "line", line), f"{prefix}{name}",
                        f"key {name!r}: {f.metadata.get('doc', '')}".rstrip(": "), "it missing")
            continue
        key_line = key_lines.get(key, getattr(value, "line", line))
        built = build(hints[name], value[key], ctx, f"{prefix}{key}", key_line,
                      field_meta(f))
        if built is not None or value[key] is None:
            kwargs[name] = built
    try:
        return cls(**kwargs)
    except TypeError:
        return None  # a required field was invalid; already reported



def _key_given(value: dict[YamlKey, JsonValue], name: str, f: dataclasses.Field[object],
               ctx: Context, prefix: str) -> str | None:
    """The key `value` gives field `f` by: its name, its old name (`old`), or None; both
    given is refused at the later one's line (which of the two is meant is unsaid)."""
    old = f.metadata.get("old")
    if old is None or old not in value:
        return name if name in value else None
    if name in value:
        key_lines = getattr(value, "key_lines", {})
        later = max((name, old), key=list(value).index)  # the file's order
        ctx.add(key_lines.get(later, getattr(value, "line", None)), f"{prefix}{later}",
                f"{name!r} or its old name {old!r}, not both", "both given")
    return str(old)


def _report_unknown_keys(value: dict[YamlKey, JsonValue], known: list[str], ctx: Context,
                         prefix: str, line: int | None, olds: dict[str, str]) -> None:
    """Each key of `value` that is none of `known` (nor an old name of one, `olds`),
    with the nearest known one."""
    key_lines = getattr(value, "key_lines", {})
    for key in value:
        if key not in known and key not in olds:
            near = _closest(str(key), known)
            hint = f" (did you mean {near!r}?)" if near else ""
            ctx.add(
                key_lines.get(key, getattr(value, "line", line)),
                f"{prefix}{key}",
                f"one of the known keys {', '.join(known)}{hint}",
                "an unknown key",
            )


def field_meta(f: dataclasses.Field[object]) -> FieldMeta:
    """The metadata `spec` gave field `f` (a read-only mapping of those keys)."""
    return typing.cast(FieldMeta, f.metadata)


def _closest(word: str, choices: list[str]) -> str | None:

    found = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return found[0] if found else None


def line_at(root: object, path: str) -> int | None:
    """The line of a dotted key path (`muscles[0].control.pid`) in a loaded file, or of
    the deepest mapping or item on it that is present."""
    node, line = root, line_of(root)
    for part in path.split("."):
        name, _, index = part.partition("[")
        if not isinstance(node, dict) or name not in node:
            break
        line = line_of(node, name) or line
        node = node[name]
        if index:
            k = int(index.rstrip("]"))
            if not isinstance(node, list) or k >= len(node):
                break
            node = node[k]
            line = line_of(node) or line
    return line


def line_of(node: object, key: str | None = None) -> int | None:
    """The line of `key` in a loaded mapping, or of the node itself."""
    if key is not None and isinstance(node, LinedDict):
        return node.key_lines.get(key, node.line)
    if isinstance(node, (LinedDict, LinedList)):
        return node.line
    return None
