"""Generates docs/fields-reference.md from the field table, the event registry and the
old names still served (`deprecated`), so the reference cannot drift from the code:
`python -m pamd.wire.declare.fields_doc > FILE`. A test checks the committed file is
current."""

from __future__ import annotations

from pamd.wire.declare import deprecated, events, fields

HEADER = """# pamd fields and events reference

Generated from `pamd/wire/declare/fields.py`, `pamd/wire/declare/events.py` and
`pamd/wire/declare/deprecated.py` by `python -m pamd.wire.declare.fields_doc`; do not
edit by hand.

What pamd records and publishes. Per tick: one loop message
(`/pamd/<rig>/loop`, `pamd_msgs/msg/LoopTiming`) and one message per muscle
(`/pamd/<rig>/state/<muscle>`, `pamd_msgs/msg/MuscleState`), both ROS 2 CDR in
MCAP and on Zenoh; the exports (`pamd export --csv/--mat`, the Python API) have the
same columns with the same units. Integers are held exactly as float64 in the tick
record and recorded as the type shown. NaN means "no value".
Events: `/pamd/<rig>/events` (JSON; its JSON schema is in every recording).
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _fields(title: str, rows: tuple[fields.Field, ...]) -> list[str]:
    out = [f"## {title}", "", "| field | unit | type | description |", "|---|---|---|---|"]
    for f in rows:
        desc = f.description
        if f.codes:
            desc += ": " + ", ".join(f"{k} {v}" for k, v in f.codes.items())
        out.append(f"| `{f.name}` | {_cell(f.unit)} | {f.type} | {_cell(desc)} |")
    return out + [""]


def _keys(keys: tuple[events.Key, ...]) -> list[str]:
    out = []
    for k in keys:
        unit = f" [{k.unit}]" if k.unit else ""
        opt = "" if k.required else " (optional)"
        out.append(f"- `{k.name}` ({'/'.join(k.types)}{unit}){opt}: {k.description}")
    return out


def generate() -> str:
    lines = [HEADER]
    lines += _fields("Loop message (one per tick)", fields.LOOP)
    head = ", ".join(f"`{n}`" for n in fields.MUSCLE_MESSAGE_HEAD)
    lines += _fields(f"Muscle message (one per muscle per tick; starts with {head})",
                     fields.MUSCLE)
    lines += _fields("Columns the exports add", fields.DERIVED)
    lines += ["## Flag bits (`flags`)", "", "| bit | value | name | meaning |",
              "|---|---|---|---|"]
    for flag, meaning in fields.FLAG_MEANINGS.items():
        bit = int(flag).bit_length() - 1
        lines.append(f"| {bit} | {int(flag)} | {flag.name} | {_cell(meaning)} |")
    lines += ["", "## Supervisor states (`state`)", "", "| code | name | meaning |",
              "|---|---|---|"]
    lines += [f"| {int(s)} | {s.name} | {m} |" for s, m in fields.STATE_MEANINGS.items()]
    lines += ["", "## Control modes (`mode`)", "", "| code | name | meaning |", "|---|---|---|"]
    lines += [f"| {int(m)} | {m.name.lower()} | {t} |" for m, t in fields.MODE_MEANINGS.items()]
    lines += ["", "## Events", "",
              "Each event is `{t_s, tick, kind, data}`: `kind` is the event's name (the headings "
              "below), `data` holds the keys listed under it.", ""]
    for k in events.DECLARED:
        where = "" if k.recorded else " Published on Zenoh only, not recorded."
        lines.append(f"### `{k.name}`")
        lines.append("")
        lines.append(f"{k.meaning[0].upper()}{k.meaning[1:]}. Emitted by: {k.emitted_by}.{where}")
        lines.append("")
        lines += _keys(k.payload)
        if k.extra:
            lines.append(f"- and: {k.extra}")
        lines.append("")
    lines += ["## Command verdicts", "",
              "The reply to every command (and the verdict inside its `command` event):", ""]
    lines += _keys(events.VERDICT)
    lines.append(f"- and: {events.VERDICT_EXTRA}")
    lines += ["", "## Old names (deprecated)", "",
              f"Still served beside their new names, and go in pamd {deprecated.REMOVED_IN}: "
              "use the new ones.", "", "| old | new | where, and how the old one still works |",
              "|---|---|---|"]
    lines += [f"| `{o.old}` | `{o.new}` | {_cell(o.where)} |" for o in deprecated.OLD_NAMES]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(generate(), end="")
