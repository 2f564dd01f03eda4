"""An `AnfisModel` as its version-1 document (the layout is in `modelfile`, which
reads it back): apart from the reader, so that the model can write itself without
an import cycle."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pamd.models.document import floats as _floats
from pamd.models.document import plain as _plain
from pamd.wire.declare.jsonsafe import JsonObject

if TYPE_CHECKING:
    from pamd.models.anfis.model import AnfisModel

FORMAT = "pamd-anfis"
VERSION = 1
#: Kinds whose constant-consequent files keep a zero ``p`` in every rule and the
#: ``consequent`` field after ``kind``: seed 001's singleton TS files were written so
#: (#28) before ANFIS had constant consequents, whose files carry no ``p`` and the field
#: after ``version``. Both are version 1 and read alike; each kind writes its own, so a
#: file read and written back is the same byte for byte.
ZERO_P_KINDS: frozenset[str] = frozenset({"ts-fuzzy"})


def to_dict(model: AnfisModel) -> JsonObject:
    """The version-1 document for `model` (plain Python values only)."""
    mf_inputs = []
    for i, v in enumerate(model.inputs):
        entry: JsonObject = {
            "input": v.name,
            "centres": _floats(model.centres[i]),
            "widths": _floats(model.widths[i]),
        }
        if model.slopes is not None:
            entry["slopes"] = _floats(model.slopes[i])
        mf_inputs.append(entry)
    linear = model.consequent == "linear"
    with_p = linear or model.kind in ZERO_P_KINDS
    rules = [
        {"mfs": list(mfs), "p": _floats(row[:-1]), "q": float(row[-1])} if with_p
        else {"mfs": list(mfs), "q": float(row[-1])}
        for mfs, row in zip(model.rule_mfs, model.consequents, strict=True)
    ]
    head: JsonObject = {"format": FORMAT}
    if model.kind != "anfis":  # ANFIS files stay as they were (no kind field)
        head["kind"] = model.kind
    if not linear and model.kind in ZERO_P_KINDS:
        head["consequent"] = model.consequent
    head["version"] = VERSION
    if not linear:  # linear files stay as they were (no consequent field)
        head.setdefault("consequent", model.consequent)
    return {
        **head,
        "inputs": [
            {"name": v.name, "unit": v.unit, "range": [float(v.min), float(v.max)]}
            for v in model.inputs
        ],
        "output": {
            "name": model.output.name,
            "unit": model.output.unit,
            "range": [float(model.output.min), float(model.output.max)],
        },
        "derived_inputs": _plain(model.derived_inputs),
        "scaling": {
            "method": model.scaling,
            "offset": _floats(model.scale_offset),
            "span": _floats(model.scale_span),
        },
        "membership": {"type": model.mf_type, "inputs": mf_inputs},
        "rules": rules,
        "provenance": _plain(model.provenance),
        "metrics": _plain(model.metrics),
    }
