"""An `estop` or `stop` always acts: whatever its size, JSON or extra fields, the
verb is honoured first and the rest is cut and said so (`salvage`). The README has
promised it since the first round; a 100,000-character reason through `pamd.connect`
was refused as too large and the rig did not stop.

What is kept: the verb's declared fields of the right type (text cut to
MAX_TEXT_CHARS, saying how much); what is dropped (extra fields, mistyped ones, an
unreadable or oversized payload) is named in the note, which goes into the recorded
reason and the reply."""

from __future__ import annotations

import dataclasses
import json
import re
import typing
from typing import Any

from pamd.commands import REGISTRY
from pamd.commands.schema import MAX_TEXT_CHARS, cap_text

PARSE_MAX_BYTES = 1 << 20  # parsed whole up to this; beyond, only the head is read
HEAD_BYTES = 8 * MAX_TEXT_CHARS
NOTE_CHARS = 120
_FIELD = r'"{name}"\s*:\s*"((?:[^"\\]|\\.)*)'


def _declared(verb: str) -> dict[str, Any]:
    """The verb's fields and their types."""
    declared = REGISTRY.public(verb)
    if declared is None:
        return {}
    hints = typing.get_type_hints(declared.args)
    return {f.name: hints[f.name] for f in dataclasses.fields(declared.args)}


def _fits(value: Any, tp: Any) -> bool:
    allowed = [a for a in typing.get_args(tp)] or [tp]
    if isinstance(value, bool):
        return bool in allowed
    if isinstance(value, (int, float)):
        return (float in allowed or int in allowed) and value == value and abs(value) < 1e300
    return any(a is not type(None) and isinstance(value, a) for a in allowed
               if isinstance(a, type))


def _from_head(raw: bytes, fields: dict[str, Any]) -> dict[str, Any]:
    """Text fields read from the head of a payload too large (or too broken) to parse."""
    head = raw[:HEAD_BYTES].decode("utf-8", "replace")
    out: dict[str, Any] = {}
    for name, tp in fields.items():
        if str in (typing.get_args(tp) or [tp]):
            m = re.search(_FIELD.format(name=re.escape(name)), head)
            if m:
                try:
                    out[name] = json.loads(f'"{m.group(1)}"')
                except ValueError:
                    out[name] = m.group(1)
    return out


def salvage(verb: str, raw: bytes) -> tuple[dict[str, Any], str]:
    """(payload the verb's parser takes, note of what was cut or dropped: "" if
    nothing)."""
    fields = _declared(verb)
    notes = []
    got: Any = None
    if len(raw) <= PARSE_MAX_BYTES:
        text = raw.decode("utf-8", "replace")
        try:
            got = json.loads(text) if text.strip() else {}
        except (ValueError, RecursionError):
            notes.append(f"payload of {len(raw)} bytes not JSON")
    else:
        notes.append(f"payload of {len(raw)} bytes read in part")
    if got is None:
        got = _from_head(raw, fields)
    elif not isinstance(got, dict):
        notes.append("payload not a JSON object")
        got = {}
    out: dict[str, Any] = {}
    dropped = []
    for k, v in got.items():
        tp = fields.get(k)
        if tp is None or not _fits(v, tp):
            dropped.append(cap_text(str(k), 40))
            continue
        if isinstance(v, str) and len(v) > MAX_TEXT_CHARS and len(raw) <= PARSE_MAX_BYTES:
            notes.append(f"{k} cut from {len(v)} characters")
        out[k] = v
    if dropped:
        shown = ", ".join(dropped[:8]) + (f" and {len(dropped) - 8} more" if len(dropped) > 8
                                          else "")
        notes.append(f"fields dropped: {shown}")
    note = cap_text("; ".join(notes), NOTE_CHARS)
    if note and "reason" in fields:
        reason = out.get("reason")
        base = reason if isinstance(reason, str) else DEFAULT_REASON.get(verb, verb)
        tail = f" [pamd: {note}]"
        room = max(MAX_TEXT_CHARS - len(tail) - 3, 40)
        out["reason"] = (base if len(base) <= room else base[:room] + "...") + tail
    return out, note


DEFAULT_REASON = {"estop": "emergency stop"}
