"""Message schemas and their ROS 2 CDR encoding, packed by hand with `struct`.

Every per-tick message is a flat ROS 2 message of primitives, so its `ros2msg`
schema text is all a reader needs (Foxglove, `mcap_ros2.decoder`, any CDR reader).
CDR (little-endian, encapsulation header 00 01 00 00) aligns each primitive to its
own size, counted from the end of the 4-byte header; `compile_record` computes that
padding once and builds one `struct.Struct` that packs the whole MCAP Message record
(record header + CDR payload) in a single call, about 1 us.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

from pamd.wire.declare import fields

CDR_LE = b"\x00\x01\x00\x00"

PRIMITIVES: dict[str, tuple[str, int]] = {
    "bool": ("?", 1), "byte": ("B", 1), "char": ("b", 1),
    "int8": ("b", 1), "uint8": ("B", 1), "int16": ("h", 2), "uint16": ("H", 2),
    "int32": ("i", 4), "uint32": ("I", 4), "int64": ("q", 8), "uint64": ("Q", 8),
    "float32": ("f", 4), "float64": ("d", 8),
}

#: fields stored as float64 in the tick record but recorded as integers (from the table)
INT_FIELDS: dict[str, str] = {f.name: f.type for f in (*fields.LOOP, *fields.MUSCLE)
                              if f.type != "float64"}

# Schema names: all `pamd_msgs/msg/...`. Readers go by topic and encoding, never by
# schema name, so recordings made before the event schema was renamed (from
# `pamd_msgs/Event`) read the same.
MUSCLE_SCHEMA_NAME = "pamd_msgs/msg/MuscleState"
LOOP_SCHEMA_NAME = "pamd_msgs/msg/LoopTiming"
EVENT_SCHEMA_NAME = "pamd_msgs/msg/Event"

# Message record header: opcode, record length, channel id, sequence, log, publish time.
MSG_HEADER = "<BQHIQQ"
MSG_HEADER_BYTES = struct.calcsize(MSG_HEADER)
OP_MESSAGE = 5


def muscle_fields() -> list[tuple[str, str]]:
    """(name, ros2 type) of the per-muscle message: tick, t_s, then the muscle fields
    (pamd.wire.declare.fields)."""
    return [(f.name, f.type) for f in fields.muscle_message()]


def loop_fields() -> list[tuple[str, str]]:
    """(name, ros2 type) of the loop message: the loop fields (pamd.wire.declare.fields)."""
    return [(f.name, f.type) for f in fields.LOOP]


def schema_text(names_types: Sequence[tuple[str, str]], title: str) -> bytes:
    """The ros2msg text; a declared field's unit and description follow it as a comment
    (readers skip comments; a person reading the file's schema learns what it holds)."""
    lines = [f"# {title}"]
    for name, typ in names_types:
        f = fields.BY_NAME.get(name)
        note = f"  # {f.unit}: {f.description}" if f is not None else ""
        if f is not None and f.codes:
            note += " (" + ", ".join(f"{k} {v}" for k, v in f.codes.items()) + ")"
        lines.append(f"{typ} {name}{note}")
    return ("\n".join(lines) + "\n").encode()


def cdr_format(fields: Sequence[tuple[str, str]]) -> str:
    """struct format (without byte order) of a flat CDR payload after its header."""
    fmt, pos = "", 0
    for _name, typ in fields:
        code, size = PRIMITIVES[typ]
        pad = (-pos) % size
        fmt += "x" * pad + code
        pos += pad + size
    return fmt


def compile_record(fields: Sequence[tuple[str, str]]) -> struct.Struct:
    """One Struct packing (opcode, length, channel, seq, log_ns, pub_ns, header,
    *fields) into a whole MCAP Message record."""
    return struct.Struct(MSG_HEADER + "4s" + cdr_format(fields))


def compile_payload(fields: Sequence[tuple[str, str]]) -> struct.Struct:
    """Struct of a CDR payload (4-byte header then fields), for decoding."""
    return struct.Struct("<4s" + cdr_format(fields))


def record_length(rec: struct.Struct) -> int:
    """Value of the MCAP record-length field for messages packed with `rec`."""
    return rec.size - 9  # opcode (1) and length (8) are not counted


def parse_flat_schema(text: str) -> list[tuple[str, str]] | None:
    """Fields of a flat ros2msg schema of primitives, or None if it is anything else
    (arrays, nested types, constants, several definitions)."""
    fields: list[tuple[str, str]] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("==="):
            return None
        parts = line.split()
        if len(parts) != 2 or parts[0] not in PRIMITIVES or "=" in line:
            return None
        fields.append((parts[1], parts[0]))
    return fields or None
