"""Generates the config reference (docs/config-reference.md) from the schema, so the
reference cannot drift from the code: `python -m pamd.config.docs > FILE`.
A test checks the committed file is current."""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import MISSING

from pamd.config.plugins import DRIVERS_GROUP, installed
from pamd.config.schema import RigConfig
from pamd.wire.schema.engine import _type_name

HEADER = """# pamd config reference

Generated from the schema by `python -m pamd.config.docs`; do not edit by hand.
Every key, its type, unit and default. Unknown keys are errors. Units are in the key
names. `pamd check-config FILE` validates a file and names file, line and key of
every problem.

Lists (`drivers`, `muscles`) hold one mapping per item; their keys are shown with
`[]`. A driver's `options` are validated by that driver type's own schema, listed
at the end per installed driver.

Bounds marked `relaxed` are hard maxima that apply only with `safety.relax_ceilings:
true`; without it the `<=` before them (the safe ceiling) is the limit. The ceilings
keep the checks they bound meaningful (a 10 s signal timeout is no stale check).
"""


def _default(f: dataclasses.Field[object]) -> str:
    if f.default is not MISSING:
        d = f.default
        if d is None:
            return "null"
        if isinstance(d, bool):
            return str(d).lower()
        return f"`{d}`"
    if f.default_factory is not MISSING:
        return "(section)" if dataclasses.is_dataclass(f.default_factory()) else "`{}`"
    return "**required**"


def _rows(cls: type, prefix: str, out: list[str]) -> None:
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        key = f"{prefix}{f.name}"
        inner = _dataclass_in(tp)
        doc = f.metadata.get("doc", "")
        if "old" in f.metadata:
            doc += f" Old name `{f.metadata['old']}`: still loads (never both)."
        unit = f.metadata.get("unit", "")
        if inner is not None:
            plural = typing.get_origin(tp) is tuple
            out.append(f"| `{key}` | {'list' if plural else 'section'} | | {_default(f)} | "
                       f"{doc} |")
            _rows(inner, f"{key}[]." if plural else f"{key}.", out)
            continue
        bounds = []
        for k, word in (("gt", ">"), ("min", ">="), ("ceiling", "<="), ("max", "<=")):
            if k in f.metadata:
                bounds.append(f"{word} {f.metadata[k]}")
        if "ceiling" in f.metadata:  # the max applies only with safety.relax_ceilings
            bounds[-1] += " relaxed"
        b = f" ({', '.join(bounds)})" if bounds else ""
        out.append(f"| `{key}` | {_type_name(tp)}{b} | {unit} | {_default(f)} | {doc} |")


def _dataclass_in(tp: object) -> type | None:
    if dataclasses.is_dataclass(tp):
        return tp  # type: ignore[return-value]
    for arg in typing.get_args(tp):
        if dataclasses.is_dataclass(arg):
            return arg  # type: ignore[return-value]
    return None


def _table(cls: type, prefix: str = "") -> list[str]:
    out = ["| key | type | unit | default | meaning |", "|---|---|---|---|---|"]
    _rows(cls, prefix, out)
    return out


def generate() -> str:
    lines = [HEADER, "## Rig config", ""] + _table(RigConfig) + [""]
    for name, ep in sorted(installed(DRIVERS_GROUP).items()):
        cls = ep.load()
        lines += [f"## Driver `{name}` options", "", (cls.__doc__ or "").strip().split("\n")[0],
                  ""]
        if dataclasses.fields(cls.options_type):
            lines += _table(cls.options_type, "options.")
        else:
            lines.append("No options.")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    print(generate(), end="")
