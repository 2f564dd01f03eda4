"""ANFIS model files: readable, versioned JSON (``"format": "pamd-anfis", "version": 1``).

Role: `save` and `load` an `AnfisModel`. Floats are written with Python's shortest
round-tripping repr (the json module's default), so `load(save(m))` predicts bit for
bit like `m`. Anything wrong with a file (not JSON, truncated, another format or
version, missing fields, wrong shapes, NaN/inf, non-positive widths) raises
`pamd.wire.errors.ModelError` with the file name and the field at fault.

Layout (version 1)::

    {
      "format": "pamd-anfis", "version": 1,
      "inputs":  [{"name": "force_n", "unit": "N", "range": [min, max]}, ...],
      "output":  {"name": "pressure_bar", "unit": "bar", "range": [min, max]},
      "derived_inputs": {"velocity_mm_s": {"derived_from": "length_mm", ...}},
      "scaling": {"method": "minmax" | "zscore", "offset": [...], "span": [...]},
      "membership": {"type": "gaussian" | "bell",
                     "inputs": [{"input": "force_n", "centres": [...],
                                 "widths": [...], ("slopes": [...])}, ...]},
      "rules": [{"mfs": [0, 0], "p": [p_1, ..., p_d], "q": q}, ...],
      ("consequent": "constant",  with rules [{"mfs": [0, 0], "q": q}, ...] and no "p";
       a ts-fuzzy file writes "p": [0, ...] in every rule, `serialize.ZERO_P_KINDS`)
      "provenance": {...free form: data files, runs, loads, training settings...},
      "metrics": {"train": {...}, "validation": {...}}
    }

Semantics: inputs are clipped to "range", scaled s = (x - offset) / span; MF
parameters are in scaled units (Gaussian: centre, sigma; bell: centre, a, b); rules
are the full grid in `itertools.product` order (last input fastest), "mfs" naming
each rule's MF index per input; rule output f = sum_i p_i s_i + q in the output
unit (f = q for ``"consequent": "constant"``, a zero-order model; a file without the
field is first order, as every file before the field was). Non-finite metric values
(undefined metrics) are written as null.
"""

from __future__ import annotations

import itertools
import math
import os
from pathlib import Path

from pamd.models.anfis.model import CONSEQUENTS, AnfisModel
from pamd.models.anfis.serialize import FORMAT as FORMAT  # re-exported: pamd.models.registry
from pamd.models.anfis.serialize import VERSION, to_dict
from pamd.models.document import field as _field
from pamd.models.document import format_json as _format
from pamd.models.document import mapping as _mapping
from pamd.models.document import numbers as _numbers
from pamd.models.document import parse_json
from pamd.models.document import variable as _variable
from pamd.wire.atomic import write_atomic
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import ModelError

#: Kinds stored in this layout (seed 001's TS fuzzy model is an ANFIS structure).
KINDS: tuple[str, ...] = ("anfis", "ts-fuzzy")


def dumps(model: AnfisModel) -> str:
    """The model file text: indented JSON with short lists and each rule on one line."""
    return _format(to_dict(model), 0) + "\n"






def save(model: AnfisModel, path: str | os.PathLike[str]) -> Path:
    """Write the model file whole or not at all (`pamd.wire.atomic`); returns the path."""
    target = Path(path)
    write_atomic(target, dumps(model))
    return target


