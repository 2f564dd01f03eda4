"""The model kinds pamd knows, found by a model file's ``kind``; the one place that
turns a model file (a path, its text or its parsed JSON) into a model.

Role: `load_model` is what every user of model files calls (`--model`, the `model`
command, a muscle's `model_file`, `pamd evaluate`); `save_model` writes any kind.
A file without a ``kind`` is an ANFIS file (``"format": "pamd-anfis"``, seed 000);
an unknown kind, a future version or a broken file raise `ModelError` naming the
file and the field.

Kinds (`KINDS`): each is declared once, in its own module, as a `pamd.models.kind.Kind`
(file reader, default inputs, training options and fit, adaptable or not, progress,
forward model, figures); `pamd train`, `pamd evaluate`, the feedforward's adaptation
check and the docs read the declarations. A new kind is its module and one `register`
line below: anfis (seed 000), ts-fuzzy (001), polynomial (002), sarosi (004), mlp and
svr (002; trained through scikit-learn, run on numpy-free arrays), qupi (003),
mamdani (001).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pamd.config.schema import MODEL_FILE_MAX_BYTES
from pamd.models import anfis_kind, fn_qupi, learned, qupi, static_force, ts_fuzzy
from pamd.models.anfis import modelfile as anfis_file
from pamd.models.contract import InverseModel
from pamd.models.document import field, format_json, parse_json
from pamd.models.domain import domain_of
from pamd.models.kind import Kind
from pamd.models.mamdani import KIND as MAMDANI
from pamd.wire.atomic import write_atomic
from pamd.wire.declare.jsonsafe import JsonValue
from pamd.wire.errors import ModelError

#: Largest model file read (bytes), declared with the config's `telemetry.models_dir`.
MAX_FILE_BYTES = MODEL_FILE_MAX_BYTES

#: The kinds by name, in the order help lists them (`register`).
# Any: kinds of different option types in one table (a `Kind` is invariant in them)
KINDS: dict[str, Kind[Any]] = {}


def register(kind: Kind[Any]) -> Kind[Any]:  # Any: as KINDS
    """Make `kind` known to every user of model kinds (files, train, evaluate, help)."""
    if kind.name in KINDS and KINDS[kind.name] is not kind:
        raise ModelError(f"model kind {kind.name!r} is declared twice")
    KINDS[kind.name] = kind
    return kind


def declared(name: str) -> Kind[Any]:  # Any: as KINDS
    """The declaration of kind `name`; ModelError lists the known kinds."""
    if name not in KINDS:
        raise ModelError(f"kind {name!r} is not known to this pamd (known: "
                         f"{', '.join(KINDS)})")
    return KINDS[name]


def adaptable(model: InverseModel) -> bool:
    """Whether online adaptation can update `model` (its kind says so)."""
    return model.kind in KINDS and KINDS[model.kind].adaptable


register(anfis_kind.KIND)
register(ts_fuzzy.KIND)
register(static_force.POLYNOMIAL)
register(static_force.SAROSI)
register(learned.MLP)
register(learned.SVR)
register(qupi.KIND)
register(fn_qupi.KIND)
register(MAMDANI)


def kind_of(doc: object) -> str:
    """The kind a parsed model file says it is (ANFIS files need not say)."""
    if not isinstance(doc, Mapping):
        raise ModelError("expected a JSON object")
    if "kind" not in doc:
        if doc.get("format") == anfis_file.FORMAT:
            return "anfis"
        raise ModelError(f"missing field kind (one of {', '.join(KINDS)})")
    kind = field(doc, "kind", str, "")
    if kind not in KINDS:
        raise ModelError(f"kind {kind!r} is not known to this pamd (known: "
                         f"{', '.join(KINDS)}); use a newer pamd or re-train the model")
    return kind


def model_from_dict(doc: object, source: str = "<document>") -> InverseModel:
    """A model from a parsed model file; `ModelError` names `source` and the field."""
    try:
        model = KINDS[kind_of(doc)].from_dict(doc)
        if "domain" in model.provenance:  # its training domain, checked (pamd.models.domain)
            domain_of(model)
        return model
    except ModelError as exc:
        raise ModelError(f"model file {source}: {exc}") from exc


def load_model(source: str | os.PathLike[str] | bytes | Mapping[str, JsonValue], *,
               name: str | None = None) -> InverseModel:
    """THE way to get a model: from a file path, the file's bytes (read by the caller,
    e.g. a remote command's checked file), or its parsed JSON. `name` labels errors
    (default: the path, or "<bytes>"/"<document>")."""
    if isinstance(source, Mapping):
        return model_from_dict(source, name or "<document>")
    if isinstance(source, bytes):
        label = name or "<bytes>"
        if len(source) > MAX_FILE_BYTES:
            raise ModelError(f"model file {label}: {len(source)} bytes is larger than any "
                             f"model file ({MAX_FILE_BYTES} at most)")
        try:
            text = source.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ModelError(f"model file {label}: not UTF-8 text ({exc})") from exc
        return model_from_dict(parse_json(text, label), label)
    p = Path(source)
    label = name or str(p)
    try:
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ModelError(f"model file {label}: {size} bytes is larger than any model "
                             f"file ({MAX_FILE_BYTES} at most)")
        data = p.read_bytes()
    except OSError as exc:
        raise ModelError(f"model file {label}: cannot read it ({exc})") from exc
    return load_model(data, name=label)


def dumps_model(model: InverseModel) -> str:
    """The model file text of any kind (indented JSON, short lists on one line)."""
    return format_json(model.to_dict(), 0) + "\n"


def save_model(model: InverseModel, path: str | os.PathLike[str]) -> Path:
    """Write any kind's model file whole or not at all (`pamd.wire.atomic`)."""
    target = Path(path)
    write_atomic(target, dumps_model(model))
    return target
