"""Shared pieces of pamd's model files: readable JSON, checked field by field.

Role: the writing (`plain`, `format_json`) and the checked reading (`field`,
`numbers`, `variable`, `parse_json`) that every kind's file uses, and the common
layout of the kinds after ANFIS (`header`, `read_header`)::

    {
      "format": "pamd-model", "kind": KIND, "version": 1,
      "inputs":  [{"name": "force_n", "unit": "N", "range": [min, max]}, ...],
      "output":  {"name": "pressure_bar", "unit": "bar", "range": [min, max]},
      "derived_inputs": {...}, "parameters": {...the kind's own...},
      "provenance": {...}, "metrics": {...}
    }

Problems raise `pamd.wire.errors.ModelError` naming the field; the registry adds the file.
ANFIS files keep their own layout (``"format": "pamd-anfis"``, `pamd.models.anfis.modelfile`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import NoReturn, SupportsFloat, TypeGuard, TypeVar, overload

from pamd.models.contract import InverseModel, Variable
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError

FORMAT = "pamd-model"

T = TypeVar("T")


def floats(values: Iterable[SupportsFloat]) -> list[float]:
    return [float(v) for v in values]


def plain(obj: object) -> JsonValue:
    """Free-form dicts -> JSON-safe values (numpy scalars/arrays, non-finite -> null)."""
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if hasattr(obj, "tolist"):  # numpy array or scalar
        return plain(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if obj is None or isinstance(obj, (str, int, float, bool)):
        return obj
    return str(obj)


def format_json(obj: object, level: int, in_list: bool = False) -> str:
    """JSON text: objects (to depth 3, not inside lists) and lists holding objects or
    lists span lines; other lists and list items stay on one line each."""
    pad, inner = "  " * level, "  " * (level + 1)
    if isinstance(obj, dict) and obj and level < 3 and not in_list:
        items = [f"{inner}{json.dumps(k)}: {format_json(v, level + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if _is_nested_list(obj):
        items = [inner + format_json(v, level + 1, in_list=True) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    return json.dumps(obj, allow_nan=False)


def _is_nested_list(obj: object) -> TypeGuard[list[JsonValue]]:
    return isinstance(obj, list) and any(isinstance(v, (dict, list)) for v in obj)


def _reject_constant(name: str) -> NoReturn:
    raise ValueError(f"non-finite number {name}")


def mapping(doc: object, where: str) -> JsonObject:
    """`doc` as a JSON object; ModelError if it is not one."""
    if not isinstance(doc, dict):
        raise ModelError(f"{where or 'document'}: expected an object")
    return doc


@overload
def field(doc: object, key: str, kind: type[T], where: str) -> T: ...
@overload
def field(doc: object, key: str, kind: tuple[type[int], type[float]], where: str) -> float: ...
def field(doc: object, key: str, kind: type | tuple[type, ...], where: str) -> object:
    """`doc[key]`, checked to be of `kind` (a bool is not a number)."""
    doc = mapping(doc, where)
    if key not in doc:
        raise ModelError(f"missing field {where + '.' if where else ''}{key}")
    value = doc[key]
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        names = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise ModelError(
            f"field {where + '.' if where else ''}{key}: expected {names}, "
            f"got {type(value).__name__}"
        )
    return value


def numbers(doc: object, key: str, where: str, length: int | None = None) -> list[float]:
    values = field(doc, key, list, where)
    label = f"{where}.{key}" if where else key
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ModelError(f"field {label}: expected numbers, found {v!r}")
        if not math.isfinite(v):
            raise ModelError(f"field {label}: non-finite number {v!r}")
    if length is not None and len(values) != length:
        raise ModelError(f"field {label}: expected {length} numbers, got {len(values)}")
    return [float(v) for v in values]


def variable(doc: object, where: str) -> Variable:
    lo, hi = numbers(doc, "range", where, 2)
    return Variable(field(doc, "name", str, where), field(doc, "unit", str, where), lo, hi)


def parse_json(text: str, source: str) -> JsonValue:
    """Parsed JSON; NaN/Infinity and broken text refused (`ModelError` naming `source`)."""
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except ValueError as exc:
        truncated = isinstance(exc, json.JSONDecodeError) and exc.pos >= len(text.rstrip())
        hint = " (the file looks truncated)" if truncated else ""
        raise ModelError(f"model file {source}: not valid JSON{hint}: {exc}") from exc


def header(model: InverseModel, kind: str, version: int) -> JsonObject:
    """The common part of a kind's document (parameters go in between)."""
    return {
        "format": FORMAT, "kind": kind, "version": version,
        "inputs": [{"name": v.name, "unit": v.unit, "range": [float(v.min), float(v.max)]}
                   for v in model.inputs],
        "output": {"name": model.output.name, "unit": model.output.unit,
                   "range": [float(model.output.min), float(model.output.max)]},
        "derived_inputs": plain(model.derived_inputs),
    }


def footer(model: InverseModel) -> JsonObject:
    return {"provenance": plain(model.provenance), "metrics": plain(model.metrics)}


def read_header(doc: object, kind: str, version: int
                ) -> tuple[list[Variable], Variable, JsonObject, JsonObject,
                           JsonObject, JsonObject]:
    """(inputs, output, derived_inputs, parameters, provenance, metrics) of a document
    of `kind`, its version checked."""
    doc = mapping(doc, "")
    got = field(doc, "version", int, "")
    if got != version:
        raise ModelError(f"{kind} model version {got} is not supported (this pamd reads "
                         f"version {version}); use a matching pamd or re-train the model")
    raw_inputs = field(doc, "inputs", list, "")
    inputs = [variable(v, f"inputs[{i}]") for i, v in enumerate(raw_inputs)]
    if not inputs:
        raise ModelError("field inputs: no inputs")
    for v in [*inputs]:
        if not v.max >= v.min:
            raise ModelError(f"input {v.name}: range {v.min}..{v.max} is empty")
    output = variable(field(doc, "output", dict, ""), "output")
    params = field(doc, "parameters", dict, "")

    def opt(key: str) -> JsonObject:
        return field(doc, key, dict, "") if key in doc else {}

    return inputs, output, opt("derived_inputs"), params, opt("provenance"), opt("metrics")