def load(path: str | os.PathLike[str]) -> AnfisModel:
    """Read a model file; raise `ModelError` naming the file and the problem."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"model file {p}: cannot read it ({exc})") from exc
    return loads(text, source=str(p))




def loads(text: str, source: str = "<string>") -> AnfisModel:
    """Parse model file text; `source` names it in error messages."""
    doc = parse_json(text, source)
    try:
        return from_dict(doc)
    except ModelError as exc:
        raise ModelError(f"model file {source}: {exc}") from exc








def from_dict(doc: object) -> AnfisModel:
    """Build a model from a parsed version-1 document (checks everything)."""
    doc = _mapping(doc, "")
    kind = _kind(doc)
    raw_inputs = _field(doc, "inputs", list, "")
    inputs = [_variable(v, f"inputs[{i}]") for i, v in enumerate(raw_inputs)]
    d = len(inputs)
    if d == 0:
        raise ModelError("field inputs: no inputs")
    output = _variable(_field(doc, "output", dict, ""), "output")
    scaling = _field(doc, "scaling", dict, "")
    mf_type, centres, widths, slopes = _membership(_field(doc, "membership", dict, ""), d)
    consequent, consequents = _consequents(doc, centres, d)
    model = AnfisModel(
        inputs,
        output,
        mf_type=mf_type,
        scaling=_field(scaling, "method", str, "scaling"),
        scale_offset=_numbers(scaling, "offset", "scaling", d),
        scale_span=_numbers(scaling, "span", "scaling", d),
        centres=centres,
        widths=widths,
        slopes=slopes if mf_type == "bell" else None,
        consequents=consequents,
        derived_inputs=_optional_dict(doc, "derived_inputs"),
        provenance=_optional_dict(doc, "provenance"),
        metrics=_optional_dict(doc, "metrics"),
        consequent=consequent,
    )
    model.kind = kind
    return model


def _kind(doc: JsonObject) -> str:
    """The document's kind, once its format and version are this layout's."""
    fmt = _field(doc, "format", str, "")
    if fmt != FORMAT:
        raise ModelError(f"format is {fmt!r}, not {FORMAT!r}: not a pamd ANFIS model")
    kind: str = _field(doc, "kind", str, "") if "kind" in doc else "anfis"
    if kind not in KINDS:
        raise ModelError(f"kind {kind!r} is not stored in the {FORMAT} layout")
    version = _field(doc, "version", int, "")
    if version != VERSION:
        raise ModelError(
            f"version {version} is not supported (this pamd reads version {VERSION}); "
            "use a matching pamd or re-train the model"
        )
    return kind


def _membership(membership: JsonObject, d: int
                ) -> tuple[str, list[list[float]], list[list[float]], list[list[float]]]:
    """(MF type, centres, widths, slopes: bell only) of each of the `d` inputs."""
    mf_type: str = _field(membership, "type", str, "membership")
    mf_inputs = _field(membership, "inputs", list, "membership")
    if len(mf_inputs) != d:
        raise ModelError(f"field membership.inputs: expected {d} entries, got {len(mf_inputs)}")
    centres, widths, slopes = [], [], []
    for i, entry in enumerate(mf_inputs):
        where = f"membership.inputs[{i}]"
        c = _numbers(entry, "centres", where)
        centres.append(c)
        widths.append(_numbers(entry, "widths", where, len(c)))
        if mf_type == "bell":
            slopes.append(_numbers(entry, "slopes", where, len(c)))
    return mf_type, centres, widths, slopes


def _consequents(doc: JsonObject, centres: list[list[float]], d: int
                 ) -> tuple[str, list[list[float]]]:
    """(the consequent form, each rule's [p, q]): one rule for each cell of the MF grid,
    in grid order."""
    n_rules = math.prod(len(c) for c in centres)
    rules = _field(doc, "rules", list, "")
    if len(rules) != n_rules:
        raise ModelError(f"field rules: expected {n_rules} rules for the MF grid, got {len(rules)}")
    consequent: str = _field(doc, "consequent", str, "") if "consequent" in doc else "linear"
    if consequent not in CONSEQUENTS:
        raise ModelError(f"field consequent: {consequent!r} is not one of {CONSEQUENTS}")
    expected_mfs = _grid(tuple(len(c) for c in centres))
    return consequent, [_rule_row(rule, mfs, f"rules[{r}]", consequent, d)
                        for r, (rule, mfs) in enumerate(zip(rules, expected_mfs, strict=True))]


def _rule_row(rule: JsonValue, mfs: tuple[int, ...], where: str, consequent: str, d: int
              ) -> list[float]:
    """One rule's [p_1 .. p_d, q] (constant: p = 0, and written without p)."""
    if _field(rule, "mfs", list, where) != list(mfs):
        raise ModelError(f"field {where}.mfs: expected {list(mfs)} (grid order)")
    q = _field(rule, "q", (int, float), where)
    if not math.isfinite(q):
        raise ModelError(f"field {where}.q: non-finite number")
    if consequent == "linear":
        return [*_numbers(rule, "p", where, d), float(q)]
    if "p" in rule and any(v != 0.0 for v in _numbers(rule, "p", where, d)):
        raise ModelError(f"field {where}.p: a model with constant consequents has p = 0 "
                         "(f = q; written without p)")
    return [*([0.0] * d), float(q)]


def _optional_dict(doc: JsonObject, key: str) -> JsonObject:
    return _field(doc, key, dict, "") if key in doc else {}


def _grid(n_mfs: tuple[int, ...]) -> list[tuple[int, ...]]:

    return list(itertools.product(*(range(m) for m in n_mfs)))
